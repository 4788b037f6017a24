//! Region classification: single person vs. not.
//!
//! Each region's box is resampled to a small fixed window on the Y plane
//! ([`window`]), described by HOG ([`hog`]) and uniform-LBP ([`lbp`]) cell
//! histograms laid out as [`layout`] documents, and scored by a linear SVM
//! ([`svm`]) whose weights are preloaded from a versioned blob: the one
//! built into the binary (`weights/classifier.bin`, made by `stature
//! train`, see [`train`]) or a file named by `classify.weights` /
//! `--weights`. Everything per region runs in buffers sized when the
//! [`Classifier`] is built: no allocation per region or frame.

use crate::config::{check_range, ConfigError};
use crate::detect::morphology::BitMask;
use crate::detect::{BBox, Region};
use crate::frame::Plane;
use core::fmt;
use serde::{Deserialize, Serialize};

pub mod eval;
pub mod hog;
pub mod layout;
pub mod lbp;
pub mod samples;
pub mod solver;
pub mod svm;
pub mod train;
pub mod window;

use layout::Layout;
use svm::{Model, WeightsError};

/// The weights built into the binary (`stature train` writes them).
pub static BUILTIN_WEIGHTS: &[u8] = include_bytes!("../../weights/classifier.bin");

/// `[classify]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClassifyConfig {
    /// Weight blob file; empty for the built-in weights.
    pub weights: String,
    /// Most regions classified per frame; the rest are skipped and counted.
    pub max_regions: usize,
    /// SVM score above which a region is a single person.
    pub threshold: f32,
    /// Regions shorter than this many pixels are not classified (too few
    /// pixels to tell) and count as "not a single person".
    pub min_height: u32,
}

impl Default for ClassifyConfig {
    fn default() -> Self {
        ClassifyConfig {
            weights: String::new(),
            max_regions: 16,
            threshold: 0.0,
            min_height: 24,
        }
    }
}

impl ClassifyConfig {
    /// Checks every value against its accepted range, and that the weights
    /// load (so a bad blob is refused before the loop starts).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("classify.max_regions", self.max_regions, 1..=256)?;
        check_range("classify.threshold", self.threshold, -10.0..=10.0)?;
        check_range("classify.min_height", self.min_height, 8..=4096)?;
        self.load_model().map_err(|e| {
            ConfigError::new(
                "classify.weights",
                format_args!("{:?}", self.weights),
                format_args!("a valid stature weight blob ({e})"),
            )
        })?;
        Ok(())
    }

    /// Reads and checks the configured weights (a file over
    /// [`svm::MAX_BLOB_BYTES`] is refused unread).
    pub fn load_model(&self) -> Result<Model, ClassifyError> {
        if self.weights.is_empty() {
            Model::from_bytes(BUILTIN_WEIGHTS).map_err(|error| ClassifyError::Weights {
                what: "built-in weights".into(),
                error,
            })
        } else {
            let bytes = crate::replace::read_capped(self.weights.as_ref(), svm::MAX_BLOB_BYTES)
                .map_err(|e| ClassifyError::Read {
                    path: self.weights.clone(),
                    error: match e {
                        crate::replace::ReadError::TooLarge { .. } => {
                            format!("{e}, too large to be a weight blob")
                        }
                        e => e.to_string(),
                    },
                })?;
            Model::from_bytes(&bytes).map_err(|error| ClassifyError::Weights {
                what: format!("weights file `{}`", self.weights),
                error,
            })
        }
    }
}

/// Why the classifier could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum ClassifyError {
    /// The weights file could not be read.
    Read {
        /// File path.
        path: String,
        /// Why.
        error: String,
    },
    /// The weights were refused.
    Weights {
        /// Which weights.
        what: String,
        /// Why.
        error: WeightsError,
    },
}

impl fmt::Display for ClassifyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClassifyError::Read { path, error } => {
                write!(f, "cannot read weights file `{path}`: {error}")
            }
            ClassifyError::Weights { what, error } => write!(f, "{what} refused: {error}"),
        }
    }
}
impl std::error::Error for ClassifyError {}

/// What the classifier says of one region.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Verdict {
    /// SVM score, positive for a single person.
    pub score: f32,
    /// Exactly one upright person.
    pub single_human: bool,
}

