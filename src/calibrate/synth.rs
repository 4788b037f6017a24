//! Synthetic head/foot observations of people walking in front of a known
//! camera, for tests and benchmarks of calibration and heights (never used
//! by the vision loop). People walk straight lines at 1.0–1.6 m/s, their
//! head bobs by up to 2 cm with the gait, the foot point is the edge of
//! the feet nearest the camera (as a silhouette's lowest pixels are; see
//! [`super::geometry::ViewGeometry::foot_offset`]), the head point is the
//! top of a round head as a camera looking down sees it (the back of the
//! head: [`super::geometry::ViewGeometry::head_radius`]), and image points
//! get Gaussian pixel noise.

use super::geometry::HeadFoot;
use crate::camera::Camera;
use crate::rng::Rng;

/// One observation with its truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SynthObs {
    /// Person (track) id, from 1.
    pub id: u32,
    /// Frame index.
    pub frame: u64,
    /// Noisy head and foot points.
    pub hf: HeadFoot,
    /// The person's standing height, metres.
    pub height: f64,
}

/// Scene parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SynthScene {
    /// Image width, pixels.
    pub width: usize,
    /// Image height, pixels.
    pub height: usize,
    /// People walking through, one after another (overlapping in time).
    pub people: usize,
    /// Mean and standard deviation of their heights, metres.
    pub height_mean: f64,
    /// Standard deviation of heights, metres.
    pub height_sd: f64,
    /// Pixel noise (standard deviation) on head and foot, pixels.
    pub noise_px: f64,
    /// Frames per second.
    pub fps: f64,
    /// Ground distance of the foot point from the point under the head,
    /// toward the camera's nadir, as a fraction of the person's height
    /// (the calibrator's default `foot_offset`; 0 puts it under the head).
    pub foot_offset: f64,
    /// Radius of the head's top as a fraction of the person's height (the
    /// calibrator's default `head_radius`; 0 puts the head point on the
    /// crown).
    pub head_radius: f64,
}

impl Default for SynthScene {
    fn default() -> Self {
        SynthScene {
            width: 640,
            height: 480,
            people: 20,
            height_mean: 1.70,
            height_sd: 0.08,
            noise_px: 0.7,
            fps: 10.0,
            foot_offset: 0.08,
            head_radius: 0.05,
        }
    }
}

/// A random downward-looking camera of the range the product targets.
pub fn random_camera(rng: &mut Rng, width: usize, height: usize) -> Camera {
    let hfov = (50.0 + 40.0 * rng.uniform()).to_radians();
    let f = (width as f64 / 2.0) / libm::tan(hfov / 2.0);
    Camera::centred(
        f,
        12.0 + 28.0 * rng.uniform(),
        -6.0 + 12.0 * rng.uniform(),
        2.5 + 5.5 * rng.uniform(),
        width,
        height,
    )
}

/// Where the camera's ray grazes the top of a ball of `radius` whose crown
/// is `crown` metres above the ground point `pos` (world coordinates): the
/// head's highest image point as a camera looking down sees it.
fn grazing_top(cam: &Camera, pos: [f64; 2], crown: f64, radius: f64) -> [f64; 3] {
    let rho = (pos[0] * pos[0] + pos[1] * pos[1]).sqrt();
    let centre = crown - radius;
    let drop = cam.height - centre;
    let ray = (rho * rho + drop * drop).sqrt();
    if rho <= 1e-9 || ray <= 1e-9 {
        return [pos[0], pos[1], crown];
    }
    // Perpendicular to the ray in the vertical plane through the camera,
    // upward: away from the camera by sin, up by cos of the ray's dip.
    let out = 1.0 + radius * (drop / ray) / rho;
    [pos[0] * out, pos[1] * out, centre + radius * rho / ray]
}

/// Walks `scene.people` people through `cam`'s view; observations where
/// head and foot are at least 2 px inside the image, sorted by frame.
pub fn walk(cam: &Camera, scene: &SynthScene, rng: &mut Rng) -> Vec<SynthObs> {
    let (w, h) = (scene.width as f64, scene.height as f64);
    let inside = |p: [f64; 2]| p[0] >= 2.0 && p[1] >= 2.0 && p[0] <= w - 3.0 && p[1] <= h - 3.0;
    let mut out = Vec::new();
    for id in 1..=scene.people as u32 {
        let height = scene.height_mean + scene.height_sd * rng.normal();
        // A start pixel in the lower 70 % of the image, on the ground.
        let mut start = None;
        for _ in 0..100 {
            let px = [w * rng.uniform(), h * (0.3 + 0.7 * rng.uniform())];
            if let Some(g) = cam.ground_point(px) {
                let head = cam.project([g[0], g[1], height]);
                if head.is_some_and(inside) && inside(px) {
                    start = Some(g);
                    break;
                }
            }
        }
        let Some(mut pos) = start else { continue };
        let heading = core::f64::consts::TAU * rng.uniform();
        let speed = 1.0 + 0.6 * rng.uniform();
        let step = [
            speed * libm::cos(heading) / scene.fps,
            speed * libm::sin(heading) / scene.fps,
        ];
        let first = u64::from(id - 1) * (scene.fps as u64) * 2;
        let phase0 = rng.uniform() * 6.0;
        for k in 0..(scene.fps as u64 * 30) {
            let bob = 0.02 * (libm::sin(phase0 + k as f64 * 2.0 * 3.5 / scene.fps).abs() - 1.0);
            let rho = (pos[0] * pos[0] + pos[1] * pos[1]).sqrt();
            let near = (1.0 - scene.foot_offset * height / rho.max(1e-9)).max(0.0);
            let (Some(foot), Some(head)) = (
                cam.project([pos[0] * near, pos[1] * near, 0.0]),
                cam.project(grazing_top(
                    cam,
                    pos,
                    height + bob,
                    scene.head_radius * height,
                )),
            ) else {
                break;
            };
            if !(inside(foot) && inside(head)) {
                break;
            }
            let n = |rng: &mut Rng, p: [f64; 2]| {
                [
                    p[0] + scene.noise_px * rng.normal(),
                    p[1] + scene.noise_px * rng.normal(),
                ]
            };
            out.push(SynthObs {
                id,
                frame: first + k,
                hf: HeadFoot {
                    head: n(rng, head),
                    foot: n(rng, foot),
                },
                height,
            });
            pos = [pos[0] + step[0], pos[1] + step[1]];
        }
    }
    out.sort_by_key(|o| (o.frame, o.id));
    out
}
