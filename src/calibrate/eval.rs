//! Host-side accuracy evaluation of calibration and heights from
//! ground-truth head/foot points (simulated scenes, PETS boxes), shared by
//! the tests and `bench/core_accuracy.rs`. Never used by the loop.

use super::geometry::HeadFoot;
use super::{CalibrateConfig, Calibrator, Estimate};
use crate::measure::{MeasureConfig, Measurer};
use crate::rng::Rng;
use std::collections::BTreeMap;

/// Observations of one person, in frame order, with the true height.
#[derive(Clone, Debug, Default)]
pub struct PersonObs {
    /// True height, metres (0 when unknown).
    pub height: f64,
    /// (frame, observation).
    pub obs: Vec<(u64, HeadFoot)>,
}

/// Accuracy of one run.
#[derive(Clone, Debug)]
pub struct Accuracy {
    /// Estimate with the population prior set to the seen people's mean.
    pub prior_matched: Option<Estimate>,
    /// Estimate with the true camera height.
    pub known_height: Option<Estimate>,
    /// Per person: (id, true height, estimated height with known camera height, samples).
    pub heights: Vec<(u32, f64, f64, u32)>,
}

impl Accuracy {
    /// Absolute height errors, metres, sorted.
    pub fn abs_errors(&self) -> Vec<f64> {
        let mut e: Vec<f64> = self.heights.iter().map(|h| (h.2 - h.1).abs()).collect();
        e.sort_by(f64::total_cmp);
        e
    }
    /// Scale-free relative errors: each estimate over the mean estimate
    /// against each truth over the mean truth, sorted.
    pub fn scale_free_errors(&self) -> Vec<f64> {
        let n = self.heights.len() as f64;
        let me = self.heights.iter().map(|h| h.2).sum::<f64>() / n;
        let mt = self.heights.iter().map(|h| h.1).sum::<f64>() / n;
        let mut e: Vec<f64> = self
            .heights
            .iter()
            .map(|h| (h.2 / me - h.1 / mt).abs() / (h.1 / mt))
            .collect();
        e.sort_by(f64::total_cmp);
        e
    }
}

/// Quantile of a sorted slice (nearest rank); NaN when empty.
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((q * (sorted.len() - 1) as f64).round() as usize).min(sorted.len() - 1)]
}

fn calibrate(
    people: &BTreeMap<u32, PersonObs>,
    cfg: &CalibrateConfig,
    w: usize,
    h: usize,
) -> Calibrator {
    let mut all: Vec<(u64, u32, HeadFoot)> = people
        .iter()
        .flat_map(|(id, p)| p.obs.iter().map(move |(f, o)| (*f, *id, *o)))
        .collect();
    all.sort_by_key(|x| (x.0, x.1));
    let mut c = Calibrator::new(cfg, w, h);
    for (f, id, o) in &all {
        c.observe(*f, *id, *o);
        c.update(*f);
    }
    c.finish(all.last().map_or(0, |x| x.0));
    c
}

/// Calibrates from `people` twice (matched prior, known camera height
/// `camera_height`) and measures everyone with the second estimate,
/// each person from their last `ring` observations as the tracker keeps them.
pub fn evaluate(
    people: &BTreeMap<u32, PersonObs>,
    camera_height: f64,
    w: usize,
    h: usize,
    ring: usize,
) -> Accuracy {
    let known: Vec<f64> = people
        .values()
        .filter(|p| p.height > 0.0 && p.obs.len() >= 3)
        .map(|p| p.height)
        .collect();
    let mean = if known.is_empty() {
        1.7
    } else {
        known.iter().sum::<f64>() / known.len() as f64
    };
    let prior = calibrate(
        people,
        &CalibrateConfig {
            prior_height_m: mean,
            foot_offset: 0.0,
            head_radius: 0.0,
            ..Default::default()
        },
        w,
        h,
    );
    let kh = calibrate(
        people,
        &CalibrateConfig {
            camera_height_m: camera_height,
            foot_offset: 0.0,
            head_radius: 0.0,
            ..Default::default()
        },
        w,
        h,
    );
    let est = kh.estimate().copied();
    let mcfg = MeasureConfig {
        min_confidence: 0.0,
        ..Default::default()
    };
    let mut m = Measurer::new(&mcfg, ring);
    let mut heights = Vec::new();
    for (id, p) in people {
        let start = p.obs.len().saturating_sub(ring);
        if let Some(c) = m.track_height(est.as_ref(), p.obs[start..].iter().map(|x| &x.1)) {
            heights.push((*id, p.height, c.height, c.samples));
        }
    }
    Accuracy {
        prior_matched: prior.estimate().copied(),
        known_height: est,
        heights,
    }
}

