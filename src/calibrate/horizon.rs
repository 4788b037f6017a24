//! The horizon from height constancy: every person keeps one height as they
//! walk, so the right horizon is the one under which each track's
//! cross-ratio heights (METHOD.md §5) stay the same along its path.
//!
//! With the principal point on the perpendicular from the vertical
//! vanishing point `v` to the horizon (the model's assumption), the horizon
//! has one unknown once `v` is known: its distance `d` from the principal
//! point. For a candidate `d`, each anchor's height relative to the camera
//! (`ViewGeometry::height_ratio`) follows, each track's heights are
//! compared with their mean, and the differences are turned into pixels of
//! image extent (where the measurement noise lives). `d` minimises their
//! robust sum: a log-spaced grid over every plausible horizon minimising
//! the median absolute residual (least median of squares: finds the basin
//! even when a few anchors are gross), then golden-section search, twice,
//! on Tukey's biweight at the noise scale learnt from the residuals.
//!
//! Why the median for the global pass: a least-squares grid was led away
//! by a handful of anchors whose head lies near or beyond the true
//! horizon (a region joining a person to something above them): their
//! height ratios are huge there and shrink as the horizon recedes, so the
//! squared cost fell all the way to the farthest candidate and the local
//! Tukey passes, searching around it, could not come back (126 live runs
//! at update interval 8: two calibrations lost, bench/RESULTS.md).
//!
//! Why not the paper's construction alone (METHOD.md §4: the head–head and
//! foot–foot lines of two observations meet on the horizon)? One pair's
//! intersection is a ratio of small differences of image extents; with the
//! few pixels of noise of live silhouettes its error has heavy tails and a
//! bias (measured on `sim:plaza`: pairs gave `d` = 95 px for a true 222 px
//! from the same points with live-sized noise, this fit 209 px; see
//! bench/RESULTS.md). This fit uses every anchor of a track at once, which
//! is the same geometric fact — constant height along a track — measured
//! with all the data.

use super::geometry::{golden, Anchor, ViewGeometry};

/// Log-spaced candidate horizons of the global (median) grid.
const GRID: usize = 64;

/// Candidates of the robust passes, between half and twice the current `d`.
const LOCAL_GRID: usize = 16;

/// Floor of the residual scale, pixels: exact data must not make the
/// robust loss narrower than the grid can resolve.
const MIN_SCALE_PX: f64 = 0.25;

/// Farthest horizon searched, in multiples of the image's half size
/// (tilt near 90° puts it far outside the image).
const FARTHEST: f64 = 200.0;

/// Fewest anchors of a track that take part.
pub const MIN_TRACK_ANCHORS: usize = 3;

/// The fitted horizon.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonFit {
    /// Horizon distance from the principal point (on the side away from
    /// `v`), pixels.
    pub d: f64,
    /// Its standard deviation, pixels (from the cost's curvature).
    pub sigma: f64,
    /// Tracks that took part.
    pub tracks: usize,
    /// Anchors that took part.
    pub anchors: usize,
    /// Robust standard deviation of the extent residuals, pixels.
    pub scale_px: f64,
}

/// The anchors of one track: `anchors[start..end]`, only those flagged.
struct Groups<'a> {
    track_of: &'a [u16],
    inlier: &'a [bool],
}

impl Groups<'_> {
    /// Calls `f(start, end)` for every run of anchors of one track with at
    /// least [`MIN_TRACK_ANCHORS`] inliers.
    fn each(&self, mut f: impl FnMut(usize, usize)) {
        let n = self.track_of.len();
        let mut start = 0;
        while start < n {
            let mut end = start;
            while end < n && self.track_of[end] == self.track_of[start] {
                end += 1;
            }
            let k = self.inlier[start..end].iter().filter(|&&x| x).count();
            if k >= MIN_TRACK_ANCHORS {
                f(start, end);
            }
            start = end;
        }
    }
}

