//! Per-person heights (paper §3.3, METHOD.md §6–7).
//!
//! Every observation's height comes from the exact cross ratio along the
//! vertical through the foot ([`crate::calibrate::geometry::ViewGeometry::height_ratio`]
//! times the camera height), not from the paper's eq. 8, which compares
//! only `y` extents and is a linear approximation (a test below measures
//! how far off it is). A track's per-frame heights `H_k` are then
//! corrected as the paper does: RANSAC draws `n_s` of them, takes their
//! mean, scores it by squared differences to all `H_k`, and keeps the best
//! of `n_i` draws. The squared differences are truncated at
//! [`MeasureConfig::inlier_m`] (an MSAC score): the paper's untruncated
//! sum is minimised by the overall mean, so an occluded frame reading
//! 1.31 m would still pull the answer; truncation keeps the
//! squared-difference score but caps each outlier's say. The result is the
//! mean of the inliers of the best draw: the heights within `inlier_m` of
//! that draw's mean (so an inlier may lie more than `inlier_m` from the
//! result).
//!
//! Heights are computed from a track's stored observations with the
//! current calibration each time they are reported, so a live track's
//! earlier observations are re-measured whenever the calibration improves.

use crate::calibrate::geometry::HeadFoot;
use crate::calibrate::Estimate;
use crate::config::{check_range, ConfigError};
use crate::rng::Rng;
use serde::{Deserialize, Serialize};

/// `[measure]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MeasureConfig {
    /// No heights until the calibration confidence reaches this (0..1).
    pub min_confidence: f64,
    /// RANSAC sample size `n_s`.
    pub ransac_samples: usize,
    /// RANSAC draws `n_i`.
    pub ransac_iterations: usize,
    /// Truncation of the squared-difference score, and the inlier band
    /// around the best draw's mean, metres.
    pub inlier_m: f64,
    /// Per-frame heights a track needs before its height is reported, at
    /// most [`crate::track::RING`]: a track keeps only its newest that many
    /// observations, so a larger value would never be reached.
    pub min_samples: usize,
    /// Frames between height records of a live track.
    pub report_interval: u32,
    /// Corrected heights below this are not reported, metres: what the
    /// classifier let through that is not a standing person (a dog, whose
    /// silhouette reads 0.9-1.0 m when it trots toward or away from the
    /// camera; a person crouching). Children under about 1.1 m (5 years)
    /// are not measured either.
    pub min_height_m: f64,
    /// Corrected heights above this are not reported, metres (two people
    /// one above the other in the image, a pole taken for a person).
    pub max_height_m: f64,
    /// Tracks that ended before the calibration was confident, kept (with
    /// their samples) until it is, then measured ([`pending`]).
    pub pending_tracks: usize,
    /// The calibration confidence those tracks wait for (at least
    /// `min_confidence`; at the end of the stream, or once the calibration
    /// has been usable for `pending_wait_s`, `min_confidence` is enough).
    pub pending_confidence: f64,
    /// Seconds of a usable calibration after which the waiting tracks are
    /// measured even if it has not reached `pending_confidence`.
    pub pending_wait_s: f64,
    /// RANSAC seed.
    pub seed: u64,
}

impl Default for MeasureConfig {
    fn default() -> Self {
        MeasureConfig {
            min_confidence: 0.25,
            ransac_samples: 5,
            ransac_iterations: 50,
            inlier_m: 0.05,
            min_samples: 8,
            report_interval: 25,
            min_height_m: 1.1,
            max_height_m: 2.4,
            pending_tracks: 16,
            pending_confidence: 0.5,
            pending_wait_s: 60.0,
            seed: 2,
        }
    }
}

