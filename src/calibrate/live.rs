//! Host-side accuracy of the whole live pipeline on a simulated scene:
//! frames through detect, classify, track, calibrate and measure exactly
//! as the loop runs them, scored against the renderer's truth. Shared by
//! the end-to-end tests and `bench/live_eval.rs`; never used by the loop.

use super::eval::quantile;
use super::geometry::HeadFoot;
use super::Estimate;
use crate::config::Config;
use crate::report::record::{Calibration, Height};
use crate::report::Reporter;
use crate::run::Pipeline;
use crate::source::sim::people::Kind;
use crate::source::sim::{SceneTruth, SimSource};
use crate::source::FrameSource;
use std::collections::{BTreeMap, BTreeSet};

/// The true object under a track's observation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Matched {
    /// Person, dog or car.
    pub kind: Kind,
    /// Its id in the clip.
    pub id: u32,
    /// Its exact head and foot points.
    pub truth: HeadFoot,
    /// Fraction of it visible.
    pub visible: f64,
}

/// One head/foot observation a track handed the calibrator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// Frame index.
    pub frame: u64,
    /// Track id.
    pub track: u32,
    /// The observed head and foot.
    pub live: HeadFoot,
    /// The true object whose box overlaps the track's most (IoU > 0.2).
    pub truth: Option<Matched>,
}

/// What one run did.
#[derive(Clone, Debug)]
pub struct LiveRun {
    /// The scene's camera.
    pub scene: SceneTruth,
    /// Every calibration observation, in frame order.
    pub observations: Vec<Observation>,
    /// The final calibration record.
    pub calibration: Option<Calibration>,
    /// The final estimate.
    pub estimate: Option<Estimate>,
    /// Final height records.
    pub final_heights: Vec<Height>,
    /// Frames each person was seen at least 90 % unoccluded, inside the image.
    pub seen_frames: BTreeMap<u32, u64>,
    /// Of those, frames in which no other visible person's box touched
    /// theirs (apart: a background model can cut them out on their own).
    pub alone_frames: BTreeMap<u32, u64>,
    /// Frames each person was counted in [`LiveRun::seen_frames`] while
    /// walking (the sim's truth: not standing still).
    pub walking_frames: BTreeMap<u32, u64>,
    /// True standing height of every person of the cast.
    pub true_heights: BTreeMap<u32, f64>,
    /// How full the loop's tables were at the end (and what they lost).
    pub occupancy: crate::run::Occupancy,
    /// Tracks ended because they re-acquired someone else (whole run).
    pub reid_splits: u64,
}

/// Intersection over union of inclusive boxes `[x0, y0, x1, y1]`.
pub fn iou(a: [f64; 4], b: [f64; 4]) -> f64 {
    let ix = (a[2].min(b[2]) - a[0].max(b[0]) + 1.0).max(0.0);
    let iy = (a[3].min(b[3]) - a[1].max(b[1]) + 1.0).max(0.0);
    let i = ix * iy;
    let area = |r: [f64; 4]| (r[2] - r[0] + 1.0) * (r[3] - r[1] + 1.0);
    i / (area(a) + area(b) - i)
}

