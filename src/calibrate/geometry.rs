//! Pure single-view geometry: the vertical vanishing point from head–foot
//! lines, the horizon from head–head/foot–foot intersections, the camera of
//! paper eq. 3 and the cross-ratio height of METHOD.md §5–6.
//!
//! Everything works in *normalised* coordinates (pixel minus principal
//! point, divided by half the larger image side) so that the homogeneous
//! least-squares problems are well conditioned (Hartley normalisation) and
//! a vanishing point at infinity is an ordinary homogeneous vector.
//!
//! Model assumptions (the paper's and METHOD.md's): square pixels, zero
//! skew, principal point at the image centre, no lens distortion, flat
//! ground, upright people. Under them the principal point lies on the
//! perpendicular from the vertical vanishing point `v` to the horizon, so
//! once `v` is known the horizon has a single unknown, its distance `d`
//! from the principal point; `f² = d·|v−p|` (eq. 3).

use crate::camera::Camera;
use crate::rng::Rng;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// One upright person seen in one frame: head-top and foot image points, pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeadFoot {
    /// Head point `[u, v]`.
    pub head: [f64; 2],
    /// Foot point `[u, v]`.
    pub foot: [f64; 2],
}

impl HeadFoot {
    /// Image extent head to foot, pixels.
    pub fn extent(&self) -> f64 {
        dist(self.head, self.foot)
    }
}

/// Pixel ↔ normalised coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normaliser {
    /// Principal point, pixels.
    pub p: [f64; 2],
    /// Pixels per normalised unit.
    pub s: f64,
}

