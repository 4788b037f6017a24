//! Classifier speed: µs per classified region, and a per-stage split.
//!
//! ```text
//! cargo bench --bench classify -- [REGIONS] [WEIGHTS|-] [total]
//! bench/callgrind.sh classify REGIONS - total     (and again with 0)
//! ```
//!
//! Regions are the PETS 2009 ground-truth boxes of frames 0..=49 (real
//! sizes, 53–155 px tall) when `../shared/data` is present, else boxes of
//! the same sizes on a synthetic textured frame. For instruction counts run
//! it under `valgrind --tool=callgrind` twice, with REGIONS = N and 0, and
//! divide the difference by N (start-up and frame decoding cancel out).

use stature::classify::{hog::Hog, lbp::Lbp, window, Classifier, ClassifyConfig};
use stature::detect::BBox;
use stature::frame::Plane;
use std::hint::black_box;
use std::time::Instant;

fn main() {
    // `cargo bench` adds `--bench`; skip options.
    let mut args = std::env::args().skip(1).filter(|a| !a.starts_with("--"));
    let n: usize = args.next().and_then(|s| s.parse().ok()).unwrap_or(20_000);
    let weights = args.next().filter(|w| w != "-").unwrap_or_default();
    // "total" skips the per-stage split (for callgrind totals).
    let stages = args.next().as_deref() != Some("total");
    let cfg = ClassifyConfig {
        weights,
        min_height: 8,
        ..Default::default()
    };
    let mut cls = match Classifier::new(&cfg) {
        Ok(c) => c,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let (luma, w, h, boxes) = frames();
    let plane = Plane::new(&luma, w, h).expect("frame");
    if n == 0 {
        println!("0 regions (callgrind baseline)");
        return;
    }
    // Warm-up: tables, caches.
    for b in boxes.iter().take(50) {
        black_box(cls.classify_box(plane, b));
    }
    let t = Instant::now();
    let mut accepted = 0;
    for i in 0..n {
        let v = cls.classify_box(plane, &boxes[i % boxes.len()]);
        accepted += usize::from(v.single_human);
    }
    let total = t.elapsed().as_secs_f64();
    println!(
        "{n} regions: {:.2} µs per region ({accepted} accepted; dim {}, window {}x{})",
        total * 1e6 / n as f64,
        cls.model().layout.dim(),
        cls.model().layout.win_w,
        cls.model().layout.win_h
    );

    if !stages {
        return;
    }
    // Per-stage split with the same layout.
    let layout = cls.model().layout.clone();
    let mut sampler = window::Sampler::new(&layout);
    let mut win = vec![0u8; sampler.len()];
    let stride = sampler.stride();
    let mut hog = Hog::new(&layout);
    let mut lbp = Lbp::new(&layout);
    let mut feats = vec![0u8; layout.dim()];
    let hd = layout.hog_dim();
    let cd = hd + layout.coarse_dim();
    let ld = cd + layout.lbp_dim();
    let stage = |name: &str, f: &mut dyn FnMut(usize)| {
        let t = Instant::now();
        for i in 0..n {
            f(i);
        }
        println!(
            "  {name:<22} {:.2} µs",
            t.elapsed().as_secs_f64() * 1e6 / n as f64
        );
    };
    stage("resample window", &mut |i| {
        let r = window::window_rect(&boxes[i % boxes.len()], &layout);
        black_box(sampler.sample(plane, &r, &mut win));
    });
    stage("HOG cells", &mut |_| {
        hog.cell_histograms(black_box(&win), stride);
    });
    stage("HOG block norm", &mut |_| {
        black_box(hog.blocks(&layout.hog_blocks, &mut feats[..hd]));
        if layout.hog_coarse {
            black_box(hog.coarse_blocks(&mut feats[hd..cd]));
        }
    });
    stage("LBP cells + norm", &mut |_| {
        lbp.histograms(black_box(&win), stride);
        black_box(lbp.features(&layout.lbp_cells, &mut feats[cd..ld]));
    });
    let ad = ld + usize::from(layout.aspect_bins);
    stage("box shape", &mut |i| {
        window::aspect_features(&boxes[i % boxes.len()], &mut feats[ld..ad]);
    });
    let model = cls.model().clone();
    stage("SVM dot product", &mut |_| {
        black_box(model.dot(black_box(&feats)));
    });
}

/// A luma frame and region boxes: PETS if available, else synthetic.
fn frames() -> (Vec<u8>, usize, usize, Vec<BBox>) {
    if let Some(dir) = stature::dataset::shared_data_dir() {
        if let (Ok(gt), Ok(mut src)) = (
            stature::dataset::load_pets_gt(&dir),
            stature::dataset::pets_video(&dir),
        ) {
            use stature::source::FrameSource;
            let mut frame = stature::frame::Frame::new(src.info().size);
            let mut boxes = Vec::new();
            for f in 0..50u32 {
                if src.next_frame(&mut frame).is_err() {
                    break;
                }
                for g in stature::dataset::boxes_of_frame(&gt, f) {
                    if let Some(b) = g.clipped(768, 576) {
                        boxes.push(b);
                    }
                }
            }
            if !boxes.is_empty() {
                return (frame.y.clone(), 768, 576, boxes);
            }
        }
    }
    let (w, h) = (768usize, 576usize);
    let mut s = 1u32;
    let luma = (0..w * h)
        .map(|i| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            ((i % w) / 3 + (i / w) / 5 + (s >> 28) as usize) as u8
        })
        .collect();
    let boxes = (0..200)
        .map(|k| {
            let bh = 53 + (k * 7) % 100;
            let bw = bh * 36 / 100;
            let x0 = (k * 37) % (w - bw);
            let y0 = (k * 53) % (h - bh);
            BBox {
                x0: x0 as u16,
                y0: y0 as u16,
                x1: (x0 + bw - 1) as u16,
                y1: (y0 + bh - 1) as u16,
            }
        })
        .collect();
    (luma, w, h, boxes)
}
