//! The built-in simulated scene (issue 4 builds the renderer here).

use super::{FrameSource, Next, SourceError, SourceInfo};
use crate::frame::Frame;

/// Renders a named scene frame by frame.
pub struct SimSource {
    info: SourceInfo,
}

impl SimSource {
    /// Opens scene `name` with options `seed=N&frames=N`.
    pub fn open(name: &str, _query: &str) -> Result<Self, SourceError> {
        Err(SourceError::Unsupported(if name.is_empty() {
            "the simulated scene is not built yet"
        } else {
            "the simulated scene is not built yet"
        }))
    }
}

impl FrameSource for SimSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }
    fn next_frame(&mut self, _frame: &mut Frame) -> Result<Next, SourceError> {
        Ok(Next::End)
    }
}
