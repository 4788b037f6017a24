//! Any bytes given as a calibration state file parse or are refused; a
//! parsed state resumes into a calibrator and updates without panicking.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stature::fuzz_entry::calibration_state(data));
