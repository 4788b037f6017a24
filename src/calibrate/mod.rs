//! Self-calibration from walking people (paper §3.2, METHOD.md §4–5).
//!
//! Tracked people give head/foot observations. The calibrator keeps a
//! bounded, spatially thinned store of them ("anchors": each the mean of a
//! track's last [`ANCHOR_SMOOTHING`] observations with the direction the
//! foot moved; a track adds one only after its foot moved
//! [`CalibrateConfig::anchor_step_px`], so a loitering person cannot
//! dominate, and each track keeps at most
//! [`CalibrateConfig::anchors_per_track`]). Every
//! [`CalibrateConfig::refit_interval`] frames with new anchors it refits:
//!
//! 1. vertical vanishing point `v` and the walkers' lean from the head–foot
//!    lines, robustly ([`vertical::fit_vertical`]);
//! 2. horizon: with the principal point at the centre the horizon is
//!    perpendicular to `p→v`, so it is one number, its distance `d` from
//!    `p`; it is the `d` under which every track keeps one height along its
//!    path ([`horizon::fit_horizon`]: the paper's head–head/foot–foot
//!    construction, measured with all of a track's anchors at once);
//! 3. eq. 3: `f² = d·|v−p|`, `tan θ = f/|v−p|`, roll `= atan2(v_x, v_y)`;
//! 4. metric scale, in one of three documented ways (see [`ScaleMode`]);
//! 5. a confidence in 0..1 from the fits' own uncertainty (the standard
//!    deviation of `f`), the number of tracks, the spatial spread and the
//!    stability between refits.
//!
//! A calibration record is produced when the estimate changes materially
//! (thresholds in the config), and a final one at the end. The store and the
//! estimate persist in a state file ([`state`]).

pub mod eval;
pub mod geometry;
pub mod horizon;
pub mod live;
pub mod state;
pub mod synth;
pub mod vertical;

use crate::config::{check_range, ConfigError};
use crate::report::record::Calibration;
use crate::rng::Rng;
use geometry::{Anchor, Degeneracy, HeadFoot, Normaliser, ViewGeometry};
use serde::{Deserialize, Serialize};
use vertical::VerticalParams;

/// The most anchors a configuration may keep (`tracks × anchors_per_track`).
/// Every refit goes over all of them, and the loop runs at the pace of the
/// refits: a 500-frame `sim:plaza` run (640x480, an AMD EPYC core) resumed
/// with a full store processed 322 frames/s with no store, 141 with 2,048
/// anchors (the default), 48 with 8,192, 24 with 16,384, 10 with 32,768
/// and 5 with 65,536; a board's core is several times slower, and cameras
/// run at 15–25 fps. 8,192 anchors are also a state file of about 1.1 MB
/// (~135 bytes each, under 200 at worst), far under
/// [`state::MAX_STATE_BYTES`].
pub const MAX_ANCHORS: usize = 8192;

/// Refits in a row that must find the same degenerate view before it is
/// logged as a warning ([`Degeneracy`]).
pub const DEGENERACY_REFITS: u32 = 3;

/// `[calibrate]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrateConfig {
    /// Scale mode (a): mean standing height of the people who pass, metres.
    pub prior_height_m: f64,
    /// Scale mode (b): known camera mounting height, metres (0 = unknown).
    pub camera_height_m: f64,
    /// Scale mode (c): height of the first person tracked long enough
    /// (the installer walking through alone), metres (0 = not used).
    pub reference_height_m: f64,
    /// Fit the walking lean with the vertical vanishing point
    /// ([`vertical`]); `false` takes every head–foot line as vertical.
    pub lean: bool,
    /// Distance of the feet's edge nearest the camera from the body's axis,
    /// as a fraction of the person's height ([`ViewGeometry::foot_offset`]):
    /// half a foot length is about 0.075 of the stature.
    pub foot_offset: f64,
    /// Radius of the top of the head as a fraction of the person's height
    /// ([`ViewGeometry::head_radius`]): a camera looking down sees the
    /// back of the head above the crown. Half the head's length or
    /// breadth is 0.045–0.056 of the stature.
    pub head_radius: f64,
    /// Random line pairs tried for the vanishing point's starting point.
    pub ransac_iterations: usize,
    /// A track adds an anchor after its foot moved this far, pixels.
    pub anchor_step_px: f64,
    /// Anchors kept per track (the store holds `tracks × this`).
    pub anchors_per_track: usize,
    /// Tracks kept in the store (the oldest is replaced when full).
    pub tracks: usize,
    /// Frames between refits (when new anchors arrived).
    pub refit_interval: u32,
    /// Below this tilt the view is "near level" (degrees).
    pub min_tilt_deg: f64,
    /// Above this tilt the view is "near vertical" (degrees).
    pub max_tilt_deg: f64,
    /// A calibration record is sent when the focal length or the camera
    /// height moves by this fraction, or an angle by `emit_angle_deg`, or
    /// the confidence by 0.05.
    pub emit_focal_change: f64,
    /// Angle change that triggers a calibration record, degrees.
    pub emit_angle_deg: f64,
    /// Seconds of stream time between state file writes, when new anchors
    /// arrived (whether or not the estimate moved).
    pub state_interval_s: f64,
    /// RANSAC seed (replays are deterministic).
    pub seed: u64,
}