impl Normaliser {
    /// For a `width`×`height` image with the principal point at its centre.
    pub fn for_image(width: usize, height: usize) -> Self {
        Normaliser {
            p: [(width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0],
            s: (width.max(height) as f64 / 2.0).max(1.0),
        }
    }
    /// Homogeneous normalised point of a pixel.
    pub fn point(&self, px: [f64; 2]) -> Vector3<f64> {
        Vector3::new(
            (px[0] - self.p[0]) / self.s,
            (px[1] - self.p[1]) / self.s,
            1.0,
        )
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

/// Distance (normalised units) of a finite homogeneous point `x` (z = 1)
/// from the line through the finite point `m` and the homogeneous `v`.
fn residual_to_vp(v: &Vector3<f64>, m: &Vector3<f64>, x: &Vector3<f64>) -> f64 {
    let l = m.cross(v);
    let n = (l.x * l.x + l.y * l.y).sqrt();
    if n < 1e-300 {
        return 0.0;
    }
    (l.dot(x) / n).abs()
}

/// Robust fit of the vertical vanishing point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VvpFit {
    /// Homogeneous normalised point, unit norm, `z >= 0` (the image side
    /// reached by walking from head to foot when finite).
    pub v: Vector3<f64>,
    /// Observations within the inlier threshold.
    pub inliers: usize,
    /// Root-mean-square head distance from its line to `v`, pixels (inliers).
    pub rms_px: f64,
}

/// Settings of the vanishing point RANSAC.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VvpParams {
    /// Inlier threshold: head distance from the line through the
    /// head–foot midpoint and `v`, pixels.
    pub inlier_px: f64,
    /// RANSAC hypotheses.
    pub iterations: usize,
}

/// Vertical vanishing point from head–foot lines: RANSAC over pairs of
/// lines, then iteratively reweighted homogeneous least squares on the
/// inliers (the weights turn the algebraic distance of `v` from each line
/// into the pixel distance of the head from the line `midpoint → v`).
/// `inlier` is scratch of `obs.len()` flags and ends marking the inliers.
/// `None` with fewer than 8 usable observations or no consensus.
pub fn fit_vvp(
    obs: &[HeadFoot],
    norm: &Normaliser,
    params: &VvpParams,
    rng: &mut Rng,
    inlier: &mut [bool],
) -> Option<VvpFit> {
    let n = obs.len().min(inlier.len());
    if n < 8 {
        return None;
    }
    let tau = params.inlier_px / norm.s;
    let line = |o: &HeadFoot| {
        let l = norm.point(o.head).cross(&norm.point(o.foot));
        let k = (l.x * l.x + l.y * l.y).sqrt();
        if k > 1e-12 {
            l / k
        } else {
            l
        }
    };
    let mid =
        |o: &HeadFoot| norm.point([0.5 * (o.head[0] + o.foot[0]), 0.5 * (o.head[1] + o.foot[1])]);
    let count = |v: &Vector3<f64>| {
        let mut c = 0usize;
        for o in &obs[..n] {
            if residual_to_vp(v, &mid(o), &norm.point(o.head)) <= tau {
                c += 1;
            }
        }
        c
    };
    let mut best: Option<(usize, Vector3<f64>)> = None;
    for _ in 0..params.iterations {
        let i = rng.below(n);
        let j = rng.below(n);
        if i == j {
            continue;
        }
        let v = line(&obs[i]).cross(&line(&obs[j]));
        let k = v.norm();
        if k < 1e-12 {
            continue;
        }
        let v = v / k;
        let c = count(&v);
        if best.map_or(true, |(bc, _)| c > bc) {
            best = Some((c, v));
        }
    }
    let (_, mut v) = best?;
    // Refinement: minimise sum_i (w_i l_i·V)^2 over unit V, w_i from the last V.
    for _ in 0..4 {
        let mut m = Matrix3::zeros();
        let mut used = 0usize;
        for (o, flag) in obs[..n].iter().zip(inlier.iter_mut()) {
            let mi = mid(o);
            *flag = residual_to_vp(&v, &mi, &norm.point(o.head)) <= tau;
            if !*flag {
                continue;
            }
            let l = line(o);
            // |l·V| is the distance of V from l scaled by V's homogeneous
            // weight; dividing by |V_xy - m V_z| gives the angle, and the
            // half extent turns the angle into a head displacement.
            let gap = ((v.x - mi.x * v.z).powi(2) + (v.y - mi.y * v.z).powi(2)).sqrt();
            let half = 0.5 * o.extent() / norm.s;
            let w = half / gap.max(1e-9);
            m += (w * w) * (l * l.transpose());
            used += 1;
        }
        if used < 2 {
            return None;
        }
        let eig = SymmetricEigen::new(m);
        let (mut k, mut lo) = (0, f64::INFINITY);
        for (idx, &e) in eig.eigenvalues.iter().enumerate() {
            if e < lo {
                lo = e;
                k = idx;
            }
        }
        v = eig.eigenvectors.column(k).into_owned();
    }
    if v.z < 0.0 {
        v = -v;
    }
    // The algebraic solution above is biased by noise in the line
    // coefficients (errors in variables push `v` outward); finish with the
    // geometric cost itself, the summed squared head distances from the
    // lines `midpoint → v`, by coordinate descent in (direction, inverse
    // distance), which stays regular when `v` is at infinity.
    let cost = |phi: f64, w: f64| {
        let v = Vector3::new(libm::sin(phi), libm::cos(phi), w);
        let mut c = 0.0;
        for (o, &flag) in obs[..n].iter().zip(inlier.iter()) {
            if flag {
                let r = residual_to_vp(&v, &mid(o), &norm.point(o.head));
                c += r * r;
            }
        }
        c
    };
    let rho = (v.x * v.x + v.y * v.y).sqrt();
    if rho > 1e-12 {
        let (mut phi, mut w) = (libm::atan2(v.x, v.y), v.z / rho);
        for round in 0..3 {
            let k = 1.0 / f64::from(1 + round);
            phi = golden(phi - 0.02 * k, phi + 0.02 * k, |x| cost(x, w));
            let span = 0.2 * w.abs().max(0.05) * k;
            w = golden(w - span, w + span, |x| cost(phi, x));
        }
        let refined = Vector3::new(libm::sin(phi), libm::cos(phi), w).normalize();
        if cost(phi, w) <= cost(libm::atan2(v.x, v.y), v.z / rho) {
            v = if refined.z < 0.0 { -refined } else { refined };
        }
    }
    let (mut inl, mut ss) = (0usize, 0.0);
    for (o, flag) in obs[..n].iter().zip(inlier.iter_mut()) {
        let r = residual_to_vp(&v, &mid(o), &norm.point(o.head));
        *flag = r <= tau;
        if *flag {
            inl += 1;
            ss += r * r;
        }
    }
    (inl >= 2).then(|| VvpFit {
        v,
        inliers: inl,
        rms_px: (ss / inl as f64).sqrt() * norm.s,
    })
}

/// Minimum of a unimodal `f` on `[a, b]` by golden-section search (40 steps).
pub fn golden(mut a: f64, mut b: f64, f: impl Fn(f64) -> f64) -> f64 {
    let phi = 0.618_033_988_749_895;
    let mut x1 = b - phi * (b - a);
    let mut x2 = a + phi * (b - a);
    let (mut f1, mut f2) = (f(x1), f(x2));
    for _ in 0..40 {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - phi * (b - a);
            f1 = f(x1);
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + phi * (b - a);
            f2 = f(x2);
        }
    }
    0.5 * (a + b)
}

