//! Per-frame drawing into caller-owned planes, with no allocation:
//! background copy → moving shadows → actors front to back → illumination
//! gain and sensor noise.
//!
//! Each actor is first rasterised on its own into a scratch buffer (so its
//! whole silhouette is known, even the parts another object or the image
//! border hides), then composited: a pixel is taken only if no nearer actor
//! took it and no prop in the depth map stands in front. That gives the
//! truth's bounding box and visible fraction exactly.

use super::background::{Background, GROUND};
use super::math::{mix64, sin, Proj, Rng, PI};
use super::people::{car, slot, Actor, Kind, Part, Pose, PALETTE};
use super::scene::SceneSpec;
use super::truth::ObjectTruth;
use crate::frame::Frame;

/// Entries of the shading table indexed by (distance / radius)².
const SHADE_STEPS: usize = 64;
/// Distinct noise offsets per frame.
const NOISE_SLACK: usize = 8192;

/// A capsule in image coordinates (f32 is plenty at pixel scale).
#[derive(Clone, Copy, Debug, Default)]
struct Cap {
    ax: f32,
    ay: f32,
    bx: f32,
    by: f32,
    ra: f32,
    rb: f32,
    col: u8,
    /// Upper fraction of the axis drawn in hair colour (heads only).
    hair: f32,
}

/// Buffers and tables the renderer owns, sized at open.
pub struct Renderer {
    w: usize,
    h: usize,
    /// Scratch silhouette of one actor: `(slot + 1) << 8 | shade`, 0 = empty.
    local: Vec<u16>,
    /// Which image pixels an actor already took this frame.
    owner: Vec<u8>,
    /// Gaussian sensor noise, luma levels.
    noise: Vec<i8>,
    /// Palette of every actor as (Y, Cb, Cr).
    palettes: Vec<[[u8; 3]; PALETTE]>,
    shade: [u8; SHADE_STEPS + 1],
    /// Extended drawing window around the image (actors partly outside still count fully).
    margin_x: i32,
    margin_y: i32,
    /// Unit ground direction a shadow falls in, and its length per metre of height.
    shadow_dir: [f64; 2],
    shadow_len: f64,
}

impl Renderer {
    /// Sizes every buffer for `spec` and precomputes the tables.
    pub fn new(spec: &SceneSpec, actors: &[Actor], seed: u64) -> Self {
        let (w, h) = (spec.width, spec.height);
        let (mx, my) = (w / 2, h / 2);
        let mut rng = Rng::new(mix64(seed ^ 0x004E_4F49_5345));
        let noise = (0..w * h + NOISE_SLACK)
            .map(|_| (spec.noise * rng.normal()).round().clamp(-127.0, 127.0) as i8)
            .collect();
        let palettes = actors
            .iter()
            .map(|a| {
                let mut p = [[0u8; 3]; PALETTE];
                for (dst, rgb) in p.iter_mut().zip(a.palette.iter()) {
                    let c = super::background::yuv([rgb[0] as f64, rgb[1] as f64, rgb[2] as f64]);
                    *dst = c.map(|v| v.round().clamp(0.0, 255.0) as u8);
                }
                p
            })
            .collect();
        let mut shade = [0u8; SHADE_STEPS + 1];
        for (i, s) in shade.iter_mut().enumerate() {
            // Lambert-like falloff across a cylinder: bright on the axis, darker at the rim.
            let q = i as f64 / SHADE_STEPS as f64;
            *s = (255.0 * (0.6 + 0.4 * (1.0 - q).sqrt())).round() as u8;
        }
        let sun = super::background::sun_dir(spec);
        let horiz = (sun[0] * sun[0] + sun[1] * sun[1]).sqrt().max(1e-9);
        Renderer {
            w,
            h,
            local: vec![0; (w + 2 * mx) * (h + 2 * my)],
            owner: vec![0; w * h],
            noise,
            palettes,
            shade,
            margin_x: mx as i32,
            margin_y: my as i32,
            shadow_dir: [-sun[0] / horiz, -sun[1] / horiz],
            shadow_len: horiz / sun[2].max(0.2),
        }
    }

