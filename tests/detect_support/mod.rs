//! Test and benchmark support for the detection stage: a float reference of
//! the same Gaussian mixture, and scoring against ground-truth boxes.
#![allow(dead_code)]

use stature::detect::morphology::BitMask;
use stature::detect::{BBox, DetectConfig, Region};
use stature::frame::Frame;
use stature::source::sim::people::Kind;
use stature::source::sim::truth::ObjectTruth;
use stature::source::sim::SimSource;

/// One float mode.
#[derive(Clone, Copy, Debug, Default)]
struct Mode {
    w: f64,
    mu: f64,
    var: f64,
}

/// Float reference of `stature::detect::background` (see its module doc for
/// the algorithm): exact `ρ = α/w`, no quantisation, no dithering, no gain
/// compensation (compare with `gain_compensation = false`).
pub struct FloatGmm {
    cfg: DetectConfig,
    k: usize,
    width: usize,
    height: usize,
    modes: Vec<Mode>,
    t: u32,
    frame: u32,
}

impl FloatGmm {
    /// A model for `width`×`height` frames.
    pub fn new(cfg: &DetectConfig, width: usize, height: usize) -> Self {
        let k = cfg.modes as usize;
        FloatGmm {
            cfg: cfg.clone(),
            k,
            width,
            height,
            modes: vec![Mode::default(); width * height * k],
            t: 0,
            frame: 0,
        }
    }

    /// Updates the model and writes the foreground mask (shadows excluded).
    pub fn apply(&mut self, frame: &Frame, mask: &mut BitMask) {
        let c = &self.cfg;
        let frames = if c.fast_startup {
            (self.t + 1).min(c.history)
        } else {
            c.history
        };
        let alpha = 1.0 / f64::from(frames);
        // Means and variances move every `n` frames at `n` times the rate,
        // per 64-pixel block, staggered (`background::updates_chunk`).
        let interval = if frames >= 16 * c.update_interval {
            c.update_interval
        } else {
            1
        };
        let alpha_fg = alpha * c.foreground_rate;
        let (tb, tg) = (
            c.background_sigma * c.background_sigma,
            c.match_sigma * c.match_sigma,
        );
        let mut fg_count = 0u64;
        for y in 0..self.height {
            for x in 0..self.width {
                let i = y * self.width + x;
                let v = f64::from(frame.y[i]);
                let update = (self.frame as usize + y + x / 64) % interval as usize == 0;
                let m = &mut self.modes[i * self.k..(i + 1) * self.k];
                let n = m.iter().take_while(|q| q.w > 0.0).count();
                if n == 0 {
                    m[0] = Mode {
                        w: alpha,
                        mu: v,
                        var: c.var_init,
                    };
                    mask.set(x, y, false);
                    continue;
                }
                let s: f64 = m.iter().map(|q| q.w).sum();
                let mut cum = 0.0;
                let mut bg = false;
                let mut matched = None;
                for (j, q) in m.iter().enumerate().take(n) {
                    let d2 = (v - q.mu) * (v - q.mu);
                    if cum < c.background_ratio * s && d2 < tb * q.var {
                        bg = true;
                    }
                    if d2 < tg * q.var {
                        matched = Some(j);
                        break;
                    }
                    cum += q.w;
                }
                let mut fg = !bg;
                if fg && c.shadow {
                    let mut cum = 0.0;
                    for q in m.iter().take(n) {
                        if cum >= c.background_ratio * s {
                            break;
                        }
                        if q.mu > 0.0 {
                            let ratio = v / q.mu;
                            if ratio >= c.shadow_min_ratio && ratio <= c.shadow_max_ratio {
                                fg = false;
                                break;
                            }
                        }
                        cum += q.w;
                    }
                }
                let a = if fg { alpha_fg } else { alpha };
                let act = a * c.complexity_prior;
                for (j, q) in m.iter_mut().enumerate().take(n) {
                    if Some(j) == matched {
                        q.w = (q.w - a * q.w + a - act).min(1.0);
                        if update {
                            let rho = (f64::from(interval) * a / q.w).min(1.0);
                            let d = v - q.mu;
                            q.mu += rho * d;
                            q.var = (q.var + rho * (d * d - q.var)).clamp(c.var_min, c.var_max);
                        }
                    } else {
                        q.w = (q.w - a * q.w - act).max(0.0);
                    }
                }
                let mut slot = match matched {
                    Some(j) => j,
                    None => {
                        let alive = m.iter().take_while(|q| q.w > 0.0).count();
                        let slot = alive.min(self.k - 1);
                        m[slot] = Mode {
                            w: a,
                            mu: v,
                            var: c.var_init,
                        };
                        slot
                    }
                };
                while slot > 0 && m[slot].w > m[slot - 1].w {
                    m.swap(slot, slot - 1);
                    slot -= 1;
                }
                // Close holes (dead modes ahead of live ones).
                let mut j = 0;
                for i2 in 0..self.k {
                    if m[i2].w > 0.0 {
                        m.swap(i2, j);
                        j += 1;
                    }
                }
                for q in m.iter_mut().skip(j) {
                    q.w = 0.0;
                }
                mask.set(x, y, fg);
                fg_count += u64::from(fg);
            }
        }
        self.t = self.t.saturating_add(1);
        let total = (self.width * self.height) as f64;
        if self.frame > 0 && fg_count as f64 > c.relearn_fraction * total {
            self.t = self.t.min(8);
        }
        self.frame += 1;
    }
}