/// One horizon measurement from two observations of the same person:
/// the intersection of the head–head and foot–foot lines projected on the
/// axis from `p` toward `v`, with what its uncertainty depends on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OffsetSample {
    /// Horizon distance from `p` on the side away from `v`, normalised units.
    pub d: f64,
    /// |g_b − g_a|: difference of the two image extents along the axis.
    pub dg: f64,
    /// Foot positions along the axis.
    pub t: [f64; 2],
    /// Head/foot noise, normalised units.
    pub noise: f64,
}

impl OffsetSample {
    /// Standard deviation of `d` if the true offset is `d_ref`.
    ///
    /// Error model: image extents `g` along the axis grow with the foot's
    /// distance `D = t + d` below the horizon, `g ∝ D`; two extents give
    /// `d = (g1 t2 − g2 t1) / (g2 − g1)`, whose sensitivity to extent noise
    /// is `D_k / (g2 − g1)`. Evaluating `D` at a common `d_ref` rather than
    /// at each sample's own `d` avoids favouring samples that happen to
    /// come out small.
    pub fn sigma(&self, d_ref: f64) -> f64 {
        let (da, db) = (self.t[0] + d_ref, self.t[1] + d_ref);
        self.noise * (da * da + db * db).sqrt() / self.dg
    }
}

/// The horizon measurement of a pair (`None` when the two lines are
/// parallel along the axis, or the positions barely differ in depth).
/// `axis` is the unit direction from `p` to `v` (normalised coordinates);
/// `noise_px` the assumed head/foot noise.
pub fn offset_sample(
    a: &HeadFoot,
    b: &HeadFoot,
    norm: &Normaliser,
    axis: [f64; 2],
    noise_px: f64,
) -> Option<OffsetSample> {
    let (ha, fa) = (norm.point(a.head), norm.point(a.foot));
    let (hb, fb) = (norm.point(b.head), norm.point(b.foot));
    let x = ha.cross(&hb).cross(&fa.cross(&fb));
    let along = x.x * axis[0] + x.y * axis[1];
    if x.z.abs() < 1e-12 * along.abs().max(1e-300) {
        return None;
    }
    let d = -along / x.z;
    let t = |p: &Vector3<f64>| p.x * axis[0] + p.y * axis[1];
    let (ga, gb) = (t(&fa) - t(&ha), t(&fb) - t(&hb));
    let dg = (gb - ga).abs();
    if dg < 1e-9 || !d.is_finite() {
        return None;
    }
    Some(OffsetSample {
        d,
        dg,
        t: [t(&fa), t(&fb)],
        noise: noise_px / norm.s,
    })
}

/// Robust weighted estimate of the horizon offset from pair samples:
/// RANSAC over candidate values (score: summed inverse variances of the
/// samples within 3σ of the candidate), then inverse-variance weighted mean
/// of the inliers, repeated until stable. Returns `(d, sigma_d, inliers)`.
pub fn fit_offset(
    samples: &[OffsetSample],
    rng: &mut Rng,
    iterations: usize,
) -> Option<(f64, f64, usize)> {
    if samples.len() < 3 {
        return None;
    }
    let score = |c: f64| {
        let mut s = 0.0;
        for x in samples {
            let sg = x.sigma(c);
            if (x.d - c).abs() <= 3.0 * sg {
                s += 1.0 / (sg * sg);
            }
        }
        s
    };
    let mut best = (f64::NEG_INFINITY, 0.0);
    for _ in 0..iterations.min(samples.len() * 2) {
        let c = samples[rng.below(samples.len())].d;
        if c <= 0.0 {
            continue;
        }
        let s = score(c);
        if s > best.0 {
            best = (s, c);
        }
    }
    if !best.0.is_finite() {
        return None;
    }
    let mut d = best.1;
    let mut out = None;
    for _ in 0..8 {
        let (mut sw, mut swd, mut k) = (0.0, 0.0, 0usize);
        for x in samples {
            let sg = x.sigma(d);
            if (x.d - d).abs() <= 3.0 * sg {
                let w = 1.0 / (sg * sg);
                sw += w;
                swd += w * x.d;
                k += 1;
            }
        }
        if k < 3 || sw <= 0.0 {
            break;
        }
        d = swd / sw;
        out = Some((d, (1.0 / sw).sqrt(), k));
    }
    out.filter(|o| o.0 > 0.0)
}

