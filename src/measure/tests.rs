//! Heights: exact cross ratio vs. the paper's linear form, and the RANSAC
//! correction on realistic per-frame heights.

use super::*;
use crate::calibrate::geometry::ViewGeometry;
use crate::camera::Camera;

/// Paper eq. 8: `H = H_ref · (y_f − y_h) / (y_f − y_ref)`, with `y_ref` the
/// image row of the point `H_ref` above the foot. Only the rows enter.
fn linear_height(g: &ViewGeometry, h_c: f64, o: &HeadFoot, h_ref: f64) -> f64 {
    let r = g.head_for_ratio(o.foot, h_ref / h_c).unwrap();
    h_ref * (o.foot[1] - o.head[1]) / (o.foot[1] - r[1])
}

fn estimate(cam: &Camera, confidence: f64) -> Estimate {
    Estimate {
        geom: ViewGeometry::of_camera(cam),
        camera_height: cam.height,
        inliers: 100,
        horizon_inliers: 100,
        focal_rel_sigma: 0.0,
        lean: 0.0,
        confidence,
        degeneracy: None,
        version: 1,
    }
}

#[test]
fn exact_heights_beat_the_linear_approximation() {
    // A low wide camera, where heads come close to the horizon: the
    // approximation (exact only for people of the reference height) is
    // off by centimetres for a 1.95 m or 1.50 m person; the cross ratio is exact.
    let cam = Camera::centred(500.0, 20.0, 5.0, 2.6, 640, 480);
    let g = ViewGeometry::of_camera(&cam);
    let mut worst_linear = 0.0f64;
    for (x, y, h) in [
        (-3.0, 5.0, 1.95),
        (2.5, 4.0, 1.95),
        (0.0, 9.0, 1.50),
        (-1.0, 3.5, 1.50),
    ] {
        let o = HeadFoot {
            head: cam.project([x, y, h]).unwrap(),
            foot: cam.project([x, y, 0.0]).unwrap(),
        };
        let exact = g.height_ratio(&o).unwrap() * cam.height;
        assert!((exact - h).abs() < 1e-9);
        let lin = linear_height(&g, cam.height, &o, 1.8);
        worst_linear = worst_linear.max((lin - h).abs());
        // Exact for the reference height itself.
        let o_ref = HeadFoot {
            head: cam.project([x, y, 1.8]).unwrap(),
            ..o
        };
        assert!((linear_height(&g, cam.height, &o_ref, 1.8) - 1.8).abs() < 1e-9);
    }
    assert!(
        worst_linear > 0.02,
        "linear approximation error only {worst_linear}"
    );
}

/// Per-frame heights of a 1.80 m person walking: gait (head bob and
/// posture, ±4 cm as in the paper's Figs. 7–8), pixel noise, and a few
/// occluded frames reading low.
fn walking_heights(rng: &mut Rng) -> Vec<f64> {
    (0..120)
        .map(|k| {
            let gait = 0.04 * (libm::sin(k as f64 * 0.7).abs() - 0.5);
            let mut h = 1.80 + gait + 0.01 * rng.normal();
            if k % 17 == 5 {
                h = 1.31 + 0.05 * rng.uniform(); // an occluder cut the legs
            }
            h
        })
        .collect()
}

#[test]
fn ransac_correction_removes_occlusion_and_pose_errors() {
    let cfg = MeasureConfig::default();
    let mut rng = Rng::new(4);
    let mut worst = 0.0f64;
    let mut mean_err = 0.0f64;
    for _ in 0..20 {
        let h = walking_heights(&mut rng);
        let c = ransac_mean(&h, &cfg, &mut rng).unwrap();
        worst = worst.max((c.height - 1.80).abs());
        let mean = h.iter().sum::<f64>() / h.len() as f64;
        mean_err = mean_err.max((mean - 1.80).abs());
        assert!(c.samples < c.considered, "occluded frames must be outliers");
    }
    assert!(worst < 0.01, "corrected error {worst}");
    assert!(
        mean_err > 3.0 * worst,
        "plain mean {mean_err} vs corrected {worst}"
    );
}

#[test]
fn heights_wait_for_confidence_and_follow_calibration_updates() {
    let cam = Camera::centred(700.0, 25.0, 2.0, 4.0, 640, 480);
    let obs: Vec<HeadFoot> = (0..40)
        .map(|k| {
            let (x, y) = (-2.0 + 0.1 * k as f64, 7.0 + 0.05 * k as f64);
            HeadFoot {
                head: cam.project([x, y, 1.72]).unwrap(),
                foot: cam.project([x, y, 0.0]).unwrap(),
            }
        })
        .collect();
    let mut m = Measurer::new(&MeasureConfig::default(), 128);
    assert!(m.track_height(None, obs.iter()).is_none());
    let below = MeasureConfig::default().min_confidence * 0.9;
    assert!(m
        .track_height(Some(&estimate(&cam, below)), obs.iter())
        .is_none());
    let c = m
        .track_height(Some(&estimate(&cam, 0.9)), obs.iter())
        .unwrap();
    assert!((c.height - 1.72).abs() < 1e-6 && c.samples == 40);
    // A better (here: different) calibration re-measures the same
    // observations: 10 % more camera height, 10 % taller person.
    let mut e = estimate(&cam, 0.9);
    e.camera_height *= 1.1;
    let c2 = m.track_height(Some(&e), obs.iter()).unwrap();
    assert!((c2.height - 1.72 * 1.1).abs() < 1e-6);
    // Too few observations: nothing.
    assert!(m.track_height(Some(&e), obs[..3].iter()).is_none());
}

#[test]
fn implausible_heights_are_not_reported() {
    // A dog's track, measured like a person, reads about 0.7 m.
    let cam = Camera::centred(700.0, 25.0, 0.0, 4.0, 640, 480);
    let est = estimate(&cam, 1.0);
    let obs: Vec<HeadFoot> = (0..20)
        .map(|k| {
            let y = 8.0 + 0.2 * f64::from(k);
            HeadFoot {
                head: cam.project([0.5, y, 0.7]).unwrap(),
                foot: cam.project([0.5, y, 0.0]).unwrap(),
            }
        })
        .collect();
    let mut m = Measurer::new(&MeasureConfig::default(), 64);
    assert_eq!(m.track_height(Some(&est), obs.iter()), None);
    let open = MeasureConfig {
        min_height_m: 0.5,
        ..Default::default()
    };
    let mut m = Measurer::new(&open, 64);
    let h = m.track_height(Some(&est), obs.iter()).unwrap();
    assert!((h.height - 0.7).abs() < 1e-6, "{h:?}");
}

#[test]
fn min_samples_cannot_exceed_what_a_track_keeps() {
    // A track keeps its newest `RING` observations: a larger minimum would
    // pass the check and then silently give no heights at all.
    let ok = MeasureConfig {
        min_samples: crate::track::RING,
        ..MeasureConfig::default()
    };
    assert!(ok.validate().is_ok());
    let too_many = MeasureConfig {
        min_samples: crate::track::RING + 1,
        ..MeasureConfig::default()
    };
    let err = too_many.validate().unwrap_err().to_string();
    assert!(
        err.contains("measure.min_samples") && err.contains("1..=128"),
        "{err}"
    );
}
