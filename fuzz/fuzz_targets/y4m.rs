//! Any byte stream given to the Y4M reader ends in frames, a clean end or an
//! error: never a panic, never an unbounded allocation.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stature::fuzz_entry::y4m(data));