/// Calls `f(residual_px)` for every anchor taking part, under horizon `d`:
/// its extent less the extent its track's median height would give there.
/// `ratios` is scratch of two `f64` per anchor (each anchor's ratio is
/// computed once, kept for the residual while a copy is sorted for the
/// median). Returns the number of tracks
/// whose median height ratio is not physical (at or below zero), which the
/// caller penalises.
fn residuals(
    anchors: &[Anchor],
    groups: &Groups<'_>,
    g: &ViewGeometry,
    ratios: &mut [f64],
    mut f: impl FnMut(f64),
) -> usize {
    let mut bad = 0;
    // The view's constants once for all the anchors (same ratios).
    let g = g.ratio_frame();
    let (ratios, kept) = ratios.split_at_mut(anchors.len());
    groups.each(|start, end| {
        let mut k = 0usize;
        for i in start..end {
            if groups.inlier[i] {
                // A ratio is finite when there is one: NaN marks none.
                let r = g.height_ratio(&anchors[i].head_foot());
                kept[i] = r.unwrap_or(f64::NAN);
                if let Some(r) = r {
                    ratios[start + k] = r;
                    k += 1;
                }
            }
        }
        if k < MIN_TRACK_ANCHORS {
            bad += 1;
            return;
        }
        // The median: a track's few frames cut by an occluder or merged
        // with a neighbour do not move its height.
        let Some(mid) = super::median(&mut ratios[start..start + k]) else {
            bad += 1;
            return;
        };
        if mid <= 1e-3 {
            bad += 1;
            return;
        }
        for i in start..end {
            let r = kept[i];
            if groups.inlier[i] && !r.is_nan() {
                f(anchors[i].extent() * (r - mid) / mid);
            }
        }
    });
    bad
}

/// The median absolute residual under horizon `d` (`out`: scratch for the
/// absolute residuals, as many as fit): how many residuals there were, their
/// median (0 with none), and the number of unphysical tracks
/// ([`residuals`]).
fn median_abs_residual(
    anchors: &[Anchor],
    groups: &Groups<'_>,
    g0: &ViewGeometry,
    d: f64,
    ratios: &mut [f64],
    out: &mut [f64],
) -> (usize, f64, usize) {
    let mut m = 0usize;
    let g = ViewGeometry { d, ..*g0 };
    let bad = residuals(anchors, groups, &g, ratios, |x| {
        if m < out.len() {
            out[m] = x.abs();
            m += 1;
        }
    });
    if m == 0 {
        return (0, 0.0, bad);
    }
    let (_, med, _) = out[..m].select_nth_unstable_by(m / 2, |a, b| a.total_cmp(b));
    (m, *med, bad)
}

/// Tukey's biweight loss of residual `x` at cut-off `c`: `x²/2` near zero,
/// bounded by `c²/6` (a gross outlier costs that whatever its size).
fn tukey(x: f64, c: f64) -> f64 {
    let u = x / c;
    if u.abs() >= 1.0 {
        c * c / 6.0
    } else {
        c * c / 6.0 * (1.0 - (1.0 - u * u).powi(3))
    }
}

/// Tukey's biweight tuning constant.
const TUKEY: f64 = 4.685;

/// Robust cost of horizon `d` (Tukey at cut-off `c` over the extent
/// residuals) plus a large penalty per track that `d` makes unphysical.
fn cost(
    anchors: &[Anchor],
    groups: &Groups<'_>,
    g0: &ViewGeometry,
    d: f64,
    c: f64,
    ratios: &mut [f64],
) -> f64 {
    let g = ViewGeometry { d, ..*g0 };
    let mut sum = 0.0;
    let bad = residuals(anchors, groups, &g, ratios, |x| sum += tukey(x, c));
    sum + bad as f64 * 1e9
}

/// Minimum of the cost over `n` log-spaced points between `lo` and `hi`,
/// refined by golden-section search between the neighbours of the best.
fn search(lo: f64, hi: f64, n: usize, f: impl Fn(f64) -> f64) -> f64 {
    let (a, b) = (libm::log(lo), libm::log(hi));
    let at = |i: usize| libm::exp(a + (b - a) * i as f64 / (n - 1) as f64);
    let mut best = (f64::INFINITY, 0usize);
    for i in 0..n {
        let c = f(at(i));
        if c < best.0 {
            best = (c, i);
        }
    }
    let i = best.1;
    let (l, h) = (at(i.saturating_sub(1)), at((i + 1).min(n - 1)));
    let x = libm::exp(golden(libm::log(l), libm::log(h), |u| f(libm::exp(u))));
    if f(x) <= best.0 {
        x
    } else {
        at(i)
    }
}

