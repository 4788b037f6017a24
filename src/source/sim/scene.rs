//! The named scenes: camera, ground, static objects, who walks by, and the
//! camera effects. Scenes are plain data; [`super::SimSource`] turns one
//! into pixels.

/// A static object that hides what is behind it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Prop {
    /// A lamp pole: foot at image fraction `(fu, fv)`, height in metres.
    Pole {
        /// Foot, as a fraction of the image width.
        fu: f64,
        /// Foot, as a fraction of the image height.
        fv: f64,
        /// Height, metres.
        height: f64,
    },
    /// A bench (1.8 m long, 0.45 m high) centred at image fraction `(fu, fv)`.
    Bench {
        /// Centre, fraction of the width.
        fu: f64,
        /// Centre, fraction of the height.
        fv: f64,
    },
    /// A low wall (0.25 m thick) centred at `(fu, fv)`, `length` along world x, `height` tall.
    Wall {
        /// Centre, fraction of the width.
        fu: f64,
        /// Centre, fraction of the height.
        fv: f64,
        /// Length along world x, metres.
        length: f64,
        /// Height, metres.
        height: f64,
    },
}

/// Ground surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ground {
    /// Square paving tiles with grout lines.
    Tiles,
    /// Grainy asphalt with painted lines.
    Asphalt,
}

/// One named scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    /// Name used in `sim:NAME`.
    pub name: &'static str,
    /// One-line description for `stature sim --list`.
    pub about: &'static str,
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// Frames per second.
    pub fps: u32,
    /// Default length in frames (`frames=N` overrides).
    pub frames: u64,
    /// Focal length, pixels.
    pub f: f64,
    /// Downward pitch, degrees.
    pub tilt_deg: f64,
    /// Roll, degrees, positive when the horizon rises to the right.
    pub roll_deg: f64,
    /// Camera height, metres.
    pub camera_height: f64,
    /// Ground surface.
    pub ground: Ground,
    /// Distance of the building facades closing the view, metres.
    pub backdrop: f64,
    /// Static occluders.
    pub props: &'static [Prop],
    /// Walkers entering per minute (singles and groups counted per walker).
    pub people_per_min: f64,
    /// Probability that an arrival is a group of 2–3 walking side by side.
    pub group_chance: f64,
    /// Probability that a walker stops for a while on the way.
    pub pause_chance: f64,
    /// Probability that a path is curved rather than straight.
    pub curve_chance: f64,
    /// Cars crossing per minute.
    pub cars_per_min: f64,
    /// Dogs crossing per minute.
    pub dogs_per_min: f64,
    /// Farthest distance a walker's path reaches, metres.
    pub max_distance: f64,
    /// Soft ground shadows.
    pub shadows: bool,
    /// Sun azimuth (world, radians from +x toward +y) and elevation, degrees.
    pub sun: (f64, f64),
    /// Sensor noise standard deviation, luma levels.
    pub noise: f64,
    /// Illumination drift amplitude (fraction of brightness) and period, seconds.
    pub drift: (f64, f64),
}

impl SceneSpec {
    /// The scene's camera as the renderer projects with it.
    pub fn projection(&self) -> super::math::Proj {
        super::math::Proj::new(
            self.f,
            self.tilt_deg,
            self.roll_deg,
            self.camera_height,
            self.width,
            self.height,
        )
    }
}

/// Every built-in scene; the first is the demo default.
pub fn scenes() -> &'static [SceneSpec] {
    &SCENES
}

/// The scene called `name`.
pub fn find(name: &str) -> Option<&'static SceneSpec> {
    SCENES.iter().find(|s| s.name == name)
}

