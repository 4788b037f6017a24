//! Moving-object detection: background model, mask clean-up, connected regions.
//!
//! (Issue 5 builds the fixed-point Zivkovic GMM here; until then the
//! detector finds no regions.)

use crate::config::ConfigError;
use crate::frame::{Frame, Size};
use serde::{Deserialize, Serialize};

/// `[detect]`
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DetectConfig {}

impl DetectConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        Ok(())
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
    /// Its run-length mask: indices into [`RegionSet::runs`], sorted by row.
    pub runs: core::ops::Range<u32>,
}

/// The regions of one frame, in buffers allocated once.
#[derive(Debug)]
pub struct RegionSet {
    regions: Vec<Region>,
    runs: Vec<Run>,
    region_capacity: usize,
    run_capacity: usize,
    /// Regions dropped this frame because the set was full.
    pub overflow: u32,
}

impl RegionSet {
    /// Room for `regions` regions and `runs` runs in all.
    pub fn with_capacity(regions: usize, runs: usize) -> Self {
        RegionSet {
            regions: Vec::with_capacity(regions),
            runs: Vec::with_capacity(runs),
            region_capacity: regions,
            run_capacity: runs,
            overflow: 0,
        }
    }
    /// Empties the set, keeping its buffers.
    pub fn clear(&mut self) {
        self.regions.clear();
        self.runs.clear();
        self.overflow = 0;
    }
    /// The regions.
    pub fn regions(&self) -> &[Region] {
        &self.regions
    }
    /// The runs of one region.
    pub fn runs_of(&self, region: &Region) -> &[Run] {
        &self.runs[region.runs.start as usize..region.runs.end as usize]
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

/// The detection stage.
#[derive(Debug)]
pub struct Detector {
    size: Size,
}

impl Detector {
    /// Sizes the background model for frames of `size`.
    pub fn new(_cfg: &DetectConfig, size: Size) -> Self {
        Detector { size }
    }
    /// Frame size this detector was built for.
    pub fn size(&self) -> Size {
        self.size
    }
    /// Updates the model with `frame` and writes its foreground regions to `out`.
    pub fn process(&mut self, _frame: &Frame, out: &mut RegionSet) {
        out.clear();
    }
}
