//! Fixed-point Zivkovic adaptive Gaussian mixture background model (the
//! algorithm behind OpenCV's MOG2), on the luma plane.
//!
//! # The model (what the float reference in `tests/detect_support/mod.rs` also does)
//!
//! Every pixel holds up to `K ≤ 4` modes `(w, μ, σ²)`, sorted by weight,
//! heaviest first; a weight of 0 marks an empty slot (empty slots always form
//! a suffix). For a new value `x`, with `S = Σ w` and `T_B = 1 − c_f`:
//!
//! 1. Walk the modes in order. Mode `k` is a *background mode* while the
//!    weight before it is below `T_B · S`. If it is a background mode and
//!    `(x−μ)² < T_b σ²`, the pixel is background. If `(x−μ)² < T_g σ²` the
//!    mode *matches*: stop walking.
//! 2. A foreground pixel that is darker than a background mode by a ratio in
//!    `[r_lo, r_hi]` is shadow (reported as background).
//! 3. Learning rate `α` (`1/history`, or `1/(t+1)` during start-up), scaled
//!    by `foreground_rate` on foreground pixels so that a standing person
//!    takes that many times longer to melt into the background.
//! 4. Every mode: `w ← w − α w − α c_T` (Zivkovic's complexity prior prunes
//!    modes whose weight reaches 0); the matched mode also gains `α` and
//!    moves its mean and variance by `ρ = α / w` (post-update weight):
//!    `μ ← μ + ρ (x−μ)`, `σ² ← σ² + ρ ((x−μ)² − σ²)`, clamped to
//!    `[σ²_min, σ²_max]`.
//!
//!    *Update interval* `N` (`update_interval`, default 8): once
//!    `α ≤ 1/(16 N)`, the mean and variance move only every `N`-th frame,
//!    by `ρ = N α / w` — the same expected drift per frame, `1/N` of the
//!    work. Which frames: those where `frame + y + ⌊x/64⌋` is a
//!    multiple of `N` (64-pixel blocks, staggered). Weights, matching and
//!    the mask are still updated every frame. Measured neutral for the
//!    masks and recall (`bench/RESULTS.md`, "Detection", "Speed").
//! 5. No match: a new mode `(α, x, σ²_init)` takes the first empty slot, or
//!    replaces the lightest mode; the changed mode is moved up to keep the
//!    order. A pixel without any mode is background and gets one.
//!
//! Weights are not renormalised (that would cost a division per pixel): the
//! background test compares against `T_B · S` instead, which is what
//! renormalising would do. A mode matched at frequency `p` settles at
//! `w = p − c_T`.
//!
//! # Fixed point
//!
//! | quantity | storage | format | range |
//! | --- | --- | --- | --- |
//! | weight `w` | `u16` | Q0.16 | `0..=65535` (0 = empty) |
//! | mean `μ` | `u8` | integer grey level | `0..=255` |
//! | variance `σ²` | `u8` | Q7.1 (units of ½ level²) | `σ²_min..=σ²_max ⊂ 1..=255` |
//! | `α`, `α c_T`, `ρ` | `u16` | Q0.16 | `ρ ≤ 65532` |
//! | thresholds `T_b`, `T_g` | `u16` | Q8.8 | `≤ 25.0` |
//!
//! **Model memory: 4 bytes per mode, 16 B/px at K = 4, 12 B/px at the
//! default K = 3** (OpenCV's MOG2 keeps 5 modes of float weight, mean and
//! variance per colour pixel).
//!
//! An 8-bit mean and variance only move by whole steps, while `ρ (x−μ)` is
//! usually a small fraction of a step (ρ ≈ 0.002). Rounding to nearest would
//! freeze them; truncation would bias them. So both are updated with
//! *dithered* rounding: `Δ = ⌊(ρ·|e| + δ) / 2¹⁶⌋` with a per-pixel
//! pseudo-random `δ ∈ [0, 2¹⁶)` from a fixed table, so `E[Δ] = ρ |e|`
//! exactly. The table and its per-frame offsets are deterministic: the
//! result is bit-exact on every platform.
//!
//! Every intermediate fits its type: `|x−μ| ≤ 255`; in the matched case
//! `2(x−μ)² < T_g σ² ≤ 25 · 255 = 6375` so the variance error `e ≤ 7938`
//! after the lane clamp of `|x−μ|` to 63 (which never binds for a match);
//! `ρ·e < 2¹⁶ · 2¹³ = 2²⁹`; `N α ≤ 1/16` (+ rounding) once the interval
//! applies, so `N α` fits Q0.16; weight sums `S ≤ 4 · 65535 < 2¹⁸`, compared in
//! `u64` against `T_B · S < 2³⁴`.
//!
//! # Speed
//!
//! Most pixels match their heaviest mode. A branch-free pass over 64-pixel
//! chunks (16-bit lanes, auto-vectorised) handles exactly those pixels when
//! the updated weight is above ½ (where `1/w` is computed by one Newton
//! step, see [`recip_q14`]), in place on the model rows; chunks off their
//! update phase take a weights-only variant (about a third of the work).
//! A second lane-wise pass (`background/batch.rs`, blocks of 8 pixels with at least 4
//! left over) finishes most of the rest (no mode matches, or a later mode
//! matches). What remains (sparse leftovers, reorders, empty pixels) goes
//! through the scalar [`slow_pixel`].
//! All paths give identical results (a test runs the scalar path
//! everywhere and compares; `bench/detect.rs --check` does it over the
//! steady state).