impl Default for CalibrateConfig {
    fn default() -> Self {
        CalibrateConfig {
            prior_height_m: 1.70,
            camera_height_m: 0.0,
            reference_height_m: 0.0,
            lean: true,
            foot_offset: 0.08,
            head_radius: 0.05,
            ransac_iterations: 300,
            anchor_step_px: 6.0,
            anchors_per_track: 32,
            tracks: 64,
            refit_interval: 10,
            min_tilt_deg: 4.0,
            max_tilt_deg: 60.0,
            emit_focal_change: 0.01,
            emit_angle_deg: 0.25,
            state_interval_s: 30.0,
            seed: 1,
        }
    }
}

impl CalibrateConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("calibrate.prior_height_m", self.prior_height_m, 0.5..=2.5)?;
        // 0 = unset; a set length must be a plausible one.
        for (key, v, lo, hi) in [
            (
                "calibrate.camera_height_m",
                self.camera_height_m,
                0.5,
                100.0,
            ),
            (
                "calibrate.reference_height_m",
                self.reference_height_m,
                0.5,
                2.5,
            ),
        ] {
            if v != 0.0 && !(lo..=hi).contains(&v) {
                return Err(ConfigError::unset_or(
                    key,
                    v,
                    format_args!("a value in {lo}..={hi}"),
                ));
            }
        }
        if self.camera_height_m > 0.0 && self.reference_height_m > 0.0 {
            return Err(ConfigError::invalid(
                "calibrate.reference_height_m",
                self.reference_height_m,
                "set either it or calibrate.camera_height_m, not both (each fixes the scale)",
            ));
        }
        check_range("calibrate.foot_offset", self.foot_offset, 0.0..=0.3)?;
        check_range("calibrate.head_radius", self.head_radius, 0.0..=0.15)?;
        check_range(
            "calibrate.ransac_iterations",
            self.ransac_iterations,
            10..=10000,
        )?;
        check_range("calibrate.anchor_step_px", self.anchor_step_px, 0.0..=500.0)?;
        check_range(
            "calibrate.anchors_per_track",
            self.anchors_per_track,
            4..=256,
        )?;
        check_range("calibrate.tracks", self.tracks, 2..=1024)?;
        let anchors = self.tracks * self.anchors_per_track;
        if anchors > MAX_ANCHORS {
            return Err(ConfigError::invalid(
                "calibrate.tracks",
                self.tracks,
                format_args!(
                    "calibrate.tracks × calibrate.anchors_per_track = {} × {} = {anchors} \
                     anchors, more than the {MAX_ANCHORS} the calibration can refit at frame rate",
                    self.tracks, self.anchors_per_track
                ),
            ));
        }
        check_range("calibrate.refit_interval", self.refit_interval, 1..=100000)?;
        check_range("calibrate.min_tilt_deg", self.min_tilt_deg, 0.0..=45.0)?;
        check_range("calibrate.max_tilt_deg", self.max_tilt_deg, 45.0..=90.0)?;
        check_range(
            "calibrate.emit_focal_change",
            self.emit_focal_change,
            0.0..=1.0,
        )?;
        check_range("calibrate.emit_angle_deg", self.emit_angle_deg, 0.0..=45.0)?;
        check_range(
            "calibrate.state_interval_s",
            self.state_interval_s,
            0.0..=86400.0,
        )?;
        Ok(())
    }

    /// The scale mode these values select: a known camera height wins, then
    /// a reference person, else the population prior.
    pub fn scale_mode(&self) -> ScaleMode {
        if self.camera_height_m > 0.0 {
            ScaleMode::CameraHeight(self.camera_height_m)
        } else if self.reference_height_m > 0.0 {
            ScaleMode::ReferencePerson(self.reference_height_m)
        } else {
            ScaleMode::PopulationPrior(self.prior_height_m)
        }
    }
}

