//! The built-in simulated scene: people walking past a known camera, with
//! exact ground truth.
//!
//! `sim:NAME?seed=N&frames=N` opens scene `NAME` (see [`scene::scenes`] or
//! `stature sim --list`). Everything random is drawn from `seed` when the
//! source opens (the cast, their paths, clothes and heights, the textures and
//! the noise table), and frame `k` is then a pure function of `k`: the same
//! scene and seed give the same bytes on every platform (no libm, no hash
//! order, no float formatting in the pixels).
//!
//! Other options: `empty=1` renders the scene without any actor (same
//! background, noise and drift: a reference for tests), `shadows=0|1`
//! overrides the scene's moving shadows, `noise=N` sets the sensor noise
//! standard deviation in luma levels (0..=40).
//!
//! Rendering writes into the caller's [`Frame`] and allocates nothing per
//! frame: the background, noise table, palettes and scratch buffers are
//! built at open. After each frame, [`SimSource::truth`] lists the objects
//! in view and [`SimSource::scene_truth`] holds the camera.
//!
//! Modules: [`scene`] (the named scenes), [`people`] (the cast and their
//! articulated poses), `background` (the static scene, ray-traced once),
//! `render` (per-frame drawing), [`truth`] (what the tests and the demo
//! compare against), [`export`] (Y4M, JSON and PNG writers for `stature sim`).

mod background;
pub mod demo;
pub mod export;
pub mod math;
pub mod people;
mod render;
pub mod scene;
pub mod truth;

use super::{query_pairs, FrameSource, Next, SourceError, SourceInfo};
use crate::frame::{Frame, Size};
use math::Proj;
use people::{Actor, Kind, Pose};
use scene::SceneSpec;
pub use truth::{CastMember, ObjectTruth, SceneTruth};

/// Longest clip accepted (11 hours at 25 fps): the cast is drawn for the whole
/// clip at open, so its memory grows with the length.
pub const MAX_FRAMES: u64 = 1_000_000;

/// The built-in scene called `name`, or an error listing them all.
pub fn scene_named(name: &str) -> Result<&'static SceneSpec, SourceError> {
    scene::find(name).ok_or_else(|| {
        let names: Vec<&str> = scene::scenes().iter().map(|s| s.name).collect();
        SourceError::Spec(format!(
            "unknown scene `{name}` (expected one of: {})",
            names.join(", ")
        ))
    })
}

/// How to open a scene (what the `sim:` query string sets).
#[derive(Clone, Debug, PartialEq)]
pub struct SimOptions {
    /// Seed of everything random (default 1).
    pub seed: u64,
    /// Clip length in frames (default: the scene's).
    pub frames: Option<u64>,
    /// Render no actors at all.
    pub empty: bool,
    /// Override the scene's moving shadows.
    pub shadows: Option<bool>,
    /// Override the sensor noise (standard deviation, luma levels).
    pub noise: Option<f64>,
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            seed: 1,
            frames: None,
            empty: false,
            shadows: None,
            noise: None,
        }
    }
}

impl SimOptions {
    /// Parses `seed=N&frames=N&empty=0|1&shadows=0|1&noise=N`.
    pub fn parse(query: &str) -> Result<Self, SourceError> {
        let mut o = SimOptions::default();
        let bad = |k: &str, v: &str, want: &str| {
            SourceError::Spec(format!("sim option `{k}={v}`: expected {want}"))
        };
        let flag = |k: &str, v: &str| match v {
            "0" | "false" => Ok(false),
            "1" | "true" | "" => Ok(true),
            _ => Err(bad(k, v, "0 or 1")),
        };
        let pairs = query_pairs(query)
            .map_err(|k| SourceError::Spec(format!("sim option `{k}` given twice in `{query}`")))?;
        for (k, v) in pairs {
            match k {
                "seed" => o.seed = v.parse().map_err(|_| bad(k, v, "an integer >= 0"))?,
                "frames" => match v.parse::<u64>() {
                    Ok(n) if (1..=MAX_FRAMES).contains(&n) => o.frames = Some(n),
                    _ => return Err(bad(k, v, &format!("an integer in 1..={MAX_FRAMES}"))),
                },
                "empty" => o.empty = flag(k, v)?,
                "shadows" => o.shadows = Some(flag(k, v)?),
                "noise" => match v.parse::<f64>() {
                    Ok(n) if (0.0..=40.0).contains(&n) => o.noise = Some(n),
                    _ => return Err(bad(k, v, "a number in 0..=40")),
                },
                _ => {
                    return Err(SourceError::Spec(format!(
                        "unknown sim option `{k}` (expected seed, frames, empty, shadows, noise)"
                    )))
                }
            }
        }
        Ok(o)
    }
}

