//! Detection-stage benchmark: ns/frame and (under callgrind) instructions
//! per pixel for the background model, the clean-up and the labelling,
//! on PETS 2009 frames resampled to the benchmark size.
//!
//! ```text
//! cargo bench --bench detect -- [--size 1280x720] [--warm 60] [--frames 40] [--dump DIR]
//!     [--interval N] [--check] [--slow]
//! valgrind --tool=callgrind --toggle-collect='*measured*' \
//!     target/release/deps/detect-* --size 1280x720 --frames 20
//! ```
//!
//! `--dump DIR` writes the resampled frames as `DIR/frames_WxH.y4m` (for
//! `bench/mog2_compare.py`). `--check` also runs every frame through a
//! second detector on the scalar path only and stops at the first frame
//! whose model or mask differs (exactness of the vectorised paths over
//! the steady state, which the 120-frame test does not reach).

use stature::dataset::{pets_video, shared_data_dir};
use stature::detect::{DetectConfig, Detector, RegionSet};
use stature::frame::{Frame, Size};
use stature::source::{FrameSource, Next};
use std::hint::black_box;
use std::io::Write;
use std::time::Instant;

/// Stage timings summed over the measured frames, nanoseconds.
#[derive(Default)]
struct Times {
    gmm: u128,
    clean: u128,
    label: u128,
}

/// The measured loop (callgrind collects only inside it).
#[inline(never)]
fn measured(det: &mut Detector, frames: &[Frame], out: &mut RegionSet, t: &mut Times) -> usize {
    let mut regions = 0;
    for f in frames {
        let t0 = Instant::now();
        segment(det, f);
        let t1 = Instant::now();
        clean(det, f);
        let t2 = Instant::now();
        label(det, out);
        let t3 = Instant::now();
        t.gmm += (t1 - t0).as_nanos();
        t.clean += (t2 - t1).as_nanos();
        t.label += (t3 - t2).as_nanos();
        regions += out.regions().len();
    }
    regions
}

#[inline(never)]
fn segment(det: &mut Detector, f: &Frame) {
    det.segment(black_box(f));
}
#[inline(never)]
fn clean(det: &mut Detector, f: &Frame) {
    det.clean_up(black_box(f));
}
#[inline(never)]
fn label(det: &mut Detector, out: &mut RegionSet) {
    det.label(out);
}

/// Nearest-neighbour resampling of all three planes (the chroma term of
/// the detector reads U and V, so they carry the clip's real colours).
fn resample(src: &Frame, size: Size) -> Frame {
    let s = src.size();
    let mut f = Frame::new(size);
    for y in 0..size.height {
        let sy = y * s.height / size.height;
        for x in 0..size.width {
            let sx = x * s.width / size.width;
            f.y[y * size.width + x] = src.y[sy * s.width + sx];
        }
    }
    let (sc, dc) = (s.chroma(), size.chroma());
    for y in 0..dc.height {
        let sy = y * sc.height / dc.height;
        for x in 0..dc.width {
            let sx = x * sc.width / dc.width;
            f.u[y * dc.width + x] = src.u[sy * sc.width + sx];
            f.v[y * dc.width + x] = src.v[sy * sc.width + sx];
        }
    }
    f
}

