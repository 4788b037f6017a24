//! A single-mode chroma background at 4:2:0 resolution, OR-ed into the
//! luma GMM's foreground mask.
//!
//! Why: clothing and paving that are close in luma (the simulated scenes,
//! grey-on-grey on PETS) leave the luma model with holes that split a
//! person into pieces, and the luma-only shadow test erases darker clothing
//! of the paving's hue. A pixel whose (Cb, Cr) differs from the background's
//! by more than a threshold is foreground whatever its luma says, so this
//! also acts as the chroma-similarity condition of the shadow test: a
//! "shadow" of another colour stays foreground.
//!
//! The model is a running average per chroma sample (mean Cb and Cr, each
//! Q8.8 in a `u16`: 4 bytes per chroma sample, 1 byte per luma pixel). All
//! arithmetic is integer, so the result is bit-exact across platforms.

use super::background::pack_flags;
use crate::frame::Frame;

/// Learning rates are Q12 fractions (4096 = 1).
const RATE_ONE: i32 = 4096;

/// Per-chroma-sample running mean of Cb and Cr.
#[derive(Debug)]
pub struct ChromaBackground {
    /// Chroma plane width (luma width rounded up, halved).
    cw: usize,
    /// Chroma plane height.
    ch: usize,
    /// Luma frame width (to clip the last chroma column of odd widths).
    width: usize,
    /// Mean Cb, Q8.8.
    cb: Vec<u16>,
    /// Mean Cr, Q8.8.
    cr: Vec<u16>,
    /// Foreground when `|ΔCb| + |ΔCr|` exceeds this, grey levels (0 = off).
    threshold: u32,
    /// A luma "shadow" whose `|ΔCb| + |ΔCr|` exceeds this is not one (≤ threshold).
    shadow_threshold: u32,
    /// Steady learning rate, Q12 (≥ 1).
    rate_min: i32,
    /// Frames learned (saturating), for the `1/(t+1)` start-up rate.
    t: u32,
    /// Foreground chroma samples in the last frame.
    foreground: u32,
}

impl ChromaBackground {
    /// A model for `width × height` luma frames. `history` sets the steady
    /// rate `1/history`, at every sample: a slower rate at foreground
    /// samples (as the GMM's `foreground_rate`) left chroma ghosts behind
    /// people who stood at start-up (sim:low false regions 0.5 -> 2.2 per
    /// frame); standing people are held by the luma GMM. `threshold` is the
    /// L1 (Cb, Cr) distance in grey levels (0 = off: [`Self::apply`] then
    /// does nothing and the model holds no samples); `shadow_threshold` the
    /// smaller one of the soft mask (0: the same as `threshold`).
    pub fn new(
        width: usize,
        height: usize,
        history: u32,
        threshold: u32,
        shadow_threshold: u32,
    ) -> Self {
        let (cw, ch) = (width.div_ceil(2), height.div_ceil(2));
        let n = if threshold == 0 { 0 } else { cw * ch };
        ChromaBackground {
            cw,
            ch,
            width,
            cb: vec![0; n],
            cr: vec![0; n],
            threshold,
            // 0: no soft mask (the luma-only shadow test).
            shadow_threshold: if shadow_threshold == 0 {
                threshold
            } else {
                shadow_threshold.min(threshold)
            },
            rate_min: (RATE_ONE / history.max(1) as i32).max(1),
            t: 0,
            foreground: 0,
        }
    }

    /// Whether the chroma term is on.
    pub fn enabled(&self) -> bool {
        self.threshold != 0
    }

    /// Foreground chroma samples of the last frame.
    pub fn foreground(&self) -> u32 {
        self.foreground
    }

    /// Restarts fast learning (`1/(t+1)` from `t`), e.g. after the luma
    /// model decided to relearn.
    pub fn relearn(&mut self, t: u32) {
        self.t = self.t.min(t);
    }

