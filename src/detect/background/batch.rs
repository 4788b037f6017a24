//! Second lane-wise pass: the pixels the fast path leaves behind.
//!
//! The fast path ([`super::fast_chunk`]) only takes pixels whose heaviest
//! mode matches with a weight above ½. The rest (≈ 4.4 % of the pixels in
//! steady state on PETS at 1280×720, ≈ 3.8 % during start-up, each ≈ 240
//! instructions in the scalar [`super::slow_pixel`], a third of that
//! gathering and scattering the modes) are mostly:
//!
//! * no mode matches (foreground, shadow, a new background value): every
//!   mode decays, a new mode `(α, x, σ²_init)` takes the first empty slot
//!   or replaces the lightest;
//! * a later mode `k ≥ 1` matches: it grows, the others decay, and in an
//!   update chunk ([`super::updates_chunk`]) its mean and variance move by
//!   `ρ = Nα/w` (per lane, scalar: below ½ it is a division).
//!
//! This pass runs the whole update (background walk with its cumulated
//! weights, shadow walk, class, learning rate by class, weights, the new
//! mode, the matched mode's dithered mean and variance step) on blocks of
//! 8 pixels (one vector of `u16`: SSE2, NEON), branch-free but for the
//! `ρ` of matched lanes, and writes the lanes it can finish exactly as the
//! scalar path would. It gives back to the scalar path (state untouched)
//! any lane that would need a reorder of the modes (the grown or new mode
//! outweighs the one before it), the first mode of an empty pixel, the
//! heaviest mode's match (the fast path refused it, `w ≤ ½`), or weight
//! sums of 2¹⁶ − 1 or more (the 32-bit background test below would
//! overflow). Blocks with fewer than [`MIN_LANES`] slow pixels stay on the
//! scalar path (a block costs about what three or four scalar pixels do).
//! Either path gives the same model: a unit test compares lane by lane on
//! random states, the PETS test and `bench/detect.rs --check` frame by
//! frame.
//!
//! # The background walk in 32 bits
//!
//! Mode `k` is a background mode while `C_k · 2¹⁶ < T_B · S` (`C_k` = the
//! weights before it, `S` all weights; the scalar path compares in `u64`).
//! With `R_k = S − C_k` and `c_f = 2¹⁶ − T_B` this is exactly
//! `C_k · c_f < T_B · R_k`. On lanes with `S ≤ 65534`: `C_k · c_f ≤ 65534 ·
//! 32768 < 2³¹` (`T_B ≥ ½` by config) and `T_B · R_k ≤ 65535 · 65534 <
//! 2³²`, so both sides are `u32` products of 16-bit values (`pmullw` +
//! `pmulhuw` on SSE2, `umull` on NEON). Weights settle at a sum of
//! `1 − n c_T < 1`; larger sums occur only right after start or relearn.

use super::{
    chunk, chunk_mut, decay, grow, mul_dither, mulhi, pack_flags, rho_q16, Lanes, Params, Rates,
    CHUNK,
};

/// Fewest slow pixels in a block for which the block pays (measured at
/// 1280×720: 3, 4, 5 gave 36.2 / 35.8 / 35.7 instr/px in start-up and
/// 27.6 / 27.5 / 27.6 in steady state, `bench/RESULTS.md`).
const MIN_LANES: u32 = 4;

/// Lanes finished by [`batch_chunk`]: which, and their mask bits.
pub(super) struct Done {
    /// Pixels finished here (their model state is written).
    pub(super) done: u64,
    /// Foreground pixels among them.
    pub(super) fg: u64,
    /// Shadow pixels among them.
    pub(super) shadow: u64,
}

/// Lanes per block: one 128-bit vector of `u16` (SSE2, NEON), so a
/// block's intermediates stay in registers and blocks without enough slow
/// pixels are skipped (64-lane blocks cost more than they saved).
const LANES: usize = 8;