/// Runs the pipeline with `cfg` over the sim source `uri`, calling
/// `per_frame` after every frame (diagnostics).
pub fn run_sim(
    uri: &str,
    cfg: &Config,
    mut per_frame: impl FnMut(&Pipeline, &SimSource),
) -> Result<LiveRun, String> {
    let mut sim = SimSource::open_uri(uri).map_err(|e| e.to_string())?;
    let scene = sim.scene_truth().clone();
    let info = sim.info().clone();
    let (w, h) = (info.size.width as f64, info.size.height as f64);
    let mut p = Pipeline::new(cfg, &info);
    let (mut reporter, rx, _) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let drain = std::thread::spawn(move || rx.iter().count());
    let mut observations = Vec::new();
    let mut seen_frames: BTreeMap<u32, u64> = BTreeMap::new();
    let mut alone_frames: BTreeMap<u32, u64> = BTreeMap::new();
    let mut walking_frames: BTreeMap<u32, u64> = BTreeMap::new();
    for k in 0..sim.frames() {
        sim.render(k, &mut p.frame);
        p.process(&mut reporter);
        for o in sim.truth() {
            let b = o.bbox.map(f64::from);
            if o.kind == Kind::Person
                && o.visible_fraction >= 0.9
                && b[0] > 2.0
                && b[1] > 2.0
                && b[2] < w - 3.0
                && b[3] < h - 3.0
            {
                *seen_frames.entry(o.id).or_default() += 1;
                if o.walking {
                    *walking_frames.entry(o.id).or_default() += 1;
                }
                let alone = sim.truth().iter().all(|q| {
                    q.id == o.id
                        || q.kind != Kind::Person
                        || q.visible_px < 50
                        || iou(b, q.bbox.map(f64::from)) <= 0.0
                });
                if alone {
                    *alone_frames.entry(o.id).or_default() += 1;
                }
            }
        }
        for t in p.tracker().tracks() {
            let Some(live) = t.fresh else { continue };
            let tb = [t.bbox.x0, t.bbox.y0, t.bbox.x1, t.bbox.y1].map(f64::from);
            let mut best: Option<(f64, Matched)> = None;
            for o in sim.truth() {
                let v = iou(tb, o.bbox.map(f64::from));
                if v > 0.2 && best.as_ref().is_none_or(|b| v > b.0) {
                    let truth = HeadFoot {
                        head: o.head_px,
                        foot: o.foot_px,
                    };
                    let (kind, id, visible) = (o.kind, o.id, o.visible_fraction);
                    best = Some((
                        v,
                        Matched {
                            kind,
                            id,
                            truth,
                            visible,
                        },
                    ));
                }
            }
            observations.push(Observation {
                frame: k,
                track: t.id,
                live,
                truth: best.map(|b| b.1),
            });
        }
        per_frame(&p, &sim);
    }
    p.finish(&mut reporter);
    drop(reporter);
    drain.join().map_err(|_| "report drain thread panicked")?;
    let occupancy = p.occupancy();
    let reid_splits = p.tracker().reid_splits;
    let true_heights = sim
        .cast()
        .iter()
        .filter(|m| m.kind == Kind::Person)
        .map(|m| (m.id, m.height_m))
        .collect();
    Ok(LiveRun {
        scene,
        observations,
        calibration: p.calibration.take(),
        estimate: p.estimate().copied(),
        final_heights: std::mem::take(&mut p.final_heights),
        seen_frames,
        alone_frames,
        walking_frames,
        true_heights,
        occupancy,
        reid_splits,
    })
}

/// Final calibration against the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CalibrationError {
    /// Focal length, relative (estimate / truth − 1).
    pub focal_rel: f64,
    /// Tilt, degrees (estimate − truth).
    pub tilt_deg: f64,
    /// Roll, degrees.
    pub roll_deg: f64,
    /// Camera height, relative.
    pub camera_height_rel: f64,
    /// Confidence of the estimate.
    pub confidence: f64,
}

/// Final heights against the truth.
#[derive(Clone, Debug, PartialEq)]
pub struct HeightScore {
    /// Final height records matched to a person.
    pub records: usize,
    /// Distinct people among them.
    pub people: usize,
    /// Median and 90th percentile of |estimate − truth|, metres.
    pub abs_median: f64,
    /// 90th percentile of |estimate − truth|, metres.
    pub abs_p90: f64,
    /// Mean signed error, metres.
    pub signed_mean: f64,
    /// Median of the scale-free error |e/ē − t/t̄| / (t/t̄).
    pub scale_free_median: f64,
    /// 90th percentile of the scale-free error.
    pub scale_free_p90: f64,
    /// People seen at least 3 s, 90 % unoccluded, inside the image.
    pub eligible: usize,
    /// Of them, people with a final height.
    pub measured: usize,
    /// People seen like that for at least 3 s with no other person's box
    /// touching theirs ([`LiveRun::alone_frames`]).
    pub eligible_alone: usize,
    /// Of them, people with a final height.
    pub measured_alone: usize,
    /// People seen like that for at least 3 s while walking
    /// ([`LiveRun::walking_frames`]): a background model cannot find someone
    /// who never moves.
    pub eligible_walking: usize,
    /// Of them, people with a final height.
    pub measured_walking: usize,
    /// Final heights whose track was mostly a dog or a car.
    pub non_person: usize,
}

impl LiveRun {
    /// The final calibration against the scene's camera.
    pub fn calibration_error(&self) -> Option<CalibrationError> {
        let c = self.calibration.as_ref()?;
        let s = &self.scene;
        Some(CalibrationError {
            focal_rel: f64::from(c.f_px) / s.f_px - 1.0,
            tilt_deg: f64::from(c.tilt_deg) - s.tilt_deg,
            roll_deg: f64::from(c.roll_deg) - s.roll_deg,
            camera_height_rel: f64::from(c.camera_height_m) / s.camera_height_m - 1.0,
            confidence: f64::from(c.confidence),
        })
    }