/// How the metric scale is set. Geometry alone fixes every height only up
/// to one factor (heights relative to the camera height); one length fixes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScaleMode {
    /// (a) The people seen have this mean height (the paper uses 1.8 m; we
    /// default to 1.70 m). Camera height = prior / interquartile mean over
    /// tracks of each track's median relative height. Absolute heights inherit the prior's
    /// error; relative heights do not.
    PopulationPrior(f64),
    /// (b) The camera is mounted this high: heights are absolute, with
    /// no assumption about the people. In principle the most accurate
    /// mode; with today's horizon bias it reads heights tall (README,
    /// "Where it stands").
    CameraHeight(f64),
    /// (c) The first person tracked long enough (8 anchors) has this
    /// height: walk through the scene alone after installation.
    ReferencePerson(f64),
}

/// How far outside the frame a resumed anchor's head or foot may lie, as a
/// fraction of the frame's width (horizontally) or height (vertically).
/// A stored point is a mean of points of regions inside the frame, so it is
/// inside too. A tenth is slack for sub-pixel estimates and for any later
/// change to how points are placed, and still far from what an edited or
/// damaged file holds (heads scaled by 1e300, a foot thousands of pixels
/// off).
pub const ANCHOR_FRAME_MARGIN: f64 = 0.1;

/// The least head-to-foot extent of a resumed anchor, pixels: no region
/// this short is classified as a person (`classify.min_height` is at least 8).
pub const MIN_ANCHOR_EXTENT_PX: f64 = 1.0;

/// What [`Calibrator::resume`] did with a state's anchors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Resumed {
    /// Anchors restored into the store.
    pub restored: usize,
    /// Anchors dropped for a point outside the frame.
    pub outside: usize,
    /// Anchors dropped as impossible otherwise (a non-finite value, a head
    /// not above the foot, a motion longer than a unit vector).
    pub impossible: usize,
}

/// The current calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Vanishing geometry (pixels).
    pub geom: ViewGeometry,
    /// Camera height above the ground, metres.
    pub camera_height: f64,
    /// Head–foot lines supporting `v`.
    pub inliers: u32,
    /// Anchors the horizon fit used.
    pub horizon_inliers: u32,
    /// Standard deviation of the focal length as a fraction of it.
    pub focal_rel_sigma: f64,
    /// Walking lean: head offset across the vertical per unit extent for a
    /// walker crossing the view ([`vertical::VerticalFit::lean`]).
    pub lean: f64,
    /// Confidence 0..1.
    pub confidence: f64,
    /// Why eq. 3 is unreliable for this view, if it is.
    pub degeneracy: Option<Degeneracy>,
    /// Bumped at every refit that changed the estimate (for re-measuring).
    pub version: u32,
}

impl Estimate {
    /// Height in metres of a head/foot observation with this calibration.
    pub fn height(&self, o: &HeadFoot) -> Option<f64> {
        self.geom.height_ratio(o).map(|r| r * self.camera_height)
    }

    /// The report record.
    pub fn record(&self, frame: u64, is_final: bool) -> Calibration {
        let h = self.geom.horizon();
        Calibration {
            frame,
            f_px: self.geom.focal() as f32,
            tilt_deg: self.geom.tilt().to_degrees() as f32,
            roll_deg: self.geom.roll().to_degrees() as f32,
            camera_height_m: self.camera_height as f32,
            horizon: [h[0] as f32, h[1] as f32, h[2] as f32],
            vertical_vp: [self.geom.v[0] as f32, self.geom.v[1] as f32],
            inliers: self.inliers,
            confidence: self.confidence as f32,
            is_final,
        }
    }
}

