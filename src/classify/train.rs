//! The trainer behind `stature train` (host side, never in the loop).
//!
//! 1. Samples: MIT CBCL crops (positives, their mirror images, and a
//!    fragment negative each) and PETS 2009 S2.L1 frames 0–599 (every
//!    `pets_stride`-th frame: jittered clean people, background, groups,
//!    fragments; see [`super::samples`]). Frames 600–794 are held out.
//! 2. Features: the production [`Extractor`], so training sees exactly the
//!    `u8` vectors the camera computes.
//! 3. Solver: L2-regularised L2-loss linear SVM in the dual, by coordinate
//!    descent (Hsieh et al. 2008, the LIBLINEAR `-s 1` method), bias as a
//!    constant feature, fixed-seed permutation each epoch.
//! 4. `C` picked from a small grid by 5-fold cross-validation grouped by
//!    source block (PETS folds are contiguous frame ranges, so neighbouring
//!    frames never sit on both sides of a split).
//! 5. One round of hard-negative mining on every training frame, retrain.
//! 6. Optional block selection (Park et al. 2012): keep the HOG blocks and
//!    LBP cells with the largest mean |w|, retrain on those columns.
//! 7. Quantise to i8, write the blob, report.

use super::layout::{Layout, BLOCK_DIM, LBP_BINS};
use super::samples::{self, Kind, Labelled, Origin, PerFrame, Rng};
use super::svm::Model;
use super::{Classifier, ClassifyConfig, Extractor};
use crate::dataset;
use crate::frame::{Frame, Plane};
use crate::source::{FrameSource, Next};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Last PETS frame used for training; later frames are held out.
pub const PETS_TRAIN_LAST: u32 = 599;

/// What to train.
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// `../shared/data`.
    pub data_dir: PathBuf,
    /// Feature layout (all blocks selected; selection happens in training).
    pub layout: Layout,
    /// Seed of every random choice.
    pub seed: u64,
    /// Fixed `C`, or `None` to pick from [`C_GRID`] by cross-validation.
    pub c: Option<f64>,
    /// Share of HOG blocks and LBP cells to keep (1 = all).
    pub select: f64,
    /// Use every n-th PETS training frame for the base set.
    pub pets_stride: u32,
    /// Also evaluate on the held-out frames and append it to the report.
    pub eval: bool,
    /// Add simulated scenes (seeds [`SIM_TRAIN_SEEDS`]) to training.
    pub sim: bool,
}

/// `C` values tried by cross-validation.
pub const C_GRID: [f64; 4] = [0.01, 0.03, 0.1, 0.3];

/// Feature rows with labels.
#[derive(Clone, Debug, Default)]
pub struct Data {
    /// Row length.
    pub dim: usize,
    /// Rows, `dim` bytes each.
    pub x: Vec<u8>,
    /// Label per row.
    pub kind: Vec<Kind>,
    /// Source per row.
    pub origin: Vec<Origin>,
    /// Cross-validation fold per row (0..5).
    pub fold: Vec<u8>,
}

impl Data {
    fn new(dim: usize) -> Self {
        Data {
            dim,
            ..Default::default()
        }
    }
    fn push(&mut self, x: &[u8], kind: Kind, origin: Origin, fold: u8) {
        self.x.extend_from_slice(x);
        self.kind.push(kind);
        self.origin.push(origin);
        self.fold.push(fold);
    }
    /// Rows.
    pub fn len(&self) -> usize {
        self.kind.len()
    }
    /// No rows.
    pub fn is_empty(&self) -> bool {
        self.kind.is_empty()
    }
    fn row(&self, i: usize) -> &[u8] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }
    fn label(&self, i: usize) -> f64 {
        if self.kind[i].positive() {
            1.0
        } else {
            -1.0
        }
    }
    /// Only the given columns.
    fn columns(&self, cols: &[usize]) -> Data {
        let mut d = Data::new(cols.len());
        d.x.reserve(self.len() * cols.len());
        for i in 0..self.len() {
            let r = self.row(i);
            d.x.extend(cols.iter().map(|&c| r[c]));
        }
        d.kind = self.kind.clone();
        d.origin = self.origin.clone();
        d.fold = self.fold.clone();
        d
    }
}