/// The URI that opens the same clip again: every option that was given
/// (the report's `hello` record and the log carry it, so a run can be
/// reproduced from its records alone).
fn describe(scene: &str, opts: &SimOptions, frames: u64) -> String {
    let mut d = format!("sim:{scene}?seed={}&frames={frames}", opts.seed);
    if opts.empty {
        d.push_str("&empty=1");
    }
    if let Some(s) = opts.shadows {
        d.push_str(if s { "&shadows=1" } else { "&shadows=0" });
    }
    if let Some(n) = opts.noise {
        d.push_str(&format!("&noise={n}"));
    }
    d
}

/// Renders a named scene frame by frame, with its ground truth.
pub struct SimSource {
    info: SourceInfo,
    spec: SceneSpec,
    opts: SimOptions,
    proj: Proj,
    /// Seed mixed with the scene name: drives the cast, textures and noise.
    seed: u64,
    frames: u64,
    next: u64,
    bg: background::Background,
    actors: Vec<Actor>,
    poses: Vec<Pose>,
    renderer: render::Renderer,
    truth: Vec<ObjectTruth>,
    scene_truth: SceneTruth,
}

impl SimSource {
    /// Opens scene `name` with the `sim:` query options (`seed=N&frames=N&...`).
    pub fn open(name: &str, query: &str) -> Result<Self, SourceError> {
        Ok(Self::new(scene_named(name)?, &SimOptions::parse(query)?))
    }

    /// Opens a `sim:NAME?...` URI.
    pub fn open_uri(uri: &str) -> Result<Self, SourceError> {
        match super::split_uri(uri) {
            Some(("sim", name, query)) => Self::open(name, query),
            _ => Err(SourceError::Spec(format!("`{uri}` is not a sim: source"))),
        }
    }

    /// Builds scene `spec` with `opts`: draws the cast, ray-traces the background and sizes every buffer.
    pub fn new(spec: &SceneSpec, opts: &SimOptions) -> Self {
        let mut spec = spec.clone();
        if let Some(s) = opts.shadows {
            spec.shadows = s;
        }
        if let Some(n) = opts.noise {
            spec.noise = n;
        }
        let frames = opts.frames.unwrap_or(spec.frames).clamp(1, MAX_FRAMES);
        let proj = spec.projection();
        // The seed picks the cast and textures; the scene name keeps scenes apart for the same seed.
        let seed = math::mix64(opts.seed) ^ name_hash(spec.name);
        let duration = frames as f64 / spec.fps as f64;
        let actors = if opts.empty {
            Vec::new()
        } else {
            people::cast(&spec, &proj, seed, duration)
        };
        let bg = background::render(&spec, &proj, seed);
        let renderer = render::Renderer::new(&spec, &actors, seed);
        let scene_truth = scene_truth(&spec, &proj, opts.seed, frames);
        let info = SourceInfo {
            size: Size {
                width: spec.width,
                height: spec.height,
            },
            fps: (spec.fps, 1),
            description: describe(spec.name, opts, frames),
            grey: false,
        };
        SimSource {
            info,
            poses: Vec::with_capacity(actors.len()),
            truth: Vec::with_capacity(actors.len()),
            spec,
            opts: opts.clone(),
            proj,
            seed,
            frames,
            next: 0,
            bg,
            actors,
            renderer,
            scene_truth,
        }
    }

