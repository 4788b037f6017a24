//! The static part of a scene, ray-traced once when the source opens: the
//! textured ground, building facades and sky, the props (pole, bench, wall)
//! with their baked shadows, a per-pixel depth map that lets props hide the
//! actors behind them, and per-pixel ground coordinates for moving shadows.

use super::math::{cos, hash2, rad, sin, smoothstep, Proj};
use super::scene::{Ground, Prop, SceneSpec};

/// Depth-map value of sky and facades (nothing there hides an actor).
pub const FAR: u16 = u16::MAX;
/// Depth-map value of open ground (actors cast shadows here).
pub const GROUND: u16 = u16::MAX - 1;

/// An axis-aligned box in world coordinates, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub lo: [f64; 3],
    /// Maximum corner.
    pub hi: [f64; 3],
}

impl Aabb {
    /// Ray parameter and outward normal where the ray `o + t·d` enters the box.
    pub fn hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<(f64, [f64; 3])> {
        let (mut t0, mut t1) = (0.0f64, f64::MAX);
        let mut axis = 0;
        let mut sign = 1.0;
        for i in 0..3 {
            if d[i].abs() < 1e-12 {
                if o[i] < self.lo[i] || o[i] > self.hi[i] {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d[i];
            let (mut a, mut b) = ((self.lo[i] - o[i]) * inv, (self.hi[i] - o[i]) * inv);
            let mut s = -1.0;
            if a > b {
                core::mem::swap(&mut a, &mut b);
                s = 1.0;
            }
            if a > t0 {
                t0 = a;
                axis = i;
                sign = s;
            }
            t1 = t1.min(b);
            if t0 > t1 {
                return None;
            }
        }
        let mut n = [0.0; 3];
        n[axis] = sign;
        (t0 > 1e-9).then_some((t0, n))
    }
}

/// One solid of a prop.
#[derive(Clone, Copy, Debug)]
enum Shape {
    Box(Aabb),
    /// Vertical cylinder: centre, radius, bottom, top.
    Cyl([f64; 2], f64, f64, f64),
}

#[derive(Clone, Copy, Debug)]
struct Solid {
    shape: Shape,
    rgb: [f64; 3],
}

impl Solid {
    fn hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<(f64, [f64; 3])> {
        match self.shape {
            Shape::Box(b) => b.hit(o, d),
            Shape::Cyl(c, r, z0, z1) => {
                let (ox, oy) = (o[0] - c[0], o[1] - c[1]);
                let a = d[0] * d[0] + d[1] * d[1];
                if a < 1e-12 {
                    return None;
                }
                let b = ox * d[0] + oy * d[1];
                let cc = ox * ox + oy * oy - r * r;
                let disc = b * b - a * cc;
                if disc < 0.0 {
                    return None;
                }
                let t = (-b - disc.sqrt()) / a;
                let z = o[2] + t * d[2];
                (t > 1e-9 && z >= z0 && z <= z1).then(|| {
                    let (nx, ny) = ((ox + t * d[0]) / r, (oy + t * d[1]) / r);
                    (t, [nx, ny, 0.0])
                })
            }
        }
    }
}

/// Where a prop stands: its anchor pixel back-projected to the ground.
fn anchor(fu: f64, fv: f64, spec: &SceneSpec, proj: &Proj) -> Option<[f64; 2]> {
    proj.ground(
        fu * (spec.width as f64 - 1.0),
        fv * (spec.height as f64 - 1.0),
    )
}

/// The solids a prop is made of.
fn solids_of(p: &Prop, spec: &SceneSpec, proj: &Proj, out: &mut Vec<Solid>) {
    let bx = |lo: [f64; 3], hi: [f64; 3], rgb: [f64; 3]| Solid {
        shape: Shape::Box(Aabb { lo, hi }),
        rgb,
    };
    match *p {
        Prop::Pole { fu, fv, height } => {
            let Some(g) = anchor(fu, fv, spec, proj) else {
                return;
            };
            let grey = [70.0, 74.0, 78.0];
            out.push(Solid {
                shape: Shape::Cyl(g, 0.07, 0.0, height),
                rgb: grey,
            });
            out.push(Solid {
                shape: Shape::Cyl(g, 0.11, 0.0, 0.5),
                rgb: grey,
            });
            out.push(bx(
                [g[0] - 0.1, g[1] - 0.25, height - 0.05],
                [g[0] + 0.1, g[1] + 0.35, height + 0.12],
                [60.0, 62.0, 66.0],
            ));
        }
        Prop::Bench { fu, fv } => {
            let Some(g) = anchor(fu, fv, spec, proj) else {
                return;
            };
            let wood = [140.0, 95.0, 55.0];
            let metal = [45.0, 45.0, 48.0];
            let (x0, x1, y0, y1) = (g[0] - 0.9, g[0] + 0.9, g[1] - 0.22, g[1] + 0.22);
            out.push(bx([x0, y0, 0.40], [x1, y1, 0.47], wood));
            out.push(bx([x0, y1 - 0.06, 0.5], [x1, y1, 0.88], wood));
            for x in [x0 + 0.1, x1 - 0.16] {
                out.push(bx([x, y0 + 0.02, 0.0], [x + 0.06, y1, 0.40], metal));
            }
        }
        Prop::Wall {
            fu,
            fv,
            length,
            height,
        } => {
            let Some(g) = anchor(fu, fv, spec, proj) else {
                return;
            };
            out.push(bx(
                [g[0] - length / 2.0, g[1] - 0.125, 0.0],
                [g[0] + length / 2.0, g[1] + 0.125, height],
                [175.0, 170.0, 160.0],
            ));
        }
    }
}

/// The ground footprint box of a prop (paths keep clear of it).
pub fn prop_box(p: &Prop, spec: &SceneSpec, proj: &Proj) -> Option<Aabb> {
    let mut v = Vec::new();
    solids_of(p, spec, proj, &mut v);
    let mut lo = [f64::MAX; 3];
    let mut hi = [f64::MIN; 3];
    for s in &v {
        let (a, b) = match s.shape {
            Shape::Box(b) => (b.lo, b.hi),
            Shape::Cyl(c, r, z0, z1) => ([c[0] - r, c[1] - r, z0], [c[0] + r, c[1] + r, z1]),
        };
        for i in 0..3 {
            lo[i] = lo[i].min(a[i]);
            hi[i] = hi[i].max(b[i]);
        }
    }
    (!v.is_empty()).then_some(Aabb { lo, hi })
}

/// BT.601 limited-range Y, Cb, Cr of an RGB colour (0..255 floats).
pub fn yuv(rgb: [f64; 3]) -> [f64; 3] {
    let [r, g, b] = rgb;
    [
        16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0,
        128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0,
        128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0,
    ]
}

/// The rendered static scene.
pub struct Background {
    /// Luma.
    pub y: Vec<u8>,
    /// Cb, 4:2:0.
    pub u: Vec<u8>,
    /// Cr, 4:2:0.
    pub v: Vec<u8>,
    /// Horizontal distance of the prop seen at each pixel, centimetres; [`GROUND`] or [`FAR`] otherwise.
    pub depth: Vec<u16>,
    /// Ground `(x, y)` at each pixel centre (empty without shadows), metres.
    pub ground: Vec<[f32; 2]>,
}

/// Unit vector toward the sun.
pub fn sun_dir(spec: &SceneSpec) -> [f64; 3] {
    let (az, el) = (spec.sun.0, rad(spec.sun.1));
    [cos(el) * cos(az), cos(el) * sin(az), sin(el)]
}

/// Where a solid can be seen, so that rays that cannot reach it skip its
/// intersection test (about two thirds of the tracing time without it).
/// Each bound is conservative, widened by a margin far above rounding
/// error, so culling never changes a pixel; `None` means "test always".
#[derive(Clone, Copy, Debug)]
struct Reach {
    /// Pixel rectangle `[u0, v0, u1, v1]` holding the projection of the
    /// solid's bounding box (a camera ray hitting the box passes through
    /// the convex hull of its projected corners).
    pixels: Option<[f64; 4]>,
    /// Ground rectangle `[x0, y0, x1, y1]` of the points whose ray toward
    /// the sun can meet the bounding box (the box's footprint swept back
    /// along the sun's direction over the box's height range).
    shadow: Option<[f64; 4]>,
}

/// Margin of a pixel bound, pixels.
const PIXEL_MARGIN: f64 = 2.0;
/// Margin of a ground bound, metres.
const GROUND_MARGIN: f64 = 0.05;

fn inside(r: Option<[f64; 4]>, a: f64, b: f64) -> bool {
    r.is_none_or(|r| a >= r[0] && a <= r[2] && b >= r[1] && b <= r[3])
}

impl Reach {
    fn of(s: &Solid, proj: &Proj, sun: [f64; 3]) -> Reach {
        let (lo, hi) = match s.shape {
            Shape::Box(b) => (b.lo, b.hi),
            Shape::Cyl(c, r, z0, z1) => ([c[0] - r, c[1] - r, z0], [c[0] + r, c[1] + r, z1]),
        };
        let mut px = [f64::MAX, f64::MAX, f64::MIN, f64::MIN];
        let mut in_front = true;
        for k in 0..8 {
            let p = [
                if k & 1 == 0 { lo[0] } else { hi[0] },
                if k & 2 == 0 { lo[1] } else { hi[1] },
                if k & 4 == 0 { lo[2] } else { hi[2] },
            ];
            // A corner near or behind the camera plane: the projection of
            // the box is unbounded, keep testing every ray.
            match proj.project(p) {
                Some((uv, depth)) if depth > 1e-3 => {
                    px = [
                        px[0].min(uv[0]),
                        px[1].min(uv[1]),
                        px[2].max(uv[0]),
                        px[3].max(uv[1]),
                    ];
                }
                _ => in_front = false,
            }
        }
        let pixels = in_front.then(|| {
            [
                px[0] - PIXEL_MARGIN,
                px[1] - PIXEL_MARGIN,
                px[2] + PIXEL_MARGIN,
                px[3] + PIXEL_MARGIN,
            ]
        });
        // Shadow rays start 1 mm above the ground: o + t·sun meets the box
        // only for t with z in [lo_z, hi_z], i.e. t in [t0, t1], where its
        // ground position is o_xy + t·sun_xy inside the footprint.
        let shadow = (sun[2] > 1e-3).then(|| {
            let t0 = ((lo[2] - 0.001) / sun[2]).max(0.0);
            let t1 = ((hi[2] - 0.001) / sun[2]).max(t0);
            let (dx, dy) = ([-t0 * sun[0], -t1 * sun[0]], [-t0 * sun[1], -t1 * sun[1]]);
            [
                lo[0] + dx[0].min(dx[1]) - GROUND_MARGIN,
                lo[1] + dy[0].min(dy[1]) - GROUND_MARGIN,
                hi[0] + dx[0].max(dx[1]) + GROUND_MARGIN,
                hi[1] + dy[0].max(dy[1]) + GROUND_MARGIN,
            ]
        });
        Reach { pixels, shadow }
    }
}

struct Tracer<'a> {
    spec: &'a SceneSpec,
    proj: &'a Proj,
    solids: Vec<Solid>,
    /// One per solid, same order.
    reach: Vec<Reach>,
    sun: [f64; 3],
    seed: u64,
}

impl Tracer<'_> {
    /// The colour a ray through `(u, v)` sees.
    fn trace(&self, u: f64, v: f64) -> [f64; 3] {
        let o = [0.0, 0.0, self.proj.h];
        let d = self.proj.ray(u, v);
        let mut best: Option<(f64, [f64; 3], [f64; 3])> = None;
        for (s, reach) in self.solids.iter().zip(&self.reach) {
            if !inside(reach.pixels, u, v) {
                continue;
            }
            if let Some((t, n)) = s.hit(o, d) {
                if best.is_none_or(|b| t < b.0) {
                    best = Some((t, n, s.rgb));
                }
            }
        }
        let t_ground = (d[2] < -1e-12).then(|| -self.proj.h / d[2]);
        let t_facade = (d[1] > 1e-12).then(|| self.spec.backdrop / d[1]);
        if let Some((t, n, rgb)) = best {
            if t_ground.is_none_or(|g| t <= g) && t_facade.is_none_or(|f| t <= f) {
                let lit = 0.5
                    + 0.5 * (n[0] * self.sun[0] + n[1] * self.sun[1] + n[2] * self.sun[2]).max(0.0);
                return [rgb[0] * lit, rgb[1] * lit, rgb[2] * lit];
            }
        }
        match (t_ground, t_facade) {
            (Some(tg), tf) if tf.is_none_or(|tf| tg <= tf) => {
                let g = [tg * d[0], tg * d[1]];
                let mut rgb =
                    self.ground_colour(g, tg * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt());
                if self.spec.shadows && self.in_prop_shadow(g) {
                    rgb = [rgb[0] * 0.62, rgb[1] * 0.62, rgb[2] * 0.66];
                }
                rgb
            }
            (_, Some(tf)) => {
                let x = tf * d[0];
                let z = self.proj.h + tf * d[2];
                self.facade(x, z).unwrap_or_else(|| self.sky(d))
            }
            _ => self.sky(d),
        }
    }

