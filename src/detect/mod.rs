//! Moving-object detection (paper 3.1, first half): a fixed-point adaptive
//! Gaussian-mixture background model on the luma plane
//! ([`background`]), morphological clean-up on packed bit masks
//! ([`morphology`]) and connected foreground regions with head and foot
//! candidates ([`regions`]).
//!
//! Every buffer is allocated in [`Detector::new`]; [`Detector::process`]
//! allocates nothing.
//!
//! # Defaults and the trade-offs behind them
//!
//! * `history = 500` frames (α = 0.002): slow illumination drift is
//!   followed with a time constant of 500 frames; faster global changes are
//!   handled by the gain compensation (`gain_threshold`) and, failing that,
//!   by relearning when more than `relearn_fraction` of the frame turns
//!   foreground at once.
//! * A standing person: the background mode of a covered pixel stops being
//!   "the background" once its weight, decaying at `α · foreground_rate`
//!   per frame, falls below `background_ratio` of the total. Measured
//!   (`tests/suite/detect_synthetic.rs`, α = 1/301): plain Zivkovic
//!   (`foreground_rate = 1`) absorbs a person who stops after 34 frames,
//!   the default `foreground_rate = 0.25` after 155 frames (15 s at 10 fps;
//!   at the steady α = 1/500 about 5/3 of both). The price: a ghost left by
//!   a background object that moves away also takes that long to heal.
//! * `update_interval = 8`: in steady state a pixel's mean and variance
//!   move every 8th frame at 8 times the rate (weights and masks every
//!   frame): measured neutral for detection, fixed-vs-float agreement and
//!   126 live calibration runs, and ≈ 6 fewer instructions per pixel than
//!   every frame (1.6 fewer than every 4th).
//! * Shadows: a foreground pixel 0.65–0.95 times as bright as a background
//!   mode is a shadow candidate (luma; OpenCV's 0.5 erased grey clothing on
//!   PETS). A pixel whose chroma differs from the [`chroma`] background by
//!   more than `chroma_threshold` is foreground anyway (keeps people whose
//!   clothes match the ground in luma whole), and a shadow candidate whose
//!   chroma differs by more than the stricter `shadow_chroma_threshold` is
//!   foreground too (a shadow darkens, it does not recolour). A candidate
//!   with foreground within `shadow_fill_rows` above and below it in its
//!   column is foreground (grey trousers under a shirt). Darker than
//!   shadow (0.58–0.65, chroma unchanged) at the bottom of a column, with
//!   nothing but such pixels under it, is a sun shadow's core at the feet
//!   and is peeled off before the opening ([`peel`]).
//! * Regions: after opening, fill and closing, a region whose column
//!   profile has a deep valley between two person-tall peaks is cut there
//!   (`split_valley`: people walking side by side).
//!   `bench/RESULTS.md` ("Detection") has the measurements.

pub mod background;
pub mod chroma;
pub mod extremes;
pub mod morphology;
pub mod peel;
pub mod regions;

use crate::config::{check_range, ConfigError};
use crate::frame::{Frame, Size};
use serde::{Deserialize, Serialize};

use background::{Background, FrameStats};
use chroma::ChromaBackground;
use morphology::BitMask;
use regions::Labeller;

