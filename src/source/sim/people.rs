//! Who moves through a scene: people (articulated walkers), dogs and cars.
//!
//! The whole cast is drawn from the seed when the source opens: paths,
//! speeds, heights, clothes, pauses and groups. A pose at time `t` is then a
//! pure function of the actor and `t`, so frames can be rendered (or their
//! truth computed) in any order.

use super::math::{cos, sin, Proj, Rng, PI};
use super::scene::SceneSpec;

/// What an object is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Kind {
    /// A walking (or standing) adult.
    Person,
    /// A dog.
    Dog,
    /// A car.
    Car,
}

impl Kind {
    /// Lower-case name.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Person => "person",
            Kind::Dog => "dog",
            Kind::Car => "car",
        }
    }
}

/// Samples of a path polyline (arc-length parameterised at run time).
const PATH_N: usize = 33;

/// A path on the ground: a polyline with its cumulative arc lengths.
#[derive(Clone, Debug)]
pub struct Path {
    pts: [[f64; 2]; PATH_N],
    cum: [f64; PATH_N],
}

impl Path {
    /// A quadratic Bézier from `a` to `b` through control point `c` (a straight line when `c` is the midpoint).
    pub fn bezier(a: [f64; 2], c: [f64; 2], b: [f64; 2]) -> Self {
        let mut pts = [[0.0; 2]; PATH_N];
        let mut cum = [0.0; PATH_N];
        for (i, p) in pts.iter_mut().enumerate() {
            let t = i as f64 / (PATH_N - 1) as f64;
            let (w0, w1, w2) = ((1.0 - t) * (1.0 - t), 2.0 * t * (1.0 - t), t * t);
            *p = [
                w0 * a[0] + w1 * c[0] + w2 * b[0],
                w0 * a[1] + w1 * c[1] + w2 * b[1],
            ];
        }
        for i in 1..PATH_N {
            let dx = pts[i][0] - pts[i - 1][0];
            let dy = pts[i][1] - pts[i - 1][1];
            cum[i] = cum[i - 1] + (dx * dx + dy * dy).sqrt();
        }
        Path { pts, cum }
    }

    /// Total length, metres.
    pub fn length(&self) -> f64 {
        self.cum[PATH_N - 1]
    }

    /// Point and unit tangent at arc length `s` (clamped to the path).
    pub fn at(&self, s: f64) -> ([f64; 2], [f64; 2]) {
        let s = s.clamp(0.0, self.length());
        let mut i = 1;
        while i < PATH_N - 1 && self.cum[i] < s {
            i += 1;
        }
        let (p0, p1) = (self.pts[i - 1], self.pts[i]);
        let seg = self.cum[i] - self.cum[i - 1];
        let t = if seg > 1e-12 {
            (s - self.cum[i - 1]) / seg
        } else {
            0.0
        };
        let (dx, dy) = (p1[0] - p0[0], p1[1] - p0[1]);
        let n = (dx * dx + dy * dy).sqrt().max(1e-12);
        ([p0[0] + t * dx, p0[1] + t * dy], [dx / n, dy / n])
    }
}

/// An RGB colour, 0..255 per channel.
pub type Rgb = [u8; 3];

/// Palette slots of a person (indices into [`Actor::palette`]).
pub mod slot {
    /// Face and hands.
    pub const SKIN: u8 = 0;
    /// Hair.
    pub const HAIR: u8 = 1;
    /// Shirt, jacket.
    pub const SHIRT: u8 = 2;
    /// Trousers or skirt.
    pub const TROUSERS: u8 = 3;
    /// Shoes.
    pub const SHOES: u8 = 4;
    /// Forearms: sleeves or bare skin.
    pub const FOREARM: u8 = 5;
    /// Shins: trousers or bare skin.
    pub const SHIN: u8 = 6;
    /// Car glass / dog nose.
    pub const DARK: u8 = 7;
}

/// Palette entries per actor.
pub const PALETTE: usize = 8;

