//! Any bytes given to the SVM weight-blob loader load or are refused with a
//! named reason; never a panic. A loaded model re-serialises to a blob that
//! loads to the same model.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stature::fuzz_entry::weights(data));
