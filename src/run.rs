//! The vision loop: owns every buffer, calls the stages in data-flow order,
//! and hands records to the reporter. Nothing here allocates per frame.

use crate::calibrate::geometry::HeadFoot;
use crate::calibrate::state::StateFile;
use crate::calibrate::Calibrator;
use crate::classify::{Classifier, Verdict};
use crate::config::Config;
use crate::detect::BBox;
use crate::detect::{Detector, RegionSet};
use crate::frame::Frame;
use crate::measure::pending::PendingPool;
use crate::measure::{Corrected, Measurer};
use crate::report::record::{self, Bye, Calibration, Height, Hello, Record, Status};
use crate::report::Reporter;
use crate::source::{FrameSource, Next, SourceError, SourceInfo, SourceState};
use crate::track::Tracker;
use std::path::{Path, PathBuf};
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
    tracker: Tracker,
    calib: Calibrator,
    measurer: Measurer,
    pending: PendingPool,
    pending_lost: u64,
    pending_measured: u64,
    /// Frame since which the calibration has been ready for heights.
    ready_since: Option<u64>,
    fps: f64,
    /// The last calibration record sent (the final one after `finish`).
    pub calibration: Option<Calibration>,
    /// Final heights of ended tracks, for summaries (the first
    /// [`FINAL_HEIGHTS_KEPT`]; all are reported regardless).
    pub final_heights: Vec<Height>,
    /// Frames processed.
    pub frames: u64,
}

/// How full the loop's fixed-size tables are (soak tests and benchmarks).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Occupancy {
    /// Live tracks.
    pub tracks: usize,
    /// Track table capacity.
    pub track_capacity: usize,
    /// Track births refused because the table was full, since start.
    pub track_overflow: u64,
    /// Tracks waiting for a confident calibration to be measured.
    pub pending: usize,
    /// Such tracks given up unmeasured because their pool was full, since start.
    pub pending_lost: u64,
    /// Such tracks measured later, since start.
    pub pending_measured: u64,
    /// Calibration anchors stored.
    pub anchors: usize,
    /// Anchor store capacity.
    pub anchor_capacity: usize,
}

/// Final heights a [`Pipeline`] keeps for its summary.
pub const FINAL_HEIGHTS_KEPT: usize = 1024;

/// A part of [`Pipeline::process`], as [`Pipeline::process_staged`] names
/// it to a [`Stages`] (per-stage benchmarks: `bench/loop.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Background model, clean-up and regions ([`Detector::process`]).
    Detect,
    /// HOG-LBP + SVM on each region (up to `classify.max_regions`).
    Classify,
    /// The tracker's step.
    Track,
    /// The tracks' fresh head/foot points into the calibrator.
    Observe,
    /// The calibrator's update (a refit when one is due).
    Calibrate,
    /// One track's height ([`Measurer::track_height`]).
    Measure,
    /// One record into the report queue ([`Reporter::send`]).
    Report,
}

/// Runs the stages of [`Pipeline::process_staged`]. Stages do not nest;
/// what is outside them (record building, the loops that pick the tracks
/// due) is little.
pub trait Stages {
    /// Runs `f`, the work of `stage`, and returns what it returns. Called
    /// in the loop: it must not allocate.
    fn run<R>(&mut self, stage: Stage, f: impl FnOnce() -> R) -> R;
}

/// Runs every stage as it is: [`Pipeline::process`].
pub struct Direct;

impl Stages for Direct {
    #[inline(always)]
    fn run<R>(&mut self, _stage: Stage, f: impl FnOnce() -> R) -> R {
        f()
    }
}

impl Pipeline {
    /// How full the track table and the anchor store are now.
    pub fn occupancy(&self) -> Occupancy {
        Occupancy {
            tracks: self.tracker.live() as usize,
            track_capacity: self.tracker.capacity(),
            track_overflow: self.tracker.overflow,
            pending: self.pending.len(),
            pending_lost: self.pending_lost,
            pending_measured: self.pending_measured,
            anchors: self.calib.anchor_count(),
            anchor_capacity: self.calib.anchor_capacity(),
        }
    }