    /// Updates the model with `frame` and ORs the chroma foreground, each
    /// sample covering its 2×2 luma pixels, into `mask` (packed bits, bit
    /// `x % 64` of word `y * words_per_row + x / 64`, as
    /// [`super::morphology::BitMask`]).
    pub fn apply(
        &mut self,
        frame: &Frame,
        mask: &mut [u64],
        soft: &mut [u64],
        words_per_row: usize,
    ) {
        self.foreground = 0;
        if !self.enabled() {
            return;
        }
        let (cbp, crp) = (frame.cb(), frame.cr());
        if self.t == 0 {
            for cy in 0..self.ch {
                let (srow_b, srow_r) = (cbp.row(cy), crp.row(cy));
                let row = cy * self.cw..(cy + 1) * self.cw;
                for (m, &x) in self.cb[row.clone()].iter_mut().zip(srow_b) {
                    *m = u16::from(x) << 8;
                }
                for (m, &x) in self.cr[row].iter_mut().zip(srow_r) {
                    *m = u16::from(x) << 8;
                }
            }
            self.t = 1;
            return;
        }
        // α = 1/(t+1) at start-up (t ≥ 1 here, so ≤ ½), then 1/history; Q12.
        let rate = (RATE_ONE / (self.t as i32).saturating_add(1)).max(self.rate_min);
        // The same rate in Q0.16 for 16-bit lanes: ≤ 2048 · 16 = 2¹⁵.
        let r16 = (rate as u16) << 4;
        let thr = (self.threshold.min(255) as u16) << 8;
        let thr_soft = (self.shadow_threshold.min(255) as u16) << 8;
        // The rate as a lane array the optimiser cannot see through (a
        // known splat makes LLVM widen the products to 32-bit lanes).
        let rv = core::hint::black_box([r16; 32]);
        let height = mask.len() / words_per_row.max(1);
        for cy in 0..self.ch {
            let (srow_b, srow_r) = (cbp.row(cy), crp.row(cy));
            let mrow_b = &mut self.cb[cy * self.cw..(cy + 1) * self.cw];
            let mrow_r = &mut self.cr[cy * self.cw..(cy + 1) * self.cw];
            // 32 chroma samples make one 64-bit luma mask word. Flags go to
            // byte lanes first (vectorisable), then are packed.
            for (j, chunk) in (0..self.cw).step_by(32).enumerate() {
                let end = (chunk + 32).min(self.cw);
                let n = end - chunk;
                let mut fg = [0u8; 32];
                let mut sf = [0u8; 32];
                let (xb, xr) = (&srow_b[chunk..end], &srow_r[chunk..end]);
                let (mb, mr) = (&mut mrow_b[chunk..end], &mut mrow_r[chunk..end]);
                if n == 32 {
                    // Fixed length: the loop vectorises without a tail.
                    let t = (&mut fg, &mut sf);
                    samples::<32>(
                        (xb.try_into().expect("32"), xr.try_into().expect("32")),
                        (mb.try_into().expect("32"), mr.try_into().expect("32")),
                        t,
                        &rv,
                        (thr, thr_soft),
                    );
                } else {
                    for i in 0..n {
                        let (f, s) =
                            sample(xb[i], xr[i], &mut mb[i], &mut mr[i], r16, (thr, thr_soft));
                        fg[i] = f;
                        sf[i] = s;
                    }
                }
                let soft_bits = pack_flags(&sf) as u32;
                if soft_bits == 0 {
                    continue;
                }
                let bits = pack_flags(&fg) as u32;
                self.foreground += bits.count_ones();
                // Clip luma columns at or beyond the frame width (odd widths,
                // last word).
                let x0 = j * 64;
                let clip = if x0 + 64 > self.width {
                    (1u64 << (self.width - x0)) - 1
                } else {
                    u64::MAX
                };
                let (word, soft_word) = (spread2(bits) & clip, spread2(soft_bits) & clip);
                for y in [2 * cy, 2 * cy + 1] {
                    if y < height && j < words_per_row {
                        mask[y * words_per_row + j] |= word;
                        soft[y * words_per_row + j] |= soft_word;
                    }
                }
            }
        }
        self.t = self.t.saturating_add(1);
    }
}

