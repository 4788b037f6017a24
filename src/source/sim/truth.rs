//! Ground truth: the camera of a scene and, per frame, every object in view.
//!
//! Conventions are those of [`crate::camera`] and the report schema: pixel
//! (0,0) is the centre of the top-left pixel, `v` grows downward, the horizon
//! `[a,b,c]` has `a²+b² = 1` and is positive below the horizon.

use super::people::Kind;
use crate::camera::Camera;
use serde::Serialize;

/// The camera of a scene, exactly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneTruth {
    /// Scene name.
    pub scene: String,
    /// Seed the clip was drawn from.
    pub seed: u64,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Frames per second.
    pub fps: u32,
    /// Frames in the clip.
    pub frames: u64,
    /// Focal length, pixels.
    pub f_px: f64,
    /// Downward pitch of the optical axis, degrees.
    pub tilt_deg: f64,
    /// Roll, degrees, positive when the horizon rises to the right.
    pub roll_deg: f64,
    /// Camera height above the ground, metres.
    pub camera_height_m: f64,
    /// Principal point `[u, v]` (the image centre).
    pub principal: [f64; 2],
    /// Intrinsic matrix K, row-major.
    pub k: [[f64; 3]; 3],
    /// World-to-camera rotation R, row-major (world z up; camera x right, y down, z forward).
    pub r: [[f64; 3]; 3],
    /// Vertical vanishing point `[u, v]`, pixels.
    pub vertical_vp: [f64; 2],
    /// Horizon `[a, b, c]`: `a·u + b·v + c = 0`, unit normal, positive below it.
    pub horizon: [f64; 3],
}

impl SceneTruth {
    /// The same camera as a [`Camera`] (for projecting, back-projecting, comparing).
    pub fn camera(&self) -> Camera {
        Camera {
            f: self.f_px,
            tilt: super::math::rad(self.tilt_deg),
            roll: super::math::rad(self.roll_deg),
            height: self.camera_height_m,
            principal: self.principal,
        }
    }
}

/// One object in one frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ObjectTruth {
    /// Person, dog or car.
    pub kind: Kind,
    /// Id, unique within the clip and stable across frames.
    pub id: u32,
    /// Group id for people walking together (0 alone).
    pub group: u32,
    /// Standing height, metres (people: top of the head standing upright; cars: roof; dogs: head top).
    pub height_m: f64,
    /// Projection of the point `height_m` straight above the foot point.
    pub head_px: [f64; 2],
    /// Projection of the ground point between the feet (cars, dogs: under the body centre).
    pub foot_px: [f64; 2],
    /// That ground point in world coordinates `(x, y)`, metres.
    pub ground_m: [f64; 2],
    /// Inclusive box `[x0, y0, x1, y1]` of the silhouette inside the image (hidden parts included).
    pub bbox: [u16; 4],
    /// Fraction of the silhouette actually seen (not hidden by nearer objects, props or the image border).
    pub visible_fraction: f64,
    /// Pixels of the object actually seen.
    pub visible_px: u32,
    /// False while the object stands still.
    pub walking: bool,
}

/// One member of a clip's cast.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CastMember {
    /// Id (as in [`ObjectTruth::id`]).
    pub id: u32,
    /// Person, dog or car.
    pub kind: Kind,
    /// Standing height, metres.
    pub height_m: f64,
    /// Group id (0 alone).
    pub group: u32,
    /// Frames in which the head and foot points are both inside the image.
    pub frames_in_view: u64,
    /// First such frame (0 when never in view).
    pub first_frame: u64,
    /// Last such frame.
    pub last_frame: u64,
}
