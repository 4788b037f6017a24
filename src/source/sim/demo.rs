//! What `stature demo` prints at the end: estimated against true
//! calibration and, per person, estimated against true height.
//!
//! The table is honest by construction: a value the pipeline did not
//! produce is printed as "not estimated" with the reason the caller gives
//! (typically the missing stage), never as a placeholder number.

use super::people::Kind;
use super::truth::{CastMember, SceneTruth};
use crate::report::record::Calibration;
use core::fmt::Write;

/// One height the pipeline reported, matched to the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightEstimate {
    /// Track id the pipeline gave.
    pub track_id: u32,
    /// Estimated height, metres.
    pub height_m: f64,
    /// The sim person it was matched to (see [`super::SimSource::person_at`]), if any.
    pub person_id: Option<u32>,
}

/// What the pipeline produced, and why the rest is missing.
#[derive(Clone, Copy, Debug)]
pub struct Estimates<'a> {
    /// Final calibration, if the pipeline produced one.
    pub calibration: Option<&'a Calibration>,
    /// Why there is no calibration (e.g. "stage missing: calibrate").
    pub calibration_missing: &'a str,
    /// Final heights.
    pub heights: &'a [HeightEstimate],
    /// Why there are no heights (e.g. "stage missing: measure").
    pub heights_missing: &'a str,
    /// Frames the pipeline ran: people who appear only after them are
    /// left out of the table.
    pub frames_run: u64,
}