/// Counters since the classifier was built (wrap only after 2^64 regions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClassifyCounters {
    /// Regions scored by the SVM.
    pub classified: u64,
    /// Regions called "not" without scoring because they were too small.
    pub too_small: u64,
    /// Regions not classified because the per-frame budget was spent.
    pub skipped: u64,
}

/// Feature extraction for one layout, with all its scratch.
#[derive(Clone, Debug)]
pub struct Extractor {
    layout: Layout,
    sampler: window::Sampler,
    win: Vec<u8>,
    hog: hog::Hog,
    lbp: lbp::Lbp,
    features: Vec<u8>,
}

impl Extractor {
    /// Scratch for `layout` (which must be valid).
    pub fn new(layout: &Layout) -> Self {
        let sampler = window::Sampler::new(layout);
        Extractor {
            win: vec![0; sampler.len()],
            sampler,
            hog: hog::Hog::new(layout),
            lbp: lbp::Lbp::new(layout),
            features: vec![0; layout.dim()],
            layout: layout.clone(),
        }
    }

    /// The layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The bordered window of the last extraction (`(w+2)·(h+2)` bytes).
    pub fn window(&self) -> &[u8] {
        &self.win
    }

    /// Computes the feature vector of `bbox` on `luma`; `None` for an
    /// empty plane.
    pub fn extract(&mut self, luma: Plane<'_>, bbox: &BBox) -> Option<&[u8]> {
        self.extract_flipped(luma, bbox, false)
    }

    /// [`Extractor::extract`], of the mirror image when `flip` is set (left
    /// and right swapped; the window is sampled as usual and flipped before
    /// the features are computed: training augmentation).
    pub fn extract_flipped(&mut self, luma: Plane<'_>, bbox: &BBox, flip: bool) -> Option<&[u8]> {
        self.extract_with_mask(luma, None, bbox, flip)
    }

    /// [`Extractor::extract_flipped`] with the detector's foreground mask
    /// of the same frame, for a layout with foreground-fill features
    /// (ignored otherwise; `None` gives the "no mask" features).
    pub fn extract_with_mask(
        &mut self,
        luma: Plane<'_>,
        mask: Option<&BitMask>,
        bbox: &BBox,
        flip: bool,
    ) -> Option<&[u8]> {
        let rect = window::window_rect(bbox, &self.layout);
        if !self.sampler.sample(luma, &rect, &mut self.win) {
            return None;
        }
        if flip {
            for row in self.win.chunks_exact_mut(self.sampler.stride()) {
                row.reverse();
            }
        }
        let stride = self.sampler.stride();
        let hd = self.layout.hog_dim();
        let cd = hd + self.layout.coarse_dim();
        let ld = cd + self.layout.lbp_dim();
        if cd > 0 {
            self.hog.cell_histograms(&self.win, stride);
            self.hog
                .blocks(&self.layout.hog_blocks, &mut self.features[..hd]);
            if cd > hd {
                self.hog.coarse_blocks(&mut self.features[hd..cd]);
            }
        }
        if ld > hd {
            self.lbp.histograms(&self.win, stride);
            self.lbp
                .features(&self.layout.lbp_cells, &mut self.features[cd..ld]);
        }
        let ad = ld + usize::from(self.layout.aspect_bins);
        window::aspect_features(bbox, &mut self.features[ld..ad]);
        if self.layout.mask_fill {
            window::mask_features(mask, &rect, &self.layout, flip, &mut self.features[ad..]);
        }
        Some(&self.features)
    }
}

/// The classification stage.
#[derive(Clone, Debug)]
pub struct Classifier {
    model: Model,
    extractor: Extractor,
    threshold: f32,
    min_height: u32,
    max_regions: usize,
    /// Work done so far.
    pub counters: ClassifyCounters,
}

impl Classifier {
    /// Builds the classifier with the configured weights.
    pub fn new(cfg: &ClassifyConfig) -> Result<Self, ClassifyError> {
        Ok(Self::with_model(cfg.load_model()?, cfg))
    }

    /// Builds the classifier around an already loaded model.
    pub fn with_model(model: Model, cfg: &ClassifyConfig) -> Self {
        Classifier {
            extractor: Extractor::new(&model.layout),
            model,
            threshold: cfg.threshold,
            min_height: cfg.min_height,
            max_regions: cfg.max_regions,
            counters: ClassifyCounters::default(),
        }
    }