    /// The scene being rendered (after option overrides).
    pub fn spec(&self) -> &SceneSpec {
        &self.spec
    }

    /// The options it was opened with.
    pub fn options(&self) -> &SimOptions {
        &self.opts
    }

    /// The camera, exactly.
    pub fn scene_truth(&self) -> &SceneTruth {
        &self.scene_truth
    }

    /// Objects in view in the last frame rendered (empty before the first).
    pub fn truth(&self) -> &[ObjectTruth] {
        &self.truth
    }

    /// Index of the frame the next call to `next_frame` renders.
    pub fn position(&self) -> u64 {
        self.next
    }

    /// Makes `frame` the next frame to render (frames are independent of each other).
    pub fn seek(&mut self, frame: u64) {
        self.next = frame;
    }

    /// Frames in the clip.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Renders frame `index` into `frame` and fills [`SimSource::truth`]; no allocation.
    pub fn render(&mut self, index: u64, frame: &mut Frame) {
        let t = index as f64 / self.spec.fps as f64;
        self.poses.clear();
        for (i, a) in self.actors.iter().enumerate() {
            let (t0, t1) = a.span();
            if t < t0 || t > t1 || self.poses.len() == self.poses.capacity() {
                continue;
            }
            if let Some(p) = a.pose(i, t, &self.proj) {
                self.poses.push(p);
            }
        }
        // Near to far; the id breaks ties so the order never depends on the sort algorithm.
        let actors = &self.actors;
        self.poses.sort_unstable_by(|a, b| {
            a.dist
                .total_cmp(&b.dist)
                .then(actors[a.actor].id.cmp(&actors[b.actor].id))
        });
        self.renderer.draw(
            frame,
            &self.spec,
            &self.proj,
            &self.bg,
            &self.actors,
            &self.poses,
            self.seed,
            index,
            t,
            &mut self.truth,
        );
        frame.index = index;
    }

    /// Every member of the cast, with the frames in which it is in view (head and foot
    /// points inside the image). Computed from the geometry alone (no rendering); allocates.
    pub fn cast(&self) -> Vec<CastMember> {
        let (w, h) = (self.spec.width as f64, self.spec.height as f64);
        let inside = |p: [f64; 2]| p[0] >= 0.0 && p[1] >= 0.0 && p[0] <= w - 1.0 && p[1] <= h - 1.0;
        self.actors
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let mut m = member(a);
                // Only the frames while the actor is on its path.
                let fps = self.spec.fps as f64;
                let (t0, t1) = a.span();
                let k0 = (t0 * fps).floor().max(0.0) as u64;
                let k1 = ((t1 * fps).ceil().max(0.0) as u64).min(self.frames.saturating_sub(1));
                for k in k0..=k1 {
                    let t = k as f64 / fps;
                    let Some(p) = a.pose(i, t, &self.proj) else {
                        continue;
                    };
                    let foot = self.proj.project([p.foot[0], p.foot[1], 0.0]);
                    let head = self.proj.project([p.foot[0], p.foot[1], a.height]);
                    if let (Some((f, _)), Some((hd, _))) = (foot, head) {
                        if inside(f) && inside(hd) {
                            if m.frames_in_view == 0 {
                                m.first_frame = k;
                            }
                            m.frames_in_view += 1;
                            m.last_frame = k;
                        }
                    }
                }
                m
            })
            .collect()
    }

    /// The person whose true foot point in frame `frame` is nearest `foot_px`, within `tol_px`
    /// (to match a reported height to the truth). Geometry only; no allocation.
    pub fn person_at(&self, frame: u64, foot_px: [f64; 2], tol_px: f64) -> Option<CastMember> {
        let t = frame as f64 / self.spec.fps as f64;
        let mut best: Option<(f64, &Actor)> = None;
        for (i, a) in self.actors.iter().enumerate() {
            if a.kind != Kind::Person {
                continue;
            }
            let Some(p) = a.pose(i, t, &self.proj) else {
                continue;
            };
            let Some((f, _)) = self.proj.project([p.foot[0], p.foot[1], 0.0]) else {
                continue;
            };
            let d = ((f[0] - foot_px[0]).powi(2) + (f[1] - foot_px[1]).powi(2)).sqrt();
            if d <= tol_px && best.is_none_or(|b| d < b.0) {
                best = Some((d, a));
            }
        }
        best.map(|(_, a)| member(a))
    }
}

