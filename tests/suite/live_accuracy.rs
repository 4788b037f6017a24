//! The whole live pipeline, end to end: calibration and heights from the
//! frames alone (detect → classify → track → calibrate → measure), on
//! every simulated scene with a seed the pipeline was not tuned on and on
//! PETS 2009 S2.L1 against its real calibration. The floors are
//! conservative (bench/RESULTS.md, "End to end", has the measured numbers,
//! from `cargo run --release --example live_eval`): they catch regressions,
//! they do not claim the targets.

use stature::calibrate::live::{run_pets, run_sim, LiveRun};
use stature::config::Config;

/// Seed 5: never looked at while the pipeline was tuned (seeds 1–4 were).
const SEED: u64 = 5;

fn run(scene: &str) -> LiveRun {
    run_sim(
        &format!("sim:{scene}?seed={SEED}"),
        &Config::default(),
        |_, _| {},
    )
    .expect("scene")
}

/// Floors of one scene: focal error, tilt and roll errors (degrees), and
/// the median absolute height error in the default scale mode (a 1.70 m
/// population prior against people drawn around 1.70 m).
fn check(scene: &str, max_focal: f64, max_tilt: f64, max_roll: f64, max_height: f64) -> LiveRun {
    let r = run(scene);
    let e = r.calibration_error().expect("a final calibration");
    let h = r.heights();
    println!("{scene}:{SEED}: {e:?}\n{scene}:{SEED}: {h:?}");
    assert!(e.focal_rel.abs() <= max_focal, "{scene}: focal {e:?}");
    assert!(e.tilt_deg.abs() <= max_tilt, "{scene}: tilt {e:?}");
    assert!(e.roll_deg.abs() <= max_roll, "{scene}: roll {e:?}");
    assert!(e.confidence >= 0.2, "{scene}: confidence {e:?}");
    assert!(h.records >= 3, "{scene}: heights {h:?}");
    assert!(h.abs_median <= max_height, "{scene}: heights {h:?}");
    assert_eq!(h.non_person, 0, "{scene}: a dog or car was measured: {h:?}");
    // A final record's box is where its head and foot were seen: inside
    // the image, around both points (a coasting track's box drifts away).
    // Their columns lie within the box, their rows may lie a little beyond
    // it: they get back what the opening took from crowns and ankles.
    let (w, hgt) = (r.scene.width as f32, r.scene.height as f32);
    for f in &r.final_heights {
        let b = f.bbox.map(f32::from);
        let tol = (0.1 * (b[3] - b[1])).max(4.0);
        assert!(
            b[2] < w && b[3] < hgt,
            "{scene}: box outside the image: {f:?}"
        );
        // The foot may lie below the box, the head above it.
        for (p, rows, what) in [
            (f.foot_px, b[1]..=b[3] + tol, "foot"),
            (f.head_px, b[1] - tol..=b[3], "head"),
        ] {
            assert!(
                (b[0]..=b[2]).contains(&p[0]) && rows.contains(&p[1]),
                "{scene}: box away from its {what} point: {f:?}"
            );
        }
    }
    assert!(
        h.measured * 2 >= h.eligible,
        "{scene}: recall of people seen 3 s {h:?}"
    );
    // People seen 3 s apart from everyone else: a background model cuts
    // them out alone, so nearly all of them are measured (seed 5: 41 of 41
    // over the six scenes, 3 to 15 per scene).
    assert!(
        h.eligible_alone >= 3 && h.measured_alone * 3 >= h.eligible_alone * 2,
        "{scene}: recall of people seen 3 s alone {h:?}"
    );
    assert_eq!(r.occupancy.pending_lost, 0, "{scene}: {:?}", r.occupancy);
    r
}

/// 144 s of `high` seed 3: a dog trotting away from the camera read
/// 1.01 m and got a height under the old 0.9 m floor (`measure.min_height_m`,
/// now 1.1 m; bench/RESULTS.md, "Observation time").
#[test]
fn a_trotting_dog_gets_no_height_in_a_long_watch() {
    let r = run_sim("sim:high?seed=3&frames=3600", &Config::default(), |_, _| {}).expect("scene");
    let h = r.heights();
    println!("high:3, 3600 frames: {h:?}");
    assert!(h.records >= 30, "{h:?}");
    assert_eq!(h.non_person, 0, "a dog or car was measured: {h:?}");
}

