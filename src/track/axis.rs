//! The body axis of a person's silhouette: the line through the centres of
//! its rows, fitted robustly, with its lean corrected for the body's shape
//! ([`body_axis`]). Head and foot points are taken on it.
//!
//! Why: the paper's head point is the top-most region pixel and its foot
//! the mean of the bottom-most ten (eq. 5). Their rows are well defined,
//! but their columns are not: the top of a head is a flat run of several
//! pixels, and the lowest ten pixels of a walking person are often one
//! foot, half a stride off the body's centre. Measured on the simulated
//! scenes (`bench/live_eval.rs`) that made the head–foot line of a single
//! frame lean by 7° (standard deviation) — as much as the true verticals
//! fan out across the whole image, which is the signal the vanishing point
//! is fitted from. Every row of the silhouette is a measurement of the
//! axis; fitted through all of them (with rows far off the line, a swinging
//! arm or a shadow at the feet, down-weighted), the direction is several
//! times steadier, and head and foot keep the rows of eq. 5.

use crate::detect::Run;

/// The fitted axis `x = x_mid + slope·(y − y_mid)`, pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Axis {
    /// Mean row of the rows used.
    pub y_mid: f64,
    /// Axis column at `y_mid`.
    pub x_mid: f64,
    /// Columns per row (0 for an axis straight down the image).
    pub slope: f64,
}

impl Axis {
    /// The axis column at row `y`.
    pub fn x_at(&self, y: f64) -> f64 {
        self.x_mid + self.slope * (y - self.y_mid)
    }
}

/// Passes of iteratively reweighted least squares after the plain fit.
const REWEIGHT_PASSES: usize = 3;

/// Rows whose centre is farther than this many mean absolute residuals
/// from the previous fit get no weight (Tukey's biweight cut-off).
const CUTOFF: f64 = 3.0;

/// Fewest rows worth a fit.
const MIN_ROWS: usize = 8;

/// Calls `f(y, centre)` for every row of `runs` (sorted by row, as
/// [`crate::detect::RegionSet::runs_of`] gives them), with the row's
/// pixel-weighted mean column.
fn for_each_row(runs: &[Run], mut f: impl FnMut(f64, f64)) {
    let mut i = 0;
    while i < runs.len() {
        let y = runs[i].y;
        let (mut n, mut sx2) = (0u64, 0u64);
        while i < runs.len() && runs[i].y == y {
            let r = runs[i];
            let len = u64::from(r.x1 - r.x0) + 1;
            n += len;
            sx2 += len * (u64::from(r.x0) + u64::from(r.x1));
            i += 1;
        }
        f(f64::from(y), sx2 as f64 / (2.0 * n as f64));
    }
}

/// Weighted least squares of row centre on row, `w(y, centre)` the weight.
fn fit(runs: &[Run], w: impl Fn(f64, f64) -> f64) -> Option<(Axis, usize)> {
    let (mut sw, mut sy, mut sx, mut syy, mut sxy, mut rows) = (0.0, 0.0, 0.0, 0.0, 0.0, 0);
    for_each_row(runs, |y, x| {
        let k = w(y, x);
        if k > 0.0 {
            sw += k;
            sy += k * y;
            sx += k * x;
            syy += k * y * y;
            sxy += k * x * y;
            rows += 1;
        }
    });
    if rows < MIN_ROWS || sw <= 0.0 {
        return None;
    }
    let (ym, xm) = (sy / sw, sx / sw);
    let vy = syy / sw - ym * ym;
    if vy <= 1.0 {
        return None;
    }
    let slope = (sxy / sw - xm * ym) / vy;
    Some((
        Axis {
            y_mid: ym,
            x_mid: xm,
            slope,
        },
        rows,
    ))
}

/// The line through the row centres of a region's run-length mask
/// (robust: rows far off it, a swinging arm or a shadow at the feet, are
/// down-weighted); `None` when it has fewer than a handful of rows.
pub fn row_axis(runs: &[Run]) -> Option<Axis> {
    let (mut axis, _) = fit(runs, |_, _| 1.0)?;
    for _ in 0..REWEIGHT_PASSES {
        // Scale of the residuals about the current fit.
        let (mut sum, mut n) = (0.0, 0usize);
        for_each_row(runs, |y, x| {
            sum += (x - axis.x_at(y)).abs();
            n += 1;
        });
        let scale = (sum / n.max(1) as f64).max(0.5) * CUTOFF;
        let prev = axis;
        match fit(runs, |y, x| {
            let u = (x - prev.x_at(y)) / scale;
            if u.abs() >= 1.0 {
                0.0
            } else {
                (1.0 - u * u).powi(2)
            }
        }) {
            Some((a, _)) => axis = a,
            None => break,
        }
    }
    Some(axis)
}

