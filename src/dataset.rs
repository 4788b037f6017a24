//! Host-side access to the recorded test data in `../shared/data`: the PETS
//! 2009 S2.L1 ground truth and video. Used by the trainer, the tests and the
//! benchmarks, never by the vision loop.

use crate::detect::BBox;
use crate::source::y4m::Y4mSource;
use crate::source::SourceError;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// `../shared/data` beside the crate root, if present.
pub fn shared_data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    dir.join("README.md").is_file().then_some(dir)
}

/// The shared data folder for a test, with the tool that decodes its video
/// (`ffmpeg`): `None` (with a message) when either is missing locally; a
/// panic when missing in CI (`CI` set), so that CI never passes silently
/// without its data. `STATURE_SKIP_DATA_TESTS` (set by cross/test.sh for
/// armv7 under emulation) skips them on purpose, in CI too.
pub fn require_shared_data(what: &str) -> Option<PathBuf> {
    // cross/test.sh sets this for armv7 under qemu-user, where the long
    // data-set runs cost more CI time than they add (see cross/test.sh).
    if std::env::var_os("STATURE_SKIP_DATA_TESTS").is_some() {
        eprintln!("skipping {what}: STATURE_SKIP_DATA_TESTS is set");
        return None;
    }
    let ffmpeg = Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let missing = match (shared_data_dir(), ffmpeg) {
        (Some(d), true) => return Some(d),
        (None, _) => "../shared/data is missing",
        (Some(_), false) => "ffmpeg is not installed (apt-get install ffmpeg)",
    };
    if std::env::var_os("CI").is_some() {
        panic!("{what}: {missing} in CI; the test cannot run without it");
    }
    eprintln!("skipping {what}: {missing}");
    None
}

/// One ground-truth person box of PETS 2009 S2.L1 (`gt.csv`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GtBox {
    /// 0-based frame index in the decoded video.
    pub frame: u32,
    /// Person id (1..=19).
    pub id: u32,
    /// Inclusive box; may reach past the image edge, so signed.
    pub x0: i32,
    /// Top row.
    pub y0: i32,
    /// Right column (inclusive).
    pub x1: i32,
    /// Bottom row (inclusive).
    pub y1: i32,
}

impl GtBox {
    /// The box clipped to a `width`×`height` image; `None` if nothing is left.
    pub fn clipped(&self, width: usize, height: usize) -> Option<BBox> {
        let x0 = self.x0.max(0);
        let y0 = self.y0.max(0);
        let x1 = self.x1.min(width as i32 - 1);
        let y1 = self.y1.min(height as i32 - 1);
        (x0 <= x1 && y0 <= y1).then_some(BBox {
            x0: x0 as u16,
            y0: y0 as u16,
            x1: x1 as u16,
            y1: y1 as u16,
        })
    }
}

/// Reads `gt.csv` (`frame,id,x0,y0,x1,y1`), sorted by frame then id.
pub fn load_pets_gt(data_dir: &Path) -> Result<Vec<GtBox>, String> {
    let path = data_dir.join("pets2009-s2l1/gt.csv");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        let v: Vec<i64> = line
            .split(',')
            .map(|f| f.trim().parse::<i64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{}:{}: {e}", path.display(), i + 1))?;
        if v.len() != 6 {
            return Err(format!("{}:{}: expected 6 fields", path.display(), i + 1));
        }
        out.push(GtBox {
            frame: v[0] as u32,
            id: v[1] as u32,
            x0: v[2] as i32,
            y0: v[3] as i32,
            x1: v[4] as i32,
            y1: v[5] as i32,
        });
    }
    Ok(out)
}

/// Ground-truth boxes of one frame (`gt` sorted by frame).
pub fn boxes_of_frame(gt: &[GtBox], frame: u32) -> &[GtBox] {
    let start = gt.partition_point(|b| b.frame < frame);
    let end = gt.partition_point(|b| b.frame <= frame);
    &gt[start..end]
}