    /// What the pixel centre hits, without colours: the depth-map value and the ground point.
    fn locate(&self, u: f64, v: f64) -> (u16, Option<[f64; 2]>) {
        let o = [0.0, 0.0, self.proj.h];
        let d = self.proj.ray(u, v);
        let t_prop = self
            .solids
            .iter()
            .zip(&self.reach)
            .filter(|(_, reach)| inside(reach.pixels, u, v))
            .filter_map(|(s, _)| s.hit(o, d))
            .map(|(t, _)| t)
            .fold(f64::MAX, f64::min);
        let t_ground = (d[2] < -1e-12).then(|| -self.proj.h / d[2]);
        let t_facade = (d[1] > 1e-12).then(|| self.spec.backdrop / d[1]);
        if t_prop < f64::MAX
            && t_ground.is_none_or(|g| t_prop <= g)
            && t_facade.is_none_or(|f| t_prop <= f)
        {
            let p = [t_prop * d[0], t_prop * d[1]];
            let dist = (p[0] * p[0] + p[1] * p[1]).sqrt();
            return ((dist * 100.0).clamp(0.0, 65_000.0) as u16, None);
        }
        match t_ground {
            Some(tg) if t_facade.is_none_or(|tf| tg <= tf) => {
                (GROUND, Some([tg * d[0], tg * d[1]]))
            }
            _ => (FAR, None),
        }
    }