fn main() {
    let mut size = Size {
        width: 1280,
        height: 720,
    };
    let (mut warm, mut frames) = (60usize, 40usize);
    let mut dump: Option<String> = None;
    let mut force_slow = false;
    let mut check = false;
    let mut cfg = DetectConfig::default();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--size" => {
                let v = args.next().expect("--size WxH");
                let (w, h) = v.split_once('x').expect("WxH");
                size = Size {
                    width: w.parse().expect("width"),
                    height: h.parse().expect("height"),
                };
            }
            "--warm" => warm = args.next().expect("n").parse().expect("n"),
            "--frames" => frames = args.next().expect("n").parse().expect("n"),
            "--dump" => dump = args.next(),
            // Every pixel through the scalar path (to price it).
            "--slow" => force_slow = true,
            "--check" => check = true,
            // Price another `detect.update_interval` without a rebuild.
            "--interval" => cfg.update_interval = args.next().expect("n").parse().expect("n"),
            // Price `detect.deep_shadow_min_ratio` (0 = the peel off).
            "--deep-shadow" => {
                cfg.deep_shadow_min_ratio = args.next().expect("ratio").parse().expect("ratio")
            }
            "--bench" => {}
            _ => {}
        }
    }
    // The model would clamp an out-of-range value and mislabel the run.
    if let Err(e) = cfg.validate() {
        eprintln!("detect bench: {e}");
        std::process::exit(2);
    }
    let Some(dir) = shared_data_dir() else {
        eprintln!("detect bench: ../shared/data missing, nothing to measure");
        return;
    };
    let mut src = pets_video(&dir).expect("ffmpeg decodes PETS");
    let mut f = Frame::new(src.info().size);
    let mut all = Vec::with_capacity(warm + frames);
    // Start at frame 100 so people are in view throughout.
    let mut i = 0;
    while all.len() < warm + frames {
        if src.next_frame(&mut f).expect("frame") != Next::Frame {
            break;
        }
        if i >= 100 {
            all.push(resample(&f, size));
        }
        i += 1;
    }
    drop(src);
    if let Some(d) = dump {
        let path = format!("{d}/frames_{}x{}.y4m", size.width, size.height);
        let mut w = std::io::BufWriter::new(std::fs::File::create(&path).expect("dump file"));
        writeln!(
            w,
            "YUV4MPEG2 W{} H{} F10:1 Ip A1:1 C420jpeg",
            size.width, size.height
        )
        .unwrap();
        for fr in &all {
            w.write_all(b"FRAME\n").unwrap();
            w.write_all(&fr.y).unwrap();
            w.write_all(&fr.u).unwrap();
            w.write_all(&fr.v).unwrap();
        }
        eprintln!("wrote {path} ({} frames)", all.len());
    }
    let mut det = Detector::new(&cfg, size);
    det.background_mut().set_force_slow(force_slow);
    let mut out = RegionSet::with_capacity(cfg.region_capacity(), cfg.run_capacity(size));
    if check {
        let mut slow = Detector::new(&cfg, size);
        slow.background_mut().set_force_slow(true);
        for (i, fr) in all.iter().enumerate() {
            det.segment(fr);
            slow.segment(fr);
            if det.raw_mask() != slow.raw_mask()
                || det.shadow_mask() != slow.shadow_mask()
                || det.background().digest() != slow.background().digest()
            {
                eprintln!("check: frame {i}: fast and scalar paths differ");
                std::process::exit(1);
            }
        }
        println!(
            "check: {} frames, fast and scalar paths identical",
            all.len()
        );
        return;
    }
    for fr in &all[..warm] {
        det.process(fr, &mut out);
    }
    let mut t = Times::default();
    let n = measured(&mut det, &all[warm..], &mut out, &mut t);
    let k = (all.len() - warm).max(1) as u128;
    let px = size.pixels() as f64;
    let per = |ns: u128| (ns / k) as f64;
    println!(
        "detect {}x{} ({} B/px model, {} measured frames, {:.1} regions/frame, {:.2} % slow-path px):",
        size.width,
        size.height,
        det.background().bytes_per_pixel(),
        k,
        n as f64 / k as f64,
        100.0 * f64::from(det.stats().slow_pixels) / px
    );
    for (name, ns) in [
        ("gmm", t.gmm),
        ("clean-up", t.clean),
        ("labelling", t.label),
        ("total", t.gmm + t.clean + t.label),
    ] {
        println!(
            "  {name:10} {:>10.0} ns/frame {:>7.2} ns/px",
            per(ns),
            per(ns) / px
        );
    }
}
