//! Any text given to the config loader is accepted or refused with an
//! error; never a panic. Accepted configs re-serialise and re-parse equal.
#![no_main]
use libfuzzer_sys::fuzz_target;
use stature::config::Config;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    if let Ok(cfg) = Config::from_toml(text) {
        let again = toml::to_string(&cfg).expect("a valid config serialises");
        let back = Config::from_toml(&again).expect("a serialised config parses");
        assert_eq!(back, cfg);
    }
});