/// `[detect]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectConfig {
    /// Frames of history: the steady-state learning rate is `1/history`.
    pub history: u32,
    /// Gaussian modes per pixel (1..=4); the model holds 4 bytes per mode and pixel.
    pub modes: u32,
    /// `1 − c_f`: the heaviest modes whose weights add up to this fraction are background.
    pub background_ratio: f64,
    /// Zivkovic's complexity prior `c_T`: modes matched less often than this die.
    pub complexity_prior: f64,
    /// A value within this many standard deviations of a mode updates that mode.
    pub match_sigma: f64,
    /// A value within this many standard deviations of a background mode is
    /// background (`≥ match_sigma`).
    pub background_sigma: f64,
    /// Variance of a new mode, grey levels squared.
    pub var_init: f64,
    /// Variance floor, grey levels squared.
    pub var_min: f64,
    /// Variance ceiling, grey levels squared.
    pub var_max: f64,
    /// Learn with `α = 1/(t+1)` over the first `history` frames.
    pub fast_startup: bool,
    /// Factor on the learning rate at foreground pixels (slows a standing
    /// person's melting into the background; 1 = plain Zivkovic).
    pub foreground_rate: f64,
    /// Frames between updates of a pixel's mean and variance (1..=8), at
    /// `update_interval` times the rate, staggered over 64-pixel blocks;
    /// weights and the mask are updated every frame. Applies once the
    /// learning rate is at most `1/(16 · update_interval)` (every frame
    /// during start-up). 1 = plain Zivkovic.
    pub update_interval: u32,
    /// Report shadows (darker by a bounded ratio) as background.
    pub shadow: bool,
    /// Darkest shadow, as a fraction of the background brightness.
    pub shadow_min_ratio: f64,
    /// Lightest shadow, as a fraction of the background brightness.
    pub shadow_max_ratio: f64,
    /// Deep shadows at the feet: a foreground pixel darker than
    /// `shadow_min_ratio` but not darker than this fraction of the
    /// background, with the background's chroma, is dropped when nothing
    /// but such pixels lies under it in its column (0 = off; see [`peel`]
    /// and `bench/RESULTS.md`, "Deep shadows peeled off the feet").
    pub deep_shadow_min_ratio: f64,
    /// Chroma term: a pixel whose (Cb, Cr) differs from a running-average
    /// chroma background by more than this L1 distance (grey levels) is
    /// foreground too, shadow or not (0 = off; luma GMM only).
    pub chroma_threshold: u32,
    /// A pixel the luma model calls shadow stays foreground when its
    /// (Cb, Cr) differs from the chroma background by more than this L1
    /// distance (grey levels, ≤ `chroma_threshold`; 0 = luma-only shadow test).
    pub shadow_chroma_threshold: u32,
    /// Rescale the model when the median brightness ratio frame/model jumps.
    pub gain_compensation: bool,
    /// Gain change (fraction) that triggers a rescale.
    pub gain_threshold: f64,
    /// Foreground fraction of a frame that restarts fast learning.
    pub relearn_fraction: f64,
    /// Opening radius in pixels (removes specks; 0 = off).
    pub open_radius: u32,
    /// The opening also keeps what a vertical line of `2r + 1` pixels fits
    /// in: the 2-pixel legs and arms of distant people, which the square
    /// removes, survive, while specks and thin horizontal bridges between
    /// people still go (0 = the square alone, the default; see
    /// [`morphology::open_keeping_vertical`]). Off by default: at 2 it
    /// finds more people's whole boxes (sim `wide` 76.6 → 93.8 %, PETS
    /// 90.0 → 90.7 %) but the live pipeline calibrates worse
    /// (`bench/RESULTS.md`, "Detection"). When on, the regions' head and
    /// foot rows come from the square opening alone
    /// ([`extremes::from_subset`]), their body axis too
    /// ([`RegionSet::fill_core`]), and a region whose box reaches well beyond
    /// those rows is [`Region::loose_ends`] (no head/foot sample).
    pub open_vertical_radius: u32,
    /// Closing half-width in pixels (fills holes and gaps; 0 = off).
    pub close_radius: u32,
    /// Closing half-height in pixels: taller than wide, it rejoins a
    /// person's legs and torso across a waist-high gap without merging
    /// people side by side.
    pub close_radius_y: u32,
    /// Smallest region kept, in pixels per megapixel of frame (scales with resolution).
    pub min_area_per_mpix: u32,
    /// A pixel called shadow is foreground when the cleaned-up mask has
    /// foreground within this many rows both above and below it in its
    /// column (grey trousers between a shirt and shoes; a ground shadow has
    /// foreground on one side only; 0 = off).
    pub shadow_fill_rows: u32,
    /// Cut a region where its column profile (pixels per column) falls to
    /// this fraction of the lower of two person-tall peaks beside it
    /// (people walking side by side; 0 = never cut).
    pub split_valley: f64,
    /// Give regions' head and foot rows back what the opening took from
    /// thin ankles and crowns ([`extremes`]).
    pub refine_extremes: bool,
    /// Regions one frame can hold (more are counted and dropped).
    pub max_regions: u32,
    /// Foreground runs per image row budgeted for the region masks.
    pub max_runs_per_row: u32,
}

