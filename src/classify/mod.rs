//! Region classification: single person vs. not.
//!
//! (Issue 6 builds HOG-LBP features and the linear SVM here; until then
//! every region is "not a single person".)

use crate::config::ConfigError;
use crate::detect::Region;
use crate::frame::Plane;
use serde::{Deserialize, Serialize};

/// `[classify]`
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClassifyConfig {}

impl ClassifyConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        Ok(())
    }
}

/// What the classifier says of one region.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Verdict {
    /// SVM score, positive for a single person.
    pub score: f32,
    /// Exactly one upright person.
    pub single_human: bool,
}

/// The classification stage.
#[derive(Debug, Default)]
pub struct Classifier {}

impl Classifier {
    /// Builds the classifier.
    pub fn new(_cfg: &ClassifyConfig) -> Self {
        Classifier {}
    }
    /// Classifies one region of the luma plane.
    pub fn classify(&mut self, _luma: Plane<'_>, _region: &Region) -> Verdict {
        Verdict::default()
    }
}