    /// Draws frame `index` (time `t`) with the actors in `poses` (sorted near to far).
    #[allow(clippy::too_many_arguments)]
    pub fn draw(
        &mut self,
        frame: &mut Frame,
        spec: &SceneSpec,
        proj: &Proj,
        bg: &Background,
        actors: &[Actor],
        poses: &[Pose],
        seed: u64,
        index: u64,
        t: f64,
        truth: &mut Vec<ObjectTruth>,
    ) {
        frame.y.copy_from_slice(&bg.y);
        frame.u.copy_from_slice(&bg.u);
        frame.v.copy_from_slice(&bg.v);
        if spec.shadows {
            for p in poses {
                self.shadow(frame, proj, bg, &actors[p.actor], p);
            }
        }
        self.owner.fill(0);
        truth.clear();
        for p in poses {
            if let Some(o) = self.actor(frame, proj, bg, &actors[p.actor], p) {
                if truth.len() < truth.capacity() {
                    truth.push(o);
                }
            }
        }
        self.finish(frame, spec, seed, index, t);
    }

    /// Illumination drift (a gain table) and sensor noise over the whole frame.
    fn finish(&self, frame: &mut Frame, spec: &SceneSpec, seed: u64, index: u64, t: f64) {
        let (amp, period) = spec.drift;
        let gain = 1.0
            + amp * sin(2.0 * PI * t / period.max(1.0))
            + 0.3 * amp * sin(2.0 * PI * t / (0.37 * period.max(1.0)) + 1.0);
        let mut lut = [0i16; 256];
        for (i, v) in lut.iter_mut().enumerate() {
            *v = (i as f64 * gain).round().clamp(0.0, 255.0) as i16;
        }
        let r = mix64(seed ^ index.wrapping_mul(0x9E37_79B9));
        let off = (r % NOISE_SLACK as u64) as usize;
        let n = frame.y.len();
        for (p, &e) in frame.y.iter_mut().zip(&self.noise[off..off + n]) {
            *p = (lut[*p as usize] + e as i16).clamp(0, 255) as u8;
        }
        // Chroma noise at half amplitude, from other offsets of the same table.
        let cu = ((r >> 20) % NOISE_SLACK as u64) as usize;
        let cv = ((r >> 40) % NOISE_SLACK as u64) as usize;
        let m = frame.u.len();
        for (p, &e) in frame.u.iter_mut().zip(&self.noise[cu..cu + m]) {
            *p = (*p as i16 + (e as i16 >> 1)).clamp(0, 255) as u8;
        }
        for (p, &e) in frame.v.iter_mut().zip(&self.noise[cv..cv + m]) {
            *p = (*p as i16 + (e as i16 >> 1)).clamp(0, 255) as u8;
        }
    }

    /// Darkens the open ground under and behind an actor (away from the sun), with soft edges.
    fn shadow(&self, frame: &mut Frame, proj: &Proj, bg: &Background, a: &Actor, p: &Pose) {
        if bg.ground.is_empty() {
            return;
        }
        let (seg_a, seg_b, radius) = match a.kind {
            Kind::Car => {
                let reach = self.shadow_len * car::ROOF * 0.5;
                let c = [
                    p.foot[0] + self.shadow_dir[0] * reach,
                    p.foot[1] + self.shadow_dir[1] * reach,
                ];
                let l = car::HALF_LEN - car::HALF_WID;
                (
                    [c[0] - p.fwd[0] * l, c[1] - p.fwd[1] * l],
                    [c[0] + p.fwd[0] * l, c[1] + p.fwd[1] * l],
                    car::HALF_WID + 0.1,
                )
            }
            Kind::Person | Kind::Dog => {
                let reach = self.shadow_len * a.height * 0.9;
                (
                    p.foot,
                    [
                        p.foot[0] + self.shadow_dir[0] * reach,
                        p.foot[1] + self.shadow_dir[1] * reach,
                    ],
                    if a.kind == Kind::Dog { 0.16 } else { 0.2 },
                )
            }
        };
        // Image box of the shadow from its ground corners.
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for c in [seg_a, seg_b] {
            for (dx, dy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                let g = [c[0] + dx * radius * 1.5, c[1] + dy * radius * 1.5, 0.0];
                let Some((px, _)) = proj.project(g) else {
                    return;
                };
                x0 = x0.min(px[0]);
                y0 = y0.min(px[1]);
                x1 = x1.max(px[0]);
                y1 = y1.max(px[1]);
            }
        }
        let (w, h) = (self.w as f64, self.h as f64);
        if x1 < 0.0 || y1 < 0.0 || x0 > w - 1.0 || y0 > h - 1.0 {
            return;
        }
        let (cx0, cx1) = (x0.max(0.0) as usize, x1.min(w - 1.0) as usize);
        let (cy0, cy1) = (y0.max(0.0) as usize, y1.min(h - 1.0) as usize);
        let (ax, ay) = (seg_a[0] as f32, seg_a[1] as f32);
        let (dx, dy) = ((seg_b[0] - seg_a[0]) as f32, (seg_b[1] - seg_a[1]) as f32);
        let inv = 1.0 / (dx * dx + dy * dy).max(1e-6);
        let r_out = radius as f32;
        let r_in = r_out * 0.35;
        for yy in cy0..=cy1 {
            let row = yy * self.w;
            for xx in cx0..=cx1 {
                let i = row + xx;
                if bg.depth[i] != GROUND {
                    continue;
                }
                let g = bg.ground[i];
                let (fx, fy) = (g[0] - ax, g[1] - ay);
                let t = ((fx * dx + fy * dy) * inv).clamp(0.0, 1.0);
                let (ex, ey) = (fx - t * dx, fy - t * dy);
                let d = (ex * ex + ey * ey).sqrt();
                if d >= r_out {
                    continue;
                }
                let s = ((r_out - d) / (r_out - r_in)).min(1.0);
                let s = s * s * (3.0 - 2.0 * s);
                let k = 1.0 - 0.42 * s * (1.0 - 0.45 * t);
                frame.y[i] = (frame.y[i] as f32 * k) as u8;
            }
        }
    }