/// The body axis of a region's run-length mask: the row-centre line
/// ([`row_axis`]) with its lean corrected for the shape of the body
/// ([`width_profile_bias`]).
///
/// Why a correction: across a slanted shape whose width changes along
/// its length, the two ends of a horizontal cut lie at different heights
/// on the body, so its centre is off the axis toward the wider side. For
/// an ellipse the centres lie on the conjugate diameter and under-read
/// the lean by `k²`, the squared width-to-height ratio; for a strip they
/// are exact. Measured on PETS 2009 against the real calibration's
/// verticals, the uncorrected row centres under-read the lean by 19 %
/// (vertical vanishing point 20 % too far, tilt 2° low).
///
/// Why from the width profile and not the ellipse of the second moments
/// (the correction `1 / (1 − k²)` used until 2026-12-04): a walker is not
/// an ellipse. A stride or a swinging arm widens the second moments
/// without bending the row centres (legs apart are symmetric about the
/// axis), so that correction over-read the lean of the simulated walkers
/// and put the vertical vanishing point 5 % too near (f 4 % low over 42
/// runs). The profile measures the bend the centres actually have
/// (bench/RESULTS.md, "The body axis from the width profile").
pub fn body_axis(runs: &[Run]) -> Option<Axis> {
    let mut axis = row_axis(runs)?;
    if let Some(beta) = width_profile_bias(runs) {
        axis.slope /= 1.0 + beta.clamp(-MAX_BIAS, MAX_BIAS);
    }
    Some(axis)
}

/// Largest under- or over-read [`body_axis`] corrects: a blob whose
/// profile says more is no upright person, and the correction
/// `1 / (1 + β)` must stay bounded (at most ×2.5).
const MAX_BIAS: f64 = 0.6;