use super::DetectConfig;
use crate::frame::Frame;

mod batch;

/// Pixels handled per fast-path chunk: one `u64` mask word.
pub const CHUNK: usize = 64;

/// Length of the dither table (a power of two), plus one row of slack.
const DITHER_PERIOD: usize = 4096;

/// Frame-invariant fixed-point parameters, derived once from the config.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Modes per pixel (1..=4).
    pub k: usize,
    /// History: steady-state learning rate is `1/history`.
    pub history: u32,
    /// `T_B = 1 − c_f`, Q0.16.
    pub tb_q16: u32,
    /// Complexity prior `c_T`, Q0.16.
    pub ct_q16: u32,
    /// `T_b` (background test, in σ²), Q8.8.
    pub tb_sig_q8: u16,
    /// `T_g` (match test, in σ²), Q8.8.
    pub tg_sig_q8: u16,
    /// Initial variance, Q7.1.
    pub var_init: u8,
    /// Variance floor, Q7.1.
    pub var_min: u8,
    /// Variance ceiling, Q7.1.
    pub var_max: u8,
    /// Learning-rate factor on foreground pixels, Q0.16.
    pub fg_rate_q16: u32,
    /// Shadow test on.
    pub shadow: bool,
    /// Lowest shadow ratio `x/μ`, Q8.8.
    pub shadow_lo_q8: u32,
    /// Highest shadow ratio `x/μ`, Q8.8.
    pub shadow_hi_q8: u32,
    /// Start-up schedule on.
    pub fast_startup: bool,
    /// Mean and variance update interval `N` in frames (1 = every frame).
    pub update_interval: u32,
}

impl Params {
    /// Converts the validated config into fixed-point values.
    pub fn from_config(c: &DetectConfig) -> Self {
        use crate::qformat::{q1, q16, q8};
        let var = |v: f64| q1(v).clamp(1, 255) as u8;
        Params {
            k: c.modes.clamp(1, 4) as usize,
            history: c.history.max(1),
            tb_q16: q16(c.background_ratio).min(65535),
            ct_q16: q16(c.complexity_prior).min(65535),
            tb_sig_q8: q8(c.background_sigma * c.background_sigma).min(6400) as u16,
            tg_sig_q8: q8(c.match_sigma * c.match_sigma).min(6400) as u16,
            var_init: var(c.var_init),
            var_min: var(c.var_min),
            var_max: var(c.var_max),
            fg_rate_q16: q16(c.foreground_rate).min(65536),
            shadow: c.shadow,
            shadow_lo_q8: q8(c.shadow_min_ratio).min(256),
            shadow_hi_q8: q8(c.shadow_max_ratio).min(256),
            fast_startup: c.fast_startup,
            update_interval: c.update_interval.clamp(1, MAX_UPDATE_INTERVAL),
        }
    }
}

/// Longest mean and variance update interval accepted.
pub const MAX_UPDATE_INTERVAL: u32 = 8;

/// Whether the 64-pixel chunk `c` of row `y` updates its means and
/// variances in frame `frame` (staggered so that every frame updates
/// `1/N` of the chunks).
#[inline(always)]
pub fn updates_chunk(interval: u32, frame: u32, y: usize, c: usize) -> bool {
    interval <= 1 || (frame as usize).wrapping_add(y).wrapping_add(c) % interval as usize == 0
}

/// Learning rates of one frame, Q0.16.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rates {
    /// `α` for background (and shadow) pixels.
    pub a: u16,
    /// `α c_T` for background pixels (`≤ a`).
    pub act: u16,
    /// `α` for foreground pixels.
    pub a_fg: u16,
    /// `α c_T` for foreground pixels (`≤ a_fg`).
    pub act_fg: u16,
    /// Frames between mean and variance updates this frame: the config's
    /// `N` once `α ≤ 1/(16 N)`, 1 before (start-up).
    pub interval: u32,
    /// `N α`, the rate of the mean and variance update (`ρ = N α / w`).
    pub ua: u16,
    /// `N α` for foreground pixels.
    pub ua_fg: u16,
}