/// Head/foot points of every person the simulated scene shows at least
/// 98 % visible and 3 px inside the image, from its exact truth plus
/// Gaussian noise of `noise_px`. Returns the people, the truth camera and
/// the image size.
pub fn sim_people(
    scene: &str,
    seed: u64,
    noise_px: f64,
) -> Result<
    (
        BTreeMap<u32, PersonObs>,
        crate::camera::Camera,
        usize,
        usize,
    ),
    String,
> {
    use crate::source::sim::{people::Kind, SimSource};
    let mut sim = SimSource::open(scene, &format!("seed={seed}")).map_err(|e| e.to_string())?;
    let st = sim.scene_truth().clone();
    let (w, h) = (st.width, st.height);
    let mut frame = crate::frame::Frame::new(crate::frame::Size {
        width: w,
        height: h,
    });
    let mut rng = Rng::new(seed ^ 0xABCD);
    let mut people: BTreeMap<u32, PersonObs> = BTreeMap::new();
    let inside = |p: [f64; 2]| {
        p[0] >= 3.0 && p[1] >= 3.0 && p[0] <= w as f64 - 4.0 && p[1] <= h as f64 - 4.0
    };
    for k in 0..sim.frames() {
        sim.render(k, &mut frame);
        for o in sim.truth() {
            if o.kind != Kind::Person
                || o.visible_fraction < 0.98
                || !inside(o.head_px)
                || !inside(o.foot_px)
            {
                continue;
            }
            let mut n = |p: [f64; 2]| {
                [
                    p[0] + noise_px * rng.normal(),
                    p[1] + noise_px * rng.normal(),
                ]
            };
            let hf = HeadFoot {
                head: n(o.head_px),
                foot: n(o.foot_px),
            };
            let e = people.entry(o.id).or_default();
            e.height = o.height_m;
            e.obs.push((k, hf));
        }
    }
    Ok((people, st.camera(), w, h))
}

/// PETS 2009 S2.L1 ground-truth boxes as head/foot points (box top and
/// bottom centres, at the pixel edges), boxes at least 5 px inside the
/// image, per id; true heights from `geometry.json` `persons` medians.
pub fn pets_people(dir: &std::path::Path) -> Result<BTreeMap<u32, PersonObs>, String> {
    let gt = crate::dataset::load_pets_gt(dir)?;
    let heights = super::live::pets_person_heights(dir)?;
    let mut people: BTreeMap<u32, PersonObs> = BTreeMap::new();
    for b in &gt {
        if b.x0 < 5 || b.y0 < 5 || b.x1 > 768 - 6 || b.y1 > 576 - 6 {
            continue;
        }
        let cx = 0.5 * f64::from(b.x0 + b.x1);
        let hf = HeadFoot {
            head: [cx, f64::from(b.y0) - 0.5],
            foot: [cx, f64::from(b.y1) + 0.5],
        };
        let e = people.entry(b.id).or_default();
        e.height = heights.get(&b.id).copied().unwrap_or(0.0);
        e.obs.push((u64::from(b.frame), hf));
    }
    Ok(people)
}
