//! Stage `calibrate` (built by its own issue).

use crate::config::ConfigError;
use serde::{Deserialize, Serialize};

/// `[calibrate]`
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrateConfig {}

impl CalibrateConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        Ok(())
    }
}
