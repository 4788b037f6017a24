//! Any bytes given to the postcard record decoder decode or fail cleanly;
//! a decoded record re-encodes and decodes to itself.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stature::fuzz_entry::postcard_record(data));