impl Rates {
    /// Rates for a learning rate `1/frames` (`frames ≥ 1`).
    pub fn new(p: &Params, frames: u32) -> Self {
        // 65536/frames rounded, clamped below 1.0.
        let a = ((65536 + frames / 2) / frames.max(1)).min(65535);
        let a_fg = ((a * p.fg_rate_q16 + 32768) >> 16).min(65535);
        let ct = |a: u32| ((a * p.ct_q16 + 32768) >> 16).min(a);
        let n = if frames >= 16 * p.update_interval {
            p.update_interval
        } else {
            1
        };
        Rates {
            a: a as u16,
            act: ct(a) as u16,
            a_fg: a_fg as u16,
            act_fg: ct(a_fg) as u16,
            interval: n,
            // N α ≤ 1/16 (+ rounding) when N > 1: fits Q0.16, ρ ≤ 2 N α ≤ 1/8.
            ua: (a * n).min(65535) as u16,
            ua_fg: (a_fg * n).min(65535) as u16,
        }
    }
}

/// `(a·b) >> 16` on 16-bit lanes (maps to `pmulhuw` / `umull`+shift).
#[inline(always)]
fn mulhi(a: u16, b: u16) -> u16 {
    ((u32::from(a) * u32::from(b)) >> 16) as u16
}

/// `⌊(a·b + δ) / 2¹⁶⌋`: the dithered product, from the 16-bit halves of
/// `a·b` (high half plus the carry out of low half + δ), so that it maps to
/// 16-bit vector lanes.
#[inline(always)]
fn mul_dither(a: u16, b: u16, dither: u16) -> u16 {
    let lo = a.wrapping_mul(b);
    mulhi(a, b) + u16::from(lo.overflowing_add(dither).1)
}

/// `1/w` in Q2.14 for a weight `w` in Q0.16 with `w > 32768` (w > ½):
/// the chord `3 − 2w` then one Newton step `r(2 − w r)`. Relative error
/// ≤ 1.6 % (the chord's 12.5 % squared) plus ≤ 2⁻¹³ rounding; all
/// products are 16×16 bits. Other `w` give a meaningless value (the
/// shifts drop bits), never a panic: the fast path computes it on every
/// lane and discards those.
#[inline(always)]
pub fn recip_q14(w: u16) -> u16 {
    // r0 ≈ 3 − 2w in Q2.14 (3 = 49152, 2w = w/2), one unit low so that
    // w > 32768 gives r0 ≤ 32767 and `r0 << 1` fits 16 bits.
    let r0 = 49151 - (w >> 1);
    // w·r0 in Q2.14, in [1 − ε, 1.125].
    let t = mulhi(w, r0);
    // 2 − w r0 in Q2.14 (≤ 16384 + rounding), r1 = r0 (2 − w r0):
    // (2 r0)·(2 (2 − w r0)) >> 16 = r0 (2 − w r0) in Q2.14; both factors < 2¹⁶.
    let e = 32768u16.saturating_sub(t);
    mulhi(r0 << 1, e << 1)
}

/// `ρ = α / w` in Q0.16 (clamped to 65532) for the matched mode's updated
/// weight `w ≥ 1`: Newton reciprocal above ½, exact division below.
#[inline(always)]
pub fn rho_q16(a: u16, w: u16) -> u16 {
    if w > 32768 {
        // (a · r) >> 14 = mulhi(a, r) << 2, r ≤ 2.0 → clamp before the shift.
        mulhi(a, recip_q14(w)).min(16383) << 2
    } else {
        ((u32::from(a) << 16) / u32::from(w.max(1))).min(65532) as u16
    }
}

/// Floor of `var · T` with `var` in Q7.1 and `T` in Q8.8: the threshold the
/// doubled squared distance `2 (x−μ)²` (also Q7.1) is compared with.
#[inline(always)]
fn threshold(var: u8, t_q8: u16) -> u16 {
    mulhi(u16::from(var) << 8, t_q8)
}

/// Weight after one frame for a mode that did not match.
#[inline(always)]
fn decay(w: u16, a: u16, act: u16) -> u16 {
    w.saturating_sub(mulhi(w, a).saturating_add(act))
}

/// Weight after one frame for the matched mode (`≥ 1` when `w ≥ 1`, since
/// `mulhi(w, a) < w` for `a < 2¹⁶`).
#[inline(always)]
fn grow(w: u16, a: u16, act: u16) -> u16 {
    (w - mulhi(w, a)).saturating_add(a - act)
}

/// Moves `μ` toward `x` by `ρ|x−μ|`, dithered (never overshoots `x`).
#[inline(always)]
fn step_mean(mu: u8, x: u8, rho: u16, dither: u16) -> u8 {
    let ad = u16::from(mu.abs_diff(x));
    let d = mul_dither(rho, ad, dither) as u8;
    if x >= mu {
        mu + d
    } else {
        mu - d
    }
}

/// Moves `σ²` (Q7.1) toward `d2 = 2(x−μ)²` by `ρ|d2 − σ²|`, dithered, then
/// clamps to `[lo, hi]`. `d2 ≤ 8191` (callers guarantee it).
#[inline(always)]
fn step_var(var: u8, d2: u16, rho: u16, dither: u16, lo: u8, hi: u8) -> u8 {
    let v = u16::from(var);
    let d = mul_dither(rho, d2.abs_diff(v), dither);
    let n = if d2 >= v { v + d } else { v - d };
    n.max(u16::from(lo)).min(u16::from(hi)) as u8
}

