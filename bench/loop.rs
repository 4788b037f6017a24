//! Per-frame cost of the whole vision loop on a fixed input.
//!
//! `cargo bench --bench loop -- [--frames N] [--size WxH] [--source URI]`
//! prints ns/frame and ns/pixel. Under callgrind
//! (`bench/callgrind.sh loop`) the same binary gives instructions per pixel.
//! The default input is a synthetic Y4M clip held in memory (same bytes
//! every run); `--source` takes any source, e.g. `sim:plaza?seed=1`.

use stature::config::Config;
use stature::frame::Size;
use stature::report::Reporter;
use stature::run::Pipeline;
use stature::source::{self, FrameSource, Next};
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;

fn main() {
    let mut frames = 300usize;
    let mut size = Size {
        width: 640,
        height: 480,
    };
    let mut uri: Option<String> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--frames" => {
                frames = args
                    .next()
                    .and_then(|v| v.parse().ok())
                    .expect("--frames N")
            }
            "--size" => {
                let v = args.next().expect("--size WxH");
                let (w, h) = v.split_once('x').expect("--size WxH");
                size = Size {
                    width: w.parse().unwrap(),
                    height: h.parse().unwrap(),
                };
            }
            "--source" => uri = args.next(),
            "--bench" => {}
            other => panic!("unknown option {other}"),
        }
    }
    let mut src: Box<dyn FrameSource + Send> = match &uri {
        Some(u) => source::open(u).unwrap_or_else(|e| panic!("{u}: {e}")),
        None => Box::new(
            source::y4m::Y4mSource::from_reader(
                Box::new(std::io::Cursor::new(common::synthetic_y4m(size, frames))),
                "synthetic".into(),
            )
            .unwrap(),
        ),
    };
    let cfg = Config::default();
    let size = src.info().size;
    let mut p = Pipeline::new(&cfg, src.info());
    // Records are discarded: this measures the vision loop, not the sinks.
    let (mut reporter, rx, _) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let drain = std::thread::spawn(move || rx.iter().count());
    let mut decode_ns = 0u128;
    let mut process_ns = 0u128;
    let mut n = 0u64;
    while n < frames as u64 {
        let t0 = Instant::now();
        match src.next_frame(&mut p.frame).expect("source") {
            Next::Frame => {}
            Next::Waiting => continue,
            Next::End => break,
        }
        let t1 = Instant::now();
        p.process(&mut reporter);
        let t2 = Instant::now();
        decode_ns += (t1 - t0).as_nanos();
        process_ns += (t2 - t1).as_nanos();
        n += 1;
    }
    p.finish(&mut reporter);
    drop(reporter);
    drain.join().unwrap();
    let px = (size.width * size.height) as f64;
    let per = |ns: u128| ns as f64 / n.max(1) as f64;
    println!(
        "input: {} ({}x{}), {n} frames",
        uri.as_deref().unwrap_or("synthetic y4m"),
        size.width,
        size.height
    );
    println!(
        "source  : {:>10.0} ns/frame {:>7.2} ns/px",
        per(decode_ns),
        per(decode_ns) / px
    );
    println!(
        "pipeline: {:>10.0} ns/frame {:>7.2} ns/px",
        per(process_ns),
        per(process_ns) / px
    );
}