    /// The object a track's observations mostly were: (kind, id).
    pub fn majority(&self) -> BTreeMap<u32, (Kind, u32)> {
        /// Observations per (kind code, object id): the kind and the count.
        type Votes = BTreeMap<(u8, u32), (Kind, usize)>;
        let mut counts: BTreeMap<u32, Votes> = BTreeMap::new();
        for o in &self.observations {
            if let Some(m) = o.truth {
                let code = match m.kind {
                    Kind::Person => 0,
                    Kind::Dog => 1,
                    Kind::Car => 2,
                };
                counts
                    .entry(o.track)
                    .or_default()
                    .entry((code, m.id))
                    .or_insert((m.kind, 0))
                    .1 += 1;
            }
        }
        counts
            .into_iter()
            .filter_map(|(t, m)| {
                m.into_iter()
                    .max_by_key(|(_, (_, n))| *n)
                    .map(|((_, id), (k, _))| (t, (k, id)))
            })
            .collect()
    }

    /// The final heights against the true heights of the people their
    /// tracks followed.
    pub fn heights(&self) -> HeightScore {
        let majority = self.majority();
        let (mut pairs, mut non_person) = (Vec::new(), 0usize);
        for hr in &self.final_heights {
            match majority.get(&hr.track_id) {
                Some((Kind::Person, id)) => {
                    if let Some(t) = self.true_heights.get(id) {
                        pairs.push((f64::from(hr.height_m), *t, *id));
                    }
                }
                Some(_) => non_person += 1,
                None => {}
            }
        }
        let n = pairs.len().max(1) as f64;
        let mut abs: Vec<f64> = pairs.iter().map(|p| (p.0 - p.1).abs()).collect();
        abs.sort_by(f64::total_cmp);
        let (me, mt) = (
            pairs.iter().map(|p| p.0).sum::<f64>() / n,
            pairs.iter().map(|p| p.1).sum::<f64>() / n,
        );
        let mut sf: Vec<f64> = pairs
            .iter()
            .map(|p| (p.0 / me - p.1 / mt).abs() / (p.1 / mt))
            .collect();
        sf.sort_by(f64::total_cmp);
        let people: BTreeSet<u32> = pairs.iter().map(|p| p.2).collect();
        let min_frames = 3.0 * f64::from(self.scene.fps);
        // (eligible, measured): people counted for at least 3 s.
        let recall = |frames: &BTreeMap<u32, u64>| {
            let eligible = frames.values().filter(|&&f| f as f64 >= min_frames);
            let measured = frames
                .iter()
                .filter(|(id, &f)| f as f64 >= min_frames && people.contains(id));
            (eligible.count(), measured.count())
        };
        let (eligible, measured) = recall(&self.seen_frames);
        let (eligible_alone, measured_alone) = recall(&self.alone_frames);
        let (eligible_walking, measured_walking) = recall(&self.walking_frames);
        HeightScore {
            records: pairs.len(),
            people: people.len(),
            abs_median: quantile(&abs, 0.5),
            abs_p90: quantile(&abs, 0.9),
            signed_mean: pairs.iter().map(|p| p.0 - p.1).sum::<f64>() / n,
            scale_free_median: quantile(&sf, 0.5),
            scale_free_p90: quantile(&sf, 0.9),
            measured,
            eligible,
            measured_alone,
            eligible_alone,
            measured_walking,
            eligible_walking,
            non_person,
        }
    }
}

/// What a run over PETS 2009 S2.L1 did, against its real calibration.
#[derive(Clone, Debug)]
pub struct PetsRun {
    /// The real calibration (`geometry.json`).
    pub truth: crate::dataset::PetsGeometry,
    /// The final calibration record.
    pub calibration: Option<Calibration>,
    /// Each final height matched to a ground-truth person: (record,
    /// person id, the person's calibration-derived height).
    pub heights: Vec<(Height, u32, f64)>,
    /// Final height records of tracks that followed no ground-truth
    /// person (false people).
    pub unmatched: usize,
    /// Final height records of a person without a calibration-derived
    /// height in `geometry.json`.
    pub no_truth: usize,
}

impl PetsRun {
    /// Final height records beyond the first of each person (a person
    /// whose track broke up is reported more than once).
    pub fn repeated(&self) -> usize {
        let people: std::collections::BTreeSet<u32> =
            self.heights.iter().map(|(_, id, _)| *id).collect();
        self.heights.len() - people.len()
    }
}