/// Formats the comparison table (several lines, ending with a newline).
pub fn comparison_table(truth: &SceneTruth, cast: &[CastMember], est: &Estimates<'_>) -> String {
    let mut s = String::new();
    let none = |why: &str| format!("not estimated ({why})");
    let _ = writeln!(
        s,
        "\nCalibration of sim:{} (seed {}, {}x{}):",
        truth.scene, truth.seed, truth.width, truth.height
    );
    let _ = writeln!(s, "  {:<22} {:>24}  {:<24} error", "", "true", "estimated");
    let c = est.calibration;
    let mut row = |name: &str, t: f64, e: Option<f64>, unit: &str| {
        let (es, err) = match e {
            Some(e) => (format!("{e:.2}"), format!("{:+.2} {unit}", e - t)),
            // The reason once, under the block: six copies made the
            // table 180 columns wide.
            None => ("not estimated".to_string(), String::new()),
        };
        let _ = writeln!(s, "  {name:<22} {t:>24.2}  {es:<24} {err}");
    };
    row(
        "focal length (px)",
        truth.f_px,
        c.map(|c| c.f_px as f64),
        "px",
    );
    row(
        "tilt (deg)",
        truth.tilt_deg,
        c.map(|c| c.tilt_deg as f64),
        "deg",
    );
    row(
        "roll (deg)",
        truth.roll_deg,
        c.map(|c| c.roll_deg as f64),
        "deg",
    );
    row(
        "camera height (m)",
        truth.camera_height_m,
        c.map(|c| c.camera_height_m as f64),
        "m",
    );
    let vp = format!("({:.1}, {:.1})", truth.vertical_vp[0], truth.vertical_vp[1]);
    let vp_est = c.map_or_else(
        || "not estimated".to_string(),
        |c| format!("({:.1}, {:.1})", c.vertical_vp[0], c.vertical_vp[1]),
    );
    let _ = writeln!(s, "  {:<22} {:>24}  {}", "vertical VP (px)", vp, vp_est);
    let hz = truth.horizon;
    let hz_s = format!("[{:.3}, {:.3}, {:.1}]", hz[0], hz[1], hz[2]);
    let hz_est = c.map_or_else(
        || "not estimated".to_string(),
        |c| {
            format!(
                "[{:.3}, {:.3}, {:.1}]",
                c.horizon[0], c.horizon[1], c.horizon[2]
            )
        },
    );
    let _ = writeln!(s, "  {:<22} {:>24}  {}", "horizon [a,b,c]", hz_s, hz_est);
    if c.is_none() {
        let _ = writeln!(
            s,
            "  calibration not estimated: {}",
            est.calibration_missing
        );
    }

    let people: Vec<&CastMember> = cast
        .iter()
        .filter(|m| m.kind == Kind::Person && m.frames_in_view > 0)
        .filter(|m| m.first_frame < est.frames_run)
        .collect();
    let _ = writeln!(
        s,
        "\nPeople in view in the {} frames run: {} (true heights drawn from N(1.70 m, 0.08 m)):",
        est.frames_run,
        people.len()
    );
    let _ = writeln!(
        s,
        "  {:>6} {:>7} {:>13} {:>11}  {:<24} error (m)",
        "person", "group", "frames", "true (m)", "estimated (m)"
    );
    let mut errors = Vec::new();
    for m in &people {
        let hits: Vec<&HeightEstimate> = est
            .heights
            .iter()
            .filter(|h| h.person_id == Some(m.id))
            .collect();
        let group = if m.group == 0 {
            "-".to_string()
        } else {
            m.group.to_string()
        };
        let frames = format!("{}-{}", m.first_frame, m.last_frame);
        let (es, err) = match hits.last() {
            Some(h) => {
                errors.push(h.height_m - m.height_m);
                (
                    format!("{:.3} (track {})", h.height_m, h.track_id),
                    format!("{:+.3}", h.height_m - m.height_m),
                )
            }
            None if est.heights.is_empty() => (none(est.heights_missing), String::new()),
            None => ("not measured".to_string(), String::new()),
        };
        let _ = writeln!(
            s,
            "  {:>6} {:>7} {:>13} {:>11.3}  {:<24} {}",
            m.id, group, frames, m.height_m, es, err
        );
    }
    let unmatched = est.heights.iter().filter(|h| h.person_id.is_none()).count();
    if unmatched > 0 {
        let _ = writeln!(
            s,
            "  {unmatched} reported heights matched no person in the truth"
        );
    }
    if !errors.is_empty() {
        let mae = errors.iter().map(|e| e.abs()).sum::<f64>() / errors.len() as f64;
        let _ = writeln!(
            s,
            "  measured {} of {} people, mean absolute error {:.3} m",
            errors.len(),
            people.len(),
            mae
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::sim::SimSource;

    #[test]
    fn table_says_not_estimated_when_stages_are_missing() {
        let sim = SimSource::open("plaza", "seed=1&frames=50").unwrap();
        let cast = sim.cast();
        let t = comparison_table(
            sim.scene_truth(),
            &cast,
            &Estimates {
                calibration: None,
                calibration_missing: "stage missing: calibrate",
                heights: &[],
                heights_missing: "stage missing: measure",
                frames_run: 50,
            },
        );
        assert!(
            t.contains("calibration not estimated: stage missing: calibrate"),
            "{t}"
        );
        assert_eq!(t.matches("stage missing: calibrate").count(), 1, "{t}");
        assert!(t.contains("620.00"), "{t}");
        let in_view = cast
            .iter()
            .filter(|m| m.kind == Kind::Person && m.frames_in_view > 0)
            .count();
        assert!(in_view > 0);
        assert_eq!(t.matches("stage missing: measure").count(), in_view, "{t}");
    }

    #[test]
    fn table_leaves_out_people_who_appear_after_the_frames_run() {
        let sim = SimSource::open("plaza", "seed=1").unwrap();
        let cast = sim.cast();
        let table = |frames_run| {
            comparison_table(
                sim.scene_truth(),
                &cast,
                &Estimates {
                    calibration: None,
                    calibration_missing: "stopped",
                    heights: &[],
                    heights_missing: "none",
                    frames_run,
                },
            )
        };
        let people = |first_before: u64| {
            cast.iter()
                .filter(|m| m.kind == Kind::Person && m.frames_in_view > 0)
                .filter(|m| m.first_frame < first_before)
                .count()
        };
        let (early, all) = (people(60), people(u64::MAX));
        assert!(0 < early && early < all, "{early} of {all}");
        let short = table(60);
        assert_eq!(
            short.matches("not estimated (none)").count(),
            early,
            "{short}"
        );
        assert!(
            short.contains(&format!("in the 60 frames run: {early} ")),
            "{short}"
        );
        let whole = table(sim.frames());
        assert_eq!(
            whole.matches("not estimated (none)").count(),
            all,
            "{whole}"
        );
    }
}
