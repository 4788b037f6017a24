//! Stage `track` (built by its own issue).

use crate::config::ConfigError;
use serde::{Deserialize, Serialize};

/// `[track]`
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TrackConfig {}

impl TrackConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        Ok(())
    }
}
