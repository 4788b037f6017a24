//! Pure single-view geometry: observations and anchors, normalised
//! coordinates, the camera of paper eq. 3 and the cross-ratio height of
//! METHOD.md §5–6. The fits that estimate the geometry from people are in
//! [`super::vertical`] and [`super::horizon`].
//!
//! Everything works in *normalised* coordinates (pixel minus principal
//! point, divided by half the larger image side) so that the homogeneous
//! least-squares problems are well conditioned (Hartley normalisation) and
//! a vanishing point at infinity is an ordinary homogeneous vector.
//!
//! Model assumptions (the paper's and METHOD.md's): square pixels, zero
//! skew, principal point at the image centre, no lens distortion, flat
//! ground, upright people whose lowest image point is the edge of their
//! feet nearest the camera ([`ViewGeometry::foot_offset`] of their height
//! from the point under the head) and whose highest image point is where
//! the camera's ray grazes the back of a round head
//! ([`ViewGeometry::head_radius`]). Under them the principal point lies on the
//! perpendicular from the vertical vanishing point `v` to the horizon, so
//! once `v` is known the horizon has a single unknown, its distance `d`
//! from the principal point; `f² = d·|v−p|` (eq. 3).

use crate::camera::Camera;
use nalgebra::Vector3;

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

/// One calibration anchor: a person's head and foot, pixels, averaged over
/// a few consecutive frames, with the direction the foot was moving.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Anchor {
    /// Head point `[u, v]`.
    pub head: [f64; 2],
    /// Foot point `[u, v]`.
    pub foot: [f64; 2],
    /// Image direction of the foot's motion, a unit vector scaled down
    /// toward zero for a person barely moving (`[0, 0]`: standing, or not
    /// known, as in state files of earlier versions).
    #[serde(default)]
    pub motion: [f64; 2],
}

impl Anchor {
    /// Head and foot alone.
    pub fn head_foot(&self) -> HeadFoot {
        HeadFoot {
            head: self.head,
            foot: self.foot,
        }
    }

    /// Image extent head to foot, pixels.
    pub fn extent(&self) -> f64 {
        dist(self.head, self.foot)
    }
}

