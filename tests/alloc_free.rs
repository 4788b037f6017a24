//! The steady-state loop performs no heap allocation: a counting global
//! allocator watches ≥ 300 frames through the full pipeline, with a report
//! sink and its I/O thread running.

use stature::alloc_count::{allocations, CountingAlloc};
use stature::config::{Config, Format};
use stature::frame::Size;
use stature::report::record::Record;
use stature::report::{self, sink, Reporter};
use stature::run::{self, LoopOptions, Pipeline};
use stature::source::{self, FrameSource, Next};
use std::sync::atomic::AtomicBool;

mod common;

#[global_allocator]
static GLOBAL: CountingAlloc = CountingAlloc;

const WARM_UP: u64 = 60;
const MEASURED: u64 = 300;

/// The sources the allocation checks run on: the built-in simulated scene
/// when this build has it, and recorded frames (Y4M) always.
fn sources() -> Vec<(String, Box<dyn FrameSource + Send>)> {
    let mut out: Vec<(String, Box<dyn FrameSource + Send>)> = Vec::new();
    let size = Size {
        width: 320,
        height: 240,
    };
    let clip = common::synthetic_y4m(size, (WARM_UP + MEASURED + 5) as usize);
    let y4m = source::y4m::Y4mSource::from_reader(
        Box::new(std::io::Cursor::new(clip)),
        "synthetic".into(),
    )
    .unwrap();
    out.push(("y4m".into(), Box::new(y4m)));
    let uri = format!("sim:plaza?seed=3&frames={}", WARM_UP + MEASURED + 5);
    match source::open(&uri) {
        Ok(s) => out.push((uri, s)),
        Err(e) => eprintln!("note: {uri} not available ({e}); checked on recorded frames only"),
    }
    out
}

// One test function: the allocation counter is process-wide, and the test
// harness runs separate tests on parallel threads (and allocates to print
// their results), which would pollute the counts.
#[test]
fn loop_allocates_nothing_after_start_up() {
    steady_state_loop_allocates_nothing();
    status_records_report_zero_allocations();
}

fn steady_state_loop_allocates_nothing() {
    for (name, mut src) in sources() {
        let cfg = Config {
            report: stature::config::ReportConfig {
                format: Format::Postcard,
                ..Default::default()
            },
            ..Default::default()
        };
        let dir = common::fresh_dir("alloc");
        let out = dir.join("records.bin");
        let sinks =
            vec![sink::Sink::open(&sink::SinkSpec::File(out.display().to_string())).unwrap()];
        let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
        let io = report::spawn_io(rx, sinks, cfg.report.format, counters.clone());
        let mut p = Pipeline::new(&cfg, src.info());
        let mut per_frame = Vec::with_capacity(MEASURED as usize);
        let mut before = 0;
        for i in 0..WARM_UP + MEASURED {
            if i == WARM_UP {
                before = allocations();
            }
            let a = allocations();
            assert_eq!(
                src.next_frame(&mut p.frame).unwrap(),
                Next::Frame,
                "{name}: frame {i}"
            );
            p.process(&mut reporter);
            if i >= WARM_UP {
                per_frame.push(allocations() - a);
            }
        }
        let total = allocations() - before;
        p.finish(&mut reporter);
        reporter.finish(std::time::Duration::from_secs(5));
        io.join().unwrap();
        let worst = per_frame
            .iter()
            .enumerate()
            .max_by_key(|(_, n)| **n)
            .unwrap();
        assert_eq!(total, 0, "{name}: {total} allocations in {MEASURED} steady-state frames (worst: frame {} with {})", worst.0 as u64 + WARM_UP, worst.1);
        assert_eq!(p.frames, WARM_UP + MEASURED);
    }
}

/// The whole `run` loop, status records included, reports 0 allocations
/// after start-up through its own `allocations` field, with the installer
/// snapshot watching the loop (it draws and writes only after it).
fn status_records_report_zero_allocations() {
    let size = Size {
        width: 160,
        height: 120,
    };
    let clip = common::synthetic_y4m(size, 400);
    let mut src = source::y4m::Y4mSource::from_reader(
        Box::new(std::io::Cursor::new(clip)),
        "synthetic".into(),
    )
    .unwrap();
    let mut cfg = Config::default();
    cfg.report.status_interval_s = 2.0; // every 50 frames at 25 fps
    cfg.report.format = Format::Postcard;
    let dir = common::fresh_dir("alloc-status");
    let out = dir.join("records.bin");
    let sinks = vec![sink::Sink::open(&sink::SinkSpec::File(out.display().to_string())).unwrap()];
    let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let io = report::spawn_io(rx, sinks, cfg.report.format, counters.clone());
    let stop = AtomicBool::new(false);
    let opts = LoopOptions {
        max_frames: 0,
        status_interval_s: cfg.report.status_interval_s,
        stop: &stop,
        allocations,
        state: None,
    };
    let snap_path = dir.join("snapshot.png");
    let mut snap = stature::snapshot::Snapshot::new(&cfg, src.info(), &snap_path, false).unwrap();
    let summary = run::run_observed(&cfg, &mut src, &mut reporter, opts, &mut snap);
    reporter.finish(std::time::Duration::from_secs(5));
    io.join().unwrap();
    assert_eq!(summary.frames, 400);
    assert!(matches!(snap.result, Some(Ok(()))) && snap_path.exists());
    let mut bytes = std::fs::read(&out).unwrap();
    let mut statuses = Vec::new();
    for frame in bytes.split_mut(|&b| b == 0).filter(|f| !f.is_empty()) {
        let mut framed = frame.to_vec();
        framed.push(0);
        if let Record::Status(s) = stature::report::encode::decode_postcard(&mut framed).unwrap() {
            statuses.push((s.frame, s.allocations));
        }
    }
    assert!(statuses.len() >= 8, "{statuses:?}");
    // The first status may include warm-up; every later one must add nothing.
    let warm = statuses[1].1;
    for (frame, n) in &statuses[1..] {
        assert_eq!(*n, warm, "allocations grew by frame {frame}: {statuses:?}");
    }
}
