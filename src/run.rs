//! The vision loop: owns every buffer, calls the stages in data-flow order,
//! and hands records to the reporter. Nothing here allocates per frame.

use crate::classify::{Classifier, Verdict};
use crate::config::Config;
use crate::detect::{Detector, RegionSet};
use crate::frame::Frame;
use crate::report::record::{self, Bye, Hello, Record, Status};
use crate::report::Reporter;
use crate::source::{FrameSource, Next, SourceError, SourceInfo, SourceState};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Every buffer and stage of the loop, built once from the configuration.
pub struct Pipeline {
    /// The frame the source fills.
    pub frame: Frame,
    detector: Detector,
    regions: RegionSet,
    classifier: Classifier,
    verdicts: Vec<Verdict>,
    max_classified: usize,
    /// Frames processed.
    pub frames: u64,
}

impl Pipeline {
    /// Allocates everything the loop will ever need for `info`'s frames.
    pub fn new(cfg: &Config, info: &SourceInfo) -> Self {
        let size = info.size;
        let max_regions = cfg.detect.region_capacity();
        Pipeline {
            frame: Frame::new(size),
            detector: Detector::new(&cfg.detect, size),
            regions: RegionSet::with_capacity(max_regions, cfg.detect.run_capacity(size)),
            classifier: Classifier::new(&cfg.classify),
            verdicts: Vec::with_capacity(max_regions),
            max_classified: max_regions,
            frames: 0,
        }
    }

    /// Runs every stage on [`Pipeline::frame`] and queues the records it yields.
    pub fn process(&mut self, _reporter: &mut Reporter) {
        self.detector.process(&self.frame, &mut self.regions);
        self.verdicts.clear();
        let luma = self.frame.luma();
        for region in self.regions.regions().iter().take(self.max_classified) {
            self.verdicts.push(self.classifier.classify(luma, region));
        }
        self.frames += 1;
    }

    /// End of stream: queues final calibration and heights.
    pub fn finish(&mut self, _reporter: &mut Reporter) {}

    /// People tracked now.
    pub fn tracks(&self) -> u32 {
        0
    }
}

/// What a finished run did.
#[derive(Debug)]
pub struct Summary {
    /// Frames processed.
    pub frames: u64,
    /// Why it stopped.
    pub stopped_by: StopReason,
    /// The source error that ended the run, if any (final records were still sent).
    pub error: Option<SourceError>,
}

/// Why the loop ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The source ended.
    EndOfStream,
    /// The configured frame count was reached.
    FrameLimit,
    /// A signal asked for a stop.
    Signal,
    /// The source failed (bad input mid-stream).
    SourceError,
}

/// Loop options that are not part of the pipeline.
pub struct LoopOptions<'a> {
    /// Stop after this many frames (0 = never).
    pub max_frames: u64,
    /// Seconds of stream time between status records.
    pub status_interval_s: f64,
    /// Set by a signal handler to stop cleanly.
    pub stop: &'a AtomicBool,
    /// Allocation count probe for status records.
    pub allocations: fn() -> u64,
}

/// Runs the loop until the source ends, fails, the frame limit, or a stop
/// request. Sends `hello` first and final records at the end whatever the
/// reason; `bye` only when the run ended cleanly (not on a source error).
pub fn run(
    cfg: &Config,
    source: &mut dyn FrameSource,
    reporter: &mut Reporter,
    opts: &LoopOptions<'_>,
) -> Summary {
    let info = source.info().clone();
    let mut p = Pipeline::new(cfg, &info);
    reporter.send(Record::Hello(Hello {
        frame: 0,
        version: record::bounded(env!("CARGO_PKG_VERSION")),
        schema: record::SCHEMA,
        source: record::bounded(&info.description),
        width: info.size.width as u32,
        height: info.size.height as u32,
        fps: info.fps_f64() as f32,
    }));
    // Status cadence in frames of stream time (deterministic for recorded input);
    // while a camera is away, wall time drives it instead.
    let fps = if info.fps_f64() > 0.0 {
        info.fps_f64()
    } else {
        25.0
    };
    let status_every = ((opts.status_interval_s * fps).round() as u64).max(1);
    let alloc_base = (opts.allocations)();
    let mut last_status = (Instant::now(), 0u64);
    let mut last_wait_status = Instant::now();
    let status =
        |p: &Pipeline, state: SourceState, reporter: &mut Reporter, last: &mut (Instant, u64)| {
            let dt = last.0.elapsed().as_secs_f64();
            let rate = if dt > 0.0 {
                (p.frames - last.1) as f64 / dt
            } else {
                0.0
            };
            *last = (Instant::now(), p.frames);
            let dropped = reporter.counters().dropped();
            reporter.send(Record::Status(Status {
                frame: p.frames,
                frames: p.frames,
                fps: rate as f32,
                dropped,
                source: record::bounded(state.as_str()),
                allocations: (opts.allocations)() - alloc_base,
                tracks: p.tracks(),
            }));
        };
    let mut error = None;
    let stopped_by = loop {
        if opts.stop.load(Ordering::Relaxed) {
            break StopReason::Signal;
        }
        if opts.max_frames > 0 && p.frames >= opts.max_frames {
            break StopReason::FrameLimit;
        }
        let next = match source.next_frame(&mut p.frame) {
            Ok(next) => next,
            Err(e) => {
                error = Some(e);
                break StopReason::SourceError;
            }
        };
        match next {
            Next::Frame => {
                p.process(reporter);
                if p.frames % status_every == 0 {
                    status(&p, source.state(), reporter, &mut last_status);
                }
            }
            Next::Waiting => {
                if last_wait_status.elapsed().as_secs_f64() >= opts.status_interval_s {
                    last_wait_status = Instant::now();
                    status(&p, source.state(), reporter, &mut last_status);
                }
            }
            Next::End => break StopReason::EndOfStream,
        }
    };
    p.finish(reporter);
    status(&p, SourceState::Ended, reporter, &mut last_status);
    if error.is_none() {
        let dropped = reporter.counters().dropped();
        reporter.send(Record::Bye(Bye {
            frame: p.frames,
            frames: p.frames,
            dropped,
        }));
    }
    Summary {
        frames: p.frames,
        stopped_by,
        error,
    }
}