    /// Rasterises one actor into the scratch buffer, composites it and returns its truth.
    fn actor(
        &mut self,
        frame: &mut Frame,
        proj: &Proj,
        bg: &Background,
        a: &Actor,
        p: &Pose,
    ) -> Option<ObjectTruth> {
        // Silhouette box, clipped to the extended window.
        let (mut caps, mut n_caps) = ([Cap::default(); super::people::MAX_PARTS], 0usize);
        let (mut x0, mut y0, mut x1, mut y1) = (f32::MAX, f32::MAX, f32::MIN, f32::MIN);
        let mut corners = [[0.0f64; 3]; 12];
        match a.kind {
            Kind::Car => {
                let n = car_corners(p, &mut corners);
                for c in &corners[..n] {
                    let (px, _) = proj.project(*c)?;
                    x0 = x0.min(px[0] as f32);
                    y0 = y0.min(px[1] as f32);
                    x1 = x1.max(px[0] as f32);
                    y1 = y1.max(px[1] as f32);
                }
            }
            Kind::Person | Kind::Dog => {
                let view = [p.foot[0], p.foot[1]];
                // Facing away from the camera: hair covers most of the head.
                let away = (p.fwd[0] * view[0] + p.fwd[1] * view[1])
                    / (view[0] * view[0] + view[1] * view[1]).sqrt().max(1e-9);
                for part in &p.parts[..p.n_parts] {
                    let Some(c) = cap(proj, part, away) else {
                        continue;
                    };
                    x0 = x0.min(c.ax - c.ra).min(c.bx - c.rb);
                    y0 = y0.min(c.ay - c.ra).min(c.by - c.rb);
                    x1 = x1.max(c.ax + c.ra).max(c.bx + c.rb);
                    y1 = y1.max(c.ay + c.ra).max(c.by + c.rb);
                    caps[n_caps] = c;
                    n_caps += 1;
                }
                if n_caps == 0 {
                    return None;
                }
            }
        }
        let (w, h) = (self.w as i32, self.h as i32);
        let (mx, my) = (self.margin_x, self.margin_y);
        // Quick reject: nothing within the image.
        if x1 < -0.5 || y1 < -0.5 || x0 > w as f32 - 0.5 || y0 > h as f32 - 0.5 {
            return None;
        }
        let bx0 = (x0.floor() as i32).max(-mx);
        let by0 = (y0.floor() as i32).max(-my);
        let bx1 = (x1.ceil() as i32).min(w + mx - 1);
        let by1 = (y1.ceil() as i32).min(h + my - 1);
        if bx1 < bx0 || by1 < by0 {
            return None;
        }
        let (lw, lh) = ((bx1 - bx0 + 1) as usize, (by1 - by0 + 1) as usize);
        let local = &mut self.local[..lw * lh];
        local.fill(0);
        match a.kind {
            Kind::Car => raycast_car(local, lw, lh, bx0, by0, proj, p),
            _ => {
                for c in &caps[..n_caps] {
                    raster(local, lw, lh, bx0, by0, c, &self.shade);
                }
            }
        }
        // Composite.
        let pal = &self.palettes[p.actor];
        let depth_cm = (p.dist * 100.0).min(65_000.0) as u16;
        let (mut full, mut visible) = (0u32, 0u32);
        let (mut ix0, mut iy0, mut ix1, mut iy1) = (i32::MAX, i32::MAX, i32::MIN, i32::MIN);
        let cw = self.w.div_ceil(2);
        for ly in 0..lh {
            let iy = by0 + ly as i32;
            let row = &local[ly * lw..(ly + 1) * lw];
            let in_rows = iy >= 0 && iy < h;
            for (lx, &e) in row.iter().enumerate() {
                if e == 0 {
                    continue;
                }
                full += 1;
                let ix = bx0 + lx as i32;
                if !in_rows || ix < 0 || ix >= w {
                    continue;
                }
                ix0 = ix0.min(ix);
                ix1 = ix1.max(ix);
                iy0 = iy0.min(iy);
                iy1 = iy1.max(iy);
                let i = iy as usize * self.w + ix as usize;
                if self.owner[i] != 0 || bg.depth[i] < depth_cm {
                    continue;
                }
                self.owner[i] = 1;
                visible += 1;
                let c = pal[((e >> 8) - 1) as usize];
                let s = (e & 0xFF) as u32;
                frame.y[i] = ((c[0] as u32 * s + 128) >> 8) as u8;
                let ci = (iy as usize >> 1) * cw + (ix as usize >> 1);
                frame.u[ci] = (128 + (((c[1] as i32 - 128) * s as i32) >> 8)) as u8;
                frame.v[ci] = (128 + (((c[2] as i32 - 128) * s as i32) >> 8)) as u8;
            }
        }
        if ix1 < ix0 {
            return None;
        }
        let foot = proj.project([p.foot[0], p.foot[1], 0.0]).map(|x| x.0)?;
        let head = proj
            .project([p.foot[0], p.foot[1], a.height])
            .map(|x| x.0)?;
        Some(ObjectTruth {
            kind: a.kind,
            id: a.id,
            group: a.group,
            height_m: a.height,
            head_px: head,
            foot_px: foot,
            ground_m: p.foot,
            bbox: [ix0 as u16, iy0 as u16, ix1 as u16, iy1 as u16],
            visible_fraction: visible as f64 / full.max(1) as f64,
            visible_px: visible,
            walking: p.walking,
        })
    }
}