/// What the model says of one pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Matches a background mode.
    Background,
    /// Foreground but a shadow of a background mode.
    Shadow,
    /// Foreground.
    Foreground,
}

/// The full per-pixel update (any case). `w`, `mu`, `var` are the pixel's
/// `K` modes; `update`: this frame moves the matched mode's mean and
/// variance ([`updates_chunk`]); returns the pixel's class.
#[allow(clippy::too_many_arguments)]
pub fn slow_pixel<const K: usize>(
    x: u8,
    w: &mut [u16; K],
    mu: &mut [u8; K],
    var: &mut [u8; K],
    p: &Params,
    r: &Rates,
    dither: u16,
    update: bool,
) -> Class {
    let n = w.iter().take_while(|&&v| v > 0).count();
    if n == 0 {
        w[0] = r.a.max(1);
        mu[0] = x;
        var[0] = p.var_init;
        return Class::Background;
    }
    let s: u64 = w.iter().map(|&v| u64::from(v)).sum();
    let tb_s = u64::from(p.tb_q16) * s;
    let mut cum: u64 = 0;
    let mut bg = false;
    let mut matched = None;
    for k in 0..n {
        let ad = u16::from(mu[k].abs_diff(x));
        let d2 = 2 * u32::from(ad) * u32::from(ad);
        if (cum << 16) < tb_s && d2 < u32::from(threshold(var[k], p.tb_sig_q8)) {
            bg = true;
        }
        if d2 < u32::from(threshold(var[k], p.tg_sig_q8)) {
            matched = Some(k);
            break;
        }
        cum += u64::from(w[k]);
    }
    let mut class = if bg {
        Class::Background
    } else {
        Class::Foreground
    };
    if !bg && p.shadow {
        let xs = u32::from(x) << 8;
        let mut cum: u64 = 0;
        for k in 0..n {
            if (cum << 16) >= tb_s {
                break;
            }
            let m = u32::from(mu[k]);
            if xs >= p.shadow_lo_q8 * m && xs <= p.shadow_hi_q8 * m && m > 0 {
                class = Class::Shadow;
                break;
            }
            cum += u64::from(w[k]);
        }
    }
    let (a, act, ua) = if class == Class::Foreground {
        (r.a_fg, r.act_fg, r.ua_fg)
    } else {
        (r.a, r.act, r.ua)
    };
    for k in 0..n {
        if Some(k) == matched {
            let wn = grow(w[k], a, act);
            w[k] = wn;
            if update {
                let rho = rho_q16(ua, wn);
                let ad = u16::from(mu[k].abs_diff(x));
                let d2 = 2 * ad * ad; // matched: ad ≤ 56, d2 < 6375
                mu[k] = step_mean(mu[k], x, rho, dither);
                var[k] = step_var(var[k], d2, rho, !dither, p.var_min, p.var_max);
            }
        } else {
            w[k] = decay(w[k], a, act);
        }
    }
    let mut slot = match matched {
        Some(k) => k,
        None => {
            let alive = w.iter().take_while(|&&v| v > 0).count();
            let slot = alive.min(K - 1);
            w[slot] = a.max(1);
            mu[slot] = x;
            var[slot] = p.var_init;
            slot
        }
    };
    while slot > 0 && w[slot] > w[slot - 1] {
        w.swap(slot, slot - 1);
        mu.swap(slot, slot - 1);
        var.swap(slot, slot - 1);
        slot -= 1;
    }
    // A mode that died ahead of the matched one (impossible while sorted,
    // kept for safety) would leave a hole: close it.
    let mut j = 0;
    for i in 0..K {
        if w[i] > 0 {
            if i != j {
                w[j] = w[i];
                mu[j] = mu[i];
                var[j] = var[i];
                w[i] = 0;
            }
            j += 1;
        }
    }
    class
}