/// Fits the horizon distance for the vertical vanishing point of `g0`
/// (its `d` is ignored). `anchors` are grouped by track (`track_of`, equal
/// values contiguous); only anchors flagged in `inlier` take part.
/// `scratch` holds three `f64` per anchor. `half_size` is the image's half
/// size in pixels (the grid's unit). `None` with fewer than two tracks of
/// [`MIN_TRACK_ANCHORS`] anchors, or when no candidate is physical.
pub fn fit_horizon(
    anchors: &[Anchor],
    track_of: &[u16],
    inlier: &[bool],
    g0: &ViewGeometry,
    half_size: f64,
    scratch: &mut [f64],
) -> Option<HorizonFit> {
    let n = anchors.len().min(track_of.len()).min(inlier.len());
    let groups = Groups {
        track_of: &track_of[..n],
        inlier: &inlier[..n],
    };
    let anchors = &anchors[..n];
    let (mut tracks, mut used) = (0usize, 0usize);
    // Every foot must be below the horizon: D(foot) = t + d > 0.
    let axis = g0.axis();
    let mut lowest_t = f64::INFINITY;
    groups.each(|s, e| {
        tracks += 1;
        for (&inlier, a) in groups.inlier[s..e].iter().zip(&anchors[s..e]) {
            if inlier {
                used += 1;
                let f = a.foot;
                let t = (f[0] - g0.p[0]) * axis[0] + (f[1] - g0.p[1]) * axis[1];
                lowest_t = lowest_t.min(t);
            }
        }
    });
    if tracks < 2 {
        return None;
    }
    let lo = (-lowest_t + 0.5).max(0.01 * half_size);
    let hi = FARTHEST * half_size;
    if !(lo < hi) {
        return None;
    }
    if scratch.len() < 3 * n {
        return None;
    }
    let (ratios, absres) = scratch.split_at_mut(2 * n);
    // search() needs a shared closure; the ratio scratch lives in a cell.
    let cell = core::cell::RefCell::new(ratios);
    let eval = |d: f64, c: f64| cost(anchors, &groups, g0, d, c, &mut cell.borrow_mut());
    // Median absolute extent residual under `d`, plus the unphysical
    // tracks' penalty (the absolute residuals live in a cell too).
    let absres = core::cell::RefCell::new(absres);
    let median_abs = |d: f64| {
        let a = &mut *absres.borrow_mut();
        match median_abs_residual(anchors, &groups, g0, d, &mut cell.borrow_mut(), a) {
            (0, _, _) => f64::INFINITY,
            (_, med, bad) => med + bad as f64 * 1e9,
        }
    };
    let mut d = search(lo, hi, GRID, median_abs);
    let absres = &mut *absres.borrow_mut();
    // Twice: the noise scale from the residuals at the current `d`, then
    // Tukey at that scale, searched around it (a redescending loss is
    // flat far from its minimum, so it refines; the median pass over
    // every plausible horizon finds the basin).
    let mut scale = 0.0;
    for _ in 0..2 {
        let (m, med, _) =
            median_abs_residual(anchors, &groups, g0, d, &mut cell.borrow_mut(), absres);
        if m < 2 * MIN_TRACK_ANCHORS {
            return None;
        }
        scale = (1.4826 * med).max(MIN_SCALE_PX);
        let c = TUKEY * scale;
        d = search((0.5 * d).max(lo), (2.0 * d).min(hi), LOCAL_GRID, |x| {
            eval(x, c)
        });
    }
    let c = TUKEY * scale;
    let c0 = eval(d, c);
    if !(c0 < 1e9) {
        return None;
    }
    // Curvature of the cost in d. Near the minimum Tukey's loss is x²/2,
    // so the cost is half the sum of squares: σ² ≈ s² / C''.
    let h = 0.02 * d;
    let cm = eval((d - h).max(lo), c);
    let cp = eval(d + h, c);
    let curv = (cp - 2.0 * c0 + cm) / (h * h);
    let sigma = if curv > 0.0 {
        (scale * scale / curv).sqrt()
    } else {
        f64::INFINITY
    };
    Some(HorizonFit {
        d,
        sigma,
        tracks,
        anchors: used,
        scale_px: scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::rng::Rng;

    /// Tracks of people walking straight lines in front of `cam`.
    fn walks(cam: &Camera, people: usize, noise: f64, rng: &mut Rng) -> (Vec<Anchor>, Vec<u16>) {
        let (mut a, mut t) = (Vec::new(), Vec::new());
        let mut id = 0u16;
        while (id as usize) < people {
            let h = 1.7 + 0.08 * rng.normal();
            let (x0, y0) = (-5.0 + 10.0 * rng.uniform(), 5.0 + 10.0 * rng.uniform());
            let th = core::f64::consts::TAU * rng.uniform();
            let mut k = 0;
            for s in 0..24 {
                let (x, y) = (
                    x0 + 0.4 * s as f64 * libm::cos(th),
                    y0 + 0.4 * s as f64 * libm::sin(th),
                );
                let (Some(f), Some(hd)) = (cam.project([x, y, 0.0]), cam.project([x, y, h])) else {
                    continue;
                };
                let inside = |p: [f64; 2]| p[0] > 2.0 && p[0] < 637.0 && p[1] > 2.0 && p[1] < 477.0;
                if !inside(f) || !inside(hd) {
                    continue;
                }
                let mut j =
                    |p: [f64; 2]| [p[0] + noise * rng.normal(), p[1] + noise * rng.normal()];
                a.push(Anchor {
                    head: j(hd),
                    foot: j(f),
                    motion: [0.0; 2],
                });
                t.push(id);
                k += 1;
            }
            if k > 0 {
                id += 1;
            }
        }
        (a, t)
    }

    #[test]
    fn recovers_the_horizon_of_known_cameras() {
        let mut rng = Rng::new(4);
        for (f, tilt, roll, hc) in [
            (620.0, 20.0, 1.5, 4.2),
            (560.0, 10.0, 0.0, 2.5),
            (650.0, 35.0, 1.0, 7.0),
            (330.0, 28.0, 5.0, 3.5),
        ] {
            let cam = Camera::centred(f, tilt, roll, hc, 640, 480);
            let truth = ViewGeometry::of_camera(&cam);
            let (a, t) = walks(&cam, 12, 1.0, &mut rng);
            let inl = vec![true; a.len()];
            let mut scratch = vec![0.0; 3 * a.len()];
            let fit = fit_horizon(&a, &t, &inl, &truth, 320.0, &mut scratch).unwrap();
            let rel = fit.d / truth.d - 1.0;
            assert!(
                rel.abs() < 0.03,
                "tilt {tilt}: d {:.1} vs {:.1} (sigma {:.1})",
                fit.d,
                truth.d,
                fit.sigma
            );
            // The stated uncertainty is of the right size.
            assert!(
                (fit.d - truth.d).abs() < 4.0 * fit.sigma + 0.5,
                "{fit:?} vs {}",
                truth.d
            );
            assert!(fit.tracks >= 10, "{fit:?}");
        }
    }

    #[test]
    fn a_track_cut_by_an_occluder_does_not_move_it() {
        let cam = Camera::centred(700.0, 25.0, 0.0, 4.6, 640, 480);
        let truth = ViewGeometry::of_camera(&cam);
        let (mut a, t) = walks(&cam, 10, 0.8, &mut Rng::new(9));
        // Every tenth anchor lost a third of its height (legs hidden).
        for x in a.iter_mut().step_by(10) {
            x.foot[1] -= 0.33 * (x.foot[1] - x.head[1]);
        }
        let inl = vec![true; a.len()];
        let mut scratch = vec![0.0; 3 * a.len()];
        let fit = fit_horizon(&a, &t, &inl, &truth, 320.0, &mut scratch).unwrap();
        assert!(
            (fit.d / truth.d - 1.0).abs() < 0.05,
            "{fit:?} vs {}",
            truth.d
        );
    }

    /// A region that joins a person to a pole or a streak above them puts
    /// the "head" at the top of the image. Under a low camera that head
    /// lies near or beyond the horizon, where a height ratio is huge and
    /// shrinks as the horizon moves away: a least-squares grid followed it
    /// to infinity (this test's low camera: `d` 160 times too far; seen
    /// live on `busy` and `plaza`). The median residual is not moved by a
    /// few such anchors.
    #[test]
    fn heads_at_the_image_top_do_not_take_it_away() {
        let mut rng = Rng::new(5);
        for (f, tilt, hc) in [(620.0, 20.0, 4.2), (1100.0, 30.0, 6.0), (560.0, 10.0, 2.5)] {
            let cam = Camera::centred(f, tilt, 1.0, hc, 640, 480);
            let truth = ViewGeometry::of_camera(&cam);
            let (mut a, t) = walks(&cam, 16, 1.5, &mut rng);
            // Two tracks of the sixteen, every third anchor.
            for (i, x) in a.iter_mut().enumerate() {
                if t[i] % 8 == 0 && i % 3 == 0 {
                    x.head[1] = 5.0;
                }
            }
            let inl = vec![true; a.len()];
            let mut scratch = vec![0.0; 3 * a.len()];
            let fit = fit_horizon(&a, &t, &inl, &truth, 320.0, &mut scratch).unwrap();
            assert!(
                (fit.d / truth.d - 1.0).abs() < 0.05,
                "tilt {tilt}: {fit:?} vs {}",
                truth.d
            );
        }
    }

    /// The paper's construction (METHOD.md §4): the head–head and foot–foot
    /// lines of two sightings of one person meet on the horizon; with the
    /// horizon perpendicular to `p→v`, each pair gives its distance `d`.
    /// The median over all well-separated pairs of a track's anchors is the
    /// robust summary compared with the consistency fit below.
    fn pairs_median(a: &[Anchor], t: &[u16], g: &ViewGeometry) -> f64 {
        let axis = g.axis();
        let along = |x: [f64; 2]| (x[0] - g.p[0]) * axis[0] + (x[1] - g.p[1]) * axis[1];
        let hom = |x: [f64; 2]| nalgebra::Vector3::new(x[0], x[1], 1.0);
        let mut ds = Vec::new();
        for i in 0..a.len() {
            for j in i + 1..a.len() {
                if t[i] != t[j] {
                    continue;
                }
                let sep = ((a[i].foot[0] - a[j].foot[0]).powi(2)
                    + (a[i].foot[1] - a[j].foot[1]).powi(2))
                .sqrt();
                if sep < 0.5 * (a[i].extent() + a[j].extent()) / 2.0 {
                    continue;
                }
                let x = hom(a[i].head)
                    .cross(&hom(a[j].head))
                    .cross(&hom(a[i].foot).cross(&hom(a[j].foot)));
                if x.z.abs() < 1e-12 {
                    continue;
                }
                ds.push(-along([x.x / x.z, x.y / x.z]));
            }
        }
        ds.sort_by(f64::total_cmp);
        ds[ds.len() / 2]
    }

    #[test]
    fn consistency_beats_the_paper_pairs_under_live_noise() {
        // 2.5 px per point is what single-frame silhouettes give after the
        // calibrator's 8-frame smoothing (bench/live_eval.rs).
        let mut rng = Rng::new(12);
        let (mut fit_err, mut pair_err) = (0.0, 0.0);
        for (f, tilt, hc) in [(620.0, 20.0, 4.2), (700.0, 25.0, 4.6), (650.0, 35.0, 7.0)] {
            let cam = Camera::centred(f, tilt, 1.0, hc, 640, 480);
            let truth = ViewGeometry::of_camera(&cam);
            let (a, t) = walks(&cam, 12, 2.5, &mut rng);
            let inl = vec![true; a.len()];
            let mut scratch = vec![0.0; 3 * a.len()];
            let fit = fit_horizon(&a, &t, &inl, &truth, 320.0, &mut scratch).unwrap();
            fit_err += (fit.d / truth.d - 1.0).abs();
            pair_err += (pairs_median(&a, &t, &truth) / truth.d - 1.0).abs();
        }
        assert!(
            fit_err / 3.0 < 0.04,
            "consistency fit off by {:.1} %",
            100.0 * fit_err / 3.0
        );
        assert!(
            pair_err > 1.5 * fit_err,
            "pairs {:.1} % vs fit {:.1} %",
            100.0 * pair_err / 3.0,
            100.0 * fit_err / 3.0
        );
    }

    #[test]
    fn one_track_is_not_enough() {
        let cam = Camera::centred(700.0, 25.0, 0.0, 4.6, 640, 480);
        let truth = ViewGeometry::of_camera(&cam);
        let (a, t) = walks(&cam, 1, 0.5, &mut Rng::new(1));
        let inl = vec![true; a.len()];
        let mut scratch = vec![0.0; 3 * a.len()];
        assert_eq!(fit_horizon(&a, &t, &inl, &truth, 320.0, &mut scratch), None);
    }
}