/// Projects a body part; `None` if it reaches behind the camera.
fn cap(proj: &Proj, part: &Part, away: f64) -> Option<Cap> {
    let (pa, za) = proj.project(part.a)?;
    let (pb, zb) = proj.project(part.b)?;
    Some(Cap {
        ax: pa[0] as f32,
        ay: pa[1] as f32,
        bx: pb[0] as f32,
        by: pb[1] as f32,
        ra: (proj.f * part.ra / za) as f32,
        rb: (proj.f * part.rb / zb) as f32,
        col: part.col,
        hair: if !part.head {
            0.0
        } else if away > 0.3 {
            0.9
        } else {
            0.45
        },
    })
}

/// Fills a tapered capsule into the scratch silhouette (first write wins: parts come near to far).
fn raster(
    local: &mut [u16],
    lw: usize,
    lh: usize,
    ox: i32,
    oy: i32,
    c: &Cap,
    shade: &[u8; SHADE_STEPS + 1],
) {
    let rmax = c.ra.max(c.rb);
    let xa = ((c.ax.min(c.bx) - rmax).floor() as i32 - ox).max(0);
    let xb = ((c.ax.max(c.bx) + rmax).ceil() as i32 - ox).min(lw as i32 - 1);
    let ya = ((c.ay.min(c.by) - rmax).floor() as i32 - oy).max(0);
    let yb = ((c.ay.max(c.by) + rmax).ceil() as i32 - oy).min(lh as i32 - 1);
    if xb < xa || yb < ya {
        return;
    }
    let (dx, dy) = (c.bx - c.ax, c.by - c.ay);
    let inv = 1.0 / (dx * dx + dy * dy).max(1e-6);
    let dr = c.rb - c.ra;
    let code = (c.col as u16 + 1) << 8;
    let hair = (super::people::slot::HAIR as u16 + 1) << 8;
    for ly in ya..=yb {
        let fy = (ly + oy) as f32 - c.ay;
        let row = ly as usize * lw;
        for lx in xa..=xb {
            let fx = (lx + ox) as f32 - c.ax;
            let t = ((fx * dx + fy * dy) * inv).clamp(0.0, 1.0);
            let (ex, ey) = (fx - t * dx, fy - t * dy);
            let d2 = ex * ex + ey * ey;
            let r = c.ra + t * dr;
            let r2 = r * r;
            if d2 > r2 {
                continue;
            }
            let e = &mut local[row + lx as usize];
            if *e != 0 {
                continue;
            }
            let q = ((d2 / r2.max(1e-6)) * SHADE_STEPS as f32) as usize;
            let base = if t < c.hair { hair } else { code };
            *e = base | shade[q.min(SHADE_STEPS)] as u16;
        }
    }
}