/// [`sample`] on `N` samples: Cb, Cr values, their means, the two flag
/// arrays, the rate per lane and the two thresholds.
#[inline(always)]
fn samples<const N: usize>(
    x: (&[u8; N], &[u8; N]),
    m: (&mut [u16; N], &mut [u16; N]),
    flags: (&mut [u8; N], &mut [u8; N]),
    rate: &[u16; N],
    thr: (u16, u16),
) {
    // Lane `i` of seven arrays at once: an index reads clearer than a zip.
    #[allow(clippy::needless_range_loop)]
    for i in 0..N {
        let (f, s) = sample(x.0[i], x.1[i], &mut m.0[i], &mut m.1[i], rate[i], thr);
        flags.0[i] = f;
        flags.1[i] = s;
    }
}

/// One chroma sample `(xb, xr)` against its means (Q8.8), updated at rate
/// `r16` (Q0.16, `≤ 2¹⁵`); returns whether `|ΔCb| + |ΔCr|` exceeds each
/// threshold (Q8.8). Unsigned 16-bit lanes only, so that 8 samples
/// vectorise to a 128-bit register: each difference as its two saturated
/// halves, one of them 0.
#[inline(always)]
fn sample(xb: u8, xr: u8, mb: &mut u16, mr: &mut u16, r16: u16, thr: (u16, u16)) -> (u8, u8) {
    let (xb8, xr8) = (u16::from(xb) << 8, u16::from(xr) << 8);
    let (bp, bn) = (xb8.saturating_sub(*mb), mb.saturating_sub(xb8));
    let (rp, rn) = (xr8.saturating_sub(*mr), mr.saturating_sub(xr8));
    // |ΔCb| + |ΔCr| saturated at 2¹⁶ − 1, above both thresholds.
    let l1 = (bp | bn).saturating_add(rp | rn);
    // The means stay within [0, 255·256]: each step is at most |Δ|.
    *mb = *mb + rate_up(bp, r16) - rate_down(bn, r16);
    *mr = *mr + rate_up(rp, r16) - rate_down(rn, r16);
    (u8::from(l1 > thr.0), u8::from(l1 > thr.1))
}

/// `d · rate` (rate `r16` in Q0.16, `≤ 2¹⁵`) rounded to nearest, halves
/// up: `⌊(d·r + 2¹⁵) / 2¹⁶⌋` from the two 16-bit halves of the product
/// (`pmulhuw` / `pmullw`).
#[inline(always)]
fn rate_up(d: u16, r16: u16) -> u16 {
    let hi = ((u32::from(d) * u32::from(r16)) >> 16) as u16;
    hi + (d.wrapping_mul(r16) >> 15)
}

/// The magnitude of the step down for a difference of `−d`: rounded to
/// nearest with halves toward `+∞` (`⌈(d·r − 2¹⁵) / 2¹⁶⌉`), so that with
/// [`rate_up`] the update is `⌊(Δ·r + 2¹⁵) / 2¹⁶⌋` for the signed `Δ`.
#[inline(always)]
fn rate_down(d: u16, r16: u16) -> u16 {
    let hi = ((u32::from(d) * u32::from(r16)) >> 16) as u16;
    hi + u16::from(d.wrapping_mul(r16) > 32768)
}

/// Moves bit `i` of `b` to bits `2i` and `2i + 1`.
fn spread2(b: u32) -> u64 {
    let w = spread(b);
    w | w << 1
}