/// Default `chroma_threshold` (see `bench/RESULTS.md`, "Detection").
const CHROMA_THRESHOLD: u32 = 16;
/// Default `shadow_fill_rows` (see `bench/RESULTS.md`, "Detection").
const SHADOW_FILL_ROWS: u32 = 12;
/// Default `split_valley` (see `bench/RESULTS.md`, "Detection").
const SPLIT_VALLEY: f64 = 0.55;
/// Default `update_interval` (see `bench/RESULTS.md`, "Detection", "Speed").
const UPDATE_INTERVAL: u32 = 8;
/// Default `shadow_chroma_threshold` (see `bench/RESULTS.md`, "Detection").
const SHADOW_CHROMA_THRESHOLD: u32 = 8;
/// Default `deep_shadow_min_ratio` (see `bench/RESULTS.md`, "Deep shadows
/// peeled off the feet": better roll, heights and box fit on the sim and
/// heights on PETS, +0.28 instr/px at 1280×720).
const DEEP_SHADOW_MIN_RATIO: f64 = 0.58;

impl Default for DetectConfig {
    fn default() -> Self {
        DetectConfig {
            history: 500,
            modes: 3,
            background_ratio: 0.9,
            complexity_prior: 0.05,
            match_sigma: 3.0,
            background_sigma: 4.0,
            var_init: 15.0,
            var_min: 4.0,
            var_max: 75.0,
            fast_startup: true,
            foreground_rate: 0.25,
            update_interval: UPDATE_INTERVAL,
            shadow: true,
            shadow_min_ratio: 0.65,
            shadow_max_ratio: 0.95,
            deep_shadow_min_ratio: DEEP_SHADOW_MIN_RATIO,
            chroma_threshold: CHROMA_THRESHOLD,
            shadow_chroma_threshold: SHADOW_CHROMA_THRESHOLD,
            gain_compensation: true,
            gain_threshold: 0.03,
            relearn_fraction: 0.6,
            open_radius: 1,
            open_vertical_radius: 0,
            close_radius: 2,
            close_radius_y: 6,
            min_area_per_mpix: 400,
            split_valley: SPLIT_VALLEY,
            refine_extremes: true,
            shadow_fill_rows: SHADOW_FILL_ROWS,
            max_regions: 64,
            max_runs_per_row: 16,
        }
    }
}