    fn sky(&self, d: [f64; 3]) -> [f64; 3] {
        let e = d[2] / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let k = smoothstep(0.0, 0.5, e);
        let lo = [214.0, 222.0, 232.0];
        let hi = [126.0, 163.0, 214.0];
        [
            lo[0] + (hi[0] - lo[0]) * k,
            lo[1] + (hi[1] - lo[1]) * k,
            lo[2] + (hi[2] - lo[2]) * k,
        ]
    }

    fn in_prop_shadow(&self, g: [f64; 2]) -> bool {
        let o = [g[0], g[1], 0.001];
        self.solids
            .iter()
            .zip(&self.reach)
            .any(|(s, reach)| inside(reach.shadow, g[0], g[1]) && s.hit(o, self.sun).is_some())
    }

    /// Building facades closing the view: 9 m modules of varying height and colour.
    fn facade(&self, x: f64, z: f64) -> Option<[f64; 3]> {
        let module = 9.0;
        let i = (x / module).floor() as i64;
        let hsh = hash2(self.seed ^ 0xFACADE, i, 0);
        let height = 7.0 + (hsh % 14) as f64;
        if z > height || z < 0.0 {
            return None;
        }
        let palette = [
            [196.0, 180.0, 156.0],
            [168.0, 98.0, 78.0],
            [150.0, 152.0, 156.0],
            [210.0, 200.0, 184.0],
            [120.0, 112.0, 104.0],
        ];
        let base = palette[((hsh >> 8) % 5) as usize];
        let lx = x - i as f64 * module;
        // Ground floor door in the middle of each module.
        if z < 2.4 && (lx - 4.5).abs() < 0.8 {
            return Some([60.0, 52.0, 48.0]);
        }
        let fz = (z - 0.8) / 3.0;
        let wz = fz - fz.floor();
        let wx = (lx / 2.25) - (lx / 2.25).floor();
        if z > 3.0 && z < height - 0.8 && wz > 0.25 && wz < 0.75 && wx > 0.25 && wx < 0.8 {
            let lit = hash2(
                self.seed,
                (lx / 2.25).floor() as i64 + i * 8,
                fz.floor() as i64,
            ) % 4;
            let g = if lit == 0 { 150.0 } else { 70.0 };
            return Some([g * 0.9, g * 0.95, g * 1.05]);
        }
        if z > height - 0.35 {
            return Some([base[0] * 0.8, base[1] * 0.8, base[2] * 0.8]);
        }
        Some(base)
    }

