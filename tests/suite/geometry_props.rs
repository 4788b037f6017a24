//! Property tests of the calibration geometry (METHOD.md eqs. 1–7): random
//! cameras in the product's range, random people on the ground, exact
//! projections. Each property is an identity of projective geometry, so
//! the tolerances are numerical, not statistical; proptest shrinks any
//! failure to a minimal camera and person.

use proptest::prelude::*;
use stature::calibrate::geometry::{Anchor, HeadFoot, Normaliser, ViewGeometry};
use stature::calibrate::horizon::fit_horizon;
use stature::calibrate::vertical::{fit_vertical, VerticalParams};
use stature::camera::Camera;
use stature::rng::Rng;

/// Focal length, tilt, roll and mounting height across the product's range
/// (METHOD.md; the simulated scenes span the same), at 640x480 or 1280x720.
fn camera() -> impl Strategy<Value = (Camera, usize, usize)> {
    (
        300.0..1500.0f64,
        10.0..40.0f64,
        -6.0..6.0f64,
        2.0..8.0f64,
        prop::bool::ANY,
    )
        .prop_map(|(f, tilt, roll, h, hd)| {
            let (w, ht) = if hd { (1280, 720) } else { (640, 480) };
            (Camera::centred(f, tilt, roll, h, w, ht), w, ht)
        })
}

/// A standing person whose foot is seen at image fraction `(fx, fy)` of
/// the lower half of the frame: `(head, foot, height)`.
fn person(cam: &Camera, w: usize, ht: usize, fx: f64, fy: f64, h: f64) -> Option<HeadFoot> {
    let px = [fx * (w as f64 - 1.0), (0.5 + 0.5 * fy) * (ht as f64 - 1.0)];
    let g = cam.ground_point(px)?;
    let foot = cam.project([g[0], g[1], 0.0])?;
    let head = cam.project([g[0], g[1], h])?;
    Some(HeadFoot { head, foot })
}

fn near(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// Eq. 3 and the tilt/roll relations give back the camera exactly from
    /// its vertical vanishing point and horizon.
    #[test]
    fn vanishing_geometry_gives_back_focal_tilt_and_roll((cam, _, _) in camera()) {
        let g = ViewGeometry::of_camera(&cam);
        prop_assert!((g.focal() / cam.f - 1.0).abs() < 1e-9, "f {} vs {}", g.focal(), cam.f);
        prop_assert!((g.tilt() - cam.tilt).abs() < 1e-9, "tilt {} vs {}", g.tilt(), cam.tilt);
        prop_assert!((g.roll() - cam.roll).abs() < 1e-9, "roll {} vs {}", g.roll(), cam.roll);
    }

    /// The cross ratio inverts projection: the height ratio of a projected
    /// person is exactly h / h_c, and the reference head of that ratio is
    /// exactly the projected head.
    #[test]
    fn cross_ratio_height_inverts_projection(
        (cam, w, ht) in camera(),
        fx in 0.0..1.0f64,
        fy in 0.05..1.0f64,
        h in 1.0..2.1f64,
    ) {
        let Some(o) = person(&cam, w, ht, fx, fy, h) else { return Ok(()); };
        let g = ViewGeometry::of_camera(&cam);
        let r = g.height_ratio(&o).expect("a person below the horizon has a ratio");
        prop_assert!((r * cam.height - h).abs() < 1e-9 * cam.height, "{} m vs {h} m", r * cam.height);
        let head = g.head_for_ratio(o.foot, h / cam.height).expect("reference head");
        prop_assert!(near(head, o.head) < 1e-6, "head {head:?} vs {:?}", o.head);
    }

    /// Head–foot lines of people anywhere in view meet at the vertical
    /// vanishing point: the fit recovers it from exact observations.
    #[test]
    fn people_give_back_the_vertical_vanishing_point(
        (cam, w, ht) in camera(),
        spots in prop::collection::vec((0.0..1.0f64, 0.05..1.0f64, 1.4..2.0f64), 8..40),
        seed in any::<u64>(),
    ) {
        let obs: Vec<Anchor> = spots
            .iter()
            .filter_map(|&(fx, fy, h)| person(&cam, w, ht, fx, fy, h))
            .map(Anchor::from)
            .collect();
        prop_assume!(obs.len() >= 8);
        let norm = Normaliser::for_image(w, ht);
        let params = VerticalParams { iterations: 64, lean: true };
        let mut inlier = vec![false; obs.len()];
        let mut scratch = vec![0.0; obs.len()];
        let fit = fit_vertical(&obs, &norm, &params, &mut Rng::new(seed), &mut inlier, &mut scratch)
            .expect("exact lines have a consensus");
        prop_assert_eq!(fit.inliers, obs.len());
        let truth = cam.vertical_vanishing_point();
        let vh = fit.vertical.homogeneous();
        let v = [norm.p[0] + norm.s * vh.x / vh.z, norm.p[1] + norm.s * vh.y / vh.z];
        let r = near(truth, cam.principal);
        prop_assert!(near(v, truth) < 1e-6 * r, "v {v:?} vs {truth:?}");
    }

    /// Two people, each seen three times at different depths (one height
    /// each), put the horizon at its true distance from the principal point.
    #[test]
    fn people_keeping_their_height_give_the_horizon(
        (cam, w, ht) in camera(),
        a in prop::collection::vec((0.0..1.0f64, 0.05..1.0f64), 3),
        b in prop::collection::vec((0.0..1.0f64, 0.05..1.0f64), 3),
        h in (1.4..2.0f64, 1.4..2.0f64),
    ) {
        let depth = |s: &[(f64, f64)]| {
            let (lo, hi) = s.iter().fold((1.0f64, 0.0f64), |(l, u), p| (l.min(p.1), u.max(p.1)));
            hi - lo
        };
        prop_assume!(depth(&a) > 0.2 && depth(&b) > 0.2);
        let mut obs = Vec::new();
        let mut track = Vec::new();
        for (k, (spots, hk)) in [(&a, h.0), (&b, h.1)].into_iter().enumerate() {
            for &(fx, fy) in spots.iter() {
                let Some(o) = person(&cam, w, ht, fx, fy, hk) else { return Ok(()); };
                obs.push(Anchor::from(o));
                track.push(k as u16);
            }
        }
        let g = ViewGeometry::of_camera(&cam);
        let inlier = vec![true; obs.len()];
        let mut scratch = vec![0.0; 3 * obs.len()];
        let fit = fit_horizon(&obs, &track, &inlier, &g, (w.max(ht) / 2) as f64, &mut scratch)
            .expect("two tracks of three");
        prop_assert!((fit.d / g.d - 1.0).abs() < 1e-4, "d {} px vs {} px", fit.d, g.d);
    }
}