impl From<HeadFoot> for Anchor {
    fn from(o: HeadFoot) -> Self {
        Anchor {
            head: o.head,
            foot: o.foot,
            motion: [0.0; 2],
        }
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
    /// How far the observed foot point is from the ground point under the
    /// head, toward the camera, as a fraction of the person's height (see
    /// [`ViewGeometry::height_ratio`]); 0 for exact foot points.
    pub foot_offset: f64,
    /// Radius of the top of the head, as a fraction of the person's
    /// height (see [`ViewGeometry::height_ratio`]); 0 for exact crowns.
    pub head_radius: f64,
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
            foot_offset: 0.0,
            head_radius: 0.0,
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
            foot_offset: 0.0,
            head_radius: 0.0,
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
    ///
    /// With a [`ViewGeometry::foot_offset`] `κ`, the foot point is first
    /// moved back to the ground point under the head: a silhouette's lowest
    /// pixels are the edge of the feet nearest the camera, not the point
    /// under the crown. On the ground that edge is `κ·h` from the body's
    /// axis toward the camera's nadir, so the ground line of the shift runs
    /// through the nadir and its image through `v`: the foot slides along
    /// the line `foot → v`, away from `v`. The shift depends on the height
    /// it corrects; three fixed-point steps settle it (each one shrinks the
    /// change by the factor `κ·∂shift/∂h`, well under 0.1).
    ///
    /// With a [`ViewGeometry::head_radius`] `η`, the head point is taken as
    /// the top of a ball of radius `η·h` whose crown is the person's
    /// height: a camera looking down sees past the crown to the back of
    /// the head, where its ray grazes the ball, so the silhouette's top
    /// reads `η·h·(1 − cos α)` taller (in the image's vertical at the
    /// head's depth; `α` the ray's angle below level). Near people are seen
    /// more steeply than far ones, so uncorrected the extents grow faster
    /// with nearness than the heights do, which the horizon fit reads as a
    /// horizon too close to the people (f too short). The grazing point
    /// lies in the vertical plane through the camera and the person, whose
    /// image is the line through `v`, so it sits on the head–foot line:
    /// the cross ratio gives the height of the point on the person's
    /// vertical that the ray through the grazing point crosses, and the
    /// same fixed-point steps solve for the crown.
    pub fn height_ratio(&self, o: &HeadFoot) -> Option<f64> {
        self.ratio_frame().height_ratio(o)
    }

    /// The per-view constants of [`ViewGeometry::height_ratio`] (axis,
    /// focal length, the tilt's sine and cosine), for many heights under
    /// one view: [`RatioFrame::height_ratio`] gives the same ratios to the
    /// bit without recomputing them (three libm calls and four square roots
    /// a height).
    pub fn ratio_frame(&self) -> RatioFrame {
        RatioFrame {
            v: self.v,
            d: self.d,
            foot_offset: self.foot_offset,
            head_radius: self.head_radius,
            ground: self.ground_frame(),
        }
    }

    /// The image of the ground point `shift` camera heights farther from
    /// the camera's nadir than the ground point seen at `foot`.
    ///
    /// Camera frame with the roll removed: x along the horizon, y along the
    /// axis `p → v`, z the optical axis; with tilt `θ` the world's down is
    /// `D = (0, cos θ, sin θ)` and its forward `F = (0, −sin θ, cos θ)`. The
    /// ray through image point `(x, y)` (relative to `p`) is `(x, y, f)`; it
    /// meets the ground (one camera height down) at lateral `x / (ray·D)`,
    /// forward `(ray·F) / (ray·D)` from the nadir.
    pub fn foot_under_head(&self, foot: [f64; 2], shift: f64) -> Option<[f64; 2]> {
        self.ground_frame().foot_under_head(foot, shift)
    }

    /// The per-view constants of [`ViewGeometry::foot_under_head`], computed
    /// once for all the fixed-point steps of a height.
    fn ground_frame(&self) -> GroundFrame {
        let a = self.axis();
        let t = self.tilt();
        GroundFrame {
            p: self.p,
            axis: a,
            across: [a[1], -a[0]],
            f: self.focal(),
            st: libm::sin(t),
            ct: libm::cos(t),
        }
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

/// A view prepared for many heights ([`ViewGeometry::ratio_frame`]).
#[derive(Clone, Copy, Debug)]
pub struct RatioFrame {
    v: [f64; 2],
    d: f64,
    foot_offset: f64,
    head_radius: f64,
    ground: GroundFrame,
}

impl RatioFrame {
    /// [`ViewGeometry::height_ratio`] of the view this was made from.
    pub fn height_ratio(&self, o: &HeadFoot) -> Option<f64> {
        let mut r = self.cross_ratio(o.head, o.foot)?;
        if self.foot_offset <= 0.0 && self.head_radius <= 0.0 {
            return Some(r);
        }
        // The head's terms and the foot's ground point (camera heights),
        // once for all the steps.
        let (head_below, hv) = (self.below_horizon(o.head), dist(o.head, self.v));
        let (g, rho) = self.ground.ground_point(o.foot)?;
        // How much taller the back of the head reads than the crown, taken
        // once at the first estimate: it changes with the height by about
        // its own 1–6 %, so the steps below would move it by under a
        // millimetre (6 mm for someone 2 m under a 7 m camera), and it is
        // the costliest part of a height (the horizon fit takes thousands
        // per refit).
        let back_of_head = if self.head_radius > 0.0 {
            let shift = self.foot_offset * r.max(0.0);
            grazing_ratio(r, self.head_radius * r.max(0.0), rho + shift) - r
        } else {
            0.0
        };
        for _ in 0..3 {
            let shift = self.foot_offset * r.max(0.0);
            let foot = if self.foot_offset > 0.0 {
                self.ground.shifted(o.foot, g, rho, shift)?
            } else {
                o.foot
            };
            r = self.cross_ratio_from(head_below, hv, foot)? - back_of_head;
        }
        Some(r)
    }

    /// [`ViewGeometry::below_horizon`], with the axis computed once.
    fn below_horizon(&self, x: [f64; 2]) -> f64 {
        let (p, n) = (self.ground.p, self.ground.axis);
        (x[0] - p[0]) * n[0] + (x[1] - p[1]) * n[1] + self.d
    }

    fn cross_ratio(&self, head: [f64; 2], foot: [f64; 2]) -> Option<f64> {
        self.cross_ratio_from(self.below_horizon(head), dist(head, self.v), foot)
    }

    /// [`RatioFrame::cross_ratio`] with the head's distances below the
    /// horizon and from `v` given (the same for every step of a height).
    fn cross_ratio_from(&self, head_below: f64, hv: f64, foot: [f64; 2]) -> Option<f64> {
        let df = self.below_horizon(foot);
        if df <= 1e-9 || hv <= 1e-9 {
            return None;
        }
        let r = 1.0 - head_below * dist(foot, self.v) / (df * hv);
        r.is_finite().then_some(r)
    }
}

/// A view's camera frame with the roll removed (see
/// [`ViewGeometry::foot_under_head`]): principal point, image axis toward
/// `v` and across it, focal length, sine and cosine of the tilt.
#[derive(Clone, Copy, Debug)]
struct GroundFrame {
    p: [f64; 2],
    axis: [f64; 2],
    across: [f64; 2],
    f: f64,
    st: f64,
    ct: f64,
}

/// The height ratio (to the camera's) that the cross ratio reads for a
/// person whose crown is at ratio `r`, with a head ball of radius `radius`
/// and the body's axis `rho` from the nadir (all in camera heights): the
/// height at which the ray through the ball's grazing top point crosses
/// the person's vertical (see [`ViewGeometry::height_ratio`]).
fn grazing_ratio(r: f64, radius: f64, rho: f64) -> f64 {
    let centre = r - radius;
    let drop = 1.0 - centre; // camera above the ball's centre
    let ray = (rho * rho + drop * drop).sqrt();
    if ray <= 1e-12 {
        return r;
    }
    // The grazing point: `radius` from the centre, perpendicular to the
    // ray and upward in the image (away from the camera when it looks down).
    let (sin_a, cos_a) = (drop / ray, rho / ray);
    let (out, up) = (rho + radius * sin_a, centre + radius * cos_a);
    if out <= 1e-12 {
        return r; // straight under the camera: no vertical to cross
    }
    1.0 - (1.0 - up) * rho / out
}

impl GroundFrame {
    /// The ground point seen at `foot` (lateral, forward from the nadir, in
    /// camera heights) and its distance from the nadir; `None` at or above
    /// the horizon.
    fn ground_point(&self, foot: [f64; 2]) -> Option<([f64; 2], f64)> {
        let (a, across, f, st, ct) = (self.axis, self.across, self.f, self.st, self.ct);
        let q = [foot[0] - self.p[0], foot[1] - self.p[1]];
        let (x, y) = (
            q[0] * across[0] + q[1] * across[1],
            q[0] * a[0] + q[1] * a[1],
        );
        let down = y * ct + f * st;
        if down <= 1e-9 {
            return None; // at or above the horizon
        }
        let g = [x / down, (f * ct - y * st) / down];
        Some((g, (g[0] * g[0] + g[1] * g[1]).sqrt()))
    }

    fn foot_under_head(&self, foot: [f64; 2], shift: f64) -> Option<[f64; 2]> {
        let (g, rho) = self.ground_point(foot)?;
        self.shifted(foot, g, rho, shift)
    }

    /// [`GroundFrame::foot_under_head`] from the ground point `g` (at `rho`
    /// from the nadir) that `foot` sees.
    fn shifted(&self, foot: [f64; 2], g: [f64; 2], rho: f64, shift: f64) -> Option<[f64; 2]> {
        let (a, across, f, st, ct) = (self.axis, self.across, self.f, self.st, self.ct);
        if rho <= 1e-9 {
            return Some(foot); // under the camera: no direction to move in
        }
        let k = 1.0 + shift / rho;
        let g = [g[0] * k, g[1] * k];
        // The ground point g·h_c in the camera frame: lateral, then F and D.
        let (px, py, pz) = (g[0], ct - g[1] * st, st + g[1] * ct);
        if pz <= 1e-9 {
            return None;
        }
        let (x, y) = (f * px / pz, f * py / pz);
        Some([
            self.p[0] + x * across[0] + y * a[0],
            self.p[1] + x * across[1] + y * a[1],
        ])
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
    fn foot_offset_undoes_a_foot_seen_nearer_the_camera() {
        let cam = Camera::centred(700.0, 30.0, -4.0, 6.0, 640, 480);
        let exact = ViewGeometry::of_camera(&cam);
        let g = ViewGeometry {
            foot_offset: 0.08,
            ..exact
        };
        for (x, y, h) in [(0.5, 7.0, 1.75), (-4.0, 12.0, 1.6), (3.0, 20.0, 1.9)] {
            let head = cam.project([x, y, h]).unwrap();
            let true_foot = cam.project([x, y, 0.0]).unwrap();
            // The edge of the feet 0.08·h nearer the nadir (the origin).
            let rho = (x * x + y * y).sqrt();
            let k = 1.0 - 0.08 * h / rho;
            let seen = cam.project([x * k, y * k, 0.0]).unwrap();
            assert!(
                seen[1] > true_foot[1] + 1.0,
                "the near edge is lower in the image"
            );
            let back = g.foot_under_head(seen, 0.08 * h / cam.height).unwrap();
            assert!(dist(back, true_foot) < 1e-6, "{back:?} {true_foot:?}");
            let r = g.height_ratio(&HeadFoot { head, foot: seen }).unwrap();
            assert!((r * cam.height - h).abs() < 1e-3, "{}", r * cam.height);
            // Uncorrected, the same points read tall.
            let raw = exact.height_ratio(&HeadFoot { head, foot: seen }).unwrap();
            assert!(raw * cam.height > h + 0.02, "{}", raw * cam.height);
        }
    }

    /// The top-most image point of a ball (sampled densely on its surface,
    /// not from the grazing formula).
    fn top_of_ball(cam: &Camera, centre: [f64; 3], radius: f64) -> [f64; 2] {
        let mut top = [0.0, f64::INFINITY];
        for i in 0..=400 {
            let polar = core::f64::consts::PI * f64::from(i) / 400.0;
            for j in 0..400 {
                let az = core::f64::consts::TAU * f64::from(j) / 400.0;
                let (sp, cp) = (libm::sin(polar), libm::cos(polar));
                let q = [
                    centre[0] + radius * sp * libm::cos(az),
                    centre[1] + radius * sp * libm::sin(az),
                    centre[2] + radius * cp,
                ];
                // Only the side facing the camera is seen.
                let n = [q[0] - centre[0], q[1] - centre[1], q[2] - centre[2]];
                let to_cam = [-q[0], -q[1], cam.height - q[2]];
                if n[0] * to_cam[0] + n[1] * to_cam[1] + n[2] * to_cam[2] < 0.0 {
                    continue;
                }
                let px = cam.project(q).unwrap();
                if px[1] < top[1] {
                    top = px;
                }
            }
        }
        top
    }

    #[test]
    fn head_radius_undoes_the_back_of_the_head_seen_from_above() {
        let cam = Camera::centred(700.0, 32.0, 3.0, 5.0, 640, 480);
        let exact = ViewGeometry::of_camera(&cam);
        let g = ViewGeometry {
            head_radius: 0.05,
            foot_offset: 0.08,
            ..exact
        };
        let mut gains = Vec::new();
        for (x, y, h) in [(0.3, 5.0, 1.75), (-2.5, 8.0, 1.6), (2.0, 16.0, 1.9)] {
            let radius = 0.05 * h;
            let head = top_of_ball(&cam, [x, y, h - radius], radius);
            let rho = (x * x + y * y).sqrt();
            let k = 1.0 - 0.08 * h / rho;
            let foot = cam.project([x * k, y * k, 0.0]).unwrap();
            let seen = HeadFoot { head, foot };
            let r = g.height_ratio(&seen).unwrap();
            // The sampling grid puts the top within a few mm of the ball's.
            assert!(
                (r * cam.height - h).abs() < 4e-3,
                "{} vs {h}",
                r * cam.height
            );
            let feet_only = ViewGeometry {
                head_radius: 0.0,
                ..g
            };
            let raw = feet_only.height_ratio(&seen).unwrap() * cam.height - h;
            assert!(raw > 0.001, "the back of the head reads tall: {raw}");
            gains.push(raw / h);
        }
        // Nearer people are seen more steeply: more of the head's back
        // (1 cm and more at 5 m from a 5 m high camera).
        assert!(gains[0] > gains[1] && gains[1] > gains[2], "{gains:?}");
        assert!(gains[0] * 1.75 > 0.01, "{gains:?}");
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