/// How far the row centres of `runs` misread the lean of the shape's own
/// axis: `β` in `slope of the centres = (1 + β) · slope of the axis`, for
/// a shape symmetric about a slightly slanted axis.
///
/// With half-width `b(y)` and `B = b²/2`, a horizontal cut of a shape
/// slanted by `φ` meets its two sides `2φ·b` apart along the axis, so its
/// centre is off the axis by `φ·B'(y)`; a line through the centres leans
/// by `φ·(1 + β)` with `β` the least-squares slope of `B'` on the row.
/// For an ellipse of width ratio `k`, `B' = −k²·(y − y_mid)`: `β = −k²`;
/// for a strip `β = 0`. `b` is half the row's pixel count, as the row
/// centre is the pixels' mean: two legs apart, each a strip, have centres
/// on the axis however wide the stride, and so does their count.
/// `B'` is a central difference over three consecutive rows; `None` with
/// too few such rows.
pub fn width_profile_bias(runs: &[Run]) -> Option<f64> {
    // (row, B) of the two rows before the current one.
    let mut before: Option<(f64, f64)> = None;
    let mut last = before;
    let (mut n, mut sy, mut sg, mut syy, mut syg) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut i = 0;
    while i < runs.len() {
        let y = runs[i].y;
        let mut width = 0u32;
        while i < runs.len() && runs[i].y == y {
            width += u32::from(runs[i].x1 - runs[i].x0) + 1;
            i += 1;
        }
        let half = 0.5 * f64::from(width);
        let row = (f64::from(y), 0.5 * half * half);
        if let (Some(a), Some(b)) = (before, last) {
            if row.0 - a.0 == 2.0 {
                let g = 0.5 * (row.1 - a.1);
                n += 1.0;
                sy += b.0;
                sg += g;
                syy += b.0 * b.0;
                syg += b.0 * g;
            }
        }
        before = last;
        last = Some(row);
    }
    if n < MIN_ROWS as f64 {
        return None;
    }
    let (my, mg) = (sy / n, sg / n);
    let vy = syy / n - my * my;
    (vy > 1.0).then(|| (syg / n - my * mg) / vy)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of a slanted bar `width` wide from row `y0` to `y1` whose
    /// centre moves `slope` columns per row, plus optional extra runs.
    fn bar(y0: u16, y1: u16, x_top: f64, slope: f64, width: u16) -> Vec<Run> {
        (y0..=y1)
            .map(|y| {
                let c = x_top + slope * f64::from(y - y0);
                let x0 = (c - f64::from(width) / 2.0).round() as u16;
                Run {
                    y,
                    x0,
                    x1: x0 + width - 1,
                }
            })
            .collect()
    }

    #[test]
    fn recovers_a_slanted_bar() {
        let runs = bar(10, 110, 50.0, 0.08, 9);
        let a = row_axis(&runs).unwrap();
        assert!((a.slope - 0.08).abs() < 0.005, "{a:?}");
        assert!((a.x_at(10.0) - 50.0).abs() < 0.6, "{a:?}");
    }

    #[test]
    fn a_side_blob_on_a_few_rows_does_not_tilt_it() {
        // A straight body with a shadow sticking out to the right over its
        // bottom eight rows (what the detector leaves at the feet).
        let mut runs = bar(0, 99, 40.0, 0.0, 12);
        for r in runs.iter_mut().skip(92) {
            r.x1 += 30;
        }
        let a = row_axis(&runs).unwrap();
        assert!(a.slope.abs() < 0.01, "{a:?}");
        assert!((a.x_at(99.0) - 40.0).abs() < 1.0, "{a:?}");
        // The plain least-squares fit is pulled over by the blob.
        let (plain, _) = fit(&runs, |_, _| 1.0).unwrap();
        assert!(plain.slope > 0.03, "{plain:?}");
    }

    #[test]
    fn two_legs_give_the_centre_between_them() {
        let mut runs = bar(0, 59, 30.0, 0.0, 10);
        for y in 60..100u16 {
            // Legs apart by a growing stride.
            let s = (y - 60) / 4;
            runs.push(Run {
                y,
                x0: 25 - s,
                x1: 28 - s,
            });
            runs.push(Run {
                y,
                x0: 32 + s,
                x1: 35 + s,
            });
        }
        let a = body_axis(&runs).unwrap();
        assert!(
            a.slope.abs() < 0.01 && (a.x_at(99.0) - 30.0).abs() < 0.6,
            "{a:?}"
        );
    }

    /// Runs of an ellipse with semi-axes `b` (across) and `a` (along),
    /// its long axis leaning `angle` radians from the image vertical.
    fn ellipse(cx: f64, cy: f64, a: f64, b: f64, angle: f64) -> Vec<Run> {
        let (s, c) = (libm::sin(angle), libm::cos(angle));
        let mut runs = Vec::new();
        for y in (cy - a - 2.0) as u16..=(cy + a + 2.0) as u16 {
            let mut start = None;
            for x in 0..=400u16 {
                let (dx, dy) = (f64::from(x) - cx, f64::from(y) - cy);
                // Into the ellipse's own frame (u across, v along).
                let (u, v) = (dx * c - dy * s, dx * s + dy * c);
                let inside = (u / b).powi(2) + (v / a).powi(2) <= 1.0;
                match (inside, start) {
                    (true, None) => start = Some(x),
                    (false, Some(x0)) => {
                        runs.push(Run { y, x0, x1: x - 1 });
                        start = None;
                    }
                    _ => {}
                }
            }
        }
        runs
    }

    #[test]
    fn the_lean_of_an_elliptical_body_is_not_under_read() {
        // 1:3 ellipse leaning 8°: row centres lie on the conjugate
        // diameter, about k² = 1/9 less tilted; the corrected axis is not.
        let angle = 8f64.to_radians();
        let runs = ellipse(200.0, 100.0, 60.0, 20.0, angle);
        let truth = libm::tan(angle);
        let rows = row_axis(&runs).unwrap();
        let body = body_axis(&runs).unwrap();
        assert!(
            (rows.slope / truth - (1.0 - 1.0 / 9.0)).abs() < 0.03,
            "rows {} vs {truth}",
            rows.slope
        );
        assert!(
            (body.slope / truth - 1.0).abs() < 0.03,
            "{} vs {truth}",
            body.slope
        );
    }

    #[test]
    fn the_lean_of_a_wide_strip_is_taken_as_it_is() {
        // A strip 30 px wide and 101 rows tall leaning 0.08 column per
        // row: its row centres are on its axis. The ellipse of its second
        // moments (k² ≈ 0.09) would have over-read the lean by 10 %.
        let runs = bar(10, 110, 50.0, 0.08, 30);
        let beta = width_profile_bias(&runs).unwrap();
        assert!(beta.abs() < 0.01, "{beta}");
        let a = body_axis(&runs).unwrap();
        assert!((a.slope - 0.08).abs() < 0.002, "{a:?}");
    }

    #[test]
    fn a_stride_does_not_bend_the_lean() {
        // A slanted walker: a torso strip, then two legs moving apart
        // (each a strip, symmetric about the axis) down to the feet.
        let slope = -0.1;
        let mut runs = bar(0, 59, 60.0, slope, 12);
        for y in 60..110u16 {
            let c = 60.0 + slope * f64::from(y);
            let s = f64::from(y - 60) / 3.0;
            for leg in [c - 3.0 - s, c + 3.0 + s] {
                let x0 = (leg - 2.0).round() as u16;
                runs.push(Run { y, x0, x1: x0 + 3 });
            }
        }
        let beta = width_profile_bias(&runs).unwrap();
        assert!(beta.abs() < 0.02, "{beta}");
        let a = body_axis(&runs).unwrap();
        assert!((a.slope - slope).abs() < 0.004, "{a:?}");
    }

    #[test]
    fn too_few_rows_give_none() {
        assert_eq!(body_axis(&bar(0, 5, 10.0, 0.0, 4)), None);
        assert_eq!(body_axis(&[]), None);
    }
}