    /// Allocates everything the loop will ever need for `info`'s frames;
    /// the calibration resumes from `run.state` when it is set.
    pub fn new(cfg: &Config, info: &SourceInfo) -> Self {
        Self::with_state(cfg, info, None)
    }

    /// [`Pipeline::new`] with the state file already opened (`None`:
    /// opened here from `run.state` when it is set).
    pub fn with_state(cfg: &Config, info: &SourceInfo, state: Option<StateFile>) -> Self {
        let size = info.size;
        let max_regions = cfg.detect.region_capacity();
        Pipeline {
            frame: Frame::new(size),
            detector: Detector::new(&cfg.detect, size),
            regions: RegionSet::with_capacity(max_regions, cfg.detect.run_capacity(size))
                .with_core(cfg.detect.core_run_capacity(size)),
            // The configuration was validated, weights included; should the
            // file have changed since, no region is called a person.
            classifier: Classifier::new(&cfg.classify).unwrap_or_else(|e| {
                log::error!("{e}; every region will be rejected");
                Classifier::reject_all(&cfg.classify)
            }),
            verdicts: Vec::with_capacity(max_regions),
            max_classified: cfg.classify.max_regions.min(max_regions),
            tracker: Tracker::new(&cfg.track, max_regions),
            calib: Self::calibrator(cfg, info, state),
            measurer: Measurer::new(&cfg.measure, crate::track::RING),
            pending: PendingPool::new(cfg.measure.pending_tracks),
            pending_lost: 0,
            pending_measured: 0,
            ready_since: None,
            fps: stream_fps(info),
            calibration: None,
            final_heights: Vec::with_capacity(FINAL_HEIGHTS_KEPT),
            frames: 0,
        }
    }

    /// The calibrator, resumed from the state file when there is a usable
    /// one (`opened`, else `run.state` opened here).
    fn calibrator(cfg: &Config, info: &SourceInfo, opened: Option<StateFile>) -> Calibrator {
        let mut c = Calibrator::new(&cfg.calibrate, info.size.width, info.size.height);
        c.set_fps(stream_fps(info));
        if !cfg.run.state.is_empty() {
            let opened = opened.map_or_else(
                || StateFile::open(std::path::Path::new(&cfg.run.state), state_capacity(cfg)),
                Ok,
            );
            let file = match opened {
                Ok(f) => f,
                Err(e) => {
                    log::warn!("calibration state {}: {e}; not kept", cfg.run.state);
                    return c;
                }
            };
            if file.in_use_elsewhere() {
                log::warn!(
                    "calibration state {}: {}; this run resumes from it but will not update it",
                    cfg.run.state,
                    crate::calibrate::state::IN_USE
                );
            } else if let Some(e) = file.lock_error() {
                log::warn!(
                    "calibration state {}: {e}; two stature processes on it would tear it",
                    cfg.run.state
                );
            }
            // Why the file cannot be resumed from, and the suffix it is
            // renamed aside with.
            let unusable = match file.load() {
                Ok(Some(saved)) => match c.resume(&saved) {
                    Ok(r) => {
                        log::info!(
                            "calibration state {}: resumed {} observation{}",
                            cfg.run.state,
                            r.restored,
                            if r.restored == 1 { "" } else { "s" }
                        );
                        // Once per start, not per anchor: a damaged file
                        // may hold thousands.
                        if r.outside > 0 {
                            log::warn!(
                                "calibration state {}: dropped {} anchors outside the frame",
                                cfg.run.state,
                                r.outside
                            );
                        }
                        if r.impossible > 0 {
                            log::warn!(
                                "calibration state {}: dropped {} impossible anchors \
                                 (not finite, head not above foot, or motion over 1)",
                                cfg.run.state,
                                r.impossible
                            );
                        }
                        None
                    }
                    Err([sw, sh, w, h]) => Some((
                        format!("it is for {sw}x{sh} frames, not {w}x{h}"),
                        format!("{sw}x{sh}"),
                    )),
                },
                Ok(None) => {
                    log::info!("calibration state {}: new file", cfg.run.state);
                    None
                }
                Err(e @ crate::calibrate::state::StateError::Corrupt(_)) => {
                    Some((e.to_string(), "corrupt".to_string()))
                }
                // Unreadable (permissions, a failing card) is not corrupt:
                // the file stays where it is and this run keeps no state.
                Err(e) => {
                    log::warn!(
                        "calibration state {}: cannot read it ({e}); running without a state file",
                        cfg.run.state
                    );
                    return c;
                }
            };
            if let Some((why, suffix)) = unusable {
                match file.set_aside(&suffix) {
                    Ok(aside) => log::warn!(
                        "calibration state {}: {why}; kept as {} and starting afresh",
                        cfg.run.state,
                        aside.display()
                    ),
                    // Rather than overwrite what could not be moved: no state.
                    Err(e) => {
                        log::warn!(
                            "calibration state {}: {why}, and it cannot be moved aside ({e}); \
                             running without a state file",
                            cfg.run.state
                        );
                        return c;
                    }
                }
            }
            c.state = Some(file);
        }
        c
    }

