//! # stature
//!
//! Firmware-style software for smart cameras: it watches a scene, finds
//! walking people, calibrates the camera from them (no checkerboard, no
//! installer measurements) and reports every person's height.
//!
//! It implements Jung, Yoon, Lee & Paik, "Object Detection and
//! Tracking-Based Camera Calibration for Normalized Human Height
//! Estimation" (J. Sensors 2016). The modules follow the data flow:
//!
//! ```text
//! source → detect → classify → track → calibrate → measure → report
//! ```
//!
//! * [`source`]: frames from a Y4M file or pipe, a V4L2 camera, or the
//!   built-in simulated scene, always as Y/U/V planes (chroma 4:2:0).
//! * [`detect`]: fixed-point Gaussian-mixture background model and
//!   connected foreground regions.
//! * [`classify`]: HOG-LBP features and a linear SVM, single person vs. not.
//! * [`track`]: small particle filters that follow people.
//! * [`calibrate`]: vanishing point, horizon, focal length, tilt, roll and
//!   camera height from the tracked people.
//! * [`measure`]: per-person heights with robust correction.
//! * [`report`]: schema v1 records and the sinks that carry them.
//! * [`run`]: the loop that owns every buffer and calls the stages in order.
//! * [`snapshot`]: the installer snapshot, a PNG of a frame with the
//!   calibration and the tracks drawn over it.
//!
//! After start-up the loop allocates nothing: every buffer is sized from the
//! [`config::Config`] when the [`run::Pipeline`] is built.
#![deny(unsafe_code)]
#![warn(missing_docs)]
// The negated float comparisons (`if !(lo < hi)`) are deliberate: they reject NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod alloc_count;
pub mod camera;
pub mod config;
pub mod dataset;
pub mod frame;
pub mod fuzz_entry;
pub mod logger;
pub mod qformat;
pub mod replace;
pub mod rng;
#[cfg(test)]
#[path = "../tests/common/scratch.rs"]
mod scratch;

pub mod source;

pub mod detect;

pub mod classify;

pub mod track;

pub mod calibrate;

pub mod measure;

pub mod report;

pub mod run;

pub mod snapshot;

/// Process exit codes, shared by the binary and documented in the README.
pub mod exit {
    /// Clean end: end of stream, requested frame count reached, or
    /// SIGINT/SIGTERM/SIGHUP (also before the source sent its first frame).
    pub const OK: i32 = 0;
    /// Internal failure (should not happen; a bug report is welcome).
    pub const INTERNAL: i32 = 1;
    /// Bad input: unreadable or malformed config, command line, source URI,
    /// frames or weights.
    pub const BAD_INPUT: i32 = 2;
    /// Unavailable: a source, sink, state file, snapshot path, output file
    /// or standard output that cannot be opened or written, training data
    /// that is missing, a feature not built in, or a report sink that
    /// delivered none of the run's records.
    pub const UNAVAILABLE: i32 = 3;
}
