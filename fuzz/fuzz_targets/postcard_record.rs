//! Any bytes given to the postcard record decoder decode or fail cleanly;
//! a decoded record re-encodes and decodes to itself.
#![no_main]
use libfuzzer_sys::fuzz_target;
use stature::config::Format;
use stature::report::encode::{decode_postcard, encode, MAX_RECORD};

fuzz_target!(|data: &[u8]| {
    let mut frame = data.to_vec();
    if let Ok(record) = decode_postcard(&mut frame) {
        let mut buf = [0u8; MAX_RECORD];
        if let Ok(bytes) = encode(&record, Format::Postcard, &mut buf) {
            let mut again = bytes.to_vec();
            assert_eq!(decode_postcard(&mut again).expect("re-decodes"), record);
        }
        // JSON of any decoded record must encode or report TooLong, never panic.
        let _ = encode(&record, Format::Json, &mut buf);
    }
});