    /// The current calibration estimate.
    pub fn estimate(&self) -> Option<&crate::calibrate::Estimate> {
        self.calib.estimate()
    }

    /// The tracker (for snapshots and tests).
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// This frame's regions and the classifier's verdict on each (the
    /// verdicts may be fewer: regions beyond `classify.max_regions` are
    /// not classified). For diagnostics and tests.
    pub fn regions(&self) -> (&RegionSet, &[Verdict]) {
        (&self.regions, &self.verdicts)
    }

    /// Heights of live and just-ended tracks: a record for every track
    /// due (or every one with `all`, at the end), final for ended tracks.
    /// A track that ended before the calibration was ready is parked and
    /// measured later ([`crate::measure::pending`]).
    fn heights<S: Stages>(&mut self, reporter: &mut Reporter, frame: u64, all: bool, st: &mut S) {
        let est = self.calib.estimate().copied();
        let ready = self.measurer.ready(est.as_ref());
        self.ready_since = if ready {
            self.ready_since.or(Some(frame))
        } else {
            None
        };
        let min_samples = self.measurer.config().min_samples;
        let interval = u64::from(self.measurer.config().report_interval);
        for t in self.tracker.tracks_mut() {
            let due = t.ended || all || (t.sampled && frame >= t.last_report + interval);
            if !due {
                continue;
            }
            let measured = st.run(Stage::Measure, || {
                self.measurer.track_height(est.as_ref(), t.sample_iter())
            });
            let Some(c) = measured else {
                if t.ended && !ready && t.samples.len() >= min_samples {
                    if let Some(old) = self.pending.park(t) {
                        // Not ready, so the one handed back cannot be measured.
                        self.pending_lost += 1;
                        log::warn!(
                            "track {}: left before the calibration was ready and the \
                             pool of such tracks is full; no height for it",
                            old.id
                        );
                    }
                }
                continue;
            };
            t.last_report = frame;
            t.reported = Some((c.height as f32, c.samples));
            // A final height is dated to the last frame the person was
            // seen, where its head/foot points were taken.
            let at = if t.ended { t.last_seen } else { frame };
            let h = height_record(at, t.id, &c, &t.last, &t.seen_box, t.ended);
            if t.ended {
                keep_final(&mut self.final_heights, &h);
                log::debug!(
                    "track {}: final height {:.3} m from {} samples",
                    h.track_id,
                    h.height_m,
                    h.samples
                );
            }
            let rec = Record::Height(h);
            st.run(Stage::Report, || reporter.send(rec));
        }
        let waited = self.ready_since.is_some_and(|f0| {
            (frame - f0) as f64 >= self.measurer.config().pending_wait_s * self.fps
        });
        let settled = self.measurer.settled(est.as_ref());
        if ready && !self.pending.is_empty() && (all || settled || waited) {
            let (measurer, finals) = (&mut self.measurer, &mut self.final_heights);
            let (waiting, mut measured) = (self.pending.len(), 0usize);
            self.pending.drain(|p| {
                let samples = p.samples.oldest_ordered();
                let Some(c) = measurer.track_height(est.as_ref(), samples) else {
                    return;
                };
                let h = height_record(p.last_seen, p.id, &c, &p.last, &p.seen_box, true);
                keep_final(finals, &h);
                reporter.send(Record::Height(h));
                measured += 1;
            });
            self.pending_measured += measured as u64;
            log::info!(
                "measured {measured} of {waiting} people who left before the calibration was ready"
            );
        }
    }

