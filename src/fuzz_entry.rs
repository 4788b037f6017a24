//! The parsers' robustness checks, shared by the `cargo fuzz` targets
//! (`fuzz/fuzz_targets/`) and the regression test that replays the
//! committed corpus and every input a fuzzer ever crashed on
//! (`tests/suite/fuzz_corpus.rs`). Each function takes arbitrary bytes and
//! panics only when an invariant is broken; refusing the input is fine.

use crate::calibrate::{state::parse_state, CalibrateConfig, Calibrator};
use crate::classify::svm::Model;
use crate::config::{Config, Format};
use crate::frame::Frame;
use crate::report::encode::{decode_postcard, encode, MAX_RECORD};
use crate::source::y4m::Y4mSource;
use crate::source::{FrameSource, Next};

/// The Y4M reader ends any byte stream in frames, a clean end or an error.
pub fn y4m(data: &[u8]) {
    let reader = Box::new(std::io::Cursor::new(data.to_vec()));
    let Ok(mut src) = Y4mSource::from_reader(reader, "fuzz".into()) else {
        return;
    };
    // Headers may claim up to 16384x16384: only allocate frames for sizes a
    // fuzz input could plausibly fill, as a real caller sizes from its config.
    let size = src.info().size;
    if size.pixels() > 1 << 20 {
        return;
    }
    let mut frame = Frame::new(size);
    for _ in 0..64 {
        match src.next_frame(&mut frame) {
            Ok(Next::Frame) | Ok(Next::Waiting) => {}
            Ok(Next::End) | Err(_) => break,
        }
    }
}

/// Any text is accepted or refused by the config loader; an accepted config
/// re-serialises and re-parses equal.
pub fn config(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(cfg) = Config::from_toml(text) {
        let again = toml::to_string(&cfg).expect("a valid config serialises");
        let back = Config::from_toml(&again).expect("a serialised config parses");
        assert_eq!(back, cfg);
    }
}

/// Postcard frames decode or fail cleanly; a decoded record re-encodes to a
/// frame that decodes and encodes to the same bytes (bytes, not values:
/// a NaN field is a fine record and never equal to itself), and encodes as
/// JSON or reports it is too long.
pub fn postcard_record(data: &[u8]) {
    let mut frame = data.to_vec();
    if let Ok(record) = decode_postcard(&mut frame) {
        let mut buf = [0u8; MAX_RECORD];
        if let Ok(bytes) = encode(&record, Format::Postcard, &mut buf) {
            let first = bytes.to_vec();
            let mut again = first.clone();
            let back = decode_postcard(&mut again).expect("re-decodes");
            let mut buf2 = [0u8; MAX_RECORD];
            let second = encode(&back, Format::Postcard, &mut buf2).expect("re-encodes");
            assert_eq!(first, second);
        }
        let _ = encode(&record, Format::Json, &mut buf);
    }
}

/// Weight blobs load or are refused with a reason; a loaded model saves to
/// a blob that loads to the same model.
pub fn weights(data: &[u8]) {
    if let Ok(model) = Model::from_bytes(data) {
        let again = Model::from_bytes(&model.to_bytes()).expect("a saved model loads");
        assert_eq!(again.to_bytes(), model.to_bytes());
    }
}

/// State files parse or are refused; a parsed state resumes into a
/// calibrator that then updates and finishes.
pub fn calibration_state(data: &[u8]) {
    if let Ok(saved) = parse_state(data) {
        let mut c = Calibrator::new(&CalibrateConfig::default(), 640, 480);
        let _ = c.resume(&saved);
        let _ = c.update(1);
        let _ = c.finish(2);
    }
}

/// A fuzz target: its name (the corpus directory's name) and its check.
pub type Target = (&'static str, fn(&[u8]));

/// Every check by its fuzz target's name (the corpus directory's name).
pub const TARGETS: [Target; 5] = [
    ("y4m", y4m),
    ("config", config),
    ("postcard_record", postcard_record),
    ("weights", weights),
    ("calibration_state", calibration_state),
];
