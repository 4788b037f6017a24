//! Any text given to the config loader is accepted or refused with an
//! error; never a panic. Accepted configs re-serialise and re-parse equal.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| stature::fuzz_entry::config(data));