/// Decodes a video file to Y4M with ffmpeg and reads it as a source.
/// `fps` (e.g. 7) relabels the stream rate without dropping frames.
pub fn decode_video(path: &Path, fps: Option<u32>) -> Result<Y4mSource, SourceError> {
    let mut cmd = Command::new("ffmpeg");
    cmd.args(["-nostdin", "-v", "error"]);
    if let Some(r) = fps {
        cmd.args(["-r", &r.to_string()]);
    }
    cmd.arg("-i")
        .arg(path)
        .args(["-f", "yuv4mpegpipe", "-pix_fmt", "yuv420p", "-"]);
    let child = cmd
        .stdout(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .map_err(|error| SourceError::Open {
            what: format!("ffmpeg for `{}` (is ffmpeg installed?)", path.display()),
            error,
        })?;
    let stdout = child
        .stdout
        .ok_or_else(|| SourceError::Spec("ffmpeg gave no output pipe".into()))?;
    Y4mSource::from_reader(Box::new(stdout), format!("ffmpeg:{}", path.display()))
}

/// The PETS 2009 S2.L1 View_001 video as a source (768x576, 795 frames).
pub fn pets_video(data_dir: &Path) -> Result<Y4mSource, SourceError> {
    decode_video(&data_dir.join("pets2009-s2l1/vtest.avi"), None)
}

/// The real calibration of PETS View_001 from `geometry.json`, as the
/// centred-principal-point camera it implies plus the true VVP and horizon.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PetsGeometry {
    /// Focal length implied with the principal point at the image centre, px.
    pub focal_px: f64,
    /// Tilt with the centred principal point, degrees.
    pub tilt_deg: f64,
    /// Roll, degrees (horizon rising to the right is positive).
    pub roll_deg: f64,
    /// Camera height, metres.
    pub camera_height_m: f64,
    /// Vertical vanishing point, px.
    pub vertical_vp: [f64; 2],
    /// Horizon `[a,b,c]`.
    pub horizon: [f64; 3],
}

/// Reads the numbers of `geometry.json` that calibration is checked against.
pub fn load_pets_geometry(data_dir: &Path) -> Result<PetsGeometry, String> {
    let path = data_dir.join("pets2009-s2l1/geometry.json");
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let num = |v: &serde_json::Value, what: &str| {
        v.as_f64()
            .ok_or_else(|| format!("{}: `{what}` is not a number", path.display()))
    };
    let arr = |key: &str, n: usize| -> Result<Vec<f64>, String> {
        let a = json[key]
            .as_array()
            .filter(|a| a.len() == n)
            .ok_or_else(|| format!("{}: `{key}` is not {n} numbers", path.display()))?;
        a.iter().map(|v| num(v, key)).collect()
    };
    let vvp = arr("vertical_vanishing_point_px", 2)?;
    let hor = arr("horizon", 3)?;
    Ok(PetsGeometry {
        focal_px: num(
            &json["image_centre_pp_equivalent"]["focal_px"],
            "image_centre_pp_equivalent.focal_px",
        )?,
        tilt_deg: num(
            &json["image_centre_pp_equivalent"]["tilt_deg"],
            "image_centre_pp_equivalent.tilt_deg",
        )?,
        roll_deg: num(&json["roll_deg"], "roll_deg")?,
        camera_height_m: num(&json["camera_height_m"], "camera_height_m")?,
        vertical_vp: [vvp[0], vvp[1]],
        horizon: [hor[0], hor[1], hor[2]],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pets_ground_truth_and_geometry_load() {
        let Some(dir) = require_shared_data("dataset loader test") else {
            return;
        };
        let gt = load_pets_gt(&dir).unwrap();
        assert_eq!(gt.len(), 4650);
        assert_eq!(
            boxes_of_frame(&gt, 0).len(),
            gt.iter().filter(|b| b.frame == 0).count()
        );
        let g = load_pets_geometry(&dir).unwrap();
        assert!((g.focal_px - 1207.0).abs() < 1e-9, "{g:?}");
        assert!((g.tilt_deg - 16.68).abs() < 1e-9 && (g.roll_deg - 3.11).abs() < 1e-9);
        assert!((g.camera_height_m - 7.066).abs() < 1e-9);
        assert_eq!(g.vertical_vp, [539.9, 4314.2]);
        assert!((g.horizon[2] - 53.698).abs() < 1e-9);
    }
}