/// One object of the cast.
#[derive(Clone, Debug)]
pub struct Actor {
    /// Unique id within the clip (from 1).
    pub id: u32,
    /// What it is.
    pub kind: Kind,
    /// Standing height (people: top of the head when standing upright), metres.
    pub height: f64,
    /// Group id (0 when walking alone).
    pub group: u32,
    /// Colours of the palette slots.
    pub palette: [Rgb; PALETTE],
    path: Path,
    /// Sideways offset from the path (groups walk side by side), metres, positive to the left.
    offset: f64,
    /// Walking speed, m/s.
    speed: f64,
    /// Time at which the actor is at the start of its path, seconds.
    t0: f64,
    /// Stop: (arc length, duration in seconds); duration 0 for none.
    pause: (f64, f64),
    /// Gait phase at the start, radians.
    phase0: f64,
    /// Stride length (two steps), metres.
    stride: f64,
    /// Width factor of the body (0.9–1.15).
    build: f64,
}

/// A body part as a tapered capsule between two world points.
#[derive(Clone, Copy, Debug, Default)]
pub struct Part {
    /// One end.
    pub a: [f64; 3],
    /// Other end.
    pub b: [f64; 3],
    /// Radius at `a`, metres.
    pub ra: f64,
    /// Radius at `b`, metres.
    pub rb: f64,
    /// Palette slot.
    pub col: u8,
    /// Head: upper half drawn in hair colour.
    pub head: bool,
}

/// Most parts a body has.
pub const MAX_PARTS: usize = 20;

/// The state of an actor at one instant.
#[derive(Clone, Copy, Debug)]
pub struct Pose {
    /// Index into the cast.
    pub actor: usize,
    /// Midpoint between the feet on the ground (people), body centre (car, dog).
    pub foot: [f64; 2],
    /// Unit heading on the ground.
    pub fwd: [f64; 2],
    /// Horizontal distance from the camera (sorts drawing), metres.
    pub dist: f64,
    /// Walking (false while standing still).
    pub walking: bool,
    /// Capsules of the body (unused for cars).
    pub parts: [Part; MAX_PARTS],
    /// Parts in use.
    pub n_parts: usize,
}

impl Actor {
    /// Path arc length at time `t`, or `None` when the actor is off its path.
    fn arc(&self, t: f64) -> Option<(f64, bool)> {
        let tau = t - self.t0;
        if tau < 0.0 {
            return None;
        }
        let (sp, d) = self.pause;
        let tp = sp / self.speed;
        let (s, walking) = if tau < tp {
            (tau * self.speed, true)
        } else if tau < tp + d {
            (sp, false)
        } else {
            ((tau - d) * self.speed, true)
        };
        (s <= self.path.length()).then_some((s, walking))
    }

    /// First and last instants the actor is on its path.
    pub fn span(&self) -> (f64, f64) {
        (
            self.t0,
            self.t0 + self.path.length() / self.speed + self.pause.1,
        )
    }

    /// The pose at time `t` seen by `proj`, or `None` when the actor is not on stage.
    pub fn pose(&self, index: usize, t: f64, proj: &Proj) -> Option<Pose> {
        let (s, walking) = self.arc(t)?;
        let (c, tan) = self.path.at(s);
        let left = [-tan[1], tan[0]];
        let root = [c[0] + left[0] * self.offset, c[1] + left[1] * self.offset];
        let mut pose = Pose {
            actor: index,
            foot: root,
            fwd: tan,
            dist: (root[0] * root[0] + root[1] * root[1]).sqrt(),
            walking,
            parts: [Part::default(); MAX_PARTS],
            n_parts: 0,
        };
        let phase = self.phase0 + 2.0 * PI * s / self.stride;
        match self.kind {
            Kind::Person => self.person_parts(&mut pose, phase, t),
            Kind::Dog => self.dog_parts(&mut pose, phase),
            Kind::Car => {}
        }
        // Sort the parts near to far, so that drawing with "first write wins" hides the far ones.
        let n = pose.n_parts;
        let depth = |p: &Part| {
            let m = [
                (p.a[0] + p.b[0]) * 0.5,
                (p.a[1] + p.b[1]) * 0.5,
                (p.a[2] + p.b[2]) * 0.5,
            ];
            proj.to_cam(m)[2]
        };
        // Insertion sort: tiny, allocation-free and deterministic.
        for i in 1..n {
            let mut j = i;
            while j > 0 && depth(&pose.parts[j]) < depth(&pose.parts[j - 1]) {
                pose.parts.swap(j, j - 1);
                j -= 1;
            }
        }
        Some(pose)
    }