/// Fast path on one 64-pixel chunk of one row, in place on the model rows:
/// every pixel whose heaviest mode matches and whose updated weight is above
/// ½ is updated here (mode 0 must not be empty: callers skip frame 0) (identically to [`slow_pixel`]); returns a bit per
/// pixel left for the slow path (whose state is untouched). `wrow` is the
/// row's weights (mode `k` at `k·wd..`), the chunk starts at column `x0`.
/// `UPDATE`: the chunk's means and variances move this frame
/// ([`updates_chunk`]); without, only weights change (a third of the work).
///
/// Written for the auto-vectoriser: 16-bit lanes only (products as
/// `mulhi`/`wrapping_mul` pairs: `pmulhuw`/`pmullw` on SSE2, `umull` on
/// NEON), compares on values below 2¹⁵ done as `i16` (one `pcmpgtw`, no
/// sign-flip), signs applied as `(d ^ s) − s`, selects as masks. Lanes
/// that fail the test compute garbage (wrapping, never a panic) that is
/// discarded.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn fast_chunk<const K: usize, const UPDATE: bool>(
    x: &[u8; CHUNK],
    wrow: &mut [u16],
    wd: usize,
    x0: usize,
    mu0: &mut [u8; CHUNK],
    var0: &mut [u8; CHUNK],
    dither: &[u16; CHUNK],
    p: &Params,
    r: &Rates,
    lanes: &Lanes,
    scratch: &mut FastScratch,
) -> u64 {
    let FastScratch {
        a_taken,
        act_taken,
        ok,
    } = scratch;
    let (act, a_net) = (r.act, r.a - r.act);
    let (av, uav, tgv) = (&lanes.a, &lanes.ua, &lanes.tg);
    let (vlo, vhi) = (i16::from(p.var_min), i16::from(p.var_max));
    let w0 = chunk_mut::<_, CHUNK>(wrow, x0);
    for i in 0..CHUNK {
        let (m, v, wo, dith) = (i16::from(mu0[i]), i16::from(var0[i]), w0[i], dither[i]);
        // |x − μ| ≤ 255 and its sign s (0 or −1).
        let diff = i16::from(x[i]) - m;
        let s = diff >> 15;
        let ad = (diff ^ s) - s;
        let adc = ad.min(63);
        let d2 = 2 * adc * adc; // < 8192
        let thr = mulhi((v as u16) << 8, tgv[i]) as i16; // ≤ 6375
        let wn = (wo - mulhi(wo, av[i])).saturating_add(a_net);
        // wn > 32768 as a signed compare of wn − 2¹⁵. No test of `wo ≠ 0`:
        // see [`Background::pass`] (mode 0 is never empty after frame 0).
        let g = (d2 < thr) & ((wn ^ 0x8000) as i16 > 0);
        w0[i] = if g { wn } else { wo };
        let tm = (-i16::from(g)) as u16;
        a_taken[i] = av[i] & tm;
        act_taken[i] = act & tm;
        ok[i] = u8::from(g);
        if !UPDATE {
            continue;
        }
        let rho = mulhi(uav[i], recip_q14(wn)).min(16383) << 2;
        let dm = mul_dither(rho, ad as u16, dith) as i16; // ≤ |x − μ|
        let m2 = m + ((dm ^ s) - s);
        let vd = d2 - v;
        let vs = vd >> 15;
        let dv = mul_dither(rho, ((vd ^ vs) - vs) as u16, !dith) as i16;
        let v2 = (v + ((dv ^ vs) - vs)).max(vlo).min(vhi);
        let gm = -i16::from(g);
        mu0[i] = ((m2 & gm) | (m & !gm)) as u8;
        var0[i] = ((v2 & gm) | (v & !gm)) as u8;
    }
    for k in 1..K {
        let wk = chunk_mut::<_, CHUNK>(wrow, k * wd + x0);
        for i in 0..CHUNK {
            wk[i] = decay(wk[i], a_taken[i], act_taken[i]);
        }
    }
    !pack_flags(ok)
}

/// Per-chunk arrays of [`fast_chunk`], owned by the frame's pass so that
/// they are not zeroed for every chunk (every lane is written before it is
/// read; measured 20 stores per chunk).
struct FastScratch {
    /// The rates the other modes decay with: `α` and `α c_T` on the lanes
    /// taken, 0 elsewhere (`decay(w, 0, 0) = w`), so their decay needs no
    /// select (12 → 5 instructions per 8 lanes and mode on SSE2).
    a_taken: [u16; CHUNK],
    /// `α c_T` on the lanes taken, 0 elsewhere.
    act_taken: [u16; CHUNK],
    /// 1 on the lanes taken (for [`pack_flags`]).
    ok: [u8; CHUNK],
}

/// Per-frame factors of the fast path as lane arrays the optimiser cannot
/// see through (made once per frame behind `black_box`): multiplying by a
/// known splat makes LLVM widen to 32-bit lanes (`pmuludq`) instead of
/// using `pmulhuw`.
struct Lanes {
    a: [u16; CHUNK],
    ua: [u16; CHUNK],
    tg: [u16; CHUNK],
    tb: [u16; CHUNK],
    /// `T_B` (Q0.16) and `c_f = 2¹⁶ − T_B` (≤ 2¹⁵, `T_B ≥ ½` by config),
    /// for the batch pass's background walk.
    tb_w: [u16; CHUNK],
    cf_w: [u16; CHUNK],
    a_fg: [u16; CHUNK],
    ua_fg: [u16; CHUNK],
}

impl Lanes {
    /// This frame's factors (callers hide the result behind `black_box`).
    fn new(p: &Params, r: &Rates) -> Self {
        Lanes {
            a: [r.a; CHUNK],
            ua: [r.ua; CHUNK],
            tg: [p.tg_sig_q8; CHUNK],
            tb: [p.tb_sig_q8; CHUNK],
            tb_w: [p.tb_q16 as u16; CHUNK],
            cf_w: [(65536 - p.tb_q16) as u16; CHUNK],
            a_fg: [r.a_fg; CHUNK],
            ua_fg: [r.ua_fg; CHUNK],
        }
    }
}