/// Pixels on which two masks agree.
pub fn agreement(a: &BitMask, b: &BitMask) -> u64 {
    let mut diff = 0u64;
    for y in 0..a.height() {
        for (p, q) in a.row(y).iter().zip(b.row(y)) {
            diff += u64::from((p ^ q).count_ones());
        }
    }
    (a.width() * a.height()) as u64 - diff
}

/// Intersection over union of two inclusive boxes.
pub fn iou(a: &BBox, b: &BBox) -> f64 {
    let ix = (i32::from(a.x1.min(b.x1)) - i32::from(a.x0.max(b.x0)) + 1).max(0);
    let iy = (i32::from(a.y1.min(b.y1)) - i32::from(a.y0.max(b.y0)) + 1).max(0);
    let inter = f64::from(ix * iy);
    let area = |b: &BBox| f64::from(b.width() * b.height());
    inter / (area(a) + area(b) - inter)
}

/// Pixels of `a` inside `b`.
pub fn overlap(a: &BBox, b: &BBox) -> u32 {
    let ix = (i32::from(a.x1.min(b.x1)) - i32::from(a.x0.max(b.x0)) + 1).max(0);
    let iy = (i32::from(a.y1.min(b.y1)) - i32::from(a.y0.max(b.y0)) + 1).max(0);
    (ix * iy) as u32
}

/// Detection scores accumulated over frames.
#[derive(Clone, Copy, Debug, Default)]
pub struct Score {
    /// Frames scored.
    pub frames: u32,
    /// Isolated truth boxes (no other truth box touching them).
    pub isolated: u32,
    /// Of those, matched by one region with IoU ≥ 0.5.
    pub matched: u32,
    /// Sum of the best IoU of each isolated box.
    pub iou_sum: f64,
    /// Regions with less than a quarter of their box inside any truth box.
    pub false_regions: u32,
    /// All regions.
    pub regions: u32,
}

impl Score {
    /// Scores one frame's regions against its truth boxes (clipped to the image).
    pub fn add(&mut self, truth: &[BBox], regions: &[Region]) {
        self.add_filtered(truth, &[], regions);
    }
    /// As [`Score::add`], scoring as people only the boxes whose `person`
    /// flag is set (all when `person` is empty).
    pub fn add_filtered(&mut self, truth: &[BBox], person: &[bool], regions: &[Region]) {
        self.frames += 1;
        self.regions += regions.len() as u32;
        for (i, t) in truth.iter().enumerate() {
            let isolated = truth
                .iter()
                .enumerate()
                .all(|(j, o)| j == i || overlap(t, o) == 0);
            if !isolated || !person.get(i).copied().unwrap_or(true) {
                continue;
            }
            self.isolated += 1;
            let best = regions.iter().map(|r| iou(t, &r.bbox)).fold(0.0, f64::max);
            self.iou_sum += best;
            if best >= 0.5 {
                self.matched += 1;
            }
        }
        for r in regions {
            let a = r.bbox.width() * r.bbox.height();
            let inside = truth.iter().map(|t| overlap(&r.bbox, t)).max().unwrap_or(0);
            if inside * 4 < a {
                self.false_regions += 1;
            }
        }
    }
    /// Fraction of isolated people matched.
    pub fn recall(&self) -> f64 {
        f64::from(self.matched) / f64::from(self.isolated.max(1))
    }
    /// False regions per frame.
    pub fn false_per_frame(&self) -> f64 {
        f64::from(self.false_regions) / f64::from(self.frames.max(1))
    }
    /// Mean best IoU of isolated people.
    pub fn mean_iou(&self) -> f64 {
        self.iou_sum / f64::from(self.isolated.max(1))
    }
}