impl DetectConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("detect.history", self.history, 2..=100_000)?;
        check_range("detect.modes", self.modes, 1..=4)?;
        check_range("detect.background_ratio", self.background_ratio, 0.5..=0.99)?;
        check_range("detect.complexity_prior", self.complexity_prior, 0.0..=0.2)?;
        check_range("detect.match_sigma", self.match_sigma, 1.0..=5.0)?;
        check_range(
            "detect.background_sigma",
            self.background_sigma,
            self.match_sigma..=5.0,
        )?;
        check_range("detect.var_min", self.var_min, 1.0..=127.0)?;
        check_range("detect.var_max", self.var_max, self.var_min..=127.0)?;
        check_range(
            "detect.var_init",
            self.var_init,
            self.var_min..=self.var_max,
        )?;
        check_range("detect.foreground_rate", self.foreground_rate, 0.0..=1.0)?;
        check_range(
            "detect.update_interval",
            self.update_interval,
            1..=background::MAX_UPDATE_INTERVAL,
        )?;
        check_range("detect.shadow_min_ratio", self.shadow_min_ratio, 0.1..=1.0)?;
        check_range(
            "detect.shadow_max_ratio",
            self.shadow_max_ratio,
            self.shadow_min_ratio..=1.0,
        )?;
        if self.deep_shadow_min_ratio != 0.0 {
            check_range(
                "detect.deep_shadow_min_ratio",
                self.deep_shadow_min_ratio,
                0.1..=self.shadow_min_ratio,
            )?;
        }
        check_range("detect.chroma_threshold", self.chroma_threshold, 0..=255)?;
        check_range(
            "detect.shadow_chroma_threshold",
            self.shadow_chroma_threshold,
            0..=self.chroma_threshold,
        )?;
        check_range("detect.gain_threshold", self.gain_threshold, 0.005..=0.5)?;
        check_range("detect.relearn_fraction", self.relearn_fraction, 0.1..=1.0)?;
        check_range("detect.open_radius", self.open_radius, 0..=4)?;
        check_range(
            "detect.open_vertical_radius",
            self.open_vertical_radius,
            0..=8,
        )?;
        check_range("detect.close_radius", self.close_radius, 0..=8)?;
        check_range("detect.close_radius_y", self.close_radius_y, 0..=16)?;
        check_range(
            "detect.min_area_per_mpix",
            self.min_area_per_mpix,
            0..=1_000_000,
        )?;
        check_range("detect.split_valley", self.split_valley, 0.0..=1.0)?;
        check_range("detect.shadow_fill_rows", self.shadow_fill_rows, 0..=256)?;
        check_range("detect.max_regions", self.max_regions, 1..=4096)?;
        check_range("detect.max_runs_per_row", self.max_runs_per_row, 1..=1024)?;
        Ok(())
    }

    /// Regions a [`RegionSet`] for this config holds.
    pub fn region_capacity(&self) -> usize {
        self.max_regions as usize
    }

    /// Runs a [`RegionSet`] for frames of `size` holds.
    pub fn run_capacity(&self, size: Size) -> usize {
        size.height * self.max_runs_per_row as usize
    }

    /// Core runs a [`RegionSet`] for this config reserves
    /// ([`RegionSet::with_core`]): as many as its runs with the vertical
    /// opening on (a core is a subset of its region), none without.
    pub fn core_run_capacity(&self, size: Size) -> usize {
        if self.open_vertical_radius > 0 && self.open_radius > 0 {
            self.run_capacity(size)
        } else {
            0
        }
    }

    /// Smallest region kept at frame `size`, in pixels.
    pub fn min_area(&self, size: Size) -> u32 {
        let a = u64::from(self.min_area_per_mpix) * size.pixels() as u64 / 1_000_000;
        a.min(u64::from(u32::MAX)) as u32
    }
}

/// An inclusive pixel box.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BBox {
    /// Left column.
    pub x0: u16,
    /// Top row.
    pub y0: u16,
    /// Right column (inclusive).
    pub x1: u16,
    /// Bottom row (inclusive).
    pub y1: u16,
}

impl BBox {
    /// Width in pixels.
    pub fn width(&self) -> u32 {
        u32::from(self.x1) - u32::from(self.x0) + 1
    }
    /// Height in pixels.
    pub fn height(&self) -> u32 {
        u32::from(self.y1) - u32::from(self.y0) + 1
    }
}

/// One horizontal run of foreground pixels, `x0..=x1` on row `y`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Run {
    /// Row.
    pub y: u16,
    /// First column.
    pub x0: u16,
    /// Last column (inclusive).
    pub x1: u16,
}

/// A connected foreground region.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Region {
    /// Foreground pixel count.
    pub area: u32,
    /// Bounding box.
    pub bbox: BBox,
    /// Head candidate: the top-most pixel (sub-pixel `[u, v]`).
    pub head: [f32; 2],
    /// Foot candidate: mean of the bottom-most 10 pixels (paper eq. 5).
    pub foot: [f32; 2],
    /// The region touches the image border.
    pub touches_border: bool,
    /// The region is a part of a larger one cut at a column (people side
    /// by side, [`DetectConfig::split_valley`]): its side at the cut is a
    /// straight image column by construction, not the person's outline,
    /// so its silhouette axis leans toward the image vertical.
    pub split: bool,
    /// Its box reaches well beyond its head or foot row (only with
    /// [`DetectConfig::open_vertical_radius`]: the head and foot rows come
    /// from the square opening, the box from the union, and they disagree
    /// by more than [`extremes::end_tolerance`]): the region is a person's
    /// box, but where the person ends is uncertain, so it gives no head or
    /// foot sample.
    pub loose_ends: bool,
    /// Its core's runs (the part the square opening kept, with
    /// [`DetectConfig::open_vertical_radius`]; empty otherwise): indices
    /// into its set's core store (read them with [`RegionSet::axis_runs_of`]).
    pub core: core::ops::Range<u32>,
    /// Its run-length mask: indices into its set's run store, sorted by
    /// row (read them with [`RegionSet::runs_of`]).
    pub runs: core::ops::Range<u32>,
}