    /// Runs every stage on [`Pipeline::frame`] and queues the records it yields.
    pub fn process(&mut self, reporter: &mut Reporter) {
        self.process_staged(reporter, &mut Direct);
    }

    /// [`Pipeline::process`], each stage run through `st` (benchmarks time
    /// or count the stages with it; `process` is this with [`Direct`]).
    pub fn process_staged<S: Stages>(&mut self, reporter: &mut Reporter, st: &mut S) {
        let frame = self.frames;
        st.run(Stage::Detect, || {
            self.detector.process(&self.frame, &mut self.regions)
        });
        st.run(Stage::Classify, || {
            self.verdicts.clear();
            let luma = self.frame.luma();
            let mask = self.detector.mask();
            let regions = self.regions.regions();
            for region in regions.iter().take(self.max_classified) {
                self.verdicts
                    .push(self.classifier.classify_masked(luma, mask, region));
            }
            self.classifier
                .note_skipped(regions.len().saturating_sub(self.max_classified));
        });
        st.run(Stage::Track, || {
            self.tracker
                .step(frame, self.fps, &self.frame, &self.regions, &self.verdicts)
        });
        if log::log_enabled!(log::Level::Trace) {
            log::trace!(
                "frame {frame}: {} regions, {} of them one person, {} tracks",
                self.regions.regions().len(),
                self.verdicts.iter().filter(|v| v.single_human).count(),
                self.tracker.live()
            );
        }
        st.run(Stage::Observe, || {
            for t in self.tracker.tracks() {
                if let Some(hf) = t.fresh {
                    self.calib.observe(frame, t.id, hf);
                }
            }
        });
        if let Some(c) = st.run(Stage::Calibrate, || self.calib.update(frame)) {
            log::debug!(
                "calibration at frame {frame}: f {:.0} px, tilt {:.2}°, roll {:.2}°, camera {:.2} m, {} inliers, confidence {:.2}",
                c.f_px,
                c.tilt_deg,
                c.roll_deg,
                c.camera_height_m,
                c.inliers,
                c.confidence
            );
            self.calibration = Some(c.clone());
            let rec = Record::Calibration(c);
            st.run(Stage::Report, || reporter.send(rec));
        }
        self.heights(reporter, frame, false, st);
        self.frames += 1;
    }

    /// End of stream: queues the final calibration, then every live
    /// track's final height measured with it.
    pub fn finish(&mut self, reporter: &mut Reporter) {
        let frame = self.frames;
        if let Some(c) = self.calib.finish(self.last_frame()) {
            self.calibration = Some(c.clone());
            reporter.send(Record::Calibration(c));
        }
        self.tracker.end_all();
        self.heights(reporter, frame, true, &mut Direct);
    }

    /// Index of the last frame processed (0 before the first): the
    /// `frame` of the records made after it (status, bye, the final
    /// calibration), which [`Pipeline::frames`] counts one past.
    pub fn last_frame(&self) -> u64 {
        self.frames.saturating_sub(1)
    }

    /// People tracked now.
    pub fn tracks(&self) -> u32 {
        self.tracker.live()
    }
}

/// The stream's frame rate, 25 when the source could not say (a V4L2
/// driver that reports no frame interval): track ages and the status
/// cadence are counted in frames of stream time and need one.
fn stream_fps(info: &SourceInfo) -> f64 {
    if info.fps_f64() > 0.0 {
        info.fps_f64()
    } else {
        25.0
    }
}

/// Keeps a copy of final height `h` for the run's summary while there is
/// room (the first [`FINAL_HEIGHTS_KEPT`]; every one is reported anyway).
fn keep_final(finals: &mut Vec<Height>, h: &Height) {
    if finals.len() < FINAL_HEIGHTS_KEPT {
        finals.push(h.clone());
    }
}