/// Why the closed forms of eq. 3 cannot be trusted for this view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Degeneracy {
    /// The camera is nearly level: the vertical vanishing point is at (or
    /// near) infinity, so focal length and tilt are undetermined.
    NearLevel,
    /// The camera looks nearly straight down: the horizon lies far outside
    /// the image and head–head/foot–foot lines are nearly parallel.
    NearVertical,
    /// The vertical vanishing point lies above the image centre (a camera
    /// looking up, or people not upright): outside the model.
    Upward,
}

impl Degeneracy {
    /// What the installer should be told.
    pub fn describe(self) -> &'static str {
        match self {
            Degeneracy::NearLevel => {
                "camera nearly level: the vertical vanishing point is near infinity, focal length and tilt are poorly determined"
            }
            Degeneracy::NearVertical => {
                "camera looks nearly straight down: the horizon is far outside the image, focal length is poorly determined"
            }
            Degeneracy::Upward => {
                "vertical vanishing point above the image centre: not a downward-looking camera over a flat floor"
            }
        }
    }
}

/// Vanishing geometry in pixels: everything heights need.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewGeometry {
    /// Principal point, pixels.
    pub p: [f64; 2],
    /// Vertical vanishing point, pixels (finite).
    pub v: [f64; 2],
    /// Horizon distance from `p` (on the side away from `v`), pixels.
    pub d: f64,
}

impl ViewGeometry {
    /// From a finite normalised vanishing point and a normalised offset.
    /// `None` when `v` is at infinity (see [`Degeneracy::NearLevel`]).
    pub fn from_normalised(v: &Vector3<f64>, d: f64, norm: &Normaliser) -> Option<Self> {
        if v.z.abs() < 1e-9 {
            return None;
        }
        let g = ViewGeometry {
            p: norm.p,
            v: [
                norm.p[0] + norm.s * v.x / v.z,
                norm.p[1] + norm.s * v.y / v.z,
            ],
            d: d * norm.s,
        };
        (g.r() > 1e-6 && g.d > 0.0 && g.v[0].is_finite() && g.v[1].is_finite()).then_some(g)
    }

    /// The exact geometry of a known camera (tests, simulation truth).
    pub fn of_camera(cam: &Camera) -> Self {
        let v = cam.vertical_vanishing_point();
        let d = crate::camera::line_distance(cam.horizon(), cam.principal).abs();
        ViewGeometry {
            p: cam.principal,
            v,
            d,
        }
    }

    /// |v − p|, pixels.
    pub fn r(&self) -> f64 {
        dist(self.v, self.p)
    }
    /// Unit axis from `p` toward `v`.
    pub fn axis(&self) -> [f64; 2] {
        let r = self.r();
        [(self.v[0] - self.p[0]) / r, (self.v[1] - self.p[1]) / r]
    }
    /// Focal length from eq. 3, `f² = d(p, l)·|v − p|`, pixels.
    pub fn focal(&self) -> f64 {
        (self.d * self.r()).sqrt()
    }
    /// Tilt (downward pitch), radians: `tan θ = f / |v − p|`.
    pub fn tilt(&self) -> f64 {
        libm::atan2(self.focal(), self.r())
    }
    /// Roll, radians, positive when the horizon rises to the right:
    /// `atan2(v_x, v_y)` relative to `p` (see `camera`'s sign note).
    pub fn roll(&self) -> f64 {
        libm::atan2(self.v[0] - self.p[0], self.v[1] - self.p[1])
    }
    /// Horizon `[a, b, c]`, unit normal, positive on the ground side.
    pub fn horizon(&self) -> [f64; 3] {
        let n = self.axis();
        [n[0], n[1], self.d - n[0] * self.p[0] - n[1] * self.p[1]]
    }
    /// Signed distance from the horizon, positive on the ground side.
    pub fn below_horizon(&self, x: [f64; 2]) -> f64 {
        let n = self.axis();
        (x[0] - self.p[0]) * n[0] + (x[1] - self.p[1]) * n[1] + self.d
    }
    /// What is wrong with this view for eq. 3, if anything: tilt under
    /// `min_tilt` is near level, over `max_tilt` near vertical (radians).
    pub fn degeneracy(&self, min_tilt: f64, max_tilt: f64) -> Option<Degeneracy> {
        let a = self.axis();
        let t = self.tilt();
        if a[1] <= 0.0 {
            Some(Degeneracy::Upward)
        } else if t < min_tilt {
            Some(Degeneracy::NearLevel)
        } else if t > max_tilt {
            Some(Degeneracy::NearVertical)
        } else {
            None
        }
    }

