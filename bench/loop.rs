//! Per-frame cost of the whole vision loop, stage by stage, on a fixed input.
//!
//! `cargo bench --bench loop -- [--frames N] [--warm W] [--size WxH] [--source URI]`
//! runs `W` frames (default 0), then measures `N` (default 300): ns/frame of
//! the source and of each stage of `Pipeline::process` (through
//! `Pipeline::process_staged`), regions classified, live tracks and
//! calibration anchors. The default input is a synthetic Y4M clip held in
//! memory (same bytes every run); `--source` takes any source, e.g.
//! `sim:plaza?seed=1` or `y4m:FILE`.
//!
//! Under callgrind, `bench/loop_callgrind.sh [same args]` counts only
//! inside [`measured_frame`] (`--toggle-collect='*measured*'`: start-up,
//! warm-up and the source's decoding or rendering are left out) and splits
//! the count by the `stage_*` functions below, one per [`Stage`].
//!
//! `--calib-anchors A [--refits R]` measures the calibrator alone instead:
//! synthetic walkers (`calibrate::synth`, 640x480, 25 fps) fill its store
//! to `A` anchors (without refitting), then the next `R` refits (default
//! 20, one every `refit_interval` frames as in the loop) are timed (under
//! callgrind: counted, in [`measured_refit`]).

use stature::calibrate::synth::{self, SynthScene};
use stature::calibrate::{CalibrateConfig, Calibrator};
use stature::config::Config;
use stature::frame::Size;
use stature::report::Reporter;
use stature::rng::Rng;
use stature::run::{Pipeline, Stage, Stages};
use stature::source::{self, FrameSource, Next};
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;

const STAGES: [Stage; 7] = [
    Stage::Detect,
    Stage::Classify,
    Stage::Track,
    Stage::Observe,
    Stage::Calibrate,
    Stage::Measure,
    Stage::Report,
];

/// Times each stage (a clock read on either side: ≈ 50 ns a stage).
#[derive(Default)]
struct Timed {
    ns: [u64; 7],
    /// The slowest frame's calibrator update.
    calibrate_max: u64,
}

impl Stages for Timed {
    fn run<R>(&mut self, stage: Stage, f: impl FnOnce() -> R) -> R {
        let t0 = Instant::now();
        // One out-of-line function per stage, so that callgrind names it.
        let r = match stage {
            Stage::Detect => stage_detect(f),
            Stage::Classify => stage_classify(f),
            Stage::Track => stage_track(f),
            Stage::Observe => stage_observe(f),
            Stage::Calibrate => stage_calibrate(f),
            Stage::Measure => stage_measure(f),
            Stage::Report => stage_report(f),
        };
        let dt = t0.elapsed().as_nanos() as u64;
        self.ns[stage as usize] += dt;
        if stage == Stage::Calibrate {
            self.calibrate_max = self.calibrate_max.max(dt);
        }
        r
    }
}

/// One out-of-line function per stage. Each passes its own tag through
/// `black_box`: with identical bodies, LLVM would merge the seven copies
/// made for one closure into one, and callgrind would give them one name.
macro_rules! stage_fns {
    ($($name:ident),*) => {$(
        #[inline(never)]
        fn $name<R>(f: impl FnOnce() -> R) -> R {
            std::hint::black_box(stringify!($name));
            f()
        }
    )*};
}
stage_fns!(
    stage_detect,
    stage_classify,
    stage_track,
    stage_observe,
    stage_calibrate,
    stage_measure,
    stage_report
);

/// One measured frame (callgrind collects only inside it).
#[inline(never)]
fn measured_frame(p: &mut Pipeline, reporter: &mut Reporter, t: &mut Timed) {
    p.process_staged(reporter, t);
}

/// One measured calibrator update (callgrind collects only inside it).
#[inline(never)]
fn measured_refit(c: &mut Calibrator, frame: u64) -> bool {
    c.update(frame).is_some()
}

struct Args {
    frames: usize,
    warm: usize,
    size: Size,
    uri: Option<String>,
    calib_anchors: Option<usize>,
    refits: usize,
}

fn args() -> Args {
    let mut a = Args {
        frames: 300,
        warm: 0,
        size: Size {
            width: 640,
            height: 480,
        },
        uri: None,
        calib_anchors: None,
        refits: 20,
    };
    let mut it = std::env::args().skip(1);
    let num = |v: Option<String>, what: &str| -> usize {
        v.and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("{what} takes a number"))
    };
    while let Some(s) = it.next() {
        match s.as_str() {
            "--frames" => a.frames = num(it.next(), "--frames"),
            "--warm" => a.warm = num(it.next(), "--warm"),
            "--calib-anchors" => a.calib_anchors = Some(num(it.next(), "--calib-anchors")),
            "--refits" => a.refits = num(it.next(), "--refits"),
            "--size" => {
                let v = it.next().expect("--size WxH");
                let (w, h) = v.split_once('x').expect("--size WxH");
                a.size = Size {
                    width: w.parse().expect("--size WxH"),
                    height: h.parse().expect("--size WxH"),
                };
            }
            "--source" => a.uri = it.next(),
            "--bench" => {}
            other => panic!("unknown option {other}"),
        }
    }
    a
}