/// A height record of track `id` measured as `c`, its points and box
/// from the frame `frame` it was last seen in.
fn height_record(
    frame: u64,
    id: u32,
    c: &Corrected,
    last: &HeadFoot,
    seen_box: &BBox,
    is_final: bool,
) -> Height {
    let b = seen_box;
    // The points' columns come from the silhouette's axis; on a region the
    // image border cuts (never a sample, but it can be the last one seen)
    // the axis can run out of the image, so they are kept within the box's
    // columns. Rows stay: the refined head and foot rows may lie a few rows
    // beyond the box (`detect.refine_extremes`).
    let inside = |p: [f64; 2]| {
        [
            (p[0] as f32).clamp(f32::from(b.x0), f32::from(b.x1)),
            p[1] as f32,
        ]
    };
    Height {
        frame,
        track_id: id,
        height_m: c.height as f32,
        samples: c.samples,
        foot_px: inside(last.foot),
        head_px: inside(last.head),
        bbox: [b.x0, b.y0, b.x1, b.y1],
        is_final,
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
    /// The final calibration, if the run produced one.
    pub calibration: Option<Calibration>,
    /// Final per-person heights (see [`FINAL_HEIGHTS_KEPT`]).
    pub heights: Vec<Height>,
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
    /// The [`Observer`] asked for a stop (`stature snapshot` once calibrated).
    Observer,
    /// The only report sink, standard output, lost its reader
    /// ([`crate::report::Counters::readers_gone`]).
    ReadersGone,
}

/// In plain words, for the log ("stopped by end of stream").
impl core::fmt::Display for StopReason {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            StopReason::EndOfStream => "end of stream",
            StopReason::FrameLimit => "frame limit",
            StopReason::Signal => "a signal",
            StopReason::SourceError => "a source error",
            // The only observer that stops a run is `stature snapshot`'s,
            // once the calibration is confident enough to measure.
            StopReason::Observer => "the calibration's confidence",
            StopReason::ReadersGone => "standard output's reader leaving",
        })
    }
}

/// Watches the loop from outside (the installer snapshot): told after every
/// processed frame and once at the very end, before the pipeline is dropped.
pub trait Observer {
    /// After a frame was processed and its records queued; `true` stops
    /// the run there, as the frame limit does. Runs in the loop: it must
    /// not allocate.
    fn frame(&mut self, _p: &Pipeline) -> bool {
        false
    }
    /// After the final records (`bye` included): the final calibration,
    /// and the tracks as the last processed frame left them (all marked
    /// ended, with their final heights). After a source error
    /// [`Pipeline::frame`] may hold part of the frame that failed.
    fn end(&mut self, _p: &Pipeline, _stopped_by: StopReason) {}
}

/// Observes nothing.
impl Observer for () {}

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
    /// The state file `run.state` names, already opened (its lock taken)
    /// by the caller's start-up checks; `None`: the loop opens
    /// `run.state` itself when it is set.
    pub state: Option<StateFile>,
}

/// Bytes of serialisation buffer a state file needs for `cfg`'s anchor
/// store: about 135 bytes of JSON per anchor, under 200 at worst, so the
/// buffer never grows and the writes do not allocate.
pub fn state_capacity(cfg: &Config) -> usize {
    4096 + 200 * cfg.calibrate.tracks * cfg.calibrate.anchors_per_track
}

/// The memory a run on frames of `size` holds, in bytes, estimated so
/// that a frame size the board cannot hold is refused at start instead of
/// bringing the OOM killer mid-run. Per pixel: the background model
/// (4 bytes per mode), about 4 bytes of frame, masks and labels, and 3 for
/// the snapshot's RGB frame when one is asked for; plus 8 MiB for the
/// rest. Measured on x86_64 at the defaults (3 modes, no snapshot):
/// 15.6 bytes per pixel over 320x240 .. 1920x1080 of peak RSS, against
/// 16 here. The snapshot measured 3.05 bytes per pixel at 3584x3584 and
/// 3.3 at 1920x1080 (its PNG is written row by row; written whole it cost
/// up to 9.5, see bench/RESULTS.md, "Peak RSS").
pub fn memory_estimate(cfg: &Config, size: crate::frame::Size) -> u64 {
    let pixels = size.width as u64 * size.height as u64;
    let snapshot = if cfg.run.snapshot.is_empty() { 0 } else { 3 };
    pixels * (4 * u64::from(cfg.detect.modes) + 4 + snapshot) + (8 << 20)
}