/// The regions of one frame, in buffers allocated once.
#[derive(Debug)]
pub struct RegionSet {
    regions: Vec<Region>,
    runs: Vec<Run>,
    /// Runs of the regions' cores ([`Region::core`]); no room is reserved
    /// unless [`RegionSet::with_core`] asked for it.
    core: Vec<Run>,
    region_capacity: usize,
    run_capacity: usize,
    /// Regions dropped this frame because the set was full.
    pub overflow: u32,
    /// Foreground runs the labeller dropped this frame because its run
    /// buffer was full (the regions below them are then incomplete).
    pub runs_dropped: u32,
}

impl RegionSet {
    /// Room for `regions` regions and `runs` runs in all.
    pub fn with_capacity(regions: usize, runs: usize) -> Self {
        RegionSet {
            regions: Vec::with_capacity(regions),
            runs: Vec::with_capacity(runs),
            core: Vec::new(),
            region_capacity: regions,
            run_capacity: runs,
            overflow: 0,
            runs_dropped: 0,
        }
    }
    /// Reserves room for `runs` core runs in all ([`Region::core`]; the
    /// detector fills them only with `detect.open_vertical_radius > 0`).
    pub fn with_core(mut self, runs: usize) -> Self {
        self.core = Vec::with_capacity(runs);
        self
    }
    /// Empties the set, keeping its buffers.
    pub fn clear(&mut self) {
        self.regions.clear();
        self.runs.clear();
        self.core.clear();
        self.overflow = 0;
        self.runs_dropped = 0;
    }
    /// The regions.
    pub fn regions(&self) -> &[Region] {
        &self.regions
    }
    /// Calls `f` with every region (mutable) and its runs.
    pub fn each_mut(&mut self, mut f: impl FnMut(&mut Region, &[Run])) {
        for r in self.regions.iter_mut() {
            f(r, &self.runs[r.runs.start as usize..r.runs.end as usize]);
        }
    }
    /// Runs this set can hold in all.
    pub fn run_capacity(&self) -> usize {
        self.run_capacity
    }
    /// Regions this set can hold.
    pub fn region_capacity(&self) -> usize {
        self.region_capacity
    }
    /// The runs of one region.
    pub fn runs_of(&self, region: &Region) -> &[Run] {
        &self.runs[region.runs.start as usize..region.runs.end as usize]
    }
    /// The runs a region's body axis is fitted to: its core's when it has
    /// one, else its own.
    pub fn axis_runs_of(&self, region: &Region) -> &[Run] {
        if region.core.is_empty() {
            self.runs_of(region)
        } else {
            &self.core[region.core.start as usize..region.core.end as usize]
        }
    }
    /// Sets every region's core to the pixels of its runs that `inner`
    /// holds, as runs. A region whose core does not fit in the reserved
    /// room, or is empty, keeps an empty core (its axis comes from its own
    /// runs).
    pub fn fill_core(&mut self, inner: &BitMask) {
        self.core.clear();
        let room = self.core.capacity();
        for r in self.regions.iter_mut() {
            let start = self.core.len();
            let mut full = false;
            for run in &self.runs[r.runs.start as usize..r.runs.end as usize] {
                let y = usize::from(run.y);
                let mut open: Option<u16> = None;
                // One column past the run counts as off: it closes a core
                // run that reaches the run's end.
                for x in u32::from(run.x0)..=u32::from(run.x1) + 1 {
                    let on = x <= u32::from(run.x1) && inner.get(x as usize, y);
                    match (on, open) {
                        (true, None) => open = Some(x as u16),
                        (false, Some(x0)) => {
                            full |= self.core.len() == room;
                            if !full {
                                self.core.push(Run {
                                    y: run.y,
                                    x0,
                                    x1: (x - 1) as u16,
                                });
                            }
                            open = None;
                        }
                        _ => {}
                    }
                }
            }
            if full {
                self.core.truncate(start);
            }
            r.core = start as u32..self.core.len() as u32;
        }
    }
    /// Adds a region with its runs; hands the region back when either buffer is full.
    pub fn push(&mut self, mut region: Region, runs: &[Run]) -> Result<(), Region> {
        if self.regions.len() == self.region_capacity
            || self.runs.len() + runs.len() > self.run_capacity
        {
            self.overflow += 1;
            return Err(region);
        }
        let start = self.runs.len() as u32;
        self.runs.extend_from_slice(runs);
        region.runs = start..self.runs.len() as u32;
        self.regions.push(region);
        Ok(())
    }
}