/// The `N` values of `s` from `at` (a chunk, or a block of the batch
/// pass; callers keep `at + N ≤ len`).
#[inline(always)]
fn chunk<T, const N: usize>(s: &[T], at: usize) -> &[T; N] {
    s[at..at + N].try_into().expect("chunk inside the row")
}

/// Mutable [`chunk`].
#[inline(always)]
fn chunk_mut<T, const N: usize>(s: &mut [T], at: usize) -> &mut [T; N] {
    (&mut s[at..at + N])
        .try_into()
        .expect("chunk inside the row")
}

/// Packs up to 64 bytes of 0/1 (a multiple of 8) into bits, byte `i` to bit
/// `i`: 8 bytes to 8 bits with one multiply.
#[inline(always)]
pub(crate) fn pack_flags<const N: usize>(flags: &[u8; N]) -> u64 {
    let mut bits = 0u64;
    for (j, c) in flags.chunks_exact(8).enumerate() {
        let v = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        bits |= (v.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * j);
    }
    bits
}

/// Statistics of the last frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Pixels that took the scalar path.
    pub slow_pixels: u32,
    /// Foreground pixels (before clean-up, shadows excluded).
    pub foreground: u32,
    /// Shadow pixels.
    pub shadow: u32,
    /// Global gain applied to the model this frame (Q8.8, 256 = none).
    pub gain_q8: u16,
    /// The start-up schedule was restarted because most of the frame changed.
    pub relearn: bool,
}

/// The per-pixel mixture model of one frame size.
#[derive(Debug)]
pub struct Background {
    width: usize,
    height: usize,
    p: Params,
    /// Weights, Q0.16: row `y`, mode `k` at `((y·K + k)·W ..)`.
    w: Vec<u16>,
    /// Means, same layout.
    mu: Vec<u8>,
    /// Variances, Q7.1, same layout.
    var: Vec<u8>,
    dither: Vec<u16>,
    /// Frames seen since start (or since a relearn), drives the schedule.
    t: u32,
    frame: u32,
    gain_hist: Vec<u32>,
    gain_threshold_q8: u32,
    gain_compensation: bool,
    relearn_fraction_q16: u32,
    force_slow: bool,
    stats: FrameStats,
}