    /// Ground texture at `g`; `range` is the ray length, which sets how much detail survives.
    fn ground_colour(&self, g: [f64; 2], range: f64) -> [f64; 3] {
        // Ground size of one pixel: range² / (f · camera height) at grazing view.
        let footprint = range * range / (self.proj.f * self.proj.h.max(0.5));
        let detail = 1.0 - smoothstep(0.03, 0.12, footprint);
        match self.spec.ground {
            Ground::Tiles => {
                let tile = 0.5;
                let (tx, ty) = ((g[0] / tile).floor(), (g[1] / tile).floor());
                let (fx, fy) = (g[0] / tile - tx, g[1] / tile - ty);
                let (ix, iy) = (tx as i64, ty as i64);
                let hsh = hash2(self.seed, ix, iy);
                // A pattern of darker bands every 6 tiles, and per-tile variation.
                let band = ix.rem_euclid(6) == 0 || iy.rem_euclid(6) == 0;
                let mut base = if band {
                    [128.0, 118.0, 108.0]
                } else {
                    [168.0, 162.0, 150.0]
                };
                let var = ((hsh % 21) as f64 - 10.0) * 0.9;
                for c in &mut base {
                    *c += var;
                }
                let edge = fx.min(1.0 - fx).min(fy).min(1.0 - fy) * tile;
                let grout = [96.0, 94.0, 92.0];
                // Grout covers ~10% of a far pixel: blend to the average where lines would alias.
                let w = if edge < 0.012 { detail } else { 0.0 } + 0.1 * (1.0 - detail);
                let grain = ((hash2(
                    self.seed ^ 7,
                    (g[0] * 40.0).floor() as i64,
                    (g[1] * 40.0).floor() as i64,
                ) % 13) as f64
                    - 6.0)
                    * detail;
                [
                    base[0] + (grout[0] - base[0]) * w + grain,
                    base[1] + (grout[1] - base[1]) * w + grain,
                    base[2] + (grout[2] - base[2]) * w + grain,
                ]
            }
            Ground::Asphalt => {
                let grain = ((hash2(
                    self.seed ^ 11,
                    (g[0] * 30.0).floor() as i64,
                    (g[1] * 30.0).floor() as i64,
                ) % 25) as f64
                    - 12.0)
                    * detail;
                let patch = ((hash2(
                    self.seed ^ 13,
                    (g[0] / 3.0).floor() as i64,
                    (g[1] / 3.0).floor() as i64,
                ) % 9) as f64
                    - 4.0)
                    * 1.5;
                let mut c = [
                    86.0 + grain + patch,
                    88.0 + grain + patch,
                    92.0 + grain + patch,
                ];
                // Painted lines across the view and dashed lane marks.
                let paint = |c: &mut [f64; 3], k: f64| {
                    for v in c.iter_mut() {
                        *v += (205.0 - *v) * k;
                    }
                };
                for y in [9.0, 16.0] {
                    if (g[1] - y).abs() < 0.08 {
                        paint(&mut c, 0.85);
                    }
                }
                if (g[1] - 12.5).abs() < 0.07 && (g[0] / 3.0).floor().rem_euclid(2.0) == 0.0 {
                    paint(&mut c, 0.8);
                }
                // Parking bays along the near line.
                if g[1] > 5.0 && g[1] < 8.5 && (g[0] / 2.6 - (g[0] / 2.6).floor()) * 2.6 < 0.1 {
                    paint(&mut c, 0.75);
                }
                c
            }
        }
    }
}

