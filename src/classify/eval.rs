//! Held-out evaluation of a classifier (host side, never in the loop):
//! PETS 2009 S2.L1 frames 600–794 and simulated clips with seeds the
//! trainer never uses, scored through the production [`Classifier`] path;
//! accuracy, precision and recall per source and kind, and a DET table.

use super::samples::{self, Detection, Kind, Labelled, Origin, PerFrame, Rng};
use super::svm::Model;
use super::train::{for_pets_frames, PETS_TRAIN_LAST, SIM_EVAL_SEEDS, SIM_SCENES, SIM_STRIDE};
use super::{Classifier, ClassifyConfig};
use crate::dataset;
use crate::detect::morphology::BitMask;
use crate::frame::Plane;
use std::fmt::Write as _;
use std::path::Path;

/// One scored evaluation box.
#[derive(Clone, Copy, Debug)]
pub struct Scored {
    /// Source.
    pub origin: Origin,
    /// Truth.
    pub kind: Kind,
    /// SVM score.
    pub score: f32,
    /// Frame index (0 for still crops).
    pub frame: u32,
    /// The box scored.
    pub bbox: crate::detect::BBox,
}

/// Scored held-out boxes.
#[derive(Clone, Debug, Default)]
pub struct Evaluation {
    /// Every box.
    pub rows: Vec<Scored>,
    /// Threshold for the tables.
    pub threshold: f32,
}

/// Accuracy, precision, recall of "single human" over some rows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Metrics {
    /// Rows.
    pub n: usize,
    /// True positives.
    pub tp: usize,
    /// False positives.
    pub fp: usize,
    /// True negatives.
    pub tn: usize,
    /// False negatives.
    pub fn_: usize,
}

impl Metrics {
    /// Share of rows right.
    pub fn accuracy(&self) -> f64 {
        (self.tp + self.tn) as f64 / self.n.max(1) as f64
    }
    /// Share of accepted rows that are people.
    pub fn precision(&self) -> f64 {
        self.tp as f64 / (self.tp + self.fp).max(1) as f64
    }
    /// Share of people accepted.
    pub fn recall(&self) -> f64 {
        self.tp as f64 / (self.tp + self.fn_).max(1) as f64
    }
}

impl Evaluation {
    /// Metrics over rows passing `filter`.
    pub fn metrics(&self, filter: impl Fn(&Scored) -> bool) -> Metrics {
        let mut m = Metrics::default();
        for r in self.rows.iter().filter(|r| filter(r)) {
            m.n += 1;
            match (r.kind.positive(), r.score > self.threshold) {
                (true, true) => m.tp += 1,
                (true, false) => m.fn_ += 1,
                (false, true) => m.fp += 1,
                (false, false) => m.tn += 1,
            }
        }
        m
    }

    /// Markdown table: per source, then per source and kind.
    pub fn table(&self) -> String {
        let mut s = String::from(
            "| source | regions | accuracy | precision | recall |\n| --- | ---: | ---: | ---: | ---: |\n",
        );
        for o in [Origin::Mit, Origin::Pets, Origin::Sim] {
            let m = self.metrics(|r| r.origin == o);
            if m.n == 0 {
                continue;
            }
            let _ = writeln!(
                s,
                "| {} | {} | {:.2} % | {:.2} % | {:.2} % |",
                o.name(),
                m.n,
                m.accuracy() * 100.0,
                m.precision() * 100.0,
                m.recall() * 100.0
            );
            for k in Kind::ALL {
                let m = self.metrics(|r| r.origin == o && r.kind == k);
                if m.n > 0 {
                    let _ = writeln!(
                        s,
                        "| {} {} | {} | {:.2} % | | |",
                        o.name(),
                        k.name(),
                        m.n,
                        m.accuracy() * 100.0
                    );
                }
            }
        }
        s
    }

    /// Area under the ROC curve of the rows passing `filter`: the chance
    /// that a random person scores above a random non-person (ties count
    /// half). Independent of the threshold, so it compares rankings.
    pub fn auc(&self, filter: impl Fn(&Scored) -> bool) -> f64 {
        let mut v: Vec<(f32, bool)> = self
            .rows
            .iter()
            .filter(|r| filter(r))
            .map(|r| (r.score, r.kind.positive()))
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (mut neg_below, mut sum) = (0.0f64, 0.0f64);
        let (np, nn) = (
            v.iter().filter(|r| r.1).count() as f64,
            v.iter().filter(|r| !r.1).count() as f64,
        );
        let mut i = 0;
        while i < v.len() {
            let mut j = i;
            while j < v.len() && v[j].0 == v[i].0 {
                j += 1;
            }
            let (p, n) =
                v[i..j].iter().fold(
                    (0.0, 0.0),
                    |(p, n), r| {
                        if r.1 {
                            (p + 1.0, n)
                        } else {
                            (p, n + 1.0)
                        }
                    },
                );
            sum += p * (neg_below + 0.5 * n);
            neg_below += n;
            i = j;
        }
        sum / (np * nn).max(1.0)
    }