    fn person_parts(&self, pose: &mut Pose, phase: f64, t: f64) {
        let h = self.height;
        let k = self.build;
        let f = [pose.fwd[0], pose.fwd[1]];
        let l = [-f[1], f[0]];
        // The legs bend backward at the knee, so the shoes sit behind the hips on average:
        // move the body forward by that average (0.0453·h walking, -0.0202·h standing,
        // from integrating the gait below over a cycle) so that, over a stride, the point
        // between the shoes follows the path.
        let centre = if pose.walking { 0.0453 } else { -0.0202 } * h;
        let root = [pose.foot[0] + f[0] * centre, pose.foot[1] + f[1] * centre];
        // Walking amplitudes; standing still keeps a little sway.
        let (hip_amp, arm_amp) = if pose.walking {
            (0.38, 0.38)
        } else {
            (0.0, 0.0)
        };
        let sway = if pose.walking {
            0.0
        } else {
            0.015 * sin(t * 1.3 + self.phase0)
        };
        let at = |fw: f64, lt: f64, z: f64| -> [f64; 3] {
            [
                root[0] + f[0] * fw + l[0] * (lt + sway),
                root[1] + f[1] * fw + l[1] * (lt + sway),
                z,
            ]
        };
        let lean = if pose.walking { 0.03 * h } else { 0.0 };
        let mut parts = [Part::default(); MAX_PARTS];
        let mut n = 0;
        let mut push = |p: Part| {
            parts[n] = p;
            n += 1;
        };
        // Legs: hip flexion alternates, the knee bends during the swing. The
        // body then drops until the lower ankle is at ankle height, which
        // gives the head bob (highest at mid-stance, lowest with legs spread).
        let upper = 0.245 * h;
        let lower = 0.246 * h;
        let ankle_min = 0.039 * h;
        let mut legs = [(0.0, 0.0, 0.0, 0.0, 0.0); 2];
        for (leg, ph) in legs.iter_mut().zip([0.0, PI]) {
            let a = hip_amp * sin(phase + ph);
            let swing = cos(phase + ph).max(0.0);
            let knee = if pose.walking {
                0.12 + 0.95 * swing * swing
            } else {
                0.05
            };
            let kfw = upper * sin(a);
            let kz = -upper * cos(a);
            let sfw = kfw + lower * sin(a - knee);
            let sz = kz - lower * cos(a - knee);
            *leg = (kfw, kz, sfw, sz, 0.0);
        }
        let drop = 0.53 * h + legs[0].3.min(legs[1].3) - ankle_min;
        let pelvis_z = 0.53 * h - drop;
        let mut shoe_mid = [0.0, 0.0];
        for (&(kfw, kz, sfw, sz, _), side) in legs.iter().zip([1.0, -1.0]) {
            let (kz, sz) = (pelvis_z + kz, pelvis_z + sz);
            let hip = at(0.0, side * 0.055 * h * k, pelvis_z);
            let knee_p = at(kfw, side * 0.05 * h * k, kz);
            let ankle = at(sfw, side * 0.045 * h * k, sz);
            let lift = sz - ankle_min;
            push(Part {
                a: hip,
                b: knee_p,
                ra: 0.042 * h * k,
                rb: 0.031 * h * k,
                col: super::people::slot::TROUSERS,
                head: false,
            });
            push(Part {
                a: knee_p,
                b: ankle,
                ra: 0.029 * h * k,
                rb: 0.021 * h,
                col: slot::SHIN,
                head: false,
            });
            let rf = 0.018 * h;
            let heel = at(sfw - 0.02 * h, side * 0.045 * h * k, rf + lift);
            let toe = at(sfw + 0.085 * h, side * 0.05 * h * k, rf * 0.8 + lift * 0.6);
            shoe_mid[0] += 0.25 * (heel[0] + toe[0]);
            shoe_mid[1] += 0.25 * (heel[1] + toe[1]);
            push(Part {
                a: heel,
                b: toe,
                ra: rf,
                rb: rf * 0.85,
                col: slot::SHOES,
                head: false,
            });
        }
        // Pelvis and torso (two side-by-side capsules: wide from the front, narrow from the side).
        push(Part {
            a: at(0.0, 0.06 * h * k, pelvis_z + 0.01 * h),
            b: at(0.0, -0.06 * h * k, pelvis_z + 0.01 * h),
            ra: 0.05 * h * k,
            rb: 0.05 * h * k,
            col: slot::TROUSERS,
            head: false,
        });
        let chest_z = pelvis_z + 0.245 * h;
        for side in [1.0, -1.0] {
            push(Part {
                a: at(0.0, side * 0.045 * h * k, pelvis_z + 0.06 * h),
                b: at(lean, side * 0.05 * h * k, chest_z),
                ra: 0.05 * h * k,
                rb: 0.055 * h * k,
                col: slot::SHIRT,
                head: false,
            });
        }
        // Neck and head; the head top sits at the standing height minus the bob.
        let top = h - drop;
        let rh = 0.052 * h;
        push(Part {
            a: at(lean, 0.0, chest_z),
            b: at(lean * 1.1, 0.0, top - 0.12 * h),
            ra: 0.03 * h,
            rb: 0.027 * h,
            col: slot::SKIN,
            head: false,
        });
        push(Part {
            a: at(lean * 1.15, 0.0, top - rh),
            b: at(lean * 1.15 + 0.008 * h, 0.0, top - 0.125 * h + rh),
            ra: rh,
            rb: rh * 0.92,
            col: slot::SKIN,
            head: true,
        });
        // Arms swing against the legs.
        let shoulder_z = chest_z + 0.02 * h;
        for (side, ph) in [(1.0, PI), (-1.0, 0.0)] {
            let b = arm_amp * sin(phase + ph);
            let elbow = 0.25 + 0.2 * (0.5 + 0.5 * sin(phase + ph));
            let sh = at(lean, side * 0.115 * h * k, shoulder_z);
            let ua = 0.186 * h;
            let efw = lean + ua * sin(b);
            let ez = shoulder_z - ua * cos(b);
            let el = at(efw, side * 0.125 * h * k, ez);
            let fa = 0.2 * h;
            let hand = at(
                efw + fa * sin(b + elbow),
                side * 0.12 * h * k,
                ez - fa * cos(b + elbow),
            );
            push(Part {
                a: sh,
                b: el,
                ra: 0.032 * h * k,
                rb: 0.026 * h * k,
                col: slot::SHIRT,
                head: false,
            });
            push(Part {
                a: el,
                b: hand,
                ra: 0.024 * h * k,
                rb: 0.02 * h,
                col: slot::FOREARM,
                head: false,
            });
        }
        pose.parts = parts;
        pose.n_parts = n;
        // The truth's foot point is the ground point between the shoes.
        pose.foot = shoe_mid;
    }