/// Consecutive observations of a track averaged into each anchor.
///
/// One frame's head and foot come from region extremes and are noisy by a
/// few pixels; on an 80–100 px person that turns the head–foot line by
/// about 5°, as much as the true verticals fan out across the image, and a
/// vanishing-point fit on such lines comes out too far away (attenuation
/// bias: tilt too low; bench/RESULTS.md, "End to end"). Consecutive frames
/// see almost the same line, so their mean has √k less noise.
pub const ANCHOR_SMOOTHING: usize = 8;

/// Per-track slot of the anchor store.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Slot {
    id: u32,
    used: bool,
    len: usize,
    last_frame: u64,
    /// Order of first appearance (for the reference-person mode).
    seq: u64,
    /// The track's latest observations (ring), averaged into its anchors.
    recent: [HeadFoot; ANCHOR_SMOOTHING],
    /// Observations in `recent` (saturates at its length).
    recent_len: usize,
    /// Next write position in `recent`.
    recent_pos: usize,
}

/// A foot displacement over the smoothing window shorter than this
/// fraction of the person's extent scales the motion direction down toward
/// zero: a person standing or shuffling has no walking lean, and the
/// direction of a tiny displacement is noise.
const WALKING_DISPLACEMENT: f64 = 0.1;

impl Slot {
    /// Adds an observation and returns the mean of the latest ones, with
    /// the direction the foot moved across them.
    fn smooth(&mut self, o: HeadFoot) -> Anchor {
        self.recent[self.recent_pos] = o;
        self.recent_pos = (self.recent_pos + 1) % ANCHOR_SMOOTHING;
        self.recent_len = (self.recent_len + 1).min(ANCHOR_SMOOTHING);
        let n = self.recent_len as f64;
        let mut m = Anchor::default();
        for r in &self.recent[..self.recent_len] {
            for i in 0..2 {
                m.head[i] += r.head[i] / n;
                m.foot[i] += r.foot[i] / n;
            }
        }
        // Oldest to newest observation of the ring.
        let newest = (self.recent_pos + ANCHOR_SMOOTHING - 1) % ANCHOR_SMOOTHING;
        let oldest = if self.recent_len < ANCHOR_SMOOTHING {
            0
        } else {
            self.recent_pos
        };
        let (a, b) = (self.recent[oldest].foot, self.recent[newest].foot);
        let mv = [b[0] - a[0], b[1] - a[1]];
        let len = (mv[0] * mv[0] + mv[1] * mv[1]).sqrt();
        let full = WALKING_DISPLACEMENT * m.extent();
        if len > 1e-9 && full > 0.0 {
            let k = (len / full).min(1.0) / len;
            m.motion = [mv[0] * k, mv[1] * k];
        }
        m
    }
}

/// The incremental self-calibration stage. Everything it needs is allocated
/// in [`Calibrator::new`].
#[derive(Debug)]
pub struct Calibrator {
    cfg: CalibrateConfig,
    norm: Normaliser,
    slots: Vec<Slot>,
    /// `slots.len() × anchors_per_track` anchors, slot-major.
    anchors: Vec<Anchor>,
    flat: Vec<Anchor>,
    flat_slot: Vec<u16>,
    inlier: Vec<bool>,
    /// Three `f64` per anchor for the fits.
    scratch: Vec<f64>,
    ratios: Vec<f64>,
    rng: Rng,
    seq: u64,
    new_anchors: u32,
    last_refit: u64,
    estimate: Option<Estimate>,
    emitted: Option<Estimate>,
    stability: f64,
    degeneracy_told: Option<Degeneracy>,
    /// The last refit's degeneracy, how many refits in a row had it, and
    /// the version of the estimate it was read from.
    degeneracy_seen: (Option<Degeneracy>, u32, u32),
    /// State file writer, if configured.
    pub state: Option<state::StateFile>,
    last_state_write: Option<u64>,
    fps: f64,
}

impl Calibrator {
    /// Sizes the store for a `width`×`height` image.
    pub fn new(cfg: &CalibrateConfig, width: usize, height: usize) -> Self {
        let total = cfg.tracks * cfg.anchors_per_track;
        Calibrator {
            cfg: cfg.clone(),
            norm: Normaliser::for_image(width, height),
            slots: vec![Slot::default(); cfg.tracks],
            anchors: vec![Anchor::default(); total],
            flat: Vec::with_capacity(total),
            flat_slot: Vec::with_capacity(total),
            inlier: vec![false; total],
            scratch: vec![0.0; 3 * total],
            ratios: Vec::with_capacity(cfg.anchors_per_track.max(cfg.tracks)),
            rng: Rng::new(cfg.seed),
            seq: 0,
            new_anchors: 0,
            last_refit: 0,
            estimate: None,
            emitted: None,
            stability: 0.0,
            degeneracy_told: None,
            degeneracy_seen: (None, 0, 0),
            state: None,
            last_state_write: None,
            fps: 25.0,
        }
    }