    /// A classifier that calls every region "not a single person" (score
    /// −1): the fallback when weights cannot be loaded after validation.
    pub fn reject_all(cfg: &ClassifyConfig) -> Self {
        let layout = Layout::default_layout();
        let zeros = vec![0.0; layout.dim()];
        Self::with_model(Model::quantise(layout, &zeros, -1.0), cfg)
    }

    /// The model in use.
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// Most regions the loop should classify per frame.
    pub fn max_regions(&self) -> usize {
        self.max_regions
    }

    /// Records that `n` regions of a frame were left unclassified.
    pub fn note_skipped(&mut self, n: usize) {
        self.counters.skipped += n as u64;
    }

    /// Classifies one region of the luma plane.
    pub fn classify(&mut self, luma: Plane<'_>, region: &Region) -> Verdict {
        self.classify_box(luma, &region.bbox)
    }

    /// Classifies one region of the luma plane, with the detector's
    /// foreground mask of the same frame (used when the weights have
    /// foreground-fill features).
    pub fn classify_masked(&mut self, luma: Plane<'_>, mask: &BitMask, region: &Region) -> Verdict {
        self.classify_box_masked(luma, Some(mask), &region.bbox)
    }

    /// Classifies a box of the luma plane (what [`Classifier::classify`]
    /// does with the region's bounding box).
    pub fn classify_box(&mut self, luma: Plane<'_>, bbox: &BBox) -> Verdict {
        self.classify_box_masked(luma, None, bbox)
    }

    /// [`Classifier::classify_box`] with an optional foreground mask.
    pub fn classify_box_masked(
        &mut self,
        luma: Plane<'_>,
        mask: Option<&BitMask>,
        bbox: &BBox,
    ) -> Verdict {
        if bbox.height() < self.min_height {
            self.counters.too_small += 1;
            return Verdict {
                score: f32::NEG_INFINITY,
                single_human: false,
            };
        }
        let Some(x) = self.extractor.extract_with_mask(luma, mask, bbox, false) else {
            return Verdict {
                score: f32::NEG_INFINITY,
                single_human: false,
            };
        };
        self.counters.classified += 1;
        let score = self.model.score(x);
        Verdict {
            score,
            single_human: score > self.threshold,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_weights_load() {
        let m = ClassifyConfig::default().load_model().unwrap();
        assert_eq!(m.weights.len(), m.layout.dim());
    }

    #[test]
    fn missing_weights_file_is_named() {
        let cfg = ClassifyConfig {
            weights: "/nonexistent/w.bin".into(),
            ..Default::default()
        };
        let e = cfg.validate().unwrap_err();
        assert_eq!(e.key, "classify.weights");
        assert!(e.to_string().contains("/nonexistent/w.bin"), "{e}");
    }

    #[test]
    fn flipped_extraction_mirrors_the_window() {
        let layout = Layout::default_layout();
        let mut ex = Extractor::new(&layout);
        let (w, h) = (120usize, 160usize);
        let img: Vec<u8> = (0..w * h)
            .map(|i| ((i % w) * 2 + (i / w) % 7) as u8)
            .collect();
        let p = Plane::new(&img, w, h).unwrap();
        let b = BBox {
            x0: 40,
            y0: 20,
            x1: 70,
            y1: 130,
        };
        let plain = ex.extract(p, &b).unwrap().to_vec();
        let win = ex.window().to_vec();
        let flipped = ex.extract_flipped(p, &b, true).unwrap().to_vec();
        let stride = usize::from(layout.win_w) + 2;
        for (a, f) in win
            .chunks_exact(stride)
            .zip(ex.window().chunks_exact(stride))
        {
            assert!(a.iter().rev().eq(f.iter()));
        }
        // A left-to-right ramp: mirrored, its gradients point the other way.
        assert_ne!(plain, flipped);
        assert_eq!(plain[plain.len() - 8..], flipped[flipped.len() - 8..]);
    }

    #[test]
    fn tiny_and_empty_inputs_do_not_panic() {
        let mut c = Classifier::new(&ClassifyConfig::default()).unwrap();
        let data = [0u8; 4];
        let p = Plane::new(&data, 2, 2).unwrap();
        let b = BBox {
            x0: 0,
            y0: 0,
            x1: 500,
            y1: 900,
        };
        assert!(!c.classify_box(p, &b).single_human || c.counters.classified == 1);
        let e = Plane::new(&[], 0, 0).unwrap();
        assert!(!c.classify_box(e, &b).single_human);
    }
}