    /// DET/ROC table: miss rate and false-positive rate per threshold,
    /// over all rows and per source.
    pub fn det_table(&self) -> String {
        let origins: Vec<Origin> = [Origin::Mit, Origin::Pets, Origin::Sim]
            .into_iter()
            .filter(|o| self.rows.iter().any(|r| r.origin == *o))
            .collect();
        let mut s = String::from("| threshold | miss rate (all) | false-positive rate (all) |");
        for o in &origins {
            let _ = write!(s, " miss {} | FP {} |", o.name(), o.name());
        }
        s.push_str("\n| ---: | ---: | ---: |");
        for _ in &origins {
            s.push_str(" ---: | ---: |");
        }
        s.push('\n');
        for k in -8..=8 {
            let t = k as f32 * 0.25;
            let e = Evaluation {
                rows: self.rows.clone(),
                threshold: t,
            };
            let rate = |m: Metrics| {
                (
                    m.fn_ as f64 * 100.0 / (m.tp + m.fn_).max(1) as f64,
                    m.fp as f64 * 100.0 / (m.fp + m.tn).max(1) as f64,
                )
            };
            let (mr, fp) = rate(e.metrics(|_| true));
            let _ = write!(s, "| {t:+.2} | {mr:.2} % | {fp:.2} % |");
            for o in &origins {
                let (mr, fp) = rate(e.metrics(|r| r.origin == *o));
                let _ = write!(s, " {mr:.2} % | {fp:.2} % |");
            }
            s.push('\n');
        }
        s
    }
}

/// How the held-out PETS boxes are drawn: one jittered copy of every clean
/// person, 3 background boxes, 2 fragments and every group per frame.
pub const EVAL_PER_FRAME: PerFrame = PerFrame {
    persons: 1,
    background: 3,
    fragments: 2,
    groups: true,
};

