//! Calibration and heights from simulated-scene truth head/foot points
//! (0.7 px noise), on a seed the code was not tuned on. Conservative
//! floors; full numbers: `cargo run --release --example core_accuracy`.

use stature::calibrate::eval::{evaluate, quantile, sim_people};

#[test]
fn sim_truth_points_calibrate_and_measure() {
    for scene in ["plaza", "high"] {
        let (people, cam, w, h) = sim_people(scene, 3, 0.7).expect("scene renders");
        let a = evaluate(&people, cam.height, w, h, stature::track::RING);
        let e = a.prior_matched.expect("a calibration");
        let f_err = (e.geom.focal() / cam.f - 1.0).abs();
        let tilt = (e.geom.tilt() - cam.tilt).abs().to_degrees();
        let roll = (e.geom.roll() - cam.roll).abs().to_degrees();
        let hc = (e.camera_height / cam.height - 1.0).abs();
        assert!(f_err < 0.03, "{scene}: focal error {f_err}");
        assert!(tilt < 1.0 && roll < 1.0, "{scene}: tilt {tilt} roll {roll}");
        assert!(hc < 0.03, "{scene}: camera height error {hc}");
        let ae = a.abs_errors();
        assert!(ae.len() >= 5, "{scene}: only {} people measured", ae.len());
        assert!(quantile(&ae, 0.5) < 0.025, "{scene}: median {:?}", ae);
        assert!(quantile(&ae, 0.9) < 0.05, "{scene}: p90 {:?}", ae);
        let sf = a.scale_free_errors();
        assert!(quantile(&sf, 0.5) < 0.015, "{scene}: scale-free {:?}", sf);
    }
}