    fn dog_parts(&self, pose: &mut Pose, phase: f64) {
        let h = self.height; // top of the head
        let f = pose.fwd;
        let root = pose.foot;
        let at = |fw: f64, lt: f64, z: f64| -> [f64; 3] {
            [
                root[0] + f[0] * fw - f[1] * lt,
                root[1] + f[1] * fw + f[0] * lt,
                z,
            ]
        };
        let body_z = 0.68 * h;
        let len = 0.75 * h;
        let mut n = 0;
        let mut parts = [Part::default(); MAX_PARTS];
        let mut push = |p: Part| {
            parts[n] = p;
            n += 1;
        };
        push(Part {
            a: at(-0.5 * len, 0.0, body_z),
            b: at(0.5 * len, 0.0, body_z + 0.03 * h),
            ra: 0.17 * h,
            rb: 0.19 * h,
            col: slot::SHIRT,
            head: false,
        });
        push(Part {
            a: at(0.55 * len, 0.0, body_z + 0.1 * h),
            b: at(0.62 * len, 0.0, h - 0.12 * h),
            ra: 0.1 * h,
            rb: 0.12 * h,
            col: slot::SHIRT,
            head: false,
        });
        push(Part {
            a: at(0.66 * len, 0.0, h - 0.12 * h),
            b: at(0.9 * len, 0.0, h - 0.2 * h),
            ra: 0.09 * h,
            rb: 0.05 * h,
            col: slot::TROUSERS,
            head: false,
        });
        // Tail, wagging slightly with the trot.
        push(Part {
            a: at(-0.5 * len, 0.0, body_z + 0.05 * h),
            b: at(-0.8 * len, 0.1 * h * sin(phase * 2.0), body_z + 0.25 * h),
            ra: 0.04 * h,
            rb: 0.025 * h,
            col: slot::SHIRT,
            head: false,
        });
        // Legs: diagonal pairs move together (trot).
        for (fw, lt, ph) in [
            (0.42, 0.1, 0.0),
            (0.42, -0.1, PI),
            (-0.42, 0.1, PI),
            (-0.42, -0.1, 0.0),
        ] {
            let a = 0.45 * sin(phase + ph);
            let top = at(fw * len, lt * h, body_z);
            let leg = body_z;
            let foot = at(
                fw * len + leg * sin(a),
                lt * h,
                (body_z - leg * cos(a)).max(0.03 * h),
            );
            push(Part {
                a: top,
                b: foot,
                ra: 0.06 * h,
                rb: 0.035 * h,
                col: slot::SHIRT,
                head: false,
            });
        }
        pose.parts = parts;
        pose.n_parts = n;
    }
}