fn main() {
    let a = args();
    if let Some(anchors) = a.calib_anchors {
        return calibrator_alone(anchors, a.refits);
    }
    let mut src: Box<dyn FrameSource + Send> = match &a.uri {
        Some(u) => source::open(u).unwrap_or_else(|e| panic!("{u}: {e}")),
        None => Box::new(
            source::y4m::Y4mSource::from_reader(
                Box::new(std::io::Cursor::new(common::synthetic_y4m(
                    a.size,
                    a.warm + a.frames,
                ))),
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
    let mut next = |p: &mut Pipeline| loop {
        match src.next_frame(&mut p.frame).expect("source") {
            Next::Frame => return true,
            Next::Waiting => continue,
            Next::End => return false,
        }
    };
    let mut warmed = 0;
    while warmed < a.warm && next(&mut p) {
        p.process(&mut reporter);
        warmed += 1;
    }
    let occ0 = p.occupancy();
    let version0 = p.estimate().map_or(0, |e| e.version);
    let mut t = Timed::default();
    let (mut source_ns, mut total_ns) = (0u64, 0u64);
    let (mut n, mut regions, mut classified, mut tracks) = (0u64, 0usize, 0usize, 0u64);
    while n < a.frames as u64 {
        let t0 = Instant::now();
        if !next(&mut p) {
            break;
        }
        let t1 = Instant::now();
        measured_frame(&mut p, &mut reporter, &mut t);
        total_ns += t1.elapsed().as_nanos() as u64;
        source_ns += (t1 - t0).as_nanos() as u64;
        let (r, v) = p.regions();
        regions += r.regions().len();
        classified += v.len();
        tracks += u64::from(p.tracks());
        n += 1;
    }
    let occ = p.occupancy();
    let refits = p.estimate().map_or(0, |e| e.version) - version0;
    p.finish(&mut reporter);
    drop(reporter);
    drain.join().unwrap();
    let px = (size.width * size.height) as f64;
    let nf = n.max(1) as f64;
    let per = |ns: u64| ns as f64 / nf;
    println!(
        "input: {} ({}x{}), frames {warmed}..{} measured",
        a.uri.as_deref().unwrap_or("synthetic y4m"),
        size.width,
        size.height,
        warmed as u64 + n
    );
    println!(
        "per frame: {:.2} regions, {:.2} classified, {:.2} live tracks; anchors {} -> {} of {}; {refits} refits with an estimate",
        regions as f64 / nf,
        classified as f64 / nf,
        tracks as f64 / nf,
        occ0.anchors,
        occ.anchors,
        occ.anchor_capacity
    );
    println!(
        "source    : {:>10.0} ns/frame {:>7.2} ns/px",
        per(source_ns),
        per(source_ns) / px
    );
    let staged: u64 = t.ns.iter().sum();
    for (s, ns) in STAGES.iter().zip(t.ns) {
        println!(
            "{:<10}: {:>10.0} ns/frame {:>7.3} ns/px {:>5.1} %",
            format!("{s:?}").to_lowercase(),
            per(ns),
            per(ns) / px,
            100.0 * ns as f64 / total_ns.max(1) as f64
        );
    }
    let other = total_ns.saturating_sub(staged);
    println!(
        "other     : {:>10.0} ns/frame {:>7.3} ns/px {:>5.1} % (clock reads included)",
        per(other),
        per(other) / px,
        100.0 * other as f64 / total_ns.max(1) as f64
    );
    println!(
        "pipeline  : {:>10.0} ns/frame {:>7.2} ns/px (slowest calibrator update {} ns)",
        per(total_ns),
        per(total_ns) / px,
        t.calibrate_max
    );
}

/// The calibrator fed synthetic walkers until it holds `anchors` anchors,
/// then timed over its next `refits` refits.
fn calibrator_alone(anchors: usize, refits: usize) {
    let cfg = CalibrateConfig::default();
    let (w, h) = (640, 480);
    let mut rng = Rng::new(7);
    let cam = synth::random_camera(&mut rng, w, h);
    let scene = SynthScene {
        people: 400,
        fps: 25.0,
        ..SynthScene::default()
    };
    let obs = synth::walk(&cam, &scene, &mut rng);
    let mut c = Calibrator::new(&cfg, w, h);
    c.set_fps(scene.fps);
    let mut it = obs.iter().peekable();
    let (mut done, mut ns, mut anchors_seen) = (0usize, 0u64, 0usize);
    let mut measuring = false;
    let mut last_frame = 0;
    while done < refits {
        let Some(frame) = it.peek().map(|o| o.frame) else {
            break;
        };
        while let Some(o) = it.next_if(|o| o.frame == frame) {
            c.observe(o.frame, o.id, o.hf);
        }
        last_frame = frame;
        if !measuring {
            // Filling: no refits (they would cost minutes under callgrind).
            measuring = c.anchor_count() >= anchors;
            continue;
        }
        let v0 = c.estimate().map_or(0, |e| e.version);
        let t0 = Instant::now();
        measured_refit(&mut c, frame);
        let dt = t0.elapsed().as_nanos() as u64;
        if c.estimate().map_or(0, |e| e.version) != v0 {
            ns += dt;
            anchors_seen += c.anchor_count();
            done += 1;
        }
    }
    let d = done.max(1);
    println!(
        "calibrator alone: {done} refits at {:.0} anchors on average (asked {anchors}, capacity {}), frame {last_frame}: {:.0} ns/refit",
        anchors_seen as f64 / d as f64,
        c.anchor_capacity(),
        ns as f64 / d as f64
    );
}
