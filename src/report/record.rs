//! Schema v1 records. Every record carries `type` and `frame`.
//!
//! JSON (human-readable serialisers) writes an internally tagged object,
//! `{"type":"height","frame":..}`; postcard (binary) writes the enum variant
//! index followed by the fields, which [`Record`]'s `Deserialize` reads back.

use heapless::String as HString;
use serde::{Deserialize, Serialize, Serializer};

/// Version of the record schema.
pub const SCHEMA: u8 = 1;

/// `hello`: first record of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// Frame number (0).
    pub frame: u64,
    /// stature version.
    pub version: HString<16>,
    /// Schema version (1).
    pub schema: u8,
    /// Source description.
    pub source: HString<128>,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Frames per second of the source (0 when unknown).
    pub fps: f32,
}

/// `calibration`: the current camera estimate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Frame number.
    pub frame: u64,
    /// Focal length, pixels.
    pub f_px: f32,
    /// Downward pitch of the optical axis, degrees.
    pub tilt_deg: f32,
    /// Roll, degrees, positive when the horizon rises to the right.
    pub roll_deg: f32,
    /// Camera height above the ground, metres.
    pub camera_height_m: f32,
    /// Horizon `[a,b,c]`: `a·u+b·v+c = 0`, `a²+b² = 1`, positive below it.
    pub horizon: [f32; 3],
    /// Vertical vanishing point `[u, v]`, pixels.
    pub vertical_vp: [f32; 2],
    /// Observations supporting the estimate.
    pub inliers: u32,
    /// Confidence, 0..1.
    pub confidence: f32,
    /// Last calibration of the run.
    #[serde(rename = "final")]
    pub is_final: bool,
}

/// `height`: one person's height.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Height {
    /// Frame number.
    pub frame: u64,
    /// Track id.
    pub track_id: u32,
    /// Height, metres.
    pub height_m: f32,
    /// Per-frame measurements behind it: those the RANSAC correction kept
    /// as inliers (within `measure.inlier_m` of the best RANSAC draw's
    /// mean; `height_m` is their mean), which may be fewer than the
    /// `measure.min_samples` a height needs measured.
    pub samples: u32,
    /// Foot point `[u, v]`, pixels (its column within `bbox`).
    pub foot_px: [f32; 2],
    /// Head point `[u, v]`, pixels (its column within `bbox`).
    pub head_px: [f32; 2],
    /// Inclusive box `[x0, y0, x1, y1]`.
    pub bbox: [u16; 4],
    /// The track ended (or the stream did): this is its last height.
    #[serde(rename = "final")]
    pub is_final: bool,
}

/// `status`: periodic health.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Status {
    /// Index of the last frame processed (`frames` − 1; 0 with none).
    pub frame: u64,
    /// Frames processed so far.
    pub frames: u64,
    /// Processing rate over the last interval, frames per wall-clock second.
    pub fps: f32,
    /// Records dropped so far (queue full or sink failure).
    pub dropped: u64,
    /// Source health: `streaming`, `reconnecting` or `ended`.
    pub source: HString<16>,
    /// Heap allocations made by the process since start-up finished
    /// (counted by the binary's allocator; 0 when not counted).
    pub allocations: u64,
    /// People tracked now.
    pub tracks: u32,
}

/// `bye`: last record of a clean run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Bye {
    /// Index of the last frame processed (`frames` − 1; 0 with none).
    pub frame: u64,
    /// Frames processed.
    pub frames: u64,
    /// Records dropped in all.
    pub dropped: u64,
}

/// Any record.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub enum Record {
    /// See [`Hello`].
    Hello(Hello),
    /// See [`Calibration`].
    Calibration(Calibration),
    /// See [`Height`].
    Height(Height),
    /// See [`Status`].
    Status(Status),
    /// See [`Bye`].
    Bye(Bye),
}

#[derive(Serialize)]
#[serde(tag = "type", rename_all = "lowercase")]
enum Tagged<'a> {
    Hello(&'a Hello),
    Calibration(&'a Calibration),
    Height(&'a Height),
    Status(&'a Status),
    Bye(&'a Bye),
}

#[derive(Serialize)]
enum Wire<'a> {
    Hello(&'a Hello),
    Calibration(&'a Calibration),
    Height(&'a Height),
    Status(&'a Status),
    Bye(&'a Bye),
}

impl Serialize for Record {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            match self {
                Record::Hello(r) => Tagged::Hello(r),
                Record::Calibration(r) => Tagged::Calibration(r),
                Record::Height(r) => Tagged::Height(r),
                Record::Status(r) => Tagged::Status(r),
                Record::Bye(r) => Tagged::Bye(r),
            }
            .serialize(s)
        } else {
            match self {
                Record::Hello(r) => Wire::Hello(r),
                Record::Calibration(r) => Wire::Calibration(r),
                Record::Height(r) => Wire::Height(r),
                Record::Status(r) => Wire::Status(r),
                Record::Bye(r) => Wire::Bye(r),
            }
            .serialize(s)
        }
    }
}

impl Record {
    /// Records the loop must never drop: hello, bye, final calibration and final heights.
    pub fn is_final(&self) -> bool {
        match self {
            Record::Hello(_) | Record::Bye(_) => true,
            Record::Calibration(c) => c.is_final,
            Record::Height(h) => h.is_final,
            Record::Status(_) => false,
        }
    }
    /// The `type` name.
    pub fn kind(&self) -> &'static str {
        match self {
            Record::Hello(_) => "hello",
            Record::Calibration(_) => "calibration",
            Record::Height(_) => "height",
            Record::Status(_) => "status",
            Record::Bye(_) => "bye",
        }
    }
}

/// Copies `s` into a bounded string. One too long is cut at a character
/// boundary and ends with `…`, so a reader can tell (a long source path
/// in `hello`).
pub fn bounded<const N: usize>(s: &str) -> HString<N> {
    let mut out = HString::new();
    if out.push_str(s).is_ok() {
        return out;
    }
    const MARK: char = '…';
    let room = N.saturating_sub(MARK.len_utf8());
    for c in s.chars() {
        if out.len() + c.len_utf8() > room {
            break;
        }
        // Within `room`, below the capacity.
        let _ = out.push(c);
    }
    // `room` left space for it (unless N is under 3 bytes: then nothing).
    let _ = out.push(MARK);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_marks_a_cut() {
        assert_eq!(bounded::<16>("streaming").as_str(), "streaming");
        assert_eq!(bounded::<9>("streaming").as_str(), "streaming");
        assert_eq!(bounded::<8>("streaming").as_str(), "strea…");
        // A cut never splits a character: 'é' is two bytes.
        assert_eq!(bounded::<8>("ééééé").as_str(), "éé…");
        let long = format!("y4m:/data/{}.y4m", "x".repeat(200));
        let b = bounded::<128>(&long);
        assert!(b.len() <= 128 && b.ends_with('…') && long.starts_with(&b[..b.len() - 3]));
    }
}