/// Moves bit `i` of `b` to bit `2i` (Morton spread).
fn spread(b: u32) -> u64 {
    let mut x = u64::from(b);
    x = (x | x << 16) & 0x0000_FFFF_0000_FFFF;
    x = (x | x << 8) & 0x00FF_00FF_00FF_00FF;
    x = (x | x << 4) & 0x0F0F_0F0F_0F0F_0F0F;
    x = (x | x << 2) & 0x3333_3333_3333_3333;
    (x | x << 1) & 0x5555_5555_5555_5555
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::morphology::BitMask;
    use crate::frame::Size;

    /// The 16-bit lane update and test equal the signed 32-bit formula
    /// `m + ⌊(Δ·rate + 2048) / 4096⌋`, `|ΔCb| + |ΔCr| > thr` (rate in Q12).
    #[test]
    fn lane_update_equals_signed_formula() {
        let mut s: u32 = 12345;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        for case in 0..400_000u32 {
            let rate = [1, 8, 9, 455, 1024, 2048][case as usize % 6] + (next() % 3) as i32 - 1;
            let rate = rate.clamp(1, 2048);
            let (xb, xr) = (next() as u8, next() as u8);
            // Means near the values (ties included) and anywhere.
            let near =
                |x: u8, r: u32| (i32::from(x) * 256 + (r % 1024) as i32 - 512).clamp(0, 65280);
            let (mut mb, mut mr) = if case % 2 == 0 {
                (near(xb, next()) as u16, near(xr, next()) as u16)
            } else {
                ((next() % 65281) as u16, (next() % 65281) as u16)
            };
            let (ob, or) = (mb, mr);
            let thr = ((next() % 256) as u16) << 8;
            let (f, _) = sample(xb, xr, &mut mb, &mut mr, (rate as u16) << 4, (thr, thr));
            let db = (i32::from(xb) << 8) - i32::from(ob);
            let dr = (i32::from(xr) << 8) - i32::from(or);
            assert_eq!(i32::from(mb), i32::from(ob) + ((db * rate + 2048) >> 12));
            assert_eq!(i32::from(mr), i32::from(or) + ((dr * rate + 2048) >> 12));
            assert_eq!(f == 1, db.abs() + dr.abs() > i32::from(thr));
        }
    }

    #[test]
    fn spread_doubles_bits() {
        assert_eq!(spread(0b1011), 0b1_00_01_01);
        assert_eq!(spread(u32::MAX), 0x5555_5555_5555_5555);
    }

    /// A patch of another hue but the same luma becomes foreground over its
    /// 2×2 luma pixels, clipped at an odd frame width.
    #[test]
    fn colour_patch_is_foreground() {
        let size = Size {
            width: 71,
            height: 9,
        };
        let mut frame = Frame::new(size);
        let mut model = ChromaBackground::new(size.width, size.height, 100, 10, 4);
        let mut mask = BitMask::new(size.width, size.height);
        let mut soft = BitMask::new(size.width, size.height);
        for _ in 0..20 {
            frame.y.fill(100);
            frame.u.fill(120);
            frame.v.fill(130);
            let wpr = mask.words_per_row();
            model.apply(&frame, mask.words_mut(), soft.words_mut(), wpr);
            assert_eq!(mask.count(), 0);
            assert_eq!(soft.count(), 0);
        }
        let cw = size.chroma().width;
        // Chroma samples 3 and the last one (35: luma 70 only) on row 1.
        frame.u[cw + 3] = 135;
        frame.v[cw + 35] = 112;
        let wpr = mask.words_per_row();
        model.apply(&frame, mask.words_mut(), soft.words_mut(), wpr);
        assert_eq!(model.foreground(), 2);
        assert_eq!(soft, mask, "beyond the threshold is beyond the soft one");
        assert_eq!(mask.count(), 4 + 2);
        assert!(mask.get(6, 2) && mask.get(7, 3) && mask.get(70, 2) && mask.get(70, 3));
        // A change within the threshold is not foreground, but beyond the
        // shadow threshold it is in the soft mask.
        let mut mask2 = BitMask::new(size.width, size.height);
        let mut soft2 = BitMask::new(size.width, size.height);
        frame.u.fill(125);
        frame.v.fill(126);
        let wpr = mask2.words_per_row();
        model.apply(&frame, mask2.words_mut(), soft2.words_mut(), wpr);
        assert_eq!(mask2.count(), 0);
        assert_eq!(soft2.count(), size.pixels() as u64);
    }
}