impl PetsRun {
    /// |estimate − calibration-derived height| of the matched final
    /// heights, metres, sorted.
    pub fn abs_errors(&self) -> Vec<f64> {
        let mut e: Vec<f64> = self
            .heights
            .iter()
            .map(|(h, _, t)| (f64::from(h.height_m) - t).abs())
            .collect();
        e.sort_by(f64::total_cmp);
        e
    }
}

/// Runs the pipeline with `cfg` over the PETS 2009 S2.L1 clip in
/// `data_dir` (decoded by ffmpeg) and matches every final height to the
/// ground-truth person most of its track's head/foot samples fell on (the
/// box whose bottom centre is nearest the foot point, within a fifth of
/// the box height).
pub fn run_pets(data_dir: &std::path::Path, cfg: &Config) -> Result<PetsRun, String> {
    use crate::source::Next;
    let truth = crate::dataset::load_pets_geometry(data_dir)?;
    let gt = crate::dataset::load_pets_gt(data_dir)?;
    let persons = pets_person_heights(data_dir)?;
    let mut src = crate::dataset::pets_video(data_dir).map_err(|e| e.to_string())?;
    let info = src.info().clone();
    let mut p = Pipeline::new(cfg, &info);
    let (mut reporter, rx, _) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let drain = std::thread::spawn(move || rx.iter().count());
    // Per track, the ground-truth people its head/foot samples fell on.
    let mut votes: BTreeMap<u32, BTreeMap<u32, usize>> = BTreeMap::new();
    loop {
        match src.next_frame(&mut p.frame).map_err(|e| e.to_string())? {
            Next::Frame => {
                p.process(&mut reporter);
                let frame = (p.frames - 1) as u32;
                for t in p.tracker().tracks() {
                    let person = t.fresh.and_then(|hf| pets_person_at(&gt, frame, hf.foot));
                    if let Some(id) = person {
                        *votes.entry(t.id).or_default().entry(id).or_default() += 1;
                    }
                }
            }
            Next::Waiting => continue,
            Next::End => break,
        }
    }
    p.finish(&mut reporter);
    drop(reporter);
    drain.join().map_err(|_| "report drain thread panicked")?;
    let (mut heights, mut unmatched, mut no_truth) = (Vec::new(), 0, 0);
    for h in std::mem::take(&mut p.final_heights) {
        // The person most of the track's samples were on; a track that
        // gave no sample on anyone, by where it was last seen.
        let person = votes
            .get(&h.track_id)
            .and_then(|v| v.iter().max_by_key(|(_, &n)| n).map(|(&id, _)| id))
            .or_else(|| pets_person_at(&gt, h.frame as u32, h.foot_px.map(f64::from)));
        match person {
            Some(id) => match persons.get(&id) {
                Some(&t) => heights.push((h, id, t)),
                None => no_truth += 1,
            },
            None => unmatched += 1,
        }
    }
    Ok(PetsRun {
        truth,
        calibration: p.calibration.take(),
        heights,
        unmatched,
        no_truth,
    })
}

/// The ground-truth person of PETS frame `frame` whose box's bottom
/// centre is nearest `foot`, within a fifth of that box's height.
fn pets_person_at(gt: &[crate::dataset::GtBox], frame: u32, foot: [f64; 2]) -> Option<u32> {
    crate::dataset::boxes_of_frame(gt, frame)
        .iter()
        .map(|b| {
            let bx = 0.5 * f64::from(b.x0 + b.x1);
            let d = ((bx - foot[0]).powi(2) + (f64::from(b.y1) - foot[1]).powi(2)).sqrt();
            (d / f64::from(b.y1 - b.y0 + 1), b.id)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .filter(|&(v, _)| v <= 0.2)
        .map(|(_, id)| id)
}

/// Each ground-truth person's height from the real calibration
/// (`geometry.json` `persons.ID.height_m_median`).
pub fn pets_person_heights(data_dir: &std::path::Path) -> Result<BTreeMap<u32, f64>, String> {
    let path = data_dir.join("pets2009-s2l1/geometry.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let persons = json["persons"]
        .as_object()
        .ok_or_else(|| format!("{}: no `persons`", path.display()))?;
    let mut out = BTreeMap::new();
    for (id, v) in persons {
        if let (Ok(id), Some(h)) = (id.parse::<u32>(), v["height_m_median"].as_f64()) {
            out.insert(id, h);
        }
    }
    Ok(out)
}