/// Car box dimensions in its own frame (x forward, y left, z up), metres.
pub mod car {
    /// Half length of the body.
    pub const HALF_LEN: f64 = 2.15;
    /// Half width of the body.
    pub const HALF_WID: f64 = 0.88;
    /// Body bottom and top.
    pub const BODY_Z: (f64, f64) = (0.3, 0.95);
    /// Cabin x extent.
    pub const CABIN_X: (f64, f64) = (-1.2, 0.85);
    /// Cabin half width.
    pub const CABIN_HALF_WID: f64 = 0.78;
    /// Roof height (the car's "standing height").
    pub const ROOF: f64 = 1.45;
    /// Wheel radius.
    pub const WHEEL_R: f64 = 0.32;
    /// Wheel centre x positions.
    pub const WHEEL_X: [f64; 2] = [-1.35, 1.35];
}

/// Draws the whole cast for `spec` from `seed` over `duration` seconds.
pub fn cast(spec: &SceneSpec, proj: &Proj, seed: u64, duration: f64) -> Vec<Actor> {
    let mut rng = Rng::new(seed ^ 0x5354_4154_5552_4531);
    let mut actors = Vec::new();
    let mut next_id = 1u32;
    let mut next_group = 1u32;
    let area = WalkArea::new(spec, proj);
    let props = prop_footprints(spec, proj);
    // People and groups arrive spread evenly over the clip (with jitter), some already on stage at t = 0.
    let pre = 14.0;
    let span = duration + pre;
    let n_people = ((spec.people_per_min / 60.0) * span).round() as usize;
    let mut placed = 0;
    let mut slot_i = 0usize;
    while placed < n_people {
        let t_arrive = -pre + (slot_i as f64 + rng.uniform()) * span / n_people.max(1) as f64;
        slot_i += 1;
        let members = if rng.chance(spec.group_chance) {
            2 + rng.below(2) as usize
        } else {
            1
        }
        .min(n_people - placed)
        .max(1);
        let path = area.path(&mut rng, proj, &props, spec.curve_chance);
        let speed = (1.35 + 0.15 * rng.normal()).clamp(0.9, 1.8);
        let pause = if rng.chance(spec.pause_chance) {
            (path.length() * rng.range(0.3, 0.6), rng.range(2.0, 7.0))
        } else {
            (0.0, 0.0)
        };
        let group = if members > 1 {
            next_group += 1;
            next_group - 1
        } else {
            0
        };
        for m in 0..members {
            let offset = if members == 1 {
                0.0
            } else {
                (m as f64 - (members as f64 - 1.0) / 2.0) * 0.62 + 0.05 * rng.normal()
            };
            let height = (1.70 + 0.08 * rng.normal()).clamp(1.45, 1.98);
            actors.push(Actor {
                id: next_id,
                kind: Kind::Person,
                height,
                group,
                palette: person_palette(&mut rng),
                path: path.clone(),
                offset,
                speed,
                t0: t_arrive + 0.15 * rng.normal(),
                pause,
                phase0: rng.range(0.0, 2.0 * PI),
                stride: 0.83 * height * rng.range(0.92, 1.08),
                build: rng.range(0.9, 1.15),
            });
            next_id += 1;
        }
        placed += members;
    }
    // Dogs trot along paths of their own.
    let n_dogs = ((spec.dogs_per_min / 60.0) * duration).round() as usize;
    for i in 0..n_dogs {
        // Dogs and cars cross during the clip (not before it), so that each one is seen.
        let t = -4.0 + (i as f64 + rng.uniform()) * duration / n_dogs as f64;
        let path = area.path(&mut rng, proj, &props, 0.6);
        let height = rng.range(0.45, 0.7);
        let coat = pick(
            &mut rng,
            &[
                [120, 85, 50],
                [40, 35, 30],
                [200, 170, 120],
                [230, 225, 215],
            ],
        );
        let mut palette = [coat; PALETTE];
        palette[slot::TROUSERS as usize] = shade(coat, 0.75);
        palette[slot::DARK as usize] = [20, 20, 20];
        actors.push(Actor {
            id: next_id,
            kind: Kind::Dog,
            height,
            group: 0,
            palette,
            path,
            offset: 0.0,
            speed: rng.range(1.3, 2.2),
            t0: t,
            pause: (0.0, 0.0),
            phase0: rng.range(0.0, 2.0 * PI),
            stride: 0.9 * height * 1.6,
            build: 1.0,
        });
        next_id += 1;
    }
    // Cars drive straight across along world x at a depth where the road is in view.
    let n_cars = ((spec.cars_per_min / 60.0) * duration).round() as usize;
    for i in 0..n_cars {
        let t = -1.0 + (i as f64 + rng.uniform()) * duration / n_cars as f64;
        let row = rng.range(0.4, 0.75) * spec.height as f64;
        let y = proj
            .ground(proj.pu, row)
            .map_or(12.0, |g| g[1])
            .min(spec.max_distance);
        let x_reach = area.half_width(y) + 5.0;
        let (a, b) = if rng.chance(0.5) {
            ([-x_reach, y], [x_reach, y])
        } else {
            ([x_reach, y + 2.0], [-x_reach, y + 2.0])
        };
        let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
        let colour = pick(
            &mut rng,
            &[
                [180, 30, 30],
                [30, 60, 140],
                [200, 200, 205],
                [25, 25, 28],
                [90, 95, 100],
                [220, 210, 190],
            ],
        );
        let mut palette = [colour; PALETTE];
        palette[slot::DARK as usize] = [35, 45, 55];
        palette[slot::SHOES as usize] = [20, 20, 20];
        actors.push(Actor {
            id: next_id,
            kind: Kind::Car,
            height: car::ROOF,
            group: 0,
            palette,
            path: Path::bezier(a, mid, b),
            offset: 0.0,
            speed: rng.range(6.0, 10.0),
            t0: t,
            pause: (0.0, 0.0),
            phase0: 0.0,
            stride: 1.0,
            build: 1.0,
        });
        next_id += 1;
    }
    actors
}