static SCENES: [SceneSpec; 6] = [
    SceneSpec {
        name: "plaza",
        about: "demo: 640x480, 4.2 m, tilt 20°, roll 1.5°, paved plaza, pole and bench, groups, a dog, shadows, 30 s",
        width: 640,
        height: 480,
        fps: 25,
        frames: 750,
        f: 620.0,
        tilt_deg: 20.0,
        roll_deg: 1.5,
        camera_height: 4.2,
        ground: Ground::Tiles,
        backdrop: 45.0,
        props: &[
            Prop::Pole {
                fu: 0.18,
                fv: 0.62,
                height: 4.0,
            },
            Prop::Bench { fu: 0.74, fv: 0.80 },
        ],
        people_per_min: 22.0,
        group_chance: 0.25,
        pause_chance: 0.2,
        curve_chance: 0.4,
        cars_per_min: 0.0,
        dogs_per_min: 2.0,
        max_distance: 22.0,
        shadows: true,
        sun: (2.85, 50.0),
        noise: 2.0,
        drift: (0.04, 23.0),
    },
    SceneSpec {
        name: "low",
        about: "low camera: 640x480, 2.5 m, tilt 10°, horizon and facades in view, a low wall, 24 s",
        width: 640,
        height: 480,
        fps: 25,
        frames: 600,
        f: 560.0,
        tilt_deg: 10.0,
        roll_deg: 0.0,
        camera_height: 2.5,
        ground: Ground::Tiles,
        backdrop: 40.0,
        props: &[Prop::Wall {
            fu: 0.7,
            fv: 0.66,
            length: 3.0,
            height: 0.8,
        }],
        people_per_min: 18.0,
        group_chance: 0.15,
        pause_chance: 0.15,
        curve_chance: 0.3,
        cars_per_min: 0.0,
        dogs_per_min: 0.0,
        max_distance: 20.0,
        shadows: false,
        sun: (-2.0, 55.0),
        noise: 1.5,
        drift: (0.03, 17.0),
    },
    SceneSpec {
        name: "mid",
        about: "mid height: 640x480, 4.6 m, tilt 25°, roll -2°, soft shadows, groups of 2-3, bench, 24 s",
        width: 640,
        height: 480,
        fps: 25,
        frames: 600,
        f: 700.0,
        tilt_deg: 25.0,
        roll_deg: -2.0,
        camera_height: 4.6,
        ground: Ground::Tiles,
        backdrop: 40.0,
        props: &[Prop::Bench { fu: 0.3, fv: 0.75 }],
        people_per_min: 20.0,
        group_chance: 0.5,
        pause_chance: 0.15,
        curve_chance: 0.4,
        cars_per_min: 0.0,
        dogs_per_min: 1.0,
        max_distance: 20.0,
        shadows: true,
        sun: (-2.8, 40.0),
        noise: 2.0,
        drift: (0.05, 19.0),
    },
    SceneSpec {
        name: "high",
        about: "high and steep: 640x480, 7 m, tilt 35°, asphalt, a car, a pole, 24 s",
        width: 640,
        height: 480,
        fps: 25,
        frames: 600,
        f: 650.0,
        tilt_deg: 35.0,
        roll_deg: 1.0,
        camera_height: 7.0,
        ground: Ground::Asphalt,
        backdrop: 60.0,
        props: &[Prop::Pole {
            fu: 0.82,
            fv: 0.55,
            height: 5.0,
        }],
        people_per_min: 16.0,
        group_chance: 0.2,
        pause_chance: 0.15,
        curve_chance: 0.4,
        cars_per_min: 4.0,
        dogs_per_min: 1.0,
        max_distance: 24.0,
        shadows: false,
        sun: (-2.0, 50.0),
        noise: 2.0,
        drift: (0.03, 21.0),
    },
    SceneSpec {
        name: "wide",
        about: "wide angle (f 330 px): 640x480, 3.5 m, tilt 28°, roll 5°, strong sensor noise, 24 s",
        width: 640,
        height: 480,
        fps: 25,
        frames: 600,
        f: 330.0,
        tilt_deg: 28.0,
        roll_deg: 5.0,
        camera_height: 3.5,
        ground: Ground::Tiles,
        backdrop: 30.0,
        props: &[
            Prop::Bench { fu: 0.6, fv: 0.7 },
            Prop::Pole {
                fu: 0.3,
                fv: 0.5,
                height: 3.5,
            },
        ],
        people_per_min: 20.0,
        group_chance: 0.2,
        pause_chance: 0.2,
        curve_chance: 0.5,
        cars_per_min: 0.0,
        dogs_per_min: 1.0,
        max_distance: 13.0,
        shadows: false,
        sun: (-2.0, 50.0),
        noise: 5.0,
        drift: (0.05, 15.0),
    },
    SceneSpec {
        name: "busy",
        about: "busy: 1280x720, 6 m, tilt 30°, roll -3°, crowds, groups, cars, dogs, shadows, 24 s",
        width: 1280,
        height: 720,
        fps: 25,
        frames: 600,
        f: 1100.0,
        tilt_deg: 30.0,
        roll_deg: -3.0,
        camera_height: 6.0,
        ground: Ground::Tiles,
        backdrop: 50.0,
        props: &[
            Prop::Pole {
                fu: 0.12,
                fv: 0.7,
                height: 4.5,
            },
            Prop::Bench { fu: 0.5, fv: 0.85 },
            Prop::Wall {
                fu: 0.82,
                fv: 0.45,
                length: 4.0,
                height: 0.9,
            },
        ],
        people_per_min: 60.0,
        group_chance: 0.35,
        pause_chance: 0.15,
        curve_chance: 0.4,
        cars_per_min: 2.0,
        dogs_per_min: 2.0,
        max_distance: 24.0,
        shadows: true,
        sun: (2.6, 45.0),
        noise: 2.5,
        drift: (0.04, 20.0),
    },
];