    /// Frames per second of the stream (for the state write interval).
    pub fn set_fps(&mut self, fps: f64) {
        if fps > 0.0 {
            self.fps = fps;
        }
    }

    /// The current estimate, if there is one.
    pub fn estimate(&self) -> Option<&Estimate> {
        self.estimate.as_ref()
    }

    /// Anchors stored now.
    pub fn anchor_count(&self) -> usize {
        self.slots.iter().filter(|s| s.used).map(|s| s.len).sum()
    }

    /// Most anchors the store holds (`tracks × anchors_per_track`).
    pub fn anchor_capacity(&self) -> usize {
        self.cfg.tracks * self.cfg.anchors_per_track
    }

    /// One observation of track `id` in frame `frame` (already checked by
    /// the tracker: single person, not at the border, not cut).
    pub fn observe(&mut self, frame: u64, id: u32, o: HeadFoot) {
        if !(o.head[1] < o.foot[1]) || !o.extent().is_finite() {
            return;
        }
        let slot = self.slot_of(frame, id);
        let o = self.slots[slot].smooth(o);
        if self.slots[slot].recent_len < ANCHOR_SMOOTHING {
            return; // not enough frames of this track yet
        }
        self.add_anchor(frame, slot, o);
    }

    /// The slot of track `id`, taking a free one (else the one seen longest
    /// ago) for a new track.
    fn slot_of(&mut self, frame: u64, id: u32) -> usize {
        match self.slots.iter().position(|s| s.used && s.id == id) {
            Some(s) => s,
            None => {
                // A free slot, else replace the track seen longest ago.
                let s = self.slots.iter().position(|s| !s.used).unwrap_or_else(|| {
                    let mut best = 0;
                    for (i, s) in self.slots.iter().enumerate() {
                        if s.last_frame < self.slots[best].last_frame {
                            best = i;
                        }
                    }
                    best
                });
                self.seq += 1;
                self.slots[s] = Slot {
                    id,
                    used: true,
                    len: 0,
                    last_frame: frame,
                    seq: self.seq,
                    ..Slot::default()
                };
                s
            }
        }
    }

    /// Stores `o` as the next anchor of `slot` unless it is within
    /// `anchor_step_px` of the previous one; thins a full track.
    fn add_anchor(&mut self, frame: u64, slot: usize, o: Anchor) {
        let k = self.cfg.anchors_per_track;
        let base = slot * k;
        let len = self.slots[slot].len;
        if len > 0 {
            let last = self.anchors[base + len - 1];
            let step =
                ((o.foot[0] - last.foot[0]).powi(2) + (o.foot[1] - last.foot[1]).powi(2)).sqrt();
            if step < self.cfg.anchor_step_px {
                return;
            }
        }
        self.slots[slot].last_frame = frame;
        if len == k {
            // Full: keep every other anchor so the track's path stays
            // covered end to end with half the density.
            for i in 0..k / 2 {
                self.anchors[base + i] = self.anchors[base + 2 * i + 1];
            }
            self.slots[slot].len = k / 2;
        }
        let len = self.slots[slot].len;
        self.anchors[base + len] = o;
        self.slots[slot].len = len + 1;
        self.new_anchors += 1;
    }