/// The cast entry of an actor, with no frames in view counted yet.
fn member(a: &Actor) -> CastMember {
    CastMember {
        id: a.id,
        kind: a.kind,
        height_m: a.height,
        group: a.group,
        frames_in_view: 0,
        first_frame: 0,
        last_frame: 0,
    }
}

fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01B3)
    })
}

fn scene_truth(spec: &SceneSpec, proj: &Proj, seed: u64, frames: u64) -> SceneTruth {
    let r = proj.r;
    // Vertical vanishing point: image of the downward direction (0, 0, -1).
    let d = [-r[0][2], -r[1][2], -r[2][2]];
    let vvp = [
        proj.pu + proj.f * d[0] / d[2],
        proj.pv + proj.f * d[1] / d[2],
    ];
    // Horizon: pixels whose ray is horizontal; oriented so the ground side is positive.
    let (a, b, cz) = (-r[0][2], -r[1][2], -r[2][2]);
    let c = cz * proj.f - a * proj.pu - b * proj.pv;
    let n = (a * a + b * b).sqrt();
    SceneTruth {
        scene: spec.name.to_string(),
        seed,
        width: spec.width,
        height: spec.height,
        fps: spec.fps,
        frames,
        f_px: spec.f,
        tilt_deg: spec.tilt_deg,
        roll_deg: spec.roll_deg,
        camera_height_m: spec.camera_height,
        principal: [proj.pu, proj.pv],
        k: [
            [proj.f, 0.0, proj.pu],
            [0.0, proj.f, proj.pv],
            [0.0, 0.0, 1.0],
        ],
        r,
        vertical_vp: vvp,
        horizon: [a / n, b / n, c / n],
    }
}

impl FrameSource for SimSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn length(&self) -> Option<u64> {
        Some(self.frames)
    }

    fn next_frame(&mut self, frame: &mut Frame) -> Result<Next, SourceError> {
        if self.next >= self.frames {
            return Ok(Next::End);
        }
        if frame.size() != self.info.size {
            return Err(SourceError::Format {
                frame: self.next,
                offset: 0,
                what: "frame buffer size differs from the scene's".into(),
            });
        }
        let k = self.next;
        self.render(k, frame);
        self.next += 1;
        Ok(Next::Frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Before: `empty`, `shadows` and `noise` were left out of the
    /// description, so the `hello` record named a different clip.
    #[test]
    fn the_description_reopens_the_same_clip() {
        for query in [
            "",
            "seed=7",
            "seed=3&frames=40&empty=1",
            "shadows=0&noise=5",
            "shadows=1&noise=2.5&seed=9",
        ] {
            let opts = SimOptions::parse(query).unwrap();
            let d = describe("plaza", &opts, 40);
            let (scheme, name, q) = crate::source::split_uri(&d).unwrap();
            assert_eq!((scheme, name), ("sim", "plaza"), "{d}");
            let again = SimOptions::parse(q).unwrap();
            assert_eq!(
                again,
                SimOptions {
                    frames: Some(40),
                    ..opts
                },
                "{query} -> {d}"
            );
        }
        assert_eq!(
            describe(
                "low",
                &SimOptions::parse("noise=5&shadows=0&empty=1").unwrap(),
                3
            ),
            "sim:low?seed=1&frames=3&empty=1&shadows=0&noise=5"
        );
    }
}