/// A trained float model: `score = Σ w_j·x_j/255 + b`.
#[derive(Clone, Debug)]
pub struct Linear {
    /// Weights per feature (features in units of 1/255).
    pub w: Vec<f32>,
    /// Bias.
    pub b: f32,
    /// Epochs run.
    pub epochs: usize,
}

impl Linear {
    /// Score of one `u8` row.
    pub fn score(&self, x: &[u8]) -> f32 {
        dot(&self.w, x) + self.b
    }
}

#[inline]
fn dot(w: &[f32], x: &[u8]) -> f32 {
    // Eight partial sums: lets the compiler vectorise without reassociation.
    let mut acc = [0f32; 8];
    let mut wc = w.chunks_exact(8);
    let mut xc = x.chunks_exact(8);
    for (a, b) in (&mut wc).zip(&mut xc) {
        for k in 0..8 {
            acc[k] += a[k] * f32::from(b[k]);
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (a, b) in wc.remainder().iter().zip(xc.remainder()) {
        s += a * f32::from(*b);
    }
    s / 255.0
}

/// Dual coordinate descent for the L2-loss SVM on the rows `idx` of `d`.
/// Stops when the projected-gradient spread falls below 0.1 (LIBLINEAR's
/// default) or after 400 epochs.
pub fn solve(d: &Data, idx: &[usize], c: f64, seed: u64) -> Linear {
    let dim = d.dim;
    let mut w = vec![0f32; dim];
    let mut b = 0f64;
    let diag = 0.5 / c;
    let qd: Vec<f64> = idx
        .iter()
        .map(|&i| {
            let r = d.row(i);
            let n: f64 = r.iter().map(|&v| (f64::from(v) / 255.0).powi(2)).sum();
            n + 1.0 + diag
        })
        .collect();
    let mut alpha = vec![0f64; idx.len()];
    let mut order: Vec<usize> = (0..idx.len()).collect();
    let mut rng = Rng::new(seed);
    let mut epochs = 0;
    while epochs < 400 {
        epochs += 1;
        rng.shuffle(&mut order);
        let (mut pg_max, mut pg_min) = (f64::NEG_INFINITY, f64::INFINITY);
        for &k in &order {
            let i = idx[k];
            let y = d.label(i);
            let r = d.row(i);
            let g = y * (f64::from(dot(&w, r)) + b) - 1.0 + diag * alpha[k];
            let pg = if alpha[k] == 0.0 { g.min(0.0) } else { g };
            pg_max = pg_max.max(pg);
            pg_min = pg_min.min(pg);
            if pg.abs() > 1e-12 {
                let old = alpha[k];
                alpha[k] = (old - g / qd[k]).max(0.0);
                let step = ((alpha[k] - old) * y) as f32;
                let s = step / 255.0;
                for (wj, &xj) in w.iter_mut().zip(r) {
                    *wj += s * f32::from(xj);
                }
                b += f64::from(step);
            }
        }
        if pg_max - pg_min < 0.1 {
            break;
        }
    }
    Linear {
        w,
        b: b as f32,
        epochs,
    }
}

/// Accuracy of `m` on rows `idx`.
fn accuracy(m: &Linear, d: &Data, idx: &[usize]) -> f64 {
    let ok = idx
        .iter()
        .filter(|&&i| (m.score(d.row(i)) > 0.0) == d.kind[i].positive())
        .count();
    ok as f64 / idx.len().max(1) as f64
}

/// 5-fold cross-validated accuracy.
pub fn cross_validate(d: &Data, c: f64, seed: u64) -> f64 {
    let mut correct = 0.0;
    for f in 0..5u8 {
        let train: Vec<usize> = (0..d.len()).filter(|&i| d.fold[i] != f).collect();
        let test: Vec<usize> = (0..d.len()).filter(|&i| d.fold[i] == f).collect();
        let m = solve(d, &train, c, seed + u64::from(f));
        correct += accuracy(&m, d, &test) * test.len() as f64;
    }
    correct / d.len() as f64
}

/// Calls `each(frame_index, luma)` for PETS frames `first..=last`.
pub fn for_pets_frames(
    data_dir: &Path,
    first: u32,
    last: u32,
    mut each: impl FnMut(u32, Plane<'_>),
) -> Result<(), String> {
    let mut src = dataset::pets_video(data_dir).map_err(|e| e.to_string())?;
    let mut frame = Frame::new(src.info().size);
    let mut k = 0u32;
    while k <= last {
        match src.next_frame(&mut frame).map_err(|e| e.to_string())? {
            Next::Frame => {}
            Next::Waiting => continue,
            Next::End => break,
        }
        if k >= first {
            each(k, frame.luma());
        }
        k += 1;
    }
    // Drain the rest so ffmpeg ends cleanly instead of on a broken pipe.
    while let Ok(Next::Frame | Next::Waiting) = src.next_frame(&mut frame) {}
    if k <= last {
        return Err(format!("PETS video ended at frame {k}, expected {last}"));
    }
    Ok(())
}

/// Builds the base training set.
fn base_set(o: &TrainOptions, ex: &mut Extractor, log: &mut String) -> Result<Data, String> {
    let mut d = Data::new(ex.layout().dim());
    let mut rng = Rng::new(o.seed);
    let margin = ex.layout().margin_q8;
    let person = samples::mit_person_box(margin);
    let files = samples::mit_files(&o.data_dir)?;
    for (i, path) in files.iter().enumerate() {
        let fold = (i % 5) as u8;
        for mirror in [false, true] {
            let (y, w, h) = samples::read_png_luma(path, mirror)?;
            let p = samples::plane(&y, w, h).ok_or("short PNG")?;
            let b = samples::to_bbox(&person, w, h).ok_or("MIT box")?;
            if let Some(x) = ex.extract(p, &b) {
                d.push(x, Kind::Person, Origin::Mit, fold);
            }
            if !mirror {
                let fr = samples::fragment(&person, &mut rng);
                if let Some(b) = samples::to_bbox(&fr, w, h) {
                    if let Some(x) = ex.extract(p, &b) {
                        d.push(x, Kind::Fragment, Origin::Mit, fold);
                    }
                }
            }
        }
    }
    let gt = dataset::load_pets_gt(&o.data_dir)?;
    let per = PerFrame {
        persons: 1,
        background: 3,
        fragments: 2,
        groups: true,
    };
    let mut boxes = Vec::new();
    for_pets_frames(&o.data_dir, 0, PETS_TRAIN_LAST, |f, luma| {
        if f % o.pets_stride != 0 {
            return;
        }
        boxes.clear();
        let g = dataset::boxes_of_frame(&gt, f);
        samples::pets_frame_samples(g, luma.width, luma.height, per, &mut rng, &mut boxes);
        let fold = (f * 5 / (PETS_TRAIN_LAST + 1)) as u8;
        for s in &boxes {
            if let Some(x) = ex.extract(luma, &s.bbox) {
                d.push(x, s.kind, Origin::Pets, fold);
            }
        }
    })?;
    if o.sim {
        for (k, scene) in SIM_SCENES.iter().enumerate() {
            for &seed in SIM_TRAIN_SEEDS {
                samples::sim::for_sim_frames(
                    scene,
                    seed,
                    SIM_STRIDE,
                    per,
                    &mut rng,
                    |_, luma, boxes| {
                        for s in boxes {
                            if let Some(x) = ex.extract(luma, &s.bbox) {
                                d.push(x, s.kind, Origin::Sim, (k % 5) as u8);
                            }
                        }
                    },
                )?;
            }
        }
    }
    let _ = writeln!(log, "base set: {}", counts(&d));
    Ok(d)
}

/// Simulated scenes used for training and evaluation.
pub const SIM_SCENES: [&str; 6] = ["plaza", "low", "mid", "high", "wide", "busy"];
/// Seeds of the simulated clips used for training.
pub const SIM_TRAIN_SEEDS: &[u64] = &[1, 2];
/// Seeds of the held-out simulated clips (never trained on).
pub const SIM_EVAL_SEEDS: &[u64] = &[101];
/// Every n-th simulated frame is sampled.
pub const SIM_STRIDE: u64 = 10;

/// Scores `model` on held-out simulated clips (seeds [`SIM_EVAL_SEEDS`]).
pub fn evaluate_sim(model: &Model, seed: u64) -> Result<Evaluation, String> {
    let cfg = ClassifyConfig {
        min_height: 8,
        ..Default::default()
    };
    let mut cls = Classifier::with_model(model.clone(), &cfg);
    let mut rng = Rng::new(seed.wrapping_add(2000));
    let mut ev = Evaluation::default();
    for scene in SIM_SCENES {
        for &s in SIM_EVAL_SEEDS {
            samples::sim::for_sim_frames(
                scene,
                s,
                SIM_STRIDE,
                EVAL_PER_FRAME,
                &mut rng,
                |f, luma, boxes| {
                    for b in boxes {
                        let v = cls.classify_box(luma, &b.bbox);
                        ev.rows.push(Scored {
                            origin: Origin::Sim,
                            kind: b.kind,
                            score: v.score,
                            frame: f as u32,
                            bbox: b.bbox,
                        });
                    }
                },
            )?;
        }
    }
    Ok(ev)
}

/// Hard negatives: every training frame, many candidates, those the first
/// model scores above −1 (inside the margin or wrong), at most `cap`.
fn mine(
    o: &TrainOptions,
    ex: &mut Extractor,
    m: &Linear,
    d: &mut Data,
    cap: usize,
) -> Result<(usize, usize), String> {
    let gt = dataset::load_pets_gt(&o.data_dir)?;
    let mut rng = Rng::new(o.seed ^ 0x5eed_0001);
    let per = PerFrame {
        persons: 0,
        background: 12,
        fragments: 4,
        groups: true,
    };
    let mut boxes: Vec<Labelled> = Vec::new();
    let mut hard: Vec<(f32, Vec<u8>, Kind, u8)> = Vec::new();
    let mut scanned = 0;
    for_pets_frames(&o.data_dir, 0, PETS_TRAIN_LAST, |f, luma| {
        boxes.clear();
        let g = dataset::boxes_of_frame(&gt, f);
        samples::pets_frame_samples(g, luma.width, luma.height, per, &mut rng, &mut boxes);
        let fold = (f * 5 / (PETS_TRAIN_LAST + 1)) as u8;
        for s in &boxes {
            if let Some(x) = ex.extract(luma, &s.bbox) {
                scanned += 1;
                let sc = m.score(x);
                if sc > -1.0 {
                    hard.push((sc, x.to_vec(), s.kind, fold));
                }
            }
        }
    })?;
    hard.sort_by(|a, b| b.0.total_cmp(&a.0));
    hard.truncate(cap);
    for (_, x, k, f) in &hard {
        d.push(x, *k, Origin::Pets, *f);
    }
    Ok((scanned, hard.len()))
}

fn counts(d: &Data) -> String {
    let mut s = String::new();
    for o in [Origin::Mit, Origin::Pets, Origin::Sim] {
        for k in Kind::ALL {
            let n = (0..d.len())
                .filter(|&i| d.origin[i] == o && d.kind[i] == k)
                .count();
            if n > 0 {
                let _ = write!(s, "{} {}={} ", o.name(), k.name(), n);
            }
        }
    }
    let pos = d.kind.iter().filter(|k| k.positive()).count();
    let _ = write!(
        s,
        "(total {} = {} positive + {} negative)",
        d.len(),
        pos,
        d.len() - pos
    );
    s
}

/// Keeps the share `keep` of HOG blocks and of LBP cells with the largest
/// mean |w|; returns the reduced layout and the kept columns.
pub fn select_blocks(layout: &Layout, w: &[f32], keep: f64) -> (Layout, Vec<usize>) {
    let nb = layout.hog_block_count();
    let nc = layout.lbp_cell_count();
    let mean_abs = |s: &[f32]| s.iter().map(|v| v.abs()).sum::<f32>() / s.len() as f32;
    let rank = |scores: Vec<f32>| -> Vec<bool> {
        let n = scores.len();
        let k = ((n as f64 * keep).round() as usize).clamp(1, n);
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
        let mut sel = vec![false; n];
        for &i in &order[..k] {
            sel[i] = true;
        }
        sel
    };
    let hog = rank(
        (0..nb)
            .map(|i| mean_abs(&w[i * BLOCK_DIM..(i + 1) * BLOCK_DIM]))
            .collect(),
    );
    let off = nb * BLOCK_DIM;
    let lbp = rank(
        (0..nc)
            .map(|i| mean_abs(&w[off + i * LBP_BINS..off + (i + 1) * LBP_BINS]))
            .collect(),
    );
    let mut cols = Vec::new();
    for (i, &s) in hog.iter().enumerate() {
        if s {
            cols.extend(i * BLOCK_DIM..(i + 1) * BLOCK_DIM);
        }
    }
    for (i, &s) in lbp.iter().enumerate() {
        if s {
            cols.extend(off + i * LBP_BINS..off + (i + 1) * LBP_BINS);
        }
    }
    let mut l = layout.clone();
    l.hog_blocks = hog;
    l.lbp_cells = lbp;
    (l, cols)
}

/// Trains a model; returns it and a Markdown report.
pub fn train(o: &TrainOptions) -> Result<(Model, String), String> {
    let t0 = Instant::now();
    o.layout.validate().map_err(|e| e.0.clone())?;
    let mut log = String::new();
    let l = &o.layout;
    let _ = writeln!(
        log,
        "# stature classifier training report\n\nlayout: window {}x{}, margin {}/256, HOG cell {} ({} blocks), LBP cell {} ({} cells, threshold {}), dim {}, layout hash {:016x}\nseed {}, PETS training frames 0..={} every {} (mining: every frame), held out: {}..=794\n",
        l.win_w, l.win_h, l.margin_q8, l.hog_cell, l.selected_blocks(), l.lbp_cell, l.selected_lbp_cells(), l.lbp_threshold, l.dim(), l.hash(),
        o.seed, PETS_TRAIN_LAST, o.pets_stride, PETS_TRAIN_LAST + 1
    );
    let _ = writeln!(
        log,
        "simulated scenes: {} (scenes {:?}, training seeds {:?}, every {} frames; held out: seeds {:?})\n",
        if o.sim { "used" } else { "not used" },
        SIM_SCENES, SIM_TRAIN_SEEDS, SIM_STRIDE, SIM_EVAL_SEEDS
    );
    let mut ex = Extractor::new(l);
    let mut d = base_set(o, &mut ex, &mut log)?;
    let all: Vec<usize> = (0..d.len()).collect();
    let c = match o.c {
        Some(c) => c,
        None => {
            let mut best = (0.0, C_GRID[0]);
            for &c in &C_GRID {
                let acc = cross_validate(&d, c, o.seed);
                let _ = writeln!(
                    log,
                    "C = {c}: 5-fold CV accuracy on the base set {:.2} %",
                    acc * 100.0
                );
                if acc > best.0 {
                    best = (acc, c);
                }
            }
            best.1
        }
    };
    let _ = writeln!(log, "C = {c}");
    let m1 = solve(&d, &all, c, o.seed);
    let _ = writeln!(
        log,
        "round 1: {} epochs, training accuracy {:.2} %",
        m1.epochs,
        accuracy(&m1, &d, &all) * 100.0
    );
    let (scanned, added) = mine(o, &mut ex, &m1, &mut d, 4000)?;
    let _ = writeln!(
        log,
        "hard-negative mining: {scanned} candidate negatives scored, {added} with score > -1 added"
    );
    let _ = writeln!(log, "final set: {}", counts(&d));
    let (layout, d) = if o.select < 1.0 {
        let all: Vec<usize> = (0..d.len()).collect();
        let full = solve(&d, &all, c, o.seed);
        let (layout, cols) = select_blocks(l, &full.w, o.select);
        let _ = writeln!(
            log,
            "block selection: kept {} of {} HOG blocks and {} of {} LBP cells by mean |w| (dim {})",
            layout.selected_blocks(),
            layout.hog_block_count(),
            layout.selected_lbp_cells(),
            layout.lbp_cell_count(),
            layout.dim()
        );
        (layout, d.columns(&cols))
    } else {
        (l.clone(), d)
    };
    let cv = cross_validate(&d, c, o.seed);
    let _ = writeln!(
        log,
        "5-fold CV accuracy on the final set: {:.2} %",
        cv * 100.0
    );
    let all: Vec<usize> = (0..d.len()).collect();
    let m = solve(&d, &all, c, o.seed);
    let model = Model::quantise(layout, &m.w, m.b);
    let agree = all
        .iter()
        .filter(|&&i| (model.score(d.row(i)) > 0.0) == (m.score(d.row(i)) > 0.0))
        .count();
    let _ = writeln!(
        log,
        "final: {} epochs, training accuracy {:.2} % (float), i8 weights agree with float on {:.2} % of training rows",
        m.epochs,
        accuracy(&m, &d, &all) * 100.0,
        agree as f64 * 100.0 / d.len() as f64
    );
    let _ = writeln!(log, "training time {:.1} s", t0.elapsed().as_secs_f64());
    if o.eval {
        let mut ev = evaluate_pets(&o.data_dir, &model, o.seed)?;
        ev.rows.extend(evaluate_sim(&model, o.seed)?.rows);
        let _ = writeln!(
            log,
            "\n## Held-out evaluation (PETS frames 600-794, sim seeds {SIM_EVAL_SEEDS:?})\n"
        );
        log.push_str(&ev.table());
        log.push('\n');
        log.push_str(&ev.det_table());
        if std::env::var_os("STATURE_TRAIN_DEBUG").is_some() {
            let mut bad: Vec<&Scored> = ev
                .rows
                .iter()
                .filter(|r| r.kind.positive() != (r.score > 0.0))
                .collect();
            bad.sort_by(|a, b| a.score.abs().total_cmp(&b.score.abs()).reverse());
            for r in bad.iter().take(60) {
                let _ = writeln!(
                    log,
                    "wrong: frame {} {:?} {:?} score {:.2}",
                    r.frame, r.kind, r.bbox, r.score
                );
            }
        }
    }
    Ok((model, log))
}

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

/// Scores `model` on held-out PETS frames 600–794 with the production
/// [`Classifier`] path (threshold 0).
pub fn evaluate_pets(data_dir: &Path, model: &Model, seed: u64) -> Result<Evaluation, String> {
    let cfg = ClassifyConfig {
        min_height: 8,
        ..Default::default()
    };
    let mut cls = Classifier::with_model(model.clone(), &cfg);
    let gt = dataset::load_pets_gt(data_dir)?;
    let mut rng = Rng::new(seed.wrapping_add(1000));
    let mut boxes = Vec::new();
    let mut ev = Evaluation::default();
    for_pets_frames(data_dir, PETS_TRAIN_LAST + 1, 794, |f, luma| {
        boxes.clear();
        let g = dataset::boxes_of_frame(&gt, f);
        samples::pets_frame_samples(
            g,
            luma.width,
            luma.height,
            EVAL_PER_FRAME,
            &mut rng,
            &mut boxes,
        );
        for s in &boxes {
            let v = cls.classify_box(luma, &s.bbox);
            ev.rows.push(Scored {
                origin: Origin::Pets,
                kind: s.kind,
                score: v.score,
                frame: f,
                bbox: s.bbox,
            });
        }
    })?;
    Ok(ev)
}