    /// Height of a person relative to the camera height, from the cross
    /// ratio along the vertical through the foot (Criminisi et al.):
    /// `h / h_c = 1 − D(head)·|foot − v| / (D(foot)·|head − v|)`, with `D`
    /// the distance below the horizon. The foot must be below the horizon
    /// and the head must not coincide with `v`.
    pub fn height_ratio(&self, o: &HeadFoot) -> Option<f64> {
        let df = self.below_horizon(o.foot);
        let hv = dist(o.head, self.v);
        if df <= 1e-9 || hv <= 1e-9 {
            return None;
        }
        let r = 1.0 - self.below_horizon(o.head) * dist(o.foot, self.v) / (df * hv);
        r.is_finite().then_some(r)
    }

    /// The image of the point `ratio·h_c` straight above `foot` (METHOD.md
    /// eq. 7's reference head, computed by inverting the cross ratio).
    pub fn head_for_ratio(&self, foot: [f64; 2], ratio: f64) -> Option<[f64; 2]> {
        // Along the line foot→v parameterised by distance s from the foot
        // (positive away from v), D(s) = D_f + s·k with k = -axis·dir.
        let fv = dist(foot, self.v);
        let df = self.below_horizon(foot);
        if fv <= 1e-9 || df <= 1e-9 {
            return None;
        }
        let dir = [(foot[0] - self.v[0]) / fv, (foot[1] - self.v[1]) / fv];
        let n = self.axis();
        let k = dir[0] * n[0] + dir[1] * n[1]; // dD/ds, negative upward
                                               // 1 - ratio = D(s)·fv / (df·(fv + s)) → linear in s.
        let q = (1.0 - ratio) * df;
        let denom = k * fv - q;
        if denom.abs() < 1e-12 {
            return None;
        }
        let s = (q * fv - df * fv) / denom;
        Some([foot[0] + s * dir[0], foot[1] + s * dir[1]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometry_of_a_camera_gives_back_its_parameters() {
        for (f, tilt, roll) in [(800.0, 20.0, 4.0), (1200.0, 35.0, -5.0), (500.0, 12.0, 0.0)] {
            let cam = Camera::centred(f, tilt, roll, 4.0, 640, 480);
            let g = ViewGeometry::of_camera(&cam);
            assert!((g.focal() - f).abs() < 1e-6 * f);
            assert!((g.tilt().to_degrees() - tilt).abs() < 1e-9);
            assert!((g.roll().to_degrees() - roll).abs() < 1e-9);
            let h = cam.horizon();
            let gh = g.horizon();
            for k in 0..3 {
                assert!((h[k] - gh[k]).abs() < 1e-6, "{h:?} {gh:?}");
            }
        }
    }

    #[test]
    fn cross_ratio_height_is_exact_and_inverts() {
        let cam = Camera::centred(900.0, 25.0, 3.0, 5.0, 640, 480);
        let g = ViewGeometry::of_camera(&cam);
        for (x, y, h) in [(0.0, 8.0, 1.8), (-3.0, 14.0, 1.55), (2.0, 6.0, 6.5)] {
            let foot = cam.project([x, y, 0.0]).unwrap();
            let head = cam.project([x, y, h]).unwrap();
            let r = g.height_ratio(&HeadFoot { head, foot }).unwrap();
            assert!((r * cam.height - h).abs() < 1e-9, "{r}");
            let back = g.head_for_ratio(foot, h / cam.height).unwrap();
            assert!(dist(back, head) < 1e-6, "{back:?} {head:?}");
        }
    }
}