    /// Refits when due; returns a calibration record when the estimate
    /// changed materially since the last one returned.
    pub fn update(&mut self, frame: u64) -> Option<Calibration> {
        if self.new_anchors == 0 || frame < self.last_refit + u64::from(self.cfg.refit_interval) {
            return None;
        }
        self.last_refit = frame;
        self.new_anchors = 0;
        self.refit();
        // The anchors changed: saved on the interval whether or not the
        // estimate moved enough for a record (a settled calibration keeps
        // learning, and a power cut must not lose it all).
        let due = self
            .last_state_write
            .is_none_or(|f| (frame - f) as f64 >= self.cfg.state_interval_s * self.fps);
        if due && self.state.is_some() {
            self.last_state_write = Some(frame);
            self.save_state();
        }
        let est = self.estimate?;
        self.tell_degeneracy(&est);
        let material = match &self.emitted {
            None => true,
            Some(e) => {
                (est.geom.focal() / e.geom.focal() - 1.0).abs() > self.cfg.emit_focal_change
                    || (est.geom.tilt() - e.geom.tilt()).abs().to_degrees()
                        > self.cfg.emit_angle_deg
                    || (est.geom.roll() - e.geom.roll()).abs().to_degrees()
                        > self.cfg.emit_angle_deg
                    || (est.camera_height / e.camera_height - 1.0).abs()
                        > self.cfg.emit_focal_change
                    || (est.confidence - e.confidence).abs() > 0.05
            }
        };
        if !material {
            return None;
        }
        self.emitted = Some(est);
        Some(est.record(frame, false))
    }

    /// The final calibration record (and a last state write).
    pub fn finish(&mut self, frame: u64) -> Option<Calibration> {
        if self.new_anchors > 0 {
            self.new_anchors = 0;
            self.refit();
        }
        if self.state.is_some() {
            self.save_state();
        }
        // The final calibration is what the user keeps: a degenerate one is
        // said however briefly it has been so.
        if let Some(dg) = self.estimate.and_then(|e| e.degeneracy) {
            self.warn_of(dg, "calibration (final)");
        }
        if let Some(st) = self.state.as_ref().filter(|st| st.in_use_elsewhere()) {
            log::warn!(
                "calibration state {}: not saved ({} to the end of this run)",
                st.path().display(),
                state::IN_USE
            );
        }
        self.estimate.map(|e| e.record(frame, true))
    }

    fn save_state(&mut self) {
        let Some(mut st) = self.state.take() else {
            return;
        };
        let k = self.cfg.anchors_per_track;
        let view = state::StateView {
            width: (self.norm.p[0] * 2.0 + 1.0).round() as u32,
            height: (self.norm.p[1] * 2.0 + 1.0).round() as u32,
            tracks: &self.slots,
            anchors: &self.anchors,
            per_track: k,
        };
        if let Err(e) = st.write(&view) {
            // The write is atomic (a temporary file renamed over it), so a
            // failure leaves the last good state in place: say so, the
            // installer's next question is whether it was lost.
            log::warn!(
                "calibration state {}: not saved: {e}; the file keeps the state saved before",
                st.path().display()
            );
        }
        self.state = Some(st);
    }

    /// Resumes from a loaded state (anchors of earlier runs). Returns the
    /// anchors restored and dropped, or, when the state is for another
    /// frame size, that size and this calibrator's (`[saved w, h, own w, h]`),
    /// restoring nothing.
    ///
    /// Anchors no run can have stored are dropped, not resumed: a point
    /// farther outside the frame than [`ANCHOR_FRAME_MARGIN`] of its size
    /// (anchors are means of observations of regions inside the frame;
    /// border-touching ones are rejected), a non-finite value, a head not
    /// at least [`MIN_ANCHOR_EXTENT_PX`] above the foot, a motion longer
    /// than a unit vector. Heads scaled by 1e300 once silenced the
    /// calibration and were written back.
    pub fn resume(&mut self, saved: &state::Saved) -> Result<Resumed, [u32; 4]> {
        let w = (self.norm.p[0] * 2.0 + 1.0).round() as u32;
        let h = (self.norm.p[1] * 2.0 + 1.0).round() as u32;
        if saved.width != w || saved.height != h {
            return Err([saved.width, saved.height, w, h]);
        }
        let (mx, my) = (
            ANCHOR_FRAME_MARGIN * f64::from(w),
            ANCHOR_FRAME_MARGIN * f64::from(h),
        );
        let in_frame = |p: [f64; 2]| {
            (-mx..=f64::from(w) + mx).contains(&p[0]) && (-my..=f64::from(h) + my).contains(&p[1])
        };
        let mut r = Resumed::default();
        // Earlier runs' track ids could collide with this run's: give them
        // ids from the top of the range.
        for (i, t) in saved.tracks.iter().enumerate() {
            let id = u32::MAX - i as u32;
            for a in t {
                let finite = a.head.iter().chain(&a.foot).chain(&a.motion);
                if !finite.into_iter().all(|x| x.is_finite()) {
                    r.impossible += 1;
                } else if !in_frame(a.head) || !in_frame(a.foot) {
                    r.outside += 1;
                } else if a.foot[1] - a.head[1] < MIN_ANCHOR_EXTENT_PX
                    || a.motion[0] * a.motion[0] + a.motion[1] * a.motion[1] > 1.0 + 1e-9
                {
                    r.impossible += 1;
                } else {
                    // Saved anchors were smoothed and thinned when first
                    // stored: they go straight into the store.
                    let slot = self.slot_of(0, id);
                    self.add_anchor(0, slot, *a);
                    r.restored += 1;
                }
            }
        }
        self.new_anchors = 0;
        self.refit();
        self.emitted = None;
        Ok(r)
    }