fn pick(rng: &mut Rng, options: &[Rgb]) -> Rgb {
    options[rng.below(options.len() as u64) as usize]
}

fn shade(c: Rgb, k: f64) -> Rgb {
    [
        (c[0] as f64 * k) as u8,
        (c[1] as f64 * k) as u8,
        (c[2] as f64 * k) as u8,
    ]
}

fn person_palette(rng: &mut Rng) -> [Rgb; PALETTE] {
    let skin = pick(
        rng,
        &[
            [235, 200, 170],
            [210, 165, 130],
            [165, 115, 80],
            [110, 75, 50],
            [225, 185, 150],
        ],
    );
    let hair = pick(
        rng,
        &[
            [25, 20, 18],
            [70, 45, 25],
            [140, 100, 55],
            [200, 170, 110],
            [130, 130, 130],
        ],
    );
    let shirt = pick(
        rng,
        &[
            [200, 40, 40],
            [40, 80, 170],
            [235, 235, 230],
            [30, 30, 35],
            [60, 130, 70],
            [230, 190, 50],
            [120, 60, 140],
            [150, 150, 155],
            [210, 120, 60],
            [80, 150, 200],
            [110, 85, 60],
        ],
    );
    let trousers = pick(
        rng,
        &[
            [40, 50, 90],
            [30, 30, 32],
            [90, 90, 95],
            [150, 130, 100],
            [60, 70, 120],
            [20, 25, 45],
            [170, 165, 160],
        ],
    );
    let shoes = pick(rng, &[[20, 20, 20], [240, 240, 240], [90, 60, 40]]);
    let forearm = if rng.chance(0.5) { skin } else { shirt };
    let shin = if rng.chance(0.15) { skin } else { trousers };
    [
        skin,
        hair,
        shirt,
        trousers,
        shoes,
        forearm,
        shin,
        [20, 20, 20],
    ]
}