impl Background {
    /// Allocates the model for `width`×`height` frames.
    pub fn new(cfg: &DetectConfig, width: usize, height: usize) -> Self {
        let p = Params::from_config(cfg);
        let n = width * height * p.k;
        // xorshift32 table: fixed seed, so every platform and run dithers alike.
        let mut s: u32 = 0x9E37_79B9;
        let dither = (0..DITHER_PERIOD + width + CHUNK)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                (s >> 16) as u16
            })
            .collect();
        Background {
            width,
            height,
            p,
            w: vec![0; n],
            mu: vec![0; n],
            var: vec![0; n],
            dither,
            t: 0,
            frame: 0,
            gain_hist: vec![0; 1024],
            gain_threshold_q8: crate::qformat::q8(cfg.gain_threshold),
            gain_compensation: cfg.gain_compensation,
            relearn_fraction_q16: crate::qformat::q16(cfg.relearn_fraction),
            force_slow: false,
            stats: FrameStats::default(),
        }
    }

    /// Bytes of model state per pixel (`4·K`).
    pub fn bytes_per_pixel(&self) -> usize {
        4 * self.p.k
    }

    /// The fixed-point parameters.
    pub fn params(&self) -> &Params {
        &self.p
    }

    /// The mean of pixel `(x, y)`'s heaviest mode (0 when it has none):
    /// its background level. Panics outside the frame.
    pub fn background_mean(&self, x: usize, y: usize) -> u8 {
        let i = y * self.p.k * self.width + x;
        if self.w[i] == 0 {
            0
        } else {
            self.mu[i]
        }
    }

    /// Statistics of the last frame.
    pub fn stats(&self) -> FrameStats {
        self.stats
    }

    /// FNV-1a digest of the whole model state (for bit-exactness checks
    /// across paths and platforms).
    pub fn digest(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |b: u8| {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0100_0000_01b3);
        };
        for &w in &self.w {
            eat(w as u8);
            eat((w >> 8) as u8);
        }
        self.mu.iter().chain(&self.var).for_each(|&b| eat(b));
        h
    }

    /// Runs every pixel through the scalar path (for tests of the fast path).
    pub fn set_force_slow(&mut self, on: bool) {
        self.force_slow = on;
    }

    /// The learning rates this frame will use.
    pub fn rates(&self) -> Rates {
        let frames = if self.p.fast_startup {
            (self.t + 1).min(self.p.history)
        } else {
            self.p.history
        };
        Rates::new(&self.p, frames)
    }

    /// Updates the model with `frame` and writes the foreground mask (one
    /// bit per pixel, rows of `words_per_row` words, bit `x % 64` of word
    /// `x / 64`) to `mask` and the pixels it called shadow to `shadow`
    /// (same layout).
    pub fn apply(
        &mut self,
        frame: &Frame,
        mask: &mut [u64],
        shadow: &mut [u64],
        words_per_row: usize,
    ) {
        let r = self.rates();
        self.stats = FrameStats {
            gain_q8: 256,
            ..FrameStats::default()
        };
        if self.gain_compensation && self.frame > 0 {
            self.compensate_gain(frame);
        }
        match self.p.k {
            1 => self.pass::<1>(frame, &r, mask, shadow, words_per_row),
            2 => self.pass::<2>(frame, &r, mask, shadow, words_per_row),
            3 => self.pass::<3>(frame, &r, mask, shadow, words_per_row),
            _ => self.pass::<4>(frame, &r, mask, shadow, words_per_row),
        }
        // Most of the frame changed at once (lights, camera moved, a gain
        // step the gain estimate could not explain): relearn fast.
        let fg = u64::from(self.stats.foreground);
        let total = (self.width * self.height) as u64;
        self.t = self.t.saturating_add(1);
        if self.frame > 0 && fg << 16 > u64::from(self.relearn_fraction_q16) * total {
            self.stats.relearn = true;
            self.t = self.t.min(RELEARN_T);
        }
        self.frame = self.frame.wrapping_add(1);
    }

    fn pass<const K: usize>(
        &mut self,
        frame: &Frame,
        r: &Rates,
        mask: &mut [u64],
        shadow_mask: &mut [u64],
        wpr: usize,
    ) {
        let (wd, ht) = (self.width, self.height);
        let p = self.p;
        let mut slow = 0u32;
        let mut fg_count = 0u32;
        let mut shadow = 0u32;
        let frame_off = (self.frame as usize).wrapping_mul(2_654_435_761) % DITHER_PERIOD;
        let lanes = core::hint::black_box(Lanes::new(&p, r));
        let mut scratch = FastScratch {
            a_taken: [0; CHUNK],
            act_taken: [0; CHUNK],
            ok: [0; CHUNK],
        };
        // Frame 0 (an empty model: every pixel gets its first mode) runs
        // on the scalar path, which every pixel would take anyway: after
        // it every pixel's mode 0 has a weight ≥ 1 for good (every path
        // leaves the new, grown or heaviest mode there: a new mode weighs
        // `max(α, 1)`, a grown one ≥ 1, and a decayed mode 0 only reaches 0
        // if every mode does, when the new mode takes slot 0), so the fast
        // path need not test for an empty mode 0.
        let first = self.frame == 0;
        for y in 0..ht {
            let xrow = &frame.y[y * wd..(y + 1) * wd];
            let base = y * K * wd;
            let wrow = &mut self.w[base..base + K * wd];
            let murow = &mut self.mu[base..base + K * wd];
            let varrow = &mut self.var[base..base + K * wd];
            let off = (frame_off + y * 1031) % DITHER_PERIOD;
            let drow = &self.dither[off..off + wd];
            let mrow = &mut mask[y * wpr..(y + 1) * wpr];
            let srow = &mut shadow_mask[y * wpr..(y + 1) * wpr];
            let full = if self.force_slow || first {
                0
            } else {
                wd / CHUNK
            };
            for (c, (mword, sword)) in mrow.iter_mut().zip(srow.iter_mut()).enumerate() {
                let x0 = c * CHUNK;
                let x1 = (x0 + CHUNK).min(wd);
                let update = updates_chunk(r.interval, self.frame, y, c);
                let mut todo = if c < full {
                    let (xs, ms, vs, ds) = (
                        chunk(xrow, x0),
                        chunk_mut(murow, x0),
                        chunk_mut(varrow, x0),
                        chunk(drow, x0),
                    );
                    let sc = &mut scratch;
                    if update {
                        fast_chunk::<K, true>(xs, wrow, wd, x0, ms, vs, ds, &p, r, &lanes, sc)
                    } else {
                        fast_chunk::<K, false>(xs, wrow, wd, x0, ms, vs, ds, &p, r, &lanes, sc)
                    }
                } else if x1 - x0 == CHUNK {
                    u64::MAX
                } else {
                    (1u64 << (x1 - x0)) - 1
                };
                let mut bits = 0u64;
                let mut sbits = 0u64;
                // The cases the fast path left, in lanes ([`batch`]).
                if K > 1 && c < full && todo != 0 {
                    let (xs, ds) = (chunk(xrow, x0), chunk(drow, x0));
                    let d = if update {
                        batch::batch_chunk::<K, true>(
                            xs, wrow, murow, varrow, wd, x0, todo, ds, &p, r, &lanes,
                        )
                    } else {
                        batch::batch_chunk::<K, false>(
                            xs, wrow, murow, varrow, wd, x0, todo, ds, &p, r, &lanes,
                        )
                    };
                    todo &= !d.done;
                    bits = d.fg;
                    sbits = d.shadow;
                    fg_count += d.fg.count_ones();
                    shadow += d.shadow.count_ones();
                }
                while todo != 0 {
                    let b = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    let x = x0 + b;
                    let mut w = [0u16; K];
                    let mut mu = [0u8; K];
                    let mut var = [0u8; K];
                    for k in 0..K {
                        w[k] = wrow[k * wd + x];
                        mu[k] = murow[k * wd + x];
                        var[k] = varrow[k * wd + x];
                    }
                    let class =
                        slow_pixel::<K>(xrow[x], &mut w, &mut mu, &mut var, &p, r, drow[x], update);
                    for k in 0..K {
                        wrow[k * wd + x] = w[k];
                        murow[k * wd + x] = mu[k];
                        varrow[k * wd + x] = var[k];
                    }
                    slow += 1;
                    match class {
                        Class::Foreground => {
                            bits |= 1 << b;
                            fg_count += 1;
                        }
                        Class::Shadow => {
                            sbits |= 1 << b;
                            shadow += 1;
                        }
                        Class::Background => {}
                    }
                }
                *mword = bits;
                *sword = sbits;
            }
        }
        self.stats.slow_pixels = slow;
        self.stats.foreground = fg_count;
        self.stats.shadow = shadow;
    }

    /// Estimates a global gain between the frame and the heaviest modes on
    /// a sparse grid (median of `x/μ`); when it is off by more than the
    /// threshold, rescales every mode's mean (and variance) by it, so a
    /// sudden exposure change does not turn the whole frame foreground.
    fn compensate_gain(&mut self, frame: &Frame) {
        // One sample per 8 rows and 16 columns: ~3500 samples at 768x576,
        // a median good to a fraction of a percent.
        const STEP_X: usize = 16;
        const STEP_Y: usize = 8;
        let (wd, ht, k) = (self.width, self.height, self.p.k);
        self.gain_hist.fill(0);
        let mut n = 0u32;
        for y in (STEP_Y / 2..ht).step_by(STEP_Y) {
            let base = y * k * wd;
            for x in (STEP_X / 2..wd).step_by(STEP_X) {
                let m = u32::from(self.mu[base + x]);
                // Heaviest mode dominant and bright enough for a ratio.
                if self.w[base + x] >= 32768 && m >= 24 {
                    let ratio = (u32::from(frame.y[y * wd + x]) << 8) / m;
                    self.gain_hist[ratio.min(1023) as usize] += 1;
                    n += 1;
                }
            }
        }
        if n < 64 {
            return;
        }
        let mut acc = 0;
        let mut g = 256u32;
        for (i, &c) in self.gain_hist.iter().enumerate() {
            acc += c;
            if 2 * acc >= n {
                g = i as u32;
                break;
            }
        }
        if g.abs_diff(256) <= self.gain_threshold_q8 {
            return;
        }
        let g2 = (g * g + 128) >> 8; // Q8.8
        for (i, w) in self.w.iter().enumerate() {
            if *w > 0 {
                let m = (u32::from(self.mu[i]) * g + 128) >> 8;
                self.mu[i] = m.min(255) as u8;
                let v = (u32::from(self.var[i]) * g2 + 128) >> 8;
                self.var[i] = v.clamp(u32::from(self.p.var_min), u32::from(self.p.var_max)) as u8;
            }
        }
        self.stats.gain_q8 = g.min(65535) as u16;
    }
}

