//! Any bytes given as a calibration state file parse or are refused; a
//! parsed state resumes into a calibrator and updates without panicking.
#![no_main]
use libfuzzer_sys::fuzz_target;
use stature::calibrate::{state::parse_state, CalibrateConfig, Calibrator};

fuzz_target!(|data: &[u8]| {
    if let Ok(saved) = parse_state(data) {
        let mut c = Calibrator::new(&CalibrateConfig::default(), 640, 480);
        c.resume(&saved);
        let _ = c.update(1);
        let _ = c.finish(2);
    }
});