    /// The full refit (bounded work: every stored anchor a few dozen times).
    fn refit(&mut self) {
        self.flat.clear();
        self.flat_slot.clear();
        for s in 0..self.slots.len() {
            if !self.slots[s].used {
                continue;
            }
            let k = self.cfg.anchors_per_track;
            for i in 0..self.slots[s].len {
                self.flat.push(self.anchors[s * k + i]);
                self.flat_slot.push(s as u16);
            }
        }
        let params = VerticalParams {
            iterations: self.cfg.ransac_iterations,
            lean: self.cfg.lean,
        };
        let n = self.flat.len();
        let Some(vfit) = vertical::fit_vertical(
            &self.flat,
            &self.norm,
            &params,
            &mut self.rng,
            &mut self.inlier[..n],
            &mut self.scratch[..n],
        ) else {
            return;
        };
        // The horizon needs a finite vanishing point (a level camera has
        // none: NearLevel, and no estimate).
        let Some(mut g0) =
            ViewGeometry::from_normalised(&vfit.vertical.homogeneous(), 1.0, &self.norm)
        else {
            return;
        };
        g0.foot_offset = self.cfg.foot_offset;
        g0.head_radius = self.cfg.head_radius;
        let Some(hfit) = horizon::fit_horizon(
            &self.flat,
            &self.flat_slot,
            &self.inlier[..n],
            &g0,
            self.norm.s,
            &mut self.scratch[..3 * n],
        ) else {
            return;
        };
        let geom = ViewGeometry { d: hfit.d, ..g0 };
        let camera_height = match self.scale(&geom) {
            Some(h) if h.is_finite() && h > 0.0 => h,
            _ => return,
        };
        let degeneracy = geom.degeneracy(
            self.cfg.min_tilt_deg.to_radians(),
            self.cfg.max_tilt_deg.to_radians(),
        );
        // f² = d·r: relative errors of d and r = |v − p| (r ∝ 1/w) add.
        let rel_d = hfit.sigma / hfit.d;
        let rel_r = vfit.sigma_w / vfit.vertical.w.abs().max(1e-12);
        let focal_rel_sigma = 0.5 * (rel_d * rel_d + rel_r * rel_r).sqrt();
        let prev_f = self.estimate.map(|e| e.geom.focal());
        let change = prev_f.map_or(1.0, |p| (geom.focal() / p - 1.0).abs());
        // Stability: smoothed agreement of successive refits (a focal
        // length moving by 5 % between refits counts as 1/e stable).
        self.stability = 0.7 * self.stability + 0.3 * libm::exp(-change / 0.05);
        let spread = self.spread();
        let c_tracks = 1.0 - libm::exp(-(hfit.tracks as f64) / 4.0);
        let c_prec = libm::exp(-focal_rel_sigma / 0.03);
        let mut confidence = c_tracks * c_prec * spread * self.stability;
        if degeneracy.is_some() {
            confidence *= 0.25;
        }
        let version = self.estimate.map_or(1, |e| e.version + 1);
        self.estimate = Some(Estimate {
            geom,
            camera_height,
            inliers: vfit.inliers as u32,
            horizon_inliers: hfit.anchors as u32,
            focal_rel_sigma,
            lean: vfit.lean,
            confidence: confidence.clamp(0.0, 1.0),
            degeneracy,
            version,
        });
    }