/// Ground footprints of the props (x0, y0, x1, y1) that paths avoid.
fn prop_footprints(spec: &SceneSpec, proj: &Proj) -> Vec<[f64; 4]> {
    spec.props
        .iter()
        .filter_map(|p| super::background::prop_box(p, spec, proj))
        .map(|b| [b.lo[0], b.lo[1], b.hi[0], b.hi[1]])
        .collect()
}

/// The part of the ground people walk on: in view and within the scene's distance.
struct WalkArea {
    y_near: f64,
    y_far: f64,
    w: f64,
    h: f64,
    f: f64,
    proj: Proj,
}

impl WalkArea {
    fn new(spec: &SceneSpec, proj: &Proj) -> Self {
        // The bottom image row's ground distance (or close to the camera when the bottom shows the sky).
        let y_bottom = proj
            .ground(proj.pu, spec.height as f64 - 1.0)
            .map_or(1.0, |g| g[1]);
        WalkArea {
            y_near: (y_bottom - 2.0).max(0.5),
            y_far: spec.max_distance,
            w: spec.width as f64,
            h: spec.height as f64,
            f: spec.f,
            proj: *proj,
        }
    }

    /// Half the width of the view at ground depth `y`, with a margin, metres.
    fn half_width(&self, y: f64) -> f64 {
        // The image row showing depth y, back-projected at both image edges.
        let fallback = y.max(1.0) * self.w / (2.0 * self.f) * 1.5 + 2.0;
        let Some((c, _)) = self.proj.project([0.0, y, 0.0]) else {
            return fallback;
        };
        match (
            self.proj.ground(0.0, c[1]),
            self.proj.ground(self.w - 1.0, c[1]),
        ) {
            (Some(l), Some(r)) => l[0].abs().max(r[0].abs()) + 1.5,
            _ => fallback,
        }
    }

    /// How much of a person at ground point `g` is in the image (0 outside, 1 fully in with margin).
    fn visible(&self, proj: &Proj, g: [f64; 2]) -> bool {
        if g[1] > self.y_far {
            return false;
        }
        let (Some((f, _)), Some((hd, _))) = (
            proj.project([g[0], g[1], 0.0]),
            proj.project([g[0], g[1], 1.75]),
        ) else {
            return false;
        };
        let m = 0.02 * self.w;
        let inside = |p: [f64; 2]| p[0] > m && p[0] < self.w - m && p[1] > m && p[1] < self.h - m;
        inside(f) && inside(hd)
    }

    /// True when a person at `g` is entirely out of the picture.
    fn hidden(&self, proj: &Proj, g: [f64; 2]) -> bool {
        let (Some((f, _)), Some((hd, _))) = (
            proj.project([g[0], g[1], 0.0]),
            proj.project([g[0], g[1], 1.9]),
        ) else {
            return true;
        };
        let half = 0.35 * (f[1] - hd[1]).abs() + 4.0;
        let x0 = f[0].min(hd[0]) - half;
        let x1 = f[0].max(hd[0]) + half;
        let y0 = hd[1].min(f[1]) - 4.0;
        let y1 = hd[1].max(f[1]) + 4.0;
        x1 < 0.0 || x0 > self.w || y1 < 0.0 || y0 > self.h
    }