impl MeasureConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("measure.min_confidence", self.min_confidence, 0.0..=1.0)?;
        check_range("measure.ransac_samples", self.ransac_samples, 1..=64)?;
        check_range(
            "measure.ransac_iterations",
            self.ransac_iterations,
            1..=10000,
        )?;
        check_range("measure.inlier_m", self.inlier_m, 0.005..=1.0)?;
        check_range(
            "measure.min_samples",
            self.min_samples,
            1..=crate::track::RING,
        )?;
        check_range("measure.report_interval", self.report_interval, 1..=100000)?;
        check_range("measure.min_height_m", self.min_height_m, 0.0..=2.0)?;
        check_range(
            "measure.max_height_m",
            self.max_height_m,
            self.min_height_m.max(1.0)..=5.0,
        )?;
        check_range("measure.pending_tracks", self.pending_tracks, 0..=256)?;
        check_range(
            "measure.pending_confidence",
            self.pending_confidence,
            self.min_confidence..=1.0,
        )?;
        check_range("measure.pending_wait_s", self.pending_wait_s, 0.0..=86400.0)?;
        Ok(())
    }
}

/// A corrected height.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corrected {
    /// Height, metres.
    pub height: f64,
    /// Per-frame heights behind it (the inliers).
    pub samples: u32,
    /// Per-frame heights considered.
    pub considered: u32,
}

/// The height stage: scratch sized once for `capacity` observations per track.
#[derive(Debug)]
pub struct Measurer {
    cfg: MeasureConfig,
    heights: Vec<f64>,
    rng: Rng,
}

impl Measurer {
    /// Room for `capacity` per-frame heights per track.
    pub fn new(cfg: &MeasureConfig, capacity: usize) -> Self {
        Measurer {
            cfg: cfg.clone(),
            heights: Vec::with_capacity(capacity),
            rng: Rng::new(cfg.seed),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &MeasureConfig {
        &self.cfg
    }

    /// Whether the calibration is good enough to report heights.
    pub fn ready(&self, est: Option<&Estimate>) -> bool {
        est.is_some_and(|e| e.confidence >= self.cfg.min_confidence)
    }

    /// Whether it is good enough for the tracks that left before it was
    /// ready ([`pending`]).
    pub fn settled(&self, est: Option<&Estimate>) -> bool {
        est.is_some_and(|e| e.confidence >= self.cfg.pending_confidence)
    }

    /// The corrected height of a track from its observations with the
    /// current calibration; `None` before the calibration is confident,
    /// with fewer than `min_samples` measurable observations, or outside
    /// `min_height_m..=max_height_m`.
    pub fn track_height<'a>(
        &mut self,
        est: Option<&Estimate>,
        obs: impl Iterator<Item = &'a HeadFoot>,
    ) -> Option<Corrected> {
        let est = est.filter(|e| e.confidence >= self.cfg.min_confidence)?;
        self.heights.clear();
        for o in obs {
            if self.heights.len() == self.heights.capacity() {
                break;
            }
            if let Some(h) = est.height(o) {
                if h.is_finite() && h > 0.0 {
                    self.heights.push(h);
                }
            }
        }
        if self.heights.len() < self.cfg.min_samples {
            return None;
        }
        ransac_mean(&self.heights, &self.cfg, &mut self.rng)
            .filter(|c| (self.cfg.min_height_m..=self.cfg.max_height_m).contains(&c.height))
    }
}

/// The paper's RANSAC correction with a truncated squared-difference score
/// (see the module documentation).
pub fn ransac_mean(h: &[f64], cfg: &MeasureConfig, rng: &mut Rng) -> Option<Corrected> {
    if h.is_empty() {
        return None;
    }
    let tau2 = cfg.inlier_m * cfg.inlier_m;
    let score = |m: f64| h.iter().map(|x| (x - m).powi(2).min(tau2)).sum::<f64>();
    let mut best = (f64::INFINITY, 0.0);
    for _ in 0..cfg.ransac_iterations {
        let mut s = 0.0;
        for _ in 0..cfg.ransac_samples {
            s += h[rng.below(h.len())];
        }
        let m = s / cfg.ransac_samples as f64;
        let sc = score(m);
        if sc < best.0 {
            best = (sc, m);
        }
    }
    let (mut sum, mut k) = (0.0, 0u32);
    for x in h {
        if (x - best.1).abs() <= cfg.inlier_m {
            sum += x;
            k += 1;
        }
    }
    (k > 0).then(|| Corrected {
        height: sum / f64::from(k),
        samples: k,
        considered: h.len() as u32,
    })
}

pub mod pending;

#[cfg(test)]
mod tests;