/// Whether a sim object is seen enough to be detectable (it counts for
/// isolation and false regions).
fn detectable(o: &ObjectTruth) -> bool {
    o.visible_fraction >= 0.5 && o.visible_px >= 100
}

/// Truth boxes of people and other objects seen enough to be detectable.
pub fn truth_boxes(src: &SimSource, out: &mut Vec<BBox>) {
    out.clear();
    out.extend(src.truth().iter().filter(|o| detectable(o)).map(|o| BBox {
        x0: o.bbox[0],
        y0: o.bbox[1],
        x1: o.bbox[2],
        y1: o.bbox[3],
    }));
}

/// Which of the [`truth_boxes`] are scored as people: walking people at
/// least 90 % visible (someone standing since frame 0 is background to
/// any background model; other objects still count for isolation and
/// false regions).
pub fn scored_people(src: &SimSource, out: &mut Vec<bool>) {
    out.clear();
    out.extend(
        src.truth()
            .iter()
            .filter(|o| detectable(o))
            .map(|o| o.kind == Kind::Person && o.walking && o.visible_fraction >= 0.9),
    );
}

/// Why an isolated truth box was not matched (IoU < 0.5 with every region).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Miss {
    /// No region touches the box.
    None,
    /// The best region also covers another truth object.
    Merged,
    /// Two or more regions lie mostly inside the box.
    Split,
    /// One region, shorter than ¾ or narrower than 0.6 of the box.
    Partial,
    /// One region, taller than 1.25 or wider than 1.4 times the box,
    /// touching no other truth object (shadow, ghost, unannotated thing).
    Grown,
    /// About the right size but shifted.
    Offset,
}

impl Miss {
    /// Every class, in report order.
    pub const ALL: [Miss; 6] = [
        Miss::None,
        Miss::Merged,
        Miss::Split,
        Miss::Partial,
        Miss::Grown,
        Miss::Offset,
    ];
}

fn box_area(b: &BBox) -> u32 {
    b.width() * b.height()
}

/// Classifies truth box `i` (isolated) against the frame's regions;
/// `None` when it is matched.
pub fn classify_miss(i: usize, truth: &[BBox], regions: &[Region]) -> Option<Miss> {
    let t = &truth[i];
    let Some(best) = regions
        .iter()
        .max_by(|a, b| iou(t, &a.bbox).total_cmp(&iou(t, &b.bbox)))
    else {
        return Some(Miss::None);
    };
    let best_iou = iou(t, &best.bbox);
    if best_iou >= 0.5 {
        return None;
    }
    if best_iou == 0.0 {
        return Some(Miss::None);
    }
    let b = best.bbox;
    let merged = truth
        .iter()
        .enumerate()
        .any(|(j, o)| j != i && overlap(&b, o) * 4 >= box_area(o));
    if merged {
        return Some(Miss::Merged);
    }
    let parts = regions
        .iter()
        .filter(|r| overlap(&r.bbox, t) * 2 >= box_area(&r.bbox))
        .count();
    let (th, tw, rh, rw) = (
        f64::from(t.height()),
        f64::from(t.width()),
        f64::from(b.height()),
        f64::from(b.width()),
    );
    Some(if parts >= 2 {
        Miss::Split
    } else if rh < 0.75 * th || rw < 0.6 * tw {
        Miss::Partial
    } else if rh > 1.25 * th || rw > 1.4 * tw {
        Miss::Grown
    } else {
        Miss::Offset
    })
}