/// Runs the full update on the lanes of one chunk that the fast path left
/// (`todo`, bit `i` = column `x0 + i`), block by block of [`LANES`]; see
/// the module doc. `wrow`, `murow`, `varrow` are the row's modes (mode `k`
/// at `k·wd..`), `dither` the chunk's dither values. `UPDATE`: the
/// chunk's means and variances move this frame.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(super) fn batch_chunk<const K: usize, const UPDATE: bool>(
    x: &[u8; CHUNK],
    wrow: &mut [u16],
    murow: &mut [u8],
    varrow: &mut [u8],
    wd: usize,
    x0: usize,
    todo: u64,
    dither: &[u16; CHUNK],
    p: &Params,
    r: &Rates,
    lanes: &Lanes,
) -> Done {
    let mut d = Done {
        done: 0,
        fg: 0,
        shadow: 0,
    };
    for b in 0..CHUNK / LANES {
        let sel = (todo >> (b * LANES)) as u8;
        if sel.count_ones() < MIN_LANES {
            continue;
        }
        let at = x0 + b * LANES;
        let xb = x[b * LANES..(b + 1) * LANES]
            .try_into()
            .expect("block inside the chunk");
        let db = dither[b * LANES..(b + 1) * LANES]
            .try_into()
            .expect("block inside the chunk");
        let (done, fg, sh) =
            block::<K, UPDATE>(xb, wrow, murow, varrow, wd, at, sel, db, p, r, lanes);
        d.done |= u64::from(done) << (b * LANES);
        d.fg |= u64::from(fg) << (b * LANES);
        d.shadow |= u64::from(sh) << (b * LANES);
    }
    d
}