/// Calls `each(frame, luma, boxes)` for every held-out PETS frame
/// (600–794) with its labelled boxes, drawn with [`EVAL_PER_FRAME`] from a
/// generator seeded by `seed`.
pub fn for_held_out_pets(
    data_dir: &Path,
    seed: u64,
    detection: Detection,
    mut each: impl FnMut(u32, Plane<'_>, Option<&BitMask>, &[Labelled]),
) -> Result<(), String> {
    let gt = dataset::load_pets_gt(data_dir)?;
    let mut rng = Rng::new(seed.wrapping_add(1000));
    let mut boxes = Vec::new();
    for_pets_frames(
        data_dir,
        PETS_TRAIN_LAST + 1,
        794,
        detection,
        |f, luma, det| {
            boxes.clear();
            let g = dataset::boxes_of_frame(&gt, f);
            let per = EVAL_PER_FRAME;
            let (w, h) = (luma.width, luma.height);
            samples::pets_frame_samples(g, w, h, per, &mut rng, &mut boxes);
            samples::pets_detected_labels(det.labelled_regions(), g, w, h, &mut boxes);
            each(f, luma, det.mask(), &boxes);
        },
    )
}

/// Calls `each(scene, frame, luma, boxes)` for every `SIM_STRIDE`-th frame
/// of the held-out simulated clips (seeds [`SIM_EVAL_SEEDS`] of every scene)
/// with its labelled boxes, drawn as for [`for_held_out_pets`].
pub fn for_held_out_sim(
    seed: u64,
    detection: Detection,
    mut each: impl FnMut(&'static str, u64, Plane<'_>, Option<&BitMask>, &[Labelled]),
) -> Result<(), String> {
    let mut rng = Rng::new(seed.wrapping_add(2000));
    for scene in SIM_SCENES {
        for &s in SIM_EVAL_SEEDS {
            let per = EVAL_PER_FRAME;
            samples::sim::for_sim_frames(
                scene,
                s,
                SIM_STRIDE,
                per,
                &mut rng,
                detection,
                |f, luma, mask, boxes| each(scene, f, luma, mask, boxes),
            )?;
        }
    }
    Ok(())
}

/// The production [`Classifier`] around `model` (threshold 0), classifying
/// boxes down to 8 px tall (the loop's `min_height` would call the
/// smallest "not a person" unseen).
pub fn scorer(model: &Model) -> Classifier {
    let cfg = ClassifyConfig {
        min_height: 8,
        ..Default::default()
    };
    Classifier::with_model(model.clone(), &cfg)
}

/// Scores `boxes` into `evs`: the true boxes into `evs[0]`, the
/// detector's regions into `evs[1]`.
fn score_into(
    evs: &mut [Evaluation; 2],
    cls: &mut Classifier,
    origin: Origin,
    frame: u32,
    view: (Plane<'_>, Option<&BitMask>),
    boxes: &[Labelled],
) {
    let (luma, mask) = view;
    for b in boxes {
        let v = cls.classify_box_masked(luma, mask, &b.bbox);
        evs[usize::from(b.detected)].rows.push(Scored {
            origin,
            kind: b.kind,
            score: v.score,
            frame,
            bbox: b.bbox,
        });
    }
}

/// Scores `model` on the held-out PETS frames 600–794 ([`scorer`]).
pub fn evaluate_pets(data_dir: &Path, model: &Model, seed: u64) -> Result<Evaluation, String> {
    let [ev, _] = held_out_pets_pass(data_dir, model, seed, false)?;
    Ok(ev)
}

/// Scores `model` on the held-out simulated clips ([`scorer`]).
pub fn evaluate_sim(model: &Model, seed: u64) -> Result<Evaluation, String> {
    let [ev, _] = held_out_sim_pass(model, seed, false)?;
    Ok(ev)
}

/// Scores `model` on the held-out PETS frames and simulated clips, both
/// on the true boxes ([`evaluate_pets`], [`evaluate_sim`]) and on the
/// detector's own regions of the same frames, labelled by the truth
/// ([`samples::detected_labels`]; ambiguous regions left out): what the
/// loop classifies. One pass over each source for both.
pub fn evaluate_held_out(
    data_dir: &Path,
    model: &Model,
    seed: u64,
) -> Result<[Evaluation; 2], String> {
    let [mut boxes, mut regions] = held_out_pets_pass(data_dir, model, seed, true)?;
    let [sim_boxes, sim_regions] = held_out_sim_pass(model, seed, true)?;
    boxes.rows.extend(sim_boxes.rows);
    regions.rows.extend(sim_regions.rows);
    Ok([boxes, regions])
}

/// The second half of [`evaluate_held_out`]: the detector's regions only.
pub fn evaluate_detected(data_dir: &Path, model: &Model, seed: u64) -> Result<Evaluation, String> {
    let [_, regions] = evaluate_held_out(data_dir, model, seed)?;
    Ok(regions)
}

/// What the held-out passes ask of the detector: its mask when the model
/// reads one, its regions when `regions` is set.
fn detection(model: &Model, regions: bool) -> Detection {
    Detection {
        mask: model.layout.mask_fill,
        label: regions,
    }
}

fn held_out_pets_pass(
    data_dir: &Path,
    model: &Model,
    seed: u64,
    regions: bool,
) -> Result<[Evaluation; 2], String> {
    let mut cls = scorer(model);
    let mut evs = <[Evaluation; 2]>::default();
    let d = detection(model, regions);
    for_held_out_pets(data_dir, seed, d, |f, luma, mask, boxes| {
        score_into(&mut evs, &mut cls, Origin::Pets, f, (luma, mask), boxes)
    })?;
    Ok(evs)
}

fn held_out_sim_pass(model: &Model, seed: u64, regions: bool) -> Result<[Evaluation; 2], String> {
    let mut cls = scorer(model);
    let mut evs = <[Evaluation; 2]>::default();
    for_held_out_sim(
        seed,
        detection(model, regions),
        |_, f, luma, mask, boxes| {
            score_into(
                &mut evs,
                &mut cls,
                Origin::Sim,
                f as u32,
                (luma, mask),
                boxes,
            )
        },
    )?;
    Ok(evs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::BBox;

    fn row(kind: Kind, score: f32) -> Scored {
        Scored {
            origin: Origin::Sim,
            kind,
            score,
            frame: 0,
            bbox: BBox::default(),
        }
    }

    #[test]
    fn auc_and_metrics() {
        let mut ev = Evaluation::default();
        for s in [1.0, 2.0, 3.0] {
            ev.rows.push(row(Kind::Person, s));
        }
        for s in [-1.0, -2.0] {
            ev.rows.push(row(Kind::Dog, s));
        }
        assert_eq!(ev.auc(|_| true), 1.0);
        let m = ev.metrics(|_| true);
        assert_eq!((m.tp, m.tn, m.fp, m.fn_), (3, 2, 0, 0));
        // One dog above every person, one tie: AUC (0 + 3·... ) by hand.
        ev.rows.push(row(Kind::Dog, 5.0));
        ev.rows.push(row(Kind::Background, 2.0));
        // Pairs: 3 persons × 4 negatives = 12; persons beat -1, -2 (6),
        // beat 2.0 once (score 3) and tie it once (score 2): 6 + 1 + 0.5.
        assert!((ev.auc(|_| true) - 7.5 / 12.0).abs() < 1e-12);
        let m = ev.metrics(|_| true);
        assert_eq!((m.tp, m.fp), (3, 2));
        assert!((m.precision() - 0.6).abs() < 1e-12 && m.recall() == 1.0);
        assert!(ev.table().contains("| sim dog | 3 |"));
        assert_eq!(ev.det_table().lines().count(), 2 + 17);
    }
}