/// Schedule position after a relearn: `α` restarts at `1/(RELEARN_T + 1)`.
const RELEARN_T: u32 = 8;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newton_reciprocal_is_within_two_percent() {
        for w in 32769..=65535u32 {
            let r = f64::from(recip_q14(w as u16)) / 16384.0;
            let exact = 65536.0 / w as f64;
            assert!((r / exact - 1.0).abs() < 0.017, "w={w} r={r} exact={exact}");
        }
    }

    #[test]
    fn dithered_mean_step_is_unbiased() {
        // ρ = 0.002, |x−μ| = 3: expected step 0.006 levels per frame.
        let rho = (0.002f64 * 65536.0).round() as u16;
        let mut moved = 0u32;
        let mut s: u32 = 1;
        for _ in 0..100_000 {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            if step_mean(100, 103, rho, (s >> 16) as u16) == 101 {
                moved += 1;
            }
        }
        let expect = 100_000.0 * f64::from(rho) * 3.0 / 65536.0;
        assert!(
            (f64::from(moved) - expect).abs() < 4.0 * expect.sqrt(),
            "{moved} vs {expect}"
        );
    }

    #[test]
    fn weights_settle_at_one_minus_ct() {
        let cfg = DetectConfig::default();
        let p = Params::from_config(&cfg);
        let r = Rates::new(&p, 100);
        let mut w = 0u16;
        w = w.max(r.a);
        for _ in 0..5000 {
            w = grow(w, r.a, r.act);
        }
        let expect = 1.0 - cfg.complexity_prior;
        let got = f64::from(w) / 65536.0;
        assert!((got - expect).abs() < 0.01, "{got} vs {expect}");
    }
}
