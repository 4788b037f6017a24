//! Detection on the simulated scenes (exact truth boxes): fixed point vs
//! float, isolated people found, and shadows not growing the boxes.

use crate::detect_support::{agreement, scored_people, truth_boxes, FloatGmm, Score};
use stature::detect::morphology::BitMask;
use stature::detect::{DetectConfig, Detector, RegionSet};
use stature::frame::Frame;
use stature::source::sim::SimSource;
use stature::source::{FrameSource, Next};

const FRAMES: u64 = 300;
const WARM_UP: u64 = 50;

/// Runs the detector (and optionally the float reference) over a scene;
/// returns the score and the mean pixel agreement with the float model.
fn run(uri: &str, with_float: bool) -> (Score, f64) {
    let mut src = SimSource::open_uri(uri).expect("sim scene");
    let size = src.info().size;
    let cfg = DetectConfig::default();
    let float_cfg = DetectConfig {
        gain_compensation: false,
        ..cfg.clone()
    };
    let mut det = Detector::new(&cfg, size);
    let mut det_nogain = Detector::new(&float_cfg, size);
    let mut float = with_float.then(|| {
        (
            FloatGmm::new(&float_cfg, size.width, size.height),
            BitMask::new(size.width, size.height),
        )
    });
    let mut out = RegionSet::with_capacity(cfg.region_capacity(), cfg.run_capacity(size));
    let mut frame = Frame::new(size);
    let mut score = Score::default();
    let mut truth = Vec::new();
    let mut people = Vec::new();
    let (mut agree, mut total) = (0u64, 0u64);
    for i in 0..FRAMES {
        assert_eq!(src.next_frame(&mut frame).expect("frame"), Next::Frame);
        det.process(&frame, &mut out);
        if let Some((f, m)) = float.as_mut() {
            det_nogain.segment(&frame);
            f.apply(&frame, m);
            agree += agreement(det_nogain.raw_mask(), m);
            total += size.pixels() as u64;
        }
        if i >= WARM_UP {
            truth_boxes(&src, &mut truth);
            scored_people(&src, &mut people);
            score.add_filtered(&truth, &people, out.regions());
        }
    }
    (score, agree as f64 / total.max(1) as f64)
}

fn report(name: &str, s: &Score, agree: f64) {
    println!(
        "{name}: agreement {:.3} %, isolated people {} matched {} ({:.1} %), mean IoU {:.3}, false regions/frame {:.2}",
        100.0 * agree,
        s.isolated,
        s.matched,
        100.0 * s.recall(),
        s.mean_iou(),
        s.false_per_frame()
    );
}

#[test]
fn sim_low_scene() {
    let (s, agree) = run("sim:low?seed=1", true);
    report("sim:low", &s, agree);
    assert!(agree >= 0.99, "agreement {agree}");
    assert!(s.isolated > 100, "{s:?}");
    // Measured 73.6 % matched, 0.68 false/frame (65.5 % before the
    // shadow-chroma test, vertical shadow fill and region splitting; still
    // below the 90 % target: grey clothes on grey paving, see
    // bench/RESULTS.md); floors catch regressions.
    assert!(s.recall() >= 0.66, "{s:?}");
    assert!(s.false_per_frame() <= 0.9, "{s:?}");
}

#[test]
fn sim_plaza_scene_with_shadows() {
    let (s, agree) = run("sim:plaza?seed=1&shadows=1", true);
    report("sim:plaza shadows", &s, agree);
    assert!(agree >= 0.99, "agreement {agree}");
    assert!(s.isolated > 100, "{s:?}");
    // Measured 96.5 % matched, 0.52 false/frame (74.8 %, 0.57 with the L1
    // chroma term alone; 25.5 %, 0.11 luma only).
    assert!(s.recall() >= 0.9, "{s:?}");
    assert!(s.false_per_frame() <= 0.7, "{s:?}");
}

/// The same clip with and without moving shadows: the boxes do not grow by
/// the shadow (the matched fraction and mean IoU hold).
#[test]
fn shadows_do_not_grow_boxes() {
    let (with, _) = run("sim:plaza?seed=1&shadows=1", false);
    let (without, _) = run("sim:plaza?seed=1&shadows=0", false);
    report("sim:plaza shadows=1", &with, 1.0);
    report("sim:plaza shadows=0", &without, 1.0);
    // Measured: mean IoU 0.856 with shadows vs 0.858 without; matched
    // 96.2 % vs 96.8 % (without the deep-shadow peel 0.818 vs 0.858; the
    // L1 chroma term alone: 0.637 vs 0.706, 74.8 % vs 81.2 %; luma only:
    // 0.409 vs 0.425, 25.5 % vs 30.2 %).
    assert!(
        with.mean_iou() >= without.mean_iou() - 0.03,
        "{with:?} vs {without:?}"
    );
    assert!(
        with.recall() >= without.recall() - 0.04,
        "{with:?} vs {without:?}"
    );
}

/// The other scenes (no float reference: the two above cover it): floors
/// a few points under what is measured (bench/RESULTS.md, "Detection").
#[test]
fn sim_other_scenes() {
    // (scene, matched floor, false/frame ceiling) // measured
    for (uri, floor, ceiling) in [
        ("sim:mid?seed=1", 0.9, 0.4),   // 96.7 %, 0.17
        ("sim:high?seed=1", 0.88, 0.6), // 93.8 %, 0.44
        ("sim:wide?seed=1", 0.7, 0.3),  // 76.0 %, 0.16
        ("sim:busy?seed=1", 0.8, 2.0),  // 86.1 %, 1.40
    ] {
        let (s, _) = run(uri, false);
        report(uri, &s, 1.0);
        assert!(s.isolated > 100, "{uri}: {s:?}");
        assert!(s.recall() >= floor, "{uri}: {s:?}");
        assert!(s.false_per_frame() <= ceiling, "{uri}: {s:?}");
    }
}