    /// Warns of a degenerate view once it has held for
    /// [`DEGENERACY_REFITS`] refits in a row (an early fit from a few
    /// people can pass through one on its way to a good estimate: PETS
    /// read "nearly level" for one refit at frame 132, then settled at a
    /// 15.8° tilt), and says so when a view it warned of no longer is.
    /// Returns what it logged: the degeneracy warned of, or `None` for the
    /// all-clear (an outer `None`: nothing).
    fn tell_degeneracy(&mut self, est: &Estimate) -> Option<Option<Degeneracy>> {
        let (seen, n, version) = self.degeneracy_seen;
        if version == est.version {
            // A refit that failed left the estimate as it was: no new look.
            return None;
        }
        let run = if seen == est.degeneracy {
            n.saturating_add(1)
        } else {
            1
        };
        self.degeneracy_seen = (est.degeneracy, run, est.version);
        match (est.degeneracy, self.degeneracy_told) {
            (Some(dg), _) if run >= DEGENERACY_REFITS => {
                self.warn_of(dg, "calibration").then_some(Some(dg))
            }
            // As many clean refits to withdraw it: a view near the limit
            // must not flap between the two.
            (None, Some(_)) if run >= DEGENERACY_REFITS => {
                log::info!(
                    "calibration: the view is no longer degenerate (f {:.0} px, tilt {:.1}°)",
                    est.geom.focal(),
                    est.geom.tilt().to_degrees()
                );
                self.degeneracy_told = None;
                Some(None)
            }
            _ => None,
        }
    }

    /// Warns of `dg` unless it is what was last told; whether it did.
    fn warn_of(&mut self, dg: Degeneracy, what: &str) -> bool {
        let new = self.degeneracy_told != Some(dg);
        if new {
            log::warn!("{what}: {}", dg.describe());
            self.degeneracy_told = Some(dg);
        }
        new
    }

    /// Spatial spread of the anchors' feet: occupied cells of a 4×4 grid
    /// over the image, 6 or more counting as full spread.
    fn spread(&self) -> f64 {
        let mut cells = 0u16;
        let (w, h) = (self.norm.p[0] * 2.0 + 1.0, self.norm.p[1] * 2.0 + 1.0);
        for a in &self.flat {
            let cx = ((a.foot[0] / w * 4.0) as i64).clamp(0, 3);
            let cy = ((a.foot[1] / h * 4.0) as i64).clamp(0, 3);
            cells |= 1 << (cy * 4 + cx);
        }
        (f64::from(cells.count_ones()) / 6.0).min(1.0)
    }

    /// Camera height from the configured scale mode and the geometry.
    fn scale(&mut self, geom: &ViewGeometry) -> Option<f64> {
        match self.cfg.scale_mode() {
            ScaleMode::CameraHeight(h) => Some(h),
            ScaleMode::PopulationPrior(mean) => {
                // Each track's median height ratio; the interquartile mean
                // over tracks, so that a dog, a fragment or two people
                // merged into one track do not move the scale.
                let mut n = 0usize;
                for s in 0..self.slots.len() {
                    if self.slots[s].used && self.slots[s].len >= 3 && n < self.scratch.len() {
                        if let Some(r) = self.median_ratio(s, geom) {
                            self.scratch[n] = r;
                            n += 1;
                        }
                    }
                }
                let rs = &mut self.scratch[..n];
                rs.sort_unstable_by(f64::total_cmp);
                let (lo, hi) = if n >= 4 { (n / 4, n - n / 4) } else { (0, n) };
                let mid = &rs[lo..hi];
                let m = mid.iter().sum::<f64>() / mid.len().max(1) as f64;
                (n > 0 && m > 0.0).then(|| mean / m)
            }
            ScaleMode::ReferencePerson(h) => {
                let mut best: Option<usize> = None;
                for (i, s) in self.slots.iter().enumerate() {
                    if s.used && s.len >= 8 && best.is_none_or(|b| s.seq < self.slots[b].seq) {
                        best = Some(i);
                    }
                }
                let r = self.median_ratio(best?, geom)?;
                (r > 0.0).then(|| h / r)
            }
        }
    }

    fn median_ratio(&mut self, s: usize, geom: &ViewGeometry) -> Option<f64> {
        self.ratios.clear();
        let k = self.cfg.anchors_per_track;
        let geom = geom.ratio_frame();
        for i in 0..self.slots[s].len {
            if let Some(r) = geom.height_ratio(&self.anchors[s * k + i].head_foot()) {
                self.ratios.push(r);
            }
        }
        median(&mut self.ratios)
    }
}

/// Median of a scratch slice (reordered in place); `None` when empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(|a, b| a.total_cmp(b));
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

#[cfg(test)]
mod tests;
