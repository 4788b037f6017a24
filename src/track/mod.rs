//! Person tracking (paper §3.1): a small particle filter per person, snapped
//! every frame to the foreground region with the largest normalised
//! overlap (eq. 4).
//!
//! * Particles: `(cx, cy, vx, vy, scale)` of the person's box, constant
//!   velocity with noise proportional to the box size; weights from the
//!   Bhattacharyya coefficient between the HSV histogram under the particle
//!   and the track's reference histogram ([`colour`]).
//! * Snapping: each track picks the region `j` maximising
//!   `|R_j ∩ T_i| / n_j` (run-length mask against the track box). A region
//!   that one track alone picks and the classifier calls a single person
//!   snaps the track (box, head, foot) and re-centres its particles. A
//!   region picked by several tracks (people merged) or called "not a
//!   single person" leaves the track coasting on its particles and
//!   withholds its samples.
//! * Births: single-person regions nobody picked. Deaths: no region for
//!   [`TrackConfig::max_coast_s`], or a region re-acquired after a gap
//!   ([`TrackConfig::reid_gap_s`]) whose torso colours are someone else's
//!   ([`TrackConfig::reid_min_similarity`]): the track ends with its own
//!   samples and the region starts a new track. The table is a
//!   fixed-capacity `heapless` vector; births beyond it are counted in
//!   [`Tracker::overflow`].
//! * Head/foot samples (eq. 5, from the region) are kept in a bounded ring
//!   per track, rejected when the region touches the border or its
//!   head–foot extent drops or jumps suddenly (an occluder cut it, or it
//!   merged with something).

pub mod axis;
pub mod colour;

use crate::calibrate::geometry::HeadFoot;
use crate::classify::Verdict;
use crate::config::{check_range, ConfigError};
use crate::detect::{BBox, Region, RegionSet};
use crate::frame::Frame;
use crate::rng::Rng;
use colour::{bhattacharyya, ColourTable, Hist, MAX_BINS};
use heapless::HistoryBuffer;
use serde::{Deserialize, Serialize};

/// Most tracks the table can hold (config `track.capacity` ≤ this).
pub const MAX_TRACKS: usize = 32;
/// Most particles per track.
pub const MAX_PARTICLES: usize = 64;
/// Head/foot samples kept per track (the newest).
pub const RING: usize = 128;

/// Foot motion, pixels, over which a head that stayed put marks a pinned
/// region top (`TrackConfig::pinned_head_ratio`).
pub const PIN_MIN_FOOT_PX: f32 = 8.0;

/// No track owns the region.
const NO_OWNER: u8 = u8::MAX;

/// `[track]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackConfig {
    /// Tracks at once (≤ 32).
    pub capacity: usize,
    /// Particles per track (≤ 64).
    pub particles: usize,
    /// Hue bins of the colour histogram.
    pub hue_bins: usize,
    /// Saturation bins.
    pub sat_bins: usize,
    /// Value bins for grey and dark pixels.
    pub value_bins: usize,
    /// A track without any region for this long ends, seconds.
    pub max_coast_s: f64,
    /// Smallest normalised overlap (eq. 4) that counts as support.
    pub min_overlap: f64,
    /// Position noise per frame, fraction of the box width/height.
    pub position_noise: f64,
    /// Head/foot extent change between samples that marks a cut or a
    /// merge (fraction); such samples are rejected.
    pub max_extent_change: f64,
    /// A track already following a person keeps snapping to the region it
    /// alone picks when the SVM score is at least this (below the
    /// classifier's own threshold) and the region's box is the size of
    /// the track's last one: a verdict that flickers on a person walking
    /// alone does not break the track. Births still need a single-person
    /// verdict.
    pub keep_score: f64,
    /// A sample whose head row has moved less than this fraction of its
    /// foot row's motion since a run of samples began (over at least
    /// [`PIN_MIN_FOOT_PX`] of foot motion) is rejected: the region's top is
    /// pinned to something that does not move (a standing person behind,
    /// a ghost in the background model) while the walker's feet do. A
    /// walker's head moves `(H − h)/H` times as far as the feet (camera
    /// height `H`, person height `h`): 0.6 at 4.2 m, 0.32 at 2.5 m, so the
    /// default 0.15 only refuses true walkers under a camera mounted below
    /// about 2 m. 0 disables it.
    pub pinned_head_ratio: f64,
    /// Head and foot points on the silhouette's fitted body axis ([`axis`]):
    /// the rows of eq. 5, the columns of the axis. `false`: eq. 5 as the
    /// paper has it (top-most pixel, mean of the bottom-most ten).
    pub axis_points: bool,
    /// A track that snaps to a region again after this long without one
    /// (coasting alone or through a merge), seconds, first checks that the
    /// region is the same person ([`TrackConfig::reid_min_similarity`]).
    pub reid_gap_s: f64,
    /// Smallest Bhattacharyya coefficient between the torso colours of the
    /// region and the track's torso model for that re-acquisition; below
    /// it, someone else walked into the coasting track's box: the track
    /// ends (its height is reported) and the region starts a new one.
    /// 0 disables the check.
    pub reid_min_similarity: f64,
    /// Random seed of the particle filters.
    pub seed: u64,
}