/// One block of [`LANES`] pixels from column `at`: the lanes of `sel`
/// this pass can finish are written; returns (finished, foreground,
/// shadow) lane bits. Every lane computes every case (garbage on lanes not
/// taken, wrapping, never a panic); the writes select per lane.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn block<const K: usize, const UPDATE: bool>(
    x: &[u8; LANES],
    wrow: &mut [u16],
    murow: &mut [u8],
    varrow: &mut [u8],
    wd: usize,
    at: usize,
    sel: u8,
    dither: &[u16; LANES],
    p: &Params,
    r: &Rates,
    lanes: &Lanes,
) -> (u8, u8, u8) {
    let var_init = p.var_init;
    // c_f = 2¹⁶ − T_B ≤ 2¹⁵ (T_B ≥ ½), T_B < 2¹⁶: both fit u16.
    // As lanes the optimiser cannot see through: a known splat made LLVM
    // widen `C_k · c_f` to `pmuludq` on 32-bit lanes.
    let (cfv, tbv_w) = (&lanes.cf_w, &lanes.tb_w);
    // Shadow ratios in Q8.8, ≤ 1.0: `ratio · μ ≤ 65280` fits u16.
    let (lo, hi) = (p.shadow_lo_q8 as u16, p.shadow_hi_q8 as u16);
    let shadow_on = mask(p.shadow);
    let (tgv, tbv, av, afv) = (&lanes.tg, &lanes.tb, &lanes.a, &lanes.a_fg);
    let w: [[u16; LANES]; K] = core::array::from_fn(|k| *chunk::<_, LANES>(wrow, k * wd + at));
    let mu: [[u8; LANES]; K] = core::array::from_fn(|k| *chunk::<_, LANES>(murow, k * wd + at));
    let var: [[u8; LANES]; K] = core::array::from_fn(|k| *chunk::<_, LANES>(varrow, k * wd + at));
    // Written as whole-array steps, one simple loop each: the vectoriser
    // turned the same work down as one loop body.
    //
    // Per mode: matches (`mg`), background test (`mb`), shadow band, all
    // for live modes only, as 0 / 0xFFFF lane masks.
    let mut mg = [[0u16; LANES]; K];
    let mut mb = [[0u16; LANES]; K];
    let mut band = [[0u16; LANES]; K];
    for k in 0..K {
        for i in 0..LANES {
            let (xv, m, v) = (u16::from(x[i]), u16::from(mu[k][i]), u16::from(var[k][i]));
            let alive = w[k][i] != 0;
            // On bytes, then widened (`pminub`/`pmaxub`; on u16 lanes it
            // took a compare and a select).
            let ad = u16::from(x[i].abs_diff(mu[k][i])).min(63);
            // Below 2¹⁵ both: signed compares (see fast_chunk).
            let d2 = (2 * ad * ad) as i16;
            mg[k][i] = mask(alive & (d2 < mulhi(v << 8, tgv[i]) as i16));
            mb[k][i] = mask(alive & (d2 < mulhi(v << 8, tbv[i]) as i16));
            let xs = xv << 8;
            band[k][i] = mask(alive & (xs >= lo * m) & (xs <= hi * m) & (m > 0));
        }
    }
    // S, saturated: a lane with S ≥ 2¹⁶ − 1 is given back, so on the lanes
    // taken every partial sum below is exact.
    let mut s = [0u16; LANES];
    for wk in &w {
        for i in 0..LANES {
            s[i] = s[i].saturating_add(wk[i]);
        }
    }
    // Walk the modes: background modes (`C_k · c_f < T_B · (S − C_k)`,
    // exact, module doc; mode 0 always), the first match, background and
    // shadow found.
    let mut cum = [0u16; LANES];
    let mut walk = [0xFFFFu16; LANES];
    let mut bg = [0u16; LANES];
    let mut sh = [0u16; LANES];
    let mut hit = [[0u16; LANES]; K];
    for k in 0..K {
        for i in 0..LANES {
            let c = cum[i];
            let el = if k == 0 {
                0xFFFF
            } else {
                let r = s[i].wrapping_sub(c);
                mask(u32::from(c) * u32::from(cfv[i]) < u32::from(tbv_w[i]) * u32::from(r))
            };
            bg[i] |= el & walk[i] & mb[k][i];
            sh[i] |= el & band[k][i];
            hit[k][i] = walk[i] & mg[k][i];
            walk[i] &= !mg[k][i];
            cum[i] = c.wrapping_add(w[k][i]);
        }
    }
    // Class and its learning rate.
    let mut fgm = [0u16; LANES];
    let mut shm = [0u16; LANES];
    let mut a = [0u16; LANES];
    let mut act = [0u16; LANES];
    let mut ua = [0u16; LANES];
    let (uav, uafv) = (&lanes.ua, &lanes.ua_fg);
    for i in 0..LANES {
        shm[i] = !bg[i] & sh[i] & shadow_on;
        fgm[i] = !bg[i] & !shm[i];
        a[i] = (afv[i] & fgm[i]) | (av[i] & !fgm[i]);
        act[i] = (r.act_fg & fgm[i]) | (r.act & !fgm[i]);
        ua[i] = (uafv[i] & fgm[i]) | (uav[i] & !fgm[i]);
    }
    // Matched mode grows, the others decay (0 stays 0); live modes after.
    let mut nw = [[0u16; LANES]; K];
    let mut alive = [0u16; LANES];
    for k in 0..K {
        for i in 0..LANES {
            let wk = w[k][i];
            let (g, d) = (grow(wk, a[i], act[i]), decay(wk, a[i], act[i]));
            let n = (g & hit[k][i]) | (d & !hit[k][i]);
            nw[k][i] = n;
            alive[i] += u16::from(n != 0);
        }
    }
    // Update chunks: the matched mode's mean and variance move by
    // `ρ = Nα/w` (post-update weight), dithered, exactly as in
    // `slow_pixel` (and in the same lane form as `fast_chunk`). `ρ` is
    // per lane, scalar (a division below ½); no match leaves `wm = 0`
    // and `ρ = 0` (the step is discarded).
    let mut nmu = [[0u8; LANES]; K];
    let mut nvar = [[0u8; LANES]; K];
    let mut wm = [0u16; LANES];
    if UPDATE {
        for k in 0..K {
            for i in 0..LANES {
                wm[i] |= nw[k][i] & hit[k][i];
            }
        }
    }
    if UPDATE && wm != [0; LANES] {
        let mut rho = [0u16; LANES];
        for i in 0..LANES {
            // Matched lanes only: the others' `ρ` is discarded (and costs a
            // division each, below ½).
            if wm[i] != 0 {
                rho[i] = rho_q16(ua[i], wm[i]);
            }
        }
        let (vlo, vhi) = (i16::from(p.var_min), i16::from(p.var_max));
        for k in 0..K {
            for i in 0..LANES {
                let (m, v, dith) = (i16::from(mu[k][i]), i16::from(var[k][i]), dither[i]);
                let diff = i16::from(x[i]) - m;
                let sg = diff >> 15;
                let ad = (diff ^ sg) - sg;
                let adc = ad.min(63);
                let d2 = 2 * adc * adc; // matched: ad ≤ 56, d2 < 6375
                let dm = mul_dither(rho[i], ad as u16, dith) as i16; // ≤ |x − μ|
                nmu[k][i] = (m + ((dm ^ sg) - sg)) as u8;
                let vd = d2 - v;
                let vs = vd >> 15;
                let dv = mul_dither(rho[i], ((vd ^ vs) - vs) as u16, !dith) as i16;
                nvar[k][i] = (v + ((dv ^ vs) - vs)).max(vlo).min(vhi) as u8;
            }
        }
    }
    // No match: the new mode `(α, x, σ²_init)` goes to the first empty slot,
    // else replaces the lightest. Lanes where the new or grown mode would
    // move up past the one before it are given back.
    let mut put = [[0u16; LANES]; K];
    let mut reorder = [0u16; LANES];
    for k in 0..K {
        for i in 0..LANES {
            let here = walk[i] & mask(alive[i].min(K as u16 - 1) == k as u16);
            let wnew = a[i].max(1);
            if k > 0 {
                let before = nw[k - 1][i];
                reorder[i] |= (here & mask(wnew > before)) | (hit[k][i] & mask(nw[k][i] > before));
            }
            nw[k][i] = (wnew & here) | (nw[k][i] & !here);
            put[k][i] = here;
        }
    }
    // Lanes taken, as masks; the flags for `pack_flags` are their low
    // bytes' lowest bit.
    let mut take = [0u16; LANES];
    let (mut tk, mut fgf, mut shf) = ([0u8; LANES], [0u8; LANES], [0u8; LANES]);
    for i in 0..LANES {
        let lane = mask(sel & (1 << i) != 0);
        let t = lane & mask(w[0][i] != 0) & !hit[0][i] & mask(s[i] < 65535) & !reorder[i];
        take[i] = t;
        tk[i] = (t & 1) as u8;
        fgf[i] = (t & fgm[i] & 1) as u8;
        shf[i] = (t & shm[i] & 1) as u8;
    }
    for k in 0..K {
        let wk = chunk_mut::<_, LANES>(wrow, k * wd + at);
        // Selects, not conditional stores (no masked stores in SSE2).
        for i in 0..LANES {
            wk[i] = (nw[k][i] & take[i]) | (w[k][i] & !take[i]);
        }
        // The new mode's mean and variance, and the matched mode's moved
        // ones: bitwise selects with byte masks (measured cheaper than
        // selecting on u16 lanes or as one u64).
        let mut nb = [0u8; LANES];
        let mut nh = [0u8; LANES];
        for i in 0..LANES {
            nb[i] = (take[i] & put[k][i]) as u8;
            nh[i] = if UPDATE {
                (take[i] & hit[k][i]) as u8
            } else {
                0
            };
        }
        let mk = chunk_mut::<_, LANES>(murow, k * wd + at);
        for i in 0..LANES {
            mk[i] = (x[i] & nb[i]) | (nmu[k][i] & nh[i]) | (mu[k][i] & !(nb[i] | nh[i]));
        }
        let vk = chunk_mut::<_, LANES>(varrow, k * wd + at);
        for i in 0..LANES {
            vk[i] = (var_init & nb[i]) | (nvar[k][i] & nh[i]) | (var[k][i] & !(nb[i] | nh[i]));
        }
    }
    (
        pack_flags(&tk) as u8,
        pack_flags(&fgf) as u8,
        pack_flags(&shf) as u8,
    )
}