/// `mid` seed 2 never reaches the confidence threshold in its 24 s clip
/// and measures no one; a longer watch gets there (at 72 s: f 6.9 % off,
/// most people measured), as a camera left running does.
#[test]
fn a_view_that_is_unsure_at_first_calibrates_with_time() {
    let short = run_sim("sim:mid?seed=2", &Config::default(), |_, _| {}).expect("scene");
    assert_eq!(short.heights().records, 0, "24 s: no heights yet");
    let r = run_sim("sim:mid?seed=2&frames=1800", &Config::default(), |_, _| {}).expect("scene");
    let e = r.calibration_error().expect("a final calibration");
    let h = r.heights();
    println!("mid:2, 1800 frames: {e:?}\n{h:?}");
    assert!(e.confidence >= 0.25, "{e:?}");
    assert!(e.focal_rel.abs() <= 0.12, "{e:?}");
    assert!(h.measured * 3 >= h.eligible * 2, "{h:?}");
}

#[test]
fn plaza_calibrates_and_measures() {
    let r = check("plaza", 0.15, 2.5, 1.5, 0.08);
    // People who walked through before the calibration was usable are
    // measured once it is (measured: 4 of them on this clip).
    assert!(r.occupancy.pending_measured >= 2, "{:?}", r.occupancy);
}

#[test]
fn low_camera_calibrates_and_measures() {
    check("low", 0.15, 2.0, 1.5, 0.08);
}

#[test]
fn mid_camera_calibrates_and_measures() {
    check("mid", 0.15, 2.0, 1.5, 0.08);
}

#[test]
fn high_camera_calibrates_and_measures() {
    // The horizon of this steep view comes out low (bench/RESULTS.md): heights
    // read 15 cm short on this seed.
    check("high", 0.25, 3.0, 1.5, 0.22);
}

#[test]
fn wide_lens_calibrates_and_measures() {
    check("wide", 0.15, 2.5, 1.5, 0.10);
}

#[test]
fn busy_1280x720_calibrates_and_measures() {
    check("busy", 0.15, 3.0, 1.5, 0.10);
}

#[test]
fn pets_calibrates_against_its_real_calibration() {
    let Some(dir) = stature::dataset::require_shared_data("PETS end-to-end test") else {
        return;
    };
    let r = run_pets(&dir, &Config::default()).expect("PETS run");
    let c = r.calibration.clone().expect("a final calibration");
    let t = r.truth;
    let errors = r.abs_errors();
    println!(
        "PETS: f {} / {} px, tilt {} / {}, roll {} / {}, camera {} / {} m, {} heights matched ({} repeats; {} of people without a true height, {} of no one), |err| {:?}",
        c.f_px,
        t.focal_px,
        c.tilt_deg,
        t.tilt_deg,
        c.roll_deg,
        t.roll_deg,
        c.camera_height_m,
        t.camera_height_m,
        r.heights.len(),
        r.repeated(),
        r.no_truth,
        r.unmatched,
        errors
    );
    // Against the camera with its principal point at the image centre
    // (the model's assumption), the equivalent of the real calibration.
    assert!((f64::from(c.f_px) / t.focal_px - 1.0).abs() <= 0.08);
    assert!((f64::from(c.tilt_deg) - t.tilt_deg).abs() <= 2.5);
    assert!((f64::from(c.roll_deg) - t.roll_deg).abs() <= 1.5);
    // Default scale mode: the 1.70 m prior against people around 1.77 m.
    assert!((f64::from(c.camera_height_m) / t.camera_height_m - 1.0).abs() <= 0.15);
    assert!(r.heights.len() >= 8, "{} heights", r.heights.len());
    // Measured 19 of the clip's 19 people, and 2 heights of no one (of
    // 44): a person is measured, and few heights belong to nobody.
    let people = r.heights.len() - r.repeated();
    assert!(people >= 14, "{people} people measured");
    assert!(r.unmatched <= 5, "{} heights of no one", r.unmatched);
    let median = errors[errors.len() / 2];
    assert!(median <= 0.12, "median height error {median} m");
}
