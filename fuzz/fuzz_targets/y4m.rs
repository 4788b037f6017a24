//! Any byte stream given to the Y4M reader ends in frames, a clean end or an
//! error: never a panic, never an unbounded allocation.
#![no_main]
use libfuzzer_sys::fuzz_target;
use stature::frame::Frame;
use stature::source::y4m::Y4mSource;
use stature::source::{FrameSource, Next};

fuzz_target!(|data: &[u8]| {
    let Ok(mut src) = Y4mSource::from_reader(Box::new(std::io::Cursor::new(data.to_vec())), "fuzz".into()) else {
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
});