/// Ray-traces the static scene (2×2 samples per pixel).
pub fn render(spec: &SceneSpec, proj: &Proj, seed: u64) -> Background {
    render_culled(spec, proj, seed, true)
}

/// [`render`], optionally testing every ray against every solid (the
/// reference the culled tracer is checked against).
fn render_culled(spec: &SceneSpec, proj: &Proj, seed: u64, cull: bool) -> Background {
    let (w, h) = (spec.width, spec.height);
    let mut solids = Vec::new();
    for p in spec.props {
        solids_of(p, spec, proj, &mut solids);
    }
    let sun = sun_dir(spec);
    let reach = solids
        .iter()
        .map(|s| {
            if cull {
                Reach::of(s, proj, sun)
            } else {
                Reach {
                    pixels: None,
                    shadow: None,
                }
            }
        })
        .collect();
    let tracer = Tracer {
        spec,
        proj,
        solids,
        reach,
        sun,
        seed: seed ^ 0x6772_6F75_6E64,
    };
    let mut y = vec![0u8; w * h];
    let mut uf = vec![0.0f64; w * h];
    let mut vf = vec![0.0f64; w * h];
    let mut depth = vec![FAR; w * h];
    let mut ground = if spec.shadows {
        vec![[0.0f32; 2]; w * h]
    } else {
        Vec::new()
    };
    for r in 0..h {
        for c in 0..w {
            let i = r * w + c;
            let centre = tracer.locate(c as f64, r as f64);
            let mut sum = [0.0; 3];
            for (du, dv) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let s = tracer.trace(c as f64 + du, r as f64 + dv);
                for (acc, c) in sum.iter_mut().zip(s) {
                    *acc += c * 0.25;
                }
            }
            let yuv = yuv(sum);
            y[i] = yuv[0].round().clamp(0.0, 255.0) as u8;
            uf[i] = yuv[1];
            vf[i] = yuv[2];
            depth[i] = centre.0;
            if let (Some(g), false) = (centre.1, ground.is_empty()) {
                ground[i] = [g[0] as f32, g[1] as f32];
            }
        }
    }
    let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
    let mut u = vec![128u8; cw * ch];
    let mut v = vec![128u8; cw * ch];
    for r in 0..ch {
        for c in 0..cw {
            let (mut su, mut sv, mut n) = (0.0, 0.0, 0.0);
            for (dr, dc) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let (rr, cc) = (2 * r + dr, 2 * c + dc);
                if rr < h && cc < w {
                    su += uf[rr * w + cc];
                    sv += vf[rr * w + cc];
                    n += 1.0;
                }
            }
            u[r * cw + c] = (su / n).round().clamp(0.0, 255.0) as u8;
            v[r * cw + c] = (sv / n).round().clamp(0.0, 255.0) as u8;
        }
    }
    Background {
        y,
        u,
        v,
        depth,
        ground,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::sim::scene::scenes;

    /// Culling skips only intersection tests that cannot succeed: every
    /// buffer of every scene, with and without its moving shadows, is
    /// identical to the one from testing every ray against every solid.
    /// (At a quarter of each scene's size, same field of view, to keep the
    /// reference cheap under emulation; the props keep their image
    /// positions.)
    #[test]
    fn culled_tracer_renders_exactly_the_reference() {
        let mut solids_seen = 0;
        for base in scenes() {
            for shadows in [true, false] {
                let mut spec = base.clone();
                spec.shadows = shadows;
                spec.width /= 4;
                spec.height /= 4;
                spec.f /= 4.0;
                let proj = spec.projection();
                let mut solids = Vec::new();
                for p in spec.props {
                    solids_of(p, &spec, &proj, &mut solids);
                }
                solids_seen += solids.len();
                // The seed changes textures, not where the props stand.
                let fast = render_culled(&spec, &proj, 1, true);
                let slow = render_culled(&spec, &proj, 1, false);
                let at = format!("{} shadows={shadows}", spec.name);
                assert!(fast.y == slow.y, "luma differs: {at}");
                assert!(fast.u == slow.u && fast.v == slow.v, "chroma differs: {at}");
                assert!(fast.depth == slow.depth, "depth differs: {at}");
                assert!(fast.ground == slow.ground, "ground points differ: {at}");
            }
        }
        assert!(solids_seen > 10, "the scenes have props to cull");
    }

    /// The bounds are not vacuous: a pixel far from a prop and a ground
    /// point far from its shadow are both outside them.
    #[test]
    fn reach_bounds_exclude_far_rays() {
        let spec = &scenes()[0];
        let proj = spec.projection();
        let sun = sun_dir(spec);
        let mut solids = Vec::new();
        for p in spec.props {
            solids_of(p, spec, &proj, &mut solids);
        }
        let (w, h) = (spec.width as f64, spec.height as f64);
        let mut culled_pixels = 0;
        let mut culled_ground = 0;
        for s in &solids {
            let reach = Reach::of(s, &proj, sun);
            let r = reach
                .pixels
                .expect("plaza's props are in front of the camera");
            // Each solid's rectangle is a small part of the image.
            assert!((r[2] - r[0]) * (r[3] - r[1]) < w * h / 8.0, "{r:?}");
            culled_pixels += usize::from(!inside(reach.pixels, 0.0, 0.0))
                + usize::from(!inside(reach.pixels, w - 1.0, h - 1.0));
            culled_ground += usize::from(!inside(reach.shadow, 1e3, 1e3));
        }
        assert!(culled_pixels >= solids.len(), "{culled_pixels}");
        assert_eq!(culled_ground, solids.len());
    }
}