/// World corners of a car's boxes (for its image box); returns how many were written.
fn car_corners(p: &Pose, out: &mut [[f64; 3]; 12]) -> usize {
    let (f, l) = (p.fwd, [-p.fwd[1], p.fwd[0]]);
    let mut n = 0;
    for (x, y) in [
        (car::HALF_LEN, car::HALF_WID + 0.05),
        (car::HALF_LEN, -car::HALF_WID - 0.05),
        (-car::HALF_LEN, car::HALF_WID + 0.05),
        (-car::HALF_LEN, -car::HALF_WID - 0.05),
    ] {
        for z in [0.0, car::BODY_Z.1] {
            out[n] = [
                p.foot[0] + f[0] * x + l[0] * y,
                p.foot[1] + f[1] * x + l[1] * y,
                z,
            ];
            n += 1;
        }
    }
    for (x, y) in [
        (car::CABIN_X.0, car::CABIN_HALF_WID),
        (car::CABIN_X.1, car::CABIN_HALF_WID),
        (car::CABIN_X.0, -car::CABIN_HALF_WID),
        (car::CABIN_X.1, -car::CABIN_HALF_WID),
    ] {
        out[n] = [
            p.foot[0] + f[0] * x + l[0] * y,
            p.foot[1] + f[1] * x + l[1] * y,
            car::ROOF,
        ];
        n += 1;
    }
    n
}

/// Ray-casts a car (body and cabin boxes, four wheels) into the scratch silhouette.
fn raycast_car(local: &mut [u16], lw: usize, lh: usize, ox: i32, oy: i32, proj: &Proj, p: &Pose) {
    use super::background::Aabb;
    let (f, l) = (p.fwd, [-p.fwd[1], p.fwd[0]]);
    // Camera centre in the car's frame (x forward, y left, z up).
    let rel = [-p.foot[0], -p.foot[1]];
    let o = [
        rel[0] * f[0] + rel[1] * f[1],
        rel[0] * l[0] + rel[1] * l[1],
        proj.h,
    ];
    let body = Aabb {
        lo: [-car::HALF_LEN, -car::HALF_WID, car::BODY_Z.0],
        hi: [car::HALF_LEN, car::HALF_WID, car::BODY_Z.1],
    };
    let cabin = Aabb {
        lo: [car::CABIN_X.0, -car::CABIN_HALF_WID, car::BODY_Z.1 - 0.01],
        hi: [car::CABIN_X.1, car::CABIN_HALF_WID, car::ROOF],
    };
    for ly in 0..lh {
        for lx in 0..lw {
            let wd = proj.ray((lx as i32 + ox) as f64, (ly as i32 + oy) as f64);
            let d = [
                wd[0] * f[0] + wd[1] * f[1],
                wd[0] * l[0] + wd[1] * l[1],
                wd[2],
            ];
            let mut best = (f64::MAX, 0u16);
            if let Some((t, n)) = body.hit(o, d) {
                let s = if n[2] > 0.5 {
                    250
                } else if n[1].abs() > 0.5 {
                    205
                } else {
                    180
                };
                best = (t, ((slot::SHIRT as u16 + 1) << 8) | s);
            }
            if let Some((t, n)) = cabin.hit(o, d) {
                if t < best.0 {
                    let code = if n[2] > 0.5 {
                        ((slot::SHIRT as u16 + 1) << 8) | 240
                    } else {
                        ((slot::DARK as u16 + 1) << 8) | 230
                    };
                    best = (t, code);
                }
            }
            // Wheels: discs in the side planes.
            for side in [-1.0, 1.0] {
                let plane = side * (car::HALF_WID + 0.02);
                if d[1].abs() < 1e-9 {
                    continue;
                }
                let t = (plane - o[1]) / d[1];
                if t <= 0.0 || t >= best.0 {
                    continue;
                }
                let (x, z) = (o[0] + t * d[0], o[2] + t * d[2]);
                for wx in car::WHEEL_X {
                    let (ex, ez) = (x - wx, z - car::WHEEL_R);
                    if ex * ex + ez * ez < car::WHEEL_R * car::WHEEL_R {
                        best = (t, ((slot::SHOES as u16 + 1) << 8) | 200);
                    }
                }
            }
            if best.1 != 0 {
                local[ly * lw + lx] = best.1;
            }
        }
    }
}