impl Default for TrackConfig {
    fn default() -> Self {
        TrackConfig {
            capacity: 32,
            particles: 32,
            hue_bins: 8,
            sat_bins: 4,
            value_bins: 4,
            max_coast_s: 1.0,
            min_overlap: 0.3,
            position_noise: 0.05,
            max_extent_change: 0.15,
            keep_score: -0.5,
            pinned_head_ratio: 0.15,
            axis_points: true,
            reid_gap_s: 0.4,
            reid_min_similarity: 0.7,
            seed: 3,
        }
    }
}

impl TrackConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("track.capacity", self.capacity, 1..=MAX_TRACKS)?;
        check_range("track.particles", self.particles, 4..=MAX_PARTICLES)?;
        check_range("track.hue_bins", self.hue_bins, 1..=16)?;
        check_range("track.sat_bins", self.sat_bins, 1..=4)?;
        check_range("track.value_bins", self.value_bins, 1..=8)?;
        check_range("track.max_coast_s", self.max_coast_s, 0.05..=60.0)?;
        check_range("track.min_overlap", self.min_overlap, 0.01..=1.0)?;
        check_range("track.position_noise", self.position_noise, 0.0..=1.0)?;
        check_range(
            "track.max_extent_change",
            self.max_extent_change,
            0.01..=1.0,
        )?;
        check_range("track.pinned_head_ratio", self.pinned_head_ratio, 0.0..=1.0)?;
        check_range("track.keep_score", self.keep_score, -10.0..=10.0)?;
        check_range("track.reid_gap_s", self.reid_gap_s, 0.0..=60.0)?;
        check_range(
            "track.reid_min_similarity",
            self.reid_min_similarity,
            0.0..=1.0,
        )?;
        if self.hue_bins * self.sat_bins + self.value_bins > MAX_BINS {
            return Err(ConfigError::new(
                "track.hue_bins",
                self.hue_bins,
                format_args!("hue_bins × sat_bins + value_bins ≤ {MAX_BINS}"),
            ));
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Particle {
    cx: f32,
    cy: f32,
    vx: f32,
    vy: f32,
    scale: f32,
    w: f32,
}

/// One tracked person.
#[derive(Clone, Debug)]
pub struct Track {
    /// Track id (from 1, never reused in a run).
    pub id: u32,
    /// Current box.
    pub bbox: BBox,
    /// Box centre, width, height (float, for the particle filter).
    centre: [f32; 2],
    size: [f32; 2],
    particles: heapless::Vec<Particle, MAX_PARTICLES>,
    hist: Hist,
    /// Colour model of the torso (the box's central half by width, rows
    /// 30–70 %): mostly the person's clothes, little background, so it
    /// tells two people apart where the whole box's model does not.
    torso: Hist,
    /// Accepted head/foot samples, newest last.
    pub samples: HistoryBuffer<HeadFoot, RING>,
    /// Sample accepted this frame for calibration, if any (a sample from a
    /// region split off a larger one goes to [`Track::samples`] only).
    pub fresh: Option<HeadFoot>,
    /// A sample was added to [`Track::samples`] this frame.
    pub sampled: bool,
    /// Latest head/foot of a snapped region (accepted or not), pixels.
    pub last: HeadFoot,
    /// Frame of `last`.
    pub last_seen: u64,
    /// Box of the region snapped to at `last_seen` (`bbox` coasts on with
    /// the particles and may leave the image after the person did).
    pub seen_box: BBox,
    /// Frames it has been tracked.
    pub age: u32,
    /// Frame of the last region support.
    pub last_support: u64,
    /// Merged with another person or a non-person region now.
    pub merged: bool,
    /// The track has ended (it is removed at the next step).
    pub ended: bool,
    /// Frame of its last height record.
    pub last_report: u64,
    /// Height (metres) and samples of its last height record, if any
    /// (set by the loop; the installer snapshot shows it).
    pub reported: Option<(f32, u32)>,
    extent: f32,
    /// Head and foot rows where the current run of head rows within
    /// `pinned_head_ratio` of the foot motion began.
    pin_start: [f32; 2],
    /// Width and height of the last region it snapped to, pixels.
    snapped: [f32; 2],
    /// Regions it snapped to (saturating).
    snaps: u32,
    rejects: u8,
    prev_snap: ([f32; 2], u64),
}

impl Track {
    /// A track born at `frame_no` on a region with box `bbox`, before its
    /// particles and colour model are set.
    pub(crate) fn born(id: u32, bbox: BBox, frame_no: u64) -> Track {
        Track {
            id,
            bbox,
            centre: [0.0; 2],
            size: [0.0; 2],
            particles: heapless::Vec::new(),
            hist: [0.0; MAX_BINS],
            torso: [0.0; MAX_BINS],
            samples: HistoryBuffer::new(),
            fresh: None,
            sampled: false,
            last: HeadFoot::default(),
            last_seen: frame_no,
            seen_box: bbox,
            age: 0,
            last_support: frame_no,
            merged: false,
            ended: false,
            last_report: frame_no,
            reported: None,
            extent: 0.0,
            pin_start: [f32::NAN; 2],
            snapped: [0.0; 2],
            snaps: 0,
            rejects: 0,
            prev_snap: ([0.0; 2], frame_no),
        }
    }

    /// Accepted samples, oldest first.
    pub fn sample_iter(&self) -> impl Iterator<Item = &HeadFoot> {
        self.samples.oldest_ordered()
    }
}

/// The tracking stage.
pub struct Tracker {
    cfg: TrackConfig,
    table: ColourTable,
    tracks: Box<heapless::Vec<Track, MAX_TRACKS>>,
    /// Tracks each region was picked by this frame.
    claims: Vec<u8>,
    /// Track that owns each region this frame ([`NO_OWNER`]: none).
    owner: Vec<u8>,
    /// Region each track picked this frame, with its eq. 4 overlap.
    picks: heapless::Vec<Option<(u16, f32)>, MAX_TRACKS>,
    next_id: u32,
    rng: Rng,
    scratch: Hist,
    /// Births refused because the table was full (whole run).
    pub overflow: u64,
    /// Tracks ended because the region they re-acquired after a gap was
    /// someone else ([`TrackConfig::reid_min_similarity`]; whole run).
    pub reid_splits: u64,
}

impl Tracker {
    /// Builds the tracker for frames with up to `regions` regions.
    pub fn new(cfg: &TrackConfig, regions: usize) -> Self {
        Tracker {
            cfg: cfg.clone(),
            table: ColourTable::new(cfg.hue_bins, cfg.sat_bins, cfg.value_bins),
            tracks: Box::default(),
            claims: vec![0; regions],
            owner: vec![NO_OWNER; regions],
            picks: heapless::Vec::new(),
            next_id: 1,
            rng: Rng::new(cfg.seed),
            scratch: [0.0; MAX_BINS],
            overflow: 0,
            reid_splits: 0,
        }
    }

    /// Live tracks (and those that ended this frame, `ended` set).
    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// Mutable access (the loop records when it reported a height).
    pub fn tracks_mut(&mut self) -> &mut [Track] {
        &mut self.tracks
    }

    /// Most tracks the table holds (config `track.capacity`, at most [`MAX_TRACKS`]).
    pub fn capacity(&self) -> usize {
        self.cfg.capacity.min(MAX_TRACKS)
    }

    /// Live (not ended) tracks.
    pub fn live(&self) -> u32 {
        self.tracks.iter().filter(|t| !t.ended).count() as u32
    }

    /// One frame: predict, weigh, snap, sample, give birth, end.
    /// `verdicts[i]` is the classifier's verdict on `regions.regions()[i]`
    /// (missing verdicts count as "not a single person").
    pub fn step(
        &mut self,
        frame_no: u64,
        fps: f64,
        frame: &Frame,
        regions: &RegionSet,
        verdicts: &[Verdict],
    ) {
        // Drop the tracks that ended last frame.
        let mut i = 0;
        while i < self.tracks.len() {
            if self.tracks[i].ended {
                self.tracks.swap_remove(i);
            } else {
                i += 1;
            }
        }
        let regs = regions.regions();
        let nreg = regs.len().min(self.claims.len());
        self.claims[..nreg].fill(0);
        self.owner[..nreg].fill(NO_OWNER);
        self.picks.clear();
        let single = |j: usize| verdicts.get(j).is_some_and(|v| v.single_human);
        // 1. Particle filter, then eq. 4 against every region.
        for t in self.tracks.iter_mut() {
            t.fresh = None;
            t.sampled = false;
            pf_step(
                t,
                &self.cfg,
                &self.table,
                frame,
                &mut self.rng,
                &mut self.scratch,
            );
            let tb = box_of(t.centre, t.size);
            let tarea = f64::from(tb.width() * tb.height()).max(1.0);
            let mut best: Option<(f64, u16)> = None;
            for (j, r) in regs.iter().enumerate().take(nreg) {
                let inter = f64::from(overlap(regions, r, &tb));
                let ov = inter / f64::from(r.area.max(1));
                // Eq. 4 ranks the regions; a region much larger than the
                // track (people merged) still supports it when it covers
                // half of the track's box.
                let supports = ov >= self.cfg.min_overlap || inter / tarea >= 0.5;
                if supports && best.is_none_or(|b| ov > b.0) {
                    best = Some((ov, j as u16));
                }
            }
            if let Some((_, j)) = best {
                self.claims[j as usize] = self.claims[j as usize].saturating_add(1);
            }
            let _ = self.picks.push(best.map(|b| (b.1, b.0 as f32)));
        }
        // Owners: a region one track picked is that track's; a single
        // person's region several tracks picked is one person, so it goes
        // to the claimant overlapping it most (the oldest on a tie) and the
        // others are duplicates of it; a group's region is nobody's (every
        // claimant coasts through the merge).
        for (i, pick) in self.picks.iter().enumerate() {
            let Some((j, ov)) = *pick else { continue };
            let j = j as usize;
            let o = self.owner[j];
            if self.claims[j] == 1 {
                self.owner[j] = i as u8;
            } else if single(j) {
                let better = o == NO_OWNER
                    || self.picks[o as usize].is_some_and(|(_, b)| ov > b)
                    || (self.picks[o as usize].is_some_and(|(_, b)| ov == b)
                        && self.tracks[i].id < self.tracks[o as usize].id);
                if better {
                    self.owner[j] = i as u8;
                }
            }
        }
        // 2. Snap, coast or end.
        let coast = (self.cfg.max_coast_s * fps.max(1.0)).ceil() as u64;
        let reid_gap = (self.cfg.reid_gap_s * fps.max(1.0)).ceil() as u64;
        for (i, (t, pick)) in self.tracks.iter_mut().zip(self.picks.iter()).enumerate() {
            t.age = t.age.saturating_add(1);
            match *pick {
                Some((j, _)) if self.owner[j as usize] == i as u8 => {
                    let j = j as usize;
                    let r = &regs[j];
                    t.last_support = frame_no;
                    let keep = verdicts
                        .get(j)
                        .is_some_and(|v| f64::from(v.score) >= self.cfg.keep_score)
                        && t.snaps >= 3
                        && same_size(t.snapped, &r.bbox);
                    let someone_else = (single(j) || keep)
                        && t.snaps > 0
                        && frame_no.saturating_sub(t.prev_snap.1) >= reid_gap
                        && self.cfg.reid_min_similarity > 0.0
                        && {
                            torso_histogram(&self.table, frame, &r.bbox, &mut self.scratch);
                            let bc = bhattacharyya(&self.scratch, &t.torso);
                            f64::from(bc) < self.cfg.reid_min_similarity
                        };
                    if someone_else {
                        // End here, and let the region give birth below if
                        // no other track claims it.
                        t.ended = true;
                        t.merged = true;
                        self.claims[j] = self.claims[j].saturating_sub(1);
                        self.reid_splits += 1;
                    } else if single(j) || keep {
                        t.merged = false;
                        snap(
                            t,
                            frame_no,
                            r,
                            regions.axis_runs_of(r),
                            &self.cfg,
                            &self.table,
                            frame,
                            &mut self.scratch,
                        );
                    } else {
                        t.merged = true;
                    }
                }
                // Another track owns this one person's region: this track
                // is its duplicate (or lost it) and coasts without support.
                Some((j, _)) if self.owner[j as usize] != NO_OWNER => {
                    t.merged = true;
                    if frame_no.saturating_sub(t.last_support) > coast {
                        t.ended = true;
                    }
                }
                Some(_) => {
                    t.last_support = frame_no;
                    t.merged = true;
                }
                None => {
                    if frame_no.saturating_sub(t.last_support) > coast {
                        t.ended = true;
                    }
                }
            }
            t.bbox = box_of(t.centre, t.size);
        }
        // 3. Births from single-person regions nobody picked.
        for (j, r) in regs.iter().enumerate().take(nreg) {
            if self.claims[j] != 0 || !single(j) {
                continue;
            }
            if self.tracks.len() >= self.cfg.capacity.min(MAX_TRACKS) {
                self.overflow += 1;
                continue;
            }
            let mut t = Track::born(self.next_id, r.bbox, frame_no);
            let (c, s) = centre_of(&r.bbox);
            t.centre = c;
            t.size = s;
            self.table
                .histogram(frame, c[0], c[1], s[0], s[1], &mut t.hist);
            for _ in 0..self.cfg.particles.min(MAX_PARTICLES) {
                let _ = t.particles.push(Particle {
                    cx: c[0],
                    cy: c[1],
                    vx: 0.0,
                    vy: 0.0,
                    scale: 1.0,
                    w: 1.0,
                });
            }
            snap(
                &mut t,
                frame_no,
                r,
                regions.axis_runs_of(r),
                &self.cfg,
                &self.table,
                frame,
                &mut self.scratch,
            );
            self.next_id += 1;
            // Capacity was checked above.
            let _ = self.tracks.push(t);
        }
    }

    /// Ends every track (end of stream).
    pub fn end_all(&mut self) {
        for t in self.tracks.iter_mut() {
            t.ended = true;
        }
    }
}

/// Whether box `b` is the size of a track's last snapped box `last`
/// (width and height): what a person walking alone looks like from one
/// frame to the next, and what a merge with a neighbour or a cut by an
/// occluder is not.
fn same_size(last: [f32; 2], b: &BBox) -> bool {
    let (w, h) = (b.width() as f32, b.height() as f32);
    last[0] > 0.0
        && last[1] > 0.0
        && (0.8..=1.25).contains(&(h / last[1]))
        && (0.7..=1.45).contains(&(w / last[0]))
}

fn centre_of(b: &BBox) -> ([f32; 2], [f32; 2]) {
    (
        [
            0.5 * (f32::from(b.x0) + f32::from(b.x1)),
            0.5 * (f32::from(b.y0) + f32::from(b.y1)),
        ],
        [b.width() as f32, b.height() as f32],
    )
}

fn box_of(c: [f32; 2], s: [f32; 2]) -> BBox {
    let q = |x: f32| x.round().clamp(0.0, f32::from(u16::MAX)) as u16;
    let x0 = q(c[0] - 0.5 * (s[0] - 1.0));
    let y0 = q(c[1] - 0.5 * (s[1] - 1.0));
    BBox {
        x0,
        y0,
        x1: q(c[0] + 0.5 * (s[0] - 1.0)).max(x0),
        y1: q(c[1] + 0.5 * (s[1] - 1.0)).max(y0),
    }
}

/// `|R ∩ T|`: region pixels inside the box, from the run-length mask.
pub fn overlap(set: &RegionSet, r: &Region, b: &BBox) -> u32 {
    if r.bbox.x1 < b.x0 || r.bbox.x0 > b.x1 || r.bbox.y1 < b.y0 || r.bbox.y0 > b.y1 {
        return 0;
    }
    let mut n = 0u32;
    for run in set.runs_of(r) {
        if run.y < b.y0 || run.y > b.y1 {
            continue;
        }
        let lo = run.x0.max(b.x0);
        let hi = run.x1.min(b.x1);
        if lo <= hi {
            n += u32::from(hi - lo) + 1;
        }
    }
    n
}

/// Predict with constant velocity, weigh by colour, estimate, resample.
fn pf_step(
    t: &mut Track,
    cfg: &TrackConfig,
    table: &ColourTable,
    frame: &Frame,
    rng: &mut Rng,
    h: &mut Hist,
) {
    let (sw, sh) = (t.size[0], t.size[1]);
    let pn = cfg.position_noise as f32;
    let mut total = 0.0f32;
    for p in t.particles.iter_mut() {
        p.vx += 0.5 * pn * sw * rng.normal() as f32;
        p.vy += 0.5 * pn * sh * rng.normal() as f32;
        p.cx += p.vx + pn * sw * rng.normal() as f32;
        p.cy += p.vy + pn * sh * rng.normal() as f32;
        p.scale = (p.scale * (1.0 + 0.02 * rng.normal() as f32)).clamp(0.7, 1.4);
        table.histogram(frame, p.cx, p.cy, sw * p.scale, sh * p.scale, h);
        let bc = bhattacharyya(h, &t.hist);
        p.w = libm::expf(-20.0 * (1.0 - bc));
        total += p.w;
    }
    if total <= 0.0 || !total.is_finite() {
        return;
    }
    let (mut cx, mut cy, mut sc) = (0.0, 0.0, 0.0);
    for p in t.particles.iter_mut() {
        p.w /= total;
        cx += p.w * p.cx;
        cy += p.w * p.cy;
        sc += p.w * p.scale;
    }
    t.centre = [cx, cy];
    t.size = [sw * sc, sh * sc];
    for p in t.particles.iter_mut() {
        p.scale /= sc.max(1e-3);
    }
    // Systematic resampling in place: cumulative weights index the old
    // set, copied through a fixed-size buffer.
    let n = t.particles.len();
    let old: heapless::Vec<Particle, MAX_PARTICLES> = t.particles.clone();
    let step = 1.0 / n as f32;
    let mut u = rng.uniform() as f32 * step;
    let mut c = old[0].w;
    let mut k = 0;
    for p in t.particles.iter_mut() {
        while u > c && k + 1 < n {
            k += 1;
            c += old[k].w;
        }
        *p = old[k];
        u += step;
    }
}

/// Colour histogram of the torso of a person whose box is `b`: the central
/// half by width, rows 30–70 % of the height.
fn torso_histogram(table: &ColourTable, frame: &Frame, b: &BBox, out: &mut Hist) {
    let (c, s) = centre_of(b);
    table.histogram(frame, c[0], c[1] - 0.1 * s[1], 0.5 * s[0], 0.4 * s[1], out);
}

/// Moves a colour model a tenth of the way toward this frame's histogram.
fn blend(model: &mut Hist, h: &Hist) {
    for (m, x) in model.iter_mut().zip(h.iter()) {
        *m = 0.9 * *m + 0.1 * x;
    }
}

/// Snap to region `r`: box, particles re-centred, colour model blended,
/// and a head/foot sample unless rejected.
// The arguments are a track, its region and separate fields of the tracker
// borrowed beside it; no struct groups them naturally.
#[allow(clippy::too_many_arguments)]
fn snap(
    t: &mut Track,
    frame_no: u64,
    r: &Region,
    runs: &[crate::detect::Run],
    cfg: &TrackConfig,
    table: &ColourTable,
    frame: &Frame,
    h: &mut Hist,
) {
    let (c, s) = centre_of(&r.bbox);
    let (dx, dy) = (c[0] - t.centre[0], c[1] - t.centre[1]);
    // The snapped displacement per frame is the best velocity evidence.
    let gap = frame_no.saturating_sub(t.prev_snap.1).max(1) as f32;
    let vel = if t.age > 1 {
        [
            (c[0] - t.prev_snap.0[0]) / gap,
            (c[1] - t.prev_snap.0[1]) / gap,
        ]
    } else {
        [0.0, 0.0]
    };
    t.prev_snap = (c, frame_no);
    for p in t.particles.iter_mut() {
        p.cx += dx;
        p.cy += dy;
        p.vx = 0.5 * p.vx + 0.5 * vel[0];
        p.vy = 0.5 * p.vy + 0.5 * vel[1];
    }
    t.centre = c;
    t.size = s;
    t.bbox = r.bbox;
    t.snapped = s;
    t.snaps = t.snaps.saturating_add(1);
    table.histogram(frame, c[0], c[1], s[0], s[1], h);
    blend(&mut t.hist, h);
    torso_histogram(table, frame, &r.bbox, h);
    if t.snaps == 1 {
        t.torso = *h;
    }
    blend(&mut t.torso, h);
    let (hy, fy) = (f64::from(r.head[1]), f64::from(r.foot[1]));
    let hf = match cfg.axis_points.then(|| axis::body_axis(runs)).flatten() {
        Some(a) => HeadFoot {
            head: [a.x_at(hy), hy],
            foot: [a.x_at(fy), fy],
        },
        None => HeadFoot {
            head: [f64::from(r.head[0]), hy],
            foot: [f64::from(r.foot[0]), fy],
        },
    };
    t.last = hf;
    t.last_seen = frame_no;
    t.seen_box = r.bbox;
    if r.touches_border || r.loose_ends {
        return;
    }
    let e = (r.foot[1] - r.head[1]).max(0.0);
    let k = cfg.max_extent_change as f32;
    let sudden = t.extent > 0.0 && (e < (1.0 - k) * t.extent || e > (1.0 + k) * t.extent);
    // A persistent change is real (e.g. after a long coast): accept after 5 frames.
    if sudden && t.rejects < 5 {
        t.rejects += 1;
        return;
    }
    // The head moves with the feet (by (H − h)/H of their motion); a head
    // row that stays while the feet walk on is the top of something else.
    let (head_y, foot_y) = (r.head[1], r.foot[1]);
    let ratio = cfg.pinned_head_ratio as f32;
    let foot_moved = (foot_y - t.pin_start[1]).abs();
    let head_moved = (head_y - t.pin_start[0]).abs();
    if ratio > 0.0 && foot_moved >= PIN_MIN_FOOT_PX && head_moved < ratio * foot_moved {
        return;
    }
    if !(head_moved <= ratio * foot_moved.max(PIN_MIN_FOOT_PX)) {
        // Not pinned (or the first sample): a new run starts here.
        t.pin_start = [head_y, foot_y];
    }
    t.rejects = 0;
    t.extent = if t.extent > 0.0 && !sudden {
        0.7 * t.extent + 0.3 * e
    } else {
        e
    };
    t.samples.write(hf);
    t.sampled = true;
    // A region cut out of a larger one has a straight column for a side:
    // its height is sound, its lean is not (calibration takes no sample).
    if !r.split {
        t.fresh = Some(hf);
    }
}

#[cfg(test)]
mod tests;