/// The detection stage: background model, clean-up, labelling.
#[derive(Debug)]
pub struct Detector {
    size: Size,
    background: Background,
    chroma: ChromaBackground,
    chroma_fg: BitMask,
    chroma_soft: BitMask,
    raw: BitMask,
    shadow: BitMask,
    clean: BitMask,
    /// The mask before the opening, for [`extremes::refine`].
    before_open: BitMask,
    refine_extremes: bool,
    scratch: BitMask,
    /// Second scratch mask for the vertical opening.
    vertical: BitMask,
    labeller: Labeller,
    open_radius: u32,
    open_vertical_radius: u32,
    close_radius: u32,
    close_radius_y: u32,
    shadow_fill_rows: usize,
    deep_shadow: Option<peel::DeepShadow>,
    min_area: u32,
}

impl Detector {
    /// Sizes the background model and every buffer for frames of `size`.
    pub fn new(cfg: &DetectConfig, size: Size) -> Self {
        Detector {
            size,
            background: Background::new(cfg, size.width, size.height),
            chroma: ChromaBackground::new(
                size.width,
                size.height,
                cfg.history,
                cfg.chroma_threshold,
                cfg.shadow_chroma_threshold,
            ),
            chroma_fg: BitMask::new(size.width, size.height),
            chroma_soft: BitMask::new(size.width, size.height),
            raw: BitMask::new(size.width, size.height),
            shadow: BitMask::new(size.width, size.height),
            clean: BitMask::new(size.width, size.height),
            before_open: BitMask::new(size.width, size.height),
            refine_extremes: cfg.refine_extremes && cfg.open_radius > 0,
            scratch: BitMask::new(size.width, size.height),
            // Only the vertical opening uses it: empty while that is off.
            vertical: if cfg.open_vertical_radius > 0 {
                BitMask::new(size.width, size.height)
            } else {
                BitMask::new(0, 0)
            },
            labeller: {
                let mut l = Labeller::new(cfg.run_capacity(size), size.width);
                l.set_split(cfg.split_valley);
                l
            },
            open_radius: cfg.open_radius,
            open_vertical_radius: cfg.open_vertical_radius,
            close_radius: cfg.close_radius,
            close_radius_y: cfg.close_radius_y,
            shadow_fill_rows: cfg.shadow_fill_rows as usize,
            deep_shadow: peel::DeepShadow::new(cfg.deep_shadow_min_ratio, cfg.shadow_min_ratio),
            min_area: cfg.min_area(size).max(1),
        }
    }
    /// Frame size this detector was built for.
    pub fn size(&self) -> Size {
        self.size
    }
    /// Updates the model with `frame` and writes its foreground regions to `out`.
    /// A frame of another size is ignored (no regions).
    pub fn process(&mut self, frame: &Frame, out: &mut RegionSet) {
        out.clear();
        if frame.size() != self.size {
            return;
        }
        self.segment(frame);
        self.clean_up(frame);
        self.label(out);
    }
    /// Stage 1: updates the background models and fills [`Self::raw_mask`]
    /// (luma GMM) and [`Self::chroma_mask`].
    pub fn segment(&mut self, frame: &Frame) {
        let wpr = self.raw.words_per_row();
        self.background
            .apply(frame, self.raw.words_mut(), self.shadow.words_mut(), wpr);
        if self.background.stats().relearn {
            self.chroma.relearn(8);
        }
        self.chroma_fg.words_mut().fill(0);
        self.chroma_soft.words_mut().fill(0);
        self.chroma.apply(
            frame,
            self.chroma_fg.words_mut(),
            self.chroma_soft.words_mut(),
            wpr,
        );
    }
    /// Stage 2: the union of the luma and chroma masks of `frame` (the one
    /// [`Self::segment`] saw), deep shadows peeled off its bottom when
    /// `detect.deep_shadow_min_ratio` is on, opened then closed, into
    /// [`Self::mask`].
    pub fn clean_up(&mut self, frame: &Frame) {
        self.clean.copy_from(&self.raw);
        if self.chroma.enabled() {
            let it = self
                .clean
                .words_mut()
                .iter_mut()
                .zip(self.chroma_fg.words())
                .zip(self.shadow.words().iter().zip(self.chroma_soft.words()));
            for ((c, &f), (&sh, &soft)) in it {
                *c |= f | (sh & soft);
            }
        }
        // On the union: a chroma-only pixel (a shoe whose colour changed
        // but not its luma) must stop the peel above it.
        if let Some(band) = self.deep_shadow {
            let luma = frame.luma();
            peel::peel(
                &mut self.clean,
                &luma,
                &self.background,
                &self.chroma_soft,
                band,
            );
        }
        let (o, cx, cy) = (self.open_radius, self.close_radius, self.close_radius_y);
        if self.refine_extremes {
            self.before_open.copy_from(&self.clean);
        }
        morphology::open_keeping_vertical(
            &mut self.clean,
            &mut self.vertical,
            &mut self.scratch,
            o,
            self.open_vertical_radius,
        );
        morphology::fill_between(&mut self.clean, &self.shadow, self.shadow_fill_rows);
        morphology::close(&mut self.clean, &mut self.scratch, cx, cy);
    }
    /// Stage 3: connected regions of [`Self::mask`] into `out` (cleared first).
    pub fn label(&mut self, out: &mut RegionSet) {
        out.clear();
        self.labeller.label(&self.clean, self.min_area, out);
        let before = &self.before_open;
        let fp = regions::FOOT_PIXELS;
        if self.open_vertical_radius > 0 && self.open_radius > 0 {
            // `vertical` holds the square opening: head and foot rows from it.
            let (square, refine) = (&self.vertical, self.refine_extremes);
            out.each_mut(|r, runs| extremes::from_subset(r, runs, square, before, fp, refine));
            // The body axis is fitted to the same pixels (thin swinging arms
            // and legs lean it).
            out.fill_core(square);
        } else if self.refine_extremes {
            out.each_mut(|r, runs| extremes::refine(r, runs, before, fp));
        }
    }
    /// The foreground mask straight from the luma model (shadows excluded).
    pub fn raw_mask(&self) -> &BitMask {
        &self.raw
    }
    /// The pixels the luma model called shadow in the last frame.
    pub fn shadow_mask(&self) -> &BitMask {
        &self.shadow
    }
    /// The chroma foreground of the last frame (empty when the term is off).
    pub fn chroma_mask(&self) -> &BitMask {
        &self.chroma_fg
    }
    /// The cleaned foreground mask the regions come from.
    pub fn mask(&self) -> &BitMask {
        &self.clean
    }
    /// The background model.
    pub fn background(&self) -> &Background {
        &self.background
    }
    /// The background model, mutable (test hooks).
    pub fn background_mut(&mut self) -> &mut Background {
        &mut self.background
    }
    /// Statistics of the last frame's model update.
    pub fn stats(&self) -> FrameStats {
        self.background.stats()
    }
    /// Smallest region kept, pixels.
    pub fn min_area(&self) -> u32 {
        self.min_area
    }
}
