//! The pinhole camera model and the conventions every module shares.
//!
//! * Pixel (0,0) is the centre of the top-left pixel; `u` grows to the
//!   right, `v` grows downward. The principal point is the image centre
//!   `((W-1)/2, (H-1)/2)`, pixels are square, there is no skew or distortion.
//! * World: `z` up, the ground is `z = 0`, the camera centre is at
//!   `(0, 0, height)` and, before tilt and roll, looks along world `+y`.
//! * Tilt `θ` is the downward pitch of the optical axis (positive looking
//!   down). Roll `ρ` is positive when the horizon rises toward the right of
//!   the image.
//! * Lines are `[a, b, c]` with `a·u + b·v + c = 0`, `a² + b² = 1`, and the
//!   horizon is positive below the horizon (on the ground side).
//!
//! With these conventions the vertical vanishing point relative to the
//! principal point is `f·cot θ·(sin ρ, cos ρ)`, so `ρ = atan2(v_x, v_y)`.
//! (METHOD.md writes `atan(-v_x/v_y)`: the paper's roll has the opposite
//! sign; PETS View_001, roll +3.1° with the horizon rising to the right,
//! has `v_x > 0`, which fixes the sign used here.)

use nalgebra::{Matrix3, Vector3};

/// A calibrated pinhole camera above a flat ground plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal length in pixels.
    pub f: f64,
    /// Downward pitch of the optical axis, radians.
    pub tilt: f64,
    /// Roll, radians, positive when the horizon rises to the right.
    pub roll: f64,
    /// Height of the camera centre above the ground, metres.
    pub height: f64,
    /// Principal point `(u, v)` in pixels.
    pub principal: [f64; 2],
}

impl Camera {
    /// A camera with the principal point at the centre of a `width`×`height` image.
    pub fn centred(
        f: f64,
        tilt_deg: f64,
        roll_deg: f64,
        height: f64,
        width: usize,
        height_px: usize,
    ) -> Self {
        Camera {
            f,
            tilt: tilt_deg.to_radians(),
            roll: roll_deg.to_radians(),
            height,
            principal: [(width as f64 - 1.0) / 2.0, (height_px as f64 - 1.0) / 2.0],
        }
    }

    /// World-to-camera rotation (camera axes: x right, y down, z forward).
    pub fn rotation(&self) -> Matrix3<f64> {
        let (st, ct) = (libm::sin(self.tilt), libm::cos(self.tilt));
        let (sr, cr) = (libm::sin(self.roll), libm::cos(self.roll));
        // Level camera looking along +y, pitched down by the tilt.
        let pitched = Matrix3::new(1.0, 0.0, 0.0, 0.0, -st, -ct, 0.0, ct, -st);
        let rolled = Matrix3::new(cr, sr, 0.0, -sr, cr, 0.0, 0.0, 0.0, 1.0);
        rolled * pitched
    }

    /// Intrinsic matrix K.
    pub fn intrinsics(&self) -> Matrix3<f64> {
        Matrix3::new(
            self.f,
            0.0,
            self.principal[0],
            0.0,
            self.f,
            self.principal[1],
            0.0,
            0.0,
            1.0,
        )
    }

    /// Camera-frame coordinates of a world point.
    pub fn to_camera(&self, world: [f64; 3]) -> Vector3<f64> {
        self.rotation() * Vector3::new(world[0], world[1], world[2] - self.height)
    }

    /// Projects a world point to pixels; `None` behind the camera.
    pub fn project(&self, world: [f64; 3]) -> Option<[f64; 2]> {
        let c = self.to_camera(world);
        (c.z > 1e-9).then(|| {
            [
                self.principal[0] + self.f * c.x / c.z,
                self.principal[1] + self.f * c.y / c.z,
            ]
        })
    }

    /// The vertical vanishing point (image of the downward vertical direction).
    pub fn vertical_vanishing_point(&self) -> [f64; 2] {
        let d = self.rotation() * Vector3::new(0.0, 0.0, -1.0);
        // d.z = sin(tilt) > 0 for a camera looking down; at tilt 0 the point is at infinity.
        [
            self.principal[0] + self.f * d.x / d.z,
            self.principal[1] + self.f * d.y / d.z,
        ]
    }