/// `0xFFFF` for true, 0 for false (a lane mask).
#[inline(always)]
fn mask(b: bool) -> u16 {
    0u16.wrapping_sub(u16::from(b))
}

#[cfg(test)]
mod tests {
    use super::super::{slow_pixel, Class, Params, Rates};
    use super::*;
    use crate::detect::DetectConfig;

    /// Random model states (sorted weights with empty suffixes, sums up to
    /// and past 2¹⁶, values near and far from the modes): every lane the
    /// batch pass takes ends exactly as the scalar path leaves it, every
    /// lane it gives back is untouched, and the common cases are taken.
    fn agrees<const K: usize, const UPDATE: bool>(frames: u32) {
        let p = Params::from_config(&DetectConfig::default());
        let r = Rates::new(&p, frames);
        let lanes = Lanes::new(&p, &r);
        let mut s: u32 = 12345;
        let mut rnd = |n: u32| {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s % n
        };
        let (mut taken, mut total) = (0u32, 0u32);
        for round in 0..400 {
            let mut w = vec![0u16; K * CHUNK];
            let mut mu = vec![0u8; K * CHUNK];
            let mut var = vec![0u8; K * CHUNK];
            let mut x = [0u8; CHUNK];
            for i in 0..CHUNK {
                let n = rnd(K as u32 + 1) as usize;
                let scale = [65535, 40000, 70000, 200][round % 4];
                let mut ws: Vec<u16> = (0..n).map(|_| 1 + rnd(scale / K as u32) as u16).collect();
                ws.sort_unstable_by(|a, b| b.cmp(a));
                for k in 0..K {
                    w[k * CHUNK + i] = ws.get(k).copied().unwrap_or(0);
                    mu[k * CHUNK + i] = rnd(256) as u8;
                    let (lo, hi) = (u32::from(p.var_min), u32::from(p.var_max));
                    var[k * CHUNK + i] = (lo + rnd(hi - lo + 1)) as u8;
                }
                // Near one of the modes, or anywhere.
                let k = rnd(K as u32) as usize;
                x[i] = match rnd(3) {
                    0 => rnd(256) as u8,
                    _ => mu[k * CHUNK + i]
                        .saturating_add(rnd(9) as u8)
                        .saturating_sub(4),
                };
            }
            let dith: [u16; CHUNK] = core::array::from_fn(|_| rnd(65536) as u16);
            let todo = u64::from(rnd(u32::MAX)) << 32 | u64::from(rnd(u32::MAX)) | 1;
            let (w0, mu0, var0) = (w.clone(), mu.clone(), var.clone());
            let d = batch_chunk::<K, UPDATE>(
                &x, &mut w, &mut mu, &mut var, CHUNK, 0, todo, &dith, &p, &r, &lanes,
            );
            assert_eq!(d.done & !todo, 0);
            for i in 0..CHUNK {
                let at = |k: usize| k * CHUNK + i;
                let mut ws: [u16; K] = core::array::from_fn(|k| w0[at(k)]);
                let mut ms: [u8; K] = core::array::from_fn(|k| mu0[at(k)]);
                let mut vs: [u8; K] = core::array::from_fn(|k| var0[at(k)]);
                let got_w: [u16; K] = core::array::from_fn(|k| w[at(k)]);
                let got_m: [u8; K] = core::array::from_fn(|k| mu[at(k)]);
                let got_v: [u8; K] = core::array::from_fn(|k| var[at(k)]);
                if d.done >> i & 1 == 0 {
                    assert_eq!((got_w, got_m, got_v), (ws, ms, vs), "lane {i} given back");
                    continue;
                }
                let class =
                    slow_pixel::<K>(x[i], &mut ws, &mut ms, &mut vs, &p, &r, dith[i], UPDATE);
                assert_eq!(
                    (got_w, got_m, got_v),
                    (ws, ms, vs),
                    "round {round} lane {i}"
                );
                assert_eq!(d.fg >> i & 1 == 1, class == Class::Foreground);
                assert_eq!(d.shadow >> i & 1 == 1, class == Class::Shadow);
            }
            taken += d.done.count_ones();
            total += todo.count_ones();
        }
        // Most lanes are the cases taken (the rest: mode 0 matches, empty
        // pixels, sums ≥ 2¹⁶, reorders, matches in update chunks).
        assert!(taken * 4 > total, "{taken} of {total}");
    }

    #[test]
    fn batch_pass_matches_scalar_path() {
        agrees::<3, false>(500);
        agrees::<3, true>(500);
        agrees::<3, true>(20);
        agrees::<2, false>(500);
        agrees::<4, false>(100);
        agrees::<4, true>(500);
    }
}
