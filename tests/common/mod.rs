//! Helpers shared by the integration tests.
#![allow(dead_code)]

use stature::frame::Size;

/// A small deterministic Y4M clip: a textured background with two
/// person-sized bright blobs walking across it, and 4:2:0 chroma.
pub fn synthetic_y4m(size: Size, frames: usize) -> Vec<u8> {
    let (w, h) = (size.width, size.height);
    let c = size.chroma();
    let mut out = format!("YUV4MPEG2 W{w} H{h} F25:1 Ip A1:1 C420jpeg\n").into_bytes();
    let mut seed = 0x2545_f491_u32;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed
    };
    for f in 0..frames {
        out.extend_from_slice(b"FRAME\n");
        let back = (w as isize - 40 - f as isize).rem_euclid(w as isize) as usize;
        let blobs = [
            ((20 + f * 2) % w, h / 3, w / 16, h / 4),
            (back, h / 2, w / 14, h / 3),
        ];
        for y in 0..h {
            for x in 0..w {
                let texture = 90 + ((x / 8 + y / 8) % 2) as u32 * 30;
                let noise = rnd() % 5;
                let inside = blobs
                    .iter()
                    .any(|&(bx, by, bw, bh)| x >= bx && x < bx + bw && y >= by && y < by + bh);
                out.push(if inside { 200 } else { (texture + noise) as u8 });
            }
        }
        out.extend(std::iter::repeat_n(110u8, c.pixels()));
        out.extend(std::iter::repeat_n(150u8, c.pixels()));
    }
    out
}

/// `stature ARGS` to its end, stdin empty, stdout and stderr captured.
pub fn run_stature(args: &[&str]) -> std::process::Output {
    std::process::Command::new(stature_bin())
        .args(args)
        .stdin(std::process::Stdio::null())
        .output()
        .unwrap()
}

/// Path of the built `stature` binary (integration tests only).
pub fn stature_bin() -> &'static str {
    env!("CARGO_BIN_EXE_stature")
}

mod scratch;
// Not every test crate that includes `common` makes scratch directories.
#[allow(unused_imports)]
pub use scratch::{fresh_dir, mkfifo, runs_from_env, with_fifo_writer, ScratchDir};