/// `MemAvailable` of `/proc/meminfo` in bytes (`text` is that file), if
/// the kernel gives it.
pub fn mem_available(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Room left under a cgroup memory limit: the limit (v2 `memory.max`, v1
/// `memory.limit_in_bytes`) minus the usage (`memory.current`,
/// `memory.usage_in_bytes`), not counting the page cache in it (the
/// `cache_key` line of `memory.stat`: `file` in v2, `total_cache` in v1;
/// the kernel reclaims it before it would refuse memory, and a service
/// restarted after reading a large file holds much of it). The arguments
/// are the files' text; `None` without a limit (v2 writes "max"; v1's
/// "unlimited" is a number near 2^63, which leaves room enough).
pub fn cgroup_room(max: &str, current: &str, stat: &str, cache_key: &str) -> Option<u64> {
    let max: u64 = max.trim().parse().ok()?;
    let current: u64 = current.trim().parse().ok()?;
    let cache: u64 = stat
        .lines()
        .find_map(|l| l.strip_prefix(cache_key)?.strip_prefix(' '))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(0);
    Some(max.saturating_sub(current.saturating_sub(cache)))
}

/// Where this process's memory controller lives, from the text of
/// `/proc/self/cgroup`: the cgroup v2 directory (line `0::/PATH`) and the
/// v1 memory hierarchy's (`N:...memory...:/PATH`, mounted at
/// `/sys/fs/cgroup/memory`). Older board images (systemd before v2 was the
/// default, hybrid mode) have the limit only in the second.
pub fn memory_cgroup_dirs(proc_self_cgroup: &str) -> (Option<PathBuf>, Option<PathBuf>) {
    let root = std::path::Path::new("/sys/fs/cgroup");
    let v2 = proc_self_cgroup
        .lines()
        .find_map(|l| l.strip_prefix("0::"))
        .map(|p| root.join(p.trim_start_matches('/')));
    let v1 = proc_self_cgroup.lines().find_map(|l| {
        let mut parts = l.splitn(3, ':');
        let (_, controllers, path) = (parts.next()?, parts.next()?, parts.next()?);
        controllers
            .split(',')
            .any(|c| c == "memory")
            .then(|| root.join("memory").join(path.trim_start_matches('/')))
    });
    (v2, v1)
}

/// The memory this process can still take, in bytes: the system's
/// `MemAvailable`, under a cgroup limit (the service's `MemoryMax`, which
/// the board profiles set; v2, or v1 on older images) the room left below
/// it, and under an address-space limit ([`vm_size`]) the room left below
/// that, whichever is least. `None` when none can be read.
pub fn memory_room() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| mem_available(&t));
    let read = |dir: &Path, files: [&str; 3], cache_key: &str| {
        let max = std::fs::read_to_string(dir.join(files[0])).ok()?;
        let current = std::fs::read_to_string(dir.join(files[1])).ok()?;
        let stat = std::fs::read_to_string(dir.join(files[2])).unwrap_or_default();
        cgroup_room(&max, &current, &stat, cache_key)
    };
    let cgroup = std::fs::read_to_string("/proc/self/cgroup")
        .ok()
        .and_then(|t| {
            let (v2, v1) = memory_cgroup_dirs(&t);
            v2.and_then(|d| read(&d, ["memory.max", "memory.current", "memory.stat"], "file"))
                .or_else(|| {
                    let files = [
                        "memory.limit_in_bytes",
                        "memory.usage_in_bytes",
                        "memory.stat",
                    ];
                    v1.and_then(|d| read(&d, files, "total_cache"))
                })
        });
    let address_space = rustix::process::getrlimit(rustix::process::Resource::As)
        .current
        .and_then(|limit| {
            let status = std::fs::read_to_string("/proc/self/status").ok()?;
            Some(limit.saturating_sub(vm_size(&status)?))
        });
    [system, cgroup, address_space].into_iter().flatten().min()
}