    /// A path that starts and ends out of view, crosses the view and avoids the props.
    fn path(&self, rng: &mut Rng, proj: &Proj, props: &[[f64; 4]], curve_chance: f64) -> Path {
        let mut best: Option<(f64, Path)> = None;
        for _ in 0..200 {
            let a = self.endpoint(rng, proj);
            let mut b = self.endpoint(rng, proj);
            for _ in 0..4 {
                if (b[0] - a[0]).abs() + (b[1] - a[1]).abs() > 6.0 {
                    break;
                }
                b = self.endpoint(rng, proj);
            }
            let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            let c = if rng.chance(curve_chance) {
                let k = rng.range(-0.35, 0.35);
                [mid[0] - dy * k, mid[1] + dx * k]
            } else {
                mid
            };
            let path = Path::bezier(a, c, b);
            let len = path.length();
            if len < 4.0 {
                continue;
            }
            // Score: the fraction of the walk in full view; reject paths through props.
            let mut seen = 0;
            let mut blocked = false;
            for i in 0..=40 {
                let (p, _) = path.at(len * i as f64 / 40.0);
                if self.visible(proj, p) {
                    seen += 1;
                }
                blocked |= props.iter().any(|r| {
                    p[0] > r[0] - 0.7 && p[0] < r[2] + 0.7 && p[1] > r[1] - 0.7 && p[1] < r[3] + 0.7
                });
            }
            let score = seen as f64 / 41.0;
            if blocked {
                continue;
            }
            if score >= 0.35 {
                return path;
            }
            if best.as_ref().is_none_or(|(s, _)| score > *s) {
                best = Some((score, path));
            }
        }
        best.map_or_else(
            || Path::bezier([-10.0, 10.0], [0.0, 10.0], [10.0, 10.0]),
            |(_, p)| p,
        )
    }

    /// A ground point just outside the view: beyond the left or right edge, below the bottom,
    /// or far away when the far side is itself out of the picture.
    fn endpoint(&self, rng: &mut Rng, proj: &Proj) -> [f64; 2] {
        for _ in 0..50 {
            let side = rng.below(4);
            let y = rng.range(self.y_near, self.y_far);
            let p = match side {
                0 | 1 => {
                    let x = self.half_width(y) * if side == 0 { -1.0 } else { 1.0 };
                    [x, y]
                }
                2 => {
                    let y = self.y_near;
                    [rng.range(-self.half_width(y), self.half_width(y)), y]
                }
                _ => {
                    let y = self.y_far + 2.0;
                    [rng.range(-self.half_width(y), self.half_width(y)), y]
                }
            };
            if self.hidden(proj, p) {
                return p;
            }
            // Push sideways until out of the picture.
            let mut q = p;
            for _ in 0..20 {
                q[0] *= 1.25;
                q[0] += q[0].signum() * 0.5;
                if self.hidden(proj, q) {
                    return q;
                }
            }
        }
        [-self.half_width(self.y_far), self.y_far]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn path_is_arc_length_parameterised() {
        let p = Path::bezier([0.0, 0.0], [5.0, 0.0], [10.0, 0.0]);
        assert!((p.length() - 10.0).abs() < 1e-9);
        let (q, t) = p.at(2.5);
        assert!((q[0] - 2.5).abs() < 1e-9 && (t[0] - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_walker_keeps_feet_on_the_ground_and_head_near_its_height() {
        let spec = super::super::scene::find("plaza").unwrap();
        let proj = Proj::new(
            spec.f,
            spec.tilt_deg,
            spec.roll_deg,
            spec.camera_height,
            640,
            480,
        );
        let cast = cast(spec, &proj, 3, 30.0);
        let (i, person) = cast
            .iter()
            .enumerate()
            .find(|(_, a)| a.kind == Kind::Person)
            .unwrap();
        let (t0, t1) = person.span();
        let mut t = t0;
        while t < t1 {
            let pose = person.pose(i, t, &proj).unwrap();
            let parts = &pose.parts[..pose.n_parts];
            let low = parts
                .iter()
                .map(|p| (p.a[2] - p.ra).min(p.b[2] - p.rb))
                .fold(f64::MAX, f64::min);
            let high = parts
                .iter()
                .map(|p| (p.a[2] + p.ra).max(p.b[2] + p.rb))
                .fold(f64::MIN, f64::max);
            assert!(low.abs() < 0.01, "lowest point {low}");
            assert!(
                high <= person.height + 1e-3 && high > person.height - 0.06,
                "top {high} for {}",
                person.height
            );
            t += 0.037;
        }
    }
}