    /// The horizon `[a, b, c]`, unit normal, positive on the ground side.
    pub fn horizon(&self) -> [f64; 3] {
        let r = self.rotation();
        // A pixel ray (u-pu, v-pv, f) in world has z = r3 · ray, negative on the ground side.
        let (a, b, cz) = (-r[(0, 2)], -r[(1, 2)], -r[(2, 2)]);
        let c = cz * self.f - a * self.principal[0] - b * self.principal[1];
        let n = (a * a + b * b).sqrt();
        [a / n, b / n, c / n]
    }

    /// Back-projects a pixel onto the ground plane `z = 0`; `None` at or above the horizon.
    pub fn ground_point(&self, px: [f64; 2]) -> Option<[f64; 2]> {
        let ray_cam = Vector3::new(px[0] - self.principal[0], px[1] - self.principal[1], self.f);
        let ray = self.rotation().transpose() * ray_cam;
        (ray.z < -1e-12).then(|| {
            let t = -self.height / ray.z;
            [t * ray.x, t * ray.y]
        })
    }
}

/// Signed distance of a point from a unit-normal line `[a, b, c]`.
pub fn line_distance(line: [f64; 3], p: [f64; 2]) -> f64 {
    line[0] * p[0] + line[1] * p[1] + line[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        Camera::centred(800.0, 20.0, 4.0, 4.0, 640, 480)
    }

    #[test]
    fn vertical_vanishing_point_matches_closed_form() {
        let c = cam();
        let v = c.vertical_vanishing_point();
        let r = c.f / libm::tan(c.tilt);
        assert!((v[0] - c.principal[0] - r * libm::sin(c.roll)).abs() < 1e-9);
        assert!((v[1] - c.principal[1] - r * libm::cos(c.roll)).abs() < 1e-9);
        // Verticals converge there: head and foot of a pole are collinear with v.
        let foot = c.project([1.5, 9.0, 0.0]).unwrap();
        let head = c.project([1.5, 9.0, 1.8]).unwrap();
        let cross = (head[0] - foot[0]) * (v[1] - foot[1]) - (head[1] - foot[1]) * (v[0] - foot[0]);
        assert!(cross.abs() < 1e-6, "{cross}");
    }

    #[test]
    fn horizon_rises_to_the_right_with_positive_roll_and_ground_is_positive() {
        let c = cam();
        let l = c.horizon();
        // Slope dv/du = -a/b < 0 means rising to the right (v points down).
        assert!(-l[0] / l[1] < 0.0);
        let foot = c.project([0.0, 6.0, 0.0]).unwrap();
        assert!(line_distance(l, foot) > 0.0);
        // A far point at eye level lies on the horizon.
        let far = c.project([50.0, 1e6, c.height]).unwrap();
        assert!(line_distance(l, far).abs() < 1e-3);
    }

    #[test]
    fn ground_point_inverts_projection() {
        let c = cam();
        let p = c.project([-2.0, 11.0, 0.0]).unwrap();
        let g = c.ground_point(p).unwrap();
        assert!((g[0] + 2.0).abs() < 1e-9 && (g[1] - 11.0).abs() < 1e-9);
        assert!(c.ground_point([320.0, -1000.0]).is_none());
    }

    #[test]
    fn paper_focal_relation_holds() {
        // f² = d(p, l) · |v − p| and tan θ = f / |v − p|.
        let c = cam();
        let v = c.vertical_vanishing_point();
        let vp = ((v[0] - c.principal[0]).powi(2) + (v[1] - c.principal[1]).powi(2)).sqrt();
        let d = line_distance(c.horizon(), c.principal).abs();
        assert!((d * vp - c.f * c.f).abs() / (c.f * c.f) < 1e-9);
        assert!((libm::atan(c.f / vp) - c.tilt).abs() < 1e-12);
    }
}