/// `VmSize` of `/proc/self/status` in bytes (`text` is that file): the
/// address space in use, which an `RLIMIT_AS` (`ulimit -v`, systemd's
/// `LimitAS=`) bounds. Past that limit an allocation fails and the process
/// aborts, so the room under it counts like the memory's.
pub fn vm_size(text: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with("VmSize:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// Runs the loop until the source ends, fails, the frame limit, or a stop
/// request. Sends `hello` first and final records at the end whatever the
/// reason; `bye` only when the run ended cleanly (not on a source error).
pub fn run(
    cfg: &Config,
    source: &mut dyn FrameSource,
    reporter: &mut Reporter,
    opts: LoopOptions<'_>,
) -> Summary {
    run_observed(cfg, source, reporter, opts, &mut ())
}

/// [`run`], telling `observer` about every frame and the end.
pub fn run_observed(
    cfg: &Config,
    source: &mut dyn FrameSource,
    reporter: &mut Reporter,
    mut opts: LoopOptions<'_>,
    observer: &mut dyn Observer,
) -> Summary {
    let info = source.info().clone();
    let mut p = Pipeline::with_state(cfg, &info, opts.state.take());
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
    let fps = stream_fps(&info);
    let status_every = ((opts.status_interval_s * fps).round() as u64).max(1);
    let alloc_base = (opts.allocations)();
    // When, at which frame count, and at what rate the last status was sent.
    let mut last_status = (Instant::now(), 0u64, 0.0f64);
    let mut last_wait_status = Instant::now();
    let status = |p: &Pipeline,
                  state: SourceState,
                  reporter: &mut Reporter,
                  last: &mut (Instant, u64, f64)| {
        let dt = last.0.elapsed().as_secs_f64();
        let rate = if state == SourceState::Ended
            && p.frames == last.1
            && dt < opts.status_interval_s.max(1.0)
        {
            // The closing status right after a periodic one (a run ending
            // on the interval): no frames to time, and 0 fps would read as
            // a stalled pipeline. After a longer silence (a stalled source,
            // then its end) or while a camera is away, 0 is the truth. (At
            // least a second: the end-of-run work falls in `dt` too.)
            last.2
        } else if dt > 0.0 {
            (p.frames - last.1) as f64 / dt
        } else {
            0.0
        };
        *last = (Instant::now(), p.frames, rate);
        let dropped = reporter.counters().dropped();
        reporter.send(Record::Status(Status {
            frame: p.last_frame(),
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
        if reporter.readers_gone() {
            break StopReason::ReadersGone;
        }
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
                if observer.frame(&p) {
                    break StopReason::Observer;
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
            frame: p.last_frame(),
            frames: p.frames,
            dropped,
        }));
    }
    observer.end(&p, stopped_by);
    Summary {
        frames: p.frames,
        stopped_by,
        error,
        calibration: p.calibration.take(),
        heights: core::mem::take(&mut p.final_heights),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Size;

    #[test]
    fn memory_estimate_follows_the_model_and_the_snapshot() {
        let mut cfg = Config::default();
        let hd = Size {
            width: 1920,
            height: 1080,
        };
        // Defaults: 3 modes, 16 bytes a pixel (peak RSS measured 36.3 MB
        // for a 1920x1080 run, 15.6 bytes a pixel above the fixed part).
        let mib = |b: u64| b >> 20;
        assert_eq!(mib(memory_estimate(&cfg, hd)), 39);
        cfg.detect.modes = 4;
        cfg.run.snapshot = "x.png".into();
        assert_eq!(mib(memory_estimate(&cfg, hd)), 53);
        // The header of a hostile or mistaken file: 16384x16384 is 4 GiB.
        let huge = Size {
            width: 16384,
            height: 16384,
        };
        assert!(memory_estimate(&Config::default(), huge) > 4 << 30);
    }

    #[test]
    fn a_state_file_handed_to_the_pipeline_keeps_its_lock_for_the_run() {
        let dir = crate::scratch::fresh_dir("run-state-handover");
        let path = dir.join("state.json");
        let mut cfg = Config::default();
        cfg.run.state = path.to_str().unwrap().into();
        let info = SourceInfo {
            size: Size {
                width: 320,
                height: 240,
            },
            fps: (25, 1),
            description: "test".into(),
            grey: false,
        };
        let checked = StateFile::open(&path, state_capacity(&cfg)).unwrap();
        assert!(!checked.in_use_elsewhere());
        // The start-up check's file is the run's: opening the path again
        // would find the check's own lock held and make the run a reader.
        let p = Pipeline::with_state(&cfg, &info, Some(checked));
        let kept = p.calib.state.as_ref().expect("the state is kept");
        assert!(!kept.in_use_elsewhere());
        // Held for as long as the pipeline lives...
        assert!(StateFile::open(&path, 0).unwrap().in_use_elsewhere());
        drop(p);
        // ...and let go with it.
        assert!(!StateFile::open(&path, 0).unwrap().in_use_elsewhere());
    }

    #[test]
    fn vm_size_is_read_from_status() {
        let text = "Name:\tstature\nVmPeak:\t  9000 kB\nVmSize:\t    3060 kB\nVmRSS:\t 1000 kB\n";
        assert_eq!(vm_size(text), Some(3060 * 1024));
        assert_eq!(vm_size("VmRSS: 1 kB\n"), None);
    }

    #[test]
    fn mem_available_is_read_from_meminfo() {
        let text = "MemTotal:        8040516 kB\nMemFree:          512000 kB\nMemAvailable:    6000000 kB\n";
        assert_eq!(mem_available(text), Some(6_000_000 * 1024));
        assert_eq!(mem_available("MemTotal: 1 kB\n"), None);
        assert_eq!(mem_available("MemAvailable: lots kB\n"), None);
        assert_eq!(
            cgroup_room("268435456\n", "100663296\n", "", "file"),
            Some(160 << 20)
        );
        // 64 MiB of it page cache: room for that too.
        let stat = "anon 33554432\nfile_mapped 1\nfile 67108864\nkernel 1048576\n";
        assert_eq!(
            cgroup_room("268435456\n", "100663296\n", stat, "file"),
            Some(224 << 20)
        );
        assert_eq!(cgroup_room("max\n", "100663296\n", "", "file"), None);
        assert_eq!(cgroup_room("1000\n", "2000\n", "", "file"), Some(0));
        // cgroup v1: the hierarchical cache line, not this group's own.
        let stat = "cache 1048576\nrss 2097152\ntotal_cache 67108864\n";
        assert_eq!(
            cgroup_room("268435456\n", "100663296\n", stat, "total_cache"),
            Some(224 << 20)
        );
        // v1 without a limit: PAGE_COUNTER_MAX pages, room beyond any system's memory.
        let unlimited = cgroup_room("9223372036854771712\n", "100663296\n", "", "total_cache");
        assert!(unlimited.unwrap() > 1 << 60);
    }

    #[test]
    fn the_memory_cgroup_is_found_in_v2_v1_and_hybrid_layouts() {
        let root = Path::new("/sys/fs/cgroup");
        let v2 = "0::/system.slice/stature.service\n";
        assert_eq!(
            memory_cgroup_dirs(v2),
            (Some(root.join("system.slice/stature.service")), None)
        );
        let v1 = "12:pids:/system.slice/stature.service\n\
                  4:memory:/system.slice/stature.service\n\
                  3:cpu,cpuacct:/system.slice/stature.service\n";
        assert_eq!(
            memory_cgroup_dirs(v1),
            (None, Some(root.join("memory/system.slice/stature.service")))
        );
        // Hybrid: both; memory_room tries v2's files first, which hold no
        // memory controller there, then v1's.
        let hybrid = format!("{v1}0::/system.slice/stature.service\n");
        let (a, b) = memory_cgroup_dirs(&hybrid);
        assert!(a.is_some() && b.is_some());
        // Controllers joined with others, and a controller merely named like it.
        assert!(memory_cgroup_dirs("7:cpu,memory:/a\n").1.is_some());
        assert!(memory_cgroup_dirs("7:memory_extra:/a\n").1.is_none());
    }

    #[test]
    fn stop_reasons_read_as_plain_words() {
        // Before, the log showed the variant names ("stopped by Observer").
        for (reason, words) in [
            (StopReason::EndOfStream, "end of stream"),
            (StopReason::FrameLimit, "frame limit"),
            (StopReason::Signal, "a signal"),
            (StopReason::SourceError, "a source error"),
            (StopReason::Observer, "the calibration's confidence"),
            (StopReason::ReadersGone, "standard output's reader leaving"),
        ] {
            assert_eq!(reason.to_string(), words);
        }
    }
}
