//! Histograms of oriented gradients on the bordered window, integer only.
//!
//! * Gradient: centred differences `[-1, 0, 1]` in x and y, so `dx`, `dy`
//!   lie in −255..=255.
//! * Magnitude: alpha-max-plus-beta-min, `max + 3/8·min` of `|dx|`, `|dy|`
//!   (within −5.3 %..+6.8 % of the Euclidean norm; HOG is normalised per
//!   block, so a near-constant relative error washes out). At most 350.
//! * Orientation: unsigned (0°..180°), found by lookup, no `atan2`: the
//!   gradient is folded into the upper half plane and both components are
//!   scaled by a power of two, rounding, until they fit in −32..=32 and
//!   0..=32 (the larger one keeps at least 16 levels, so the angle error
//!   stays under 2.6°, a eighth of a bin), then a 33×65 table gives the
//!   two nearest bins and the Q8 weight of the upper one. The vote is split
//!   linearly between the two bins.
//! * Cell histogram entries are Q8 magnitude sums: at most
//!   `cell² · 350 · 256` (< 2^27 for 32-px cells), in `u32`.
//! * Block normalisation, "L2-clip": a 2×2-cell block is divided by
//!   `sqrt(Σv² + ε²)` with `ε` = one grey level of mean magnitude over the
//!   block (`block_px · 256`), clipped at 0.2 and scaled so 0.2 ↦ 255. It is
//!   done with one integer square root and one division per block
//!   (Σv² < 2^60 in `u64`); each value then costs a multiply and a shift.
//!   Dalal & Triggs' L2-Hys renormalises after clipping; we skip that
//!   second pass (measured in `bench/RESULTS.md`).

use super::layout::{Layout, BLOCK_DIM, HOG_BINS};
use std::sync::OnceLock;

/// Scale mapping a normalised value of 0.2 (the clip) to 255.
const CLIP_SCALE: u64 = 1275;

/// Columns of the orientation table (reduced `dx` in −32..=32).
const TABLE_COLS: usize = 65;
/// Entries of the orientation table (reduced `dy` in 0..=32).
const TABLE_LEN: usize = 33 * TABLE_COLS;

/// Table entry: `lo << 12 | hi << 8 | frac_q8` for every reduced gradient,
/// at `dy · 65 + dx + 32`.
fn orientation_table() -> &'static [u16; TABLE_LEN] {
    static TABLE: OnceLock<[u16; TABLE_LEN]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0u16; TABLE_LEN];
        for dy in 0..=32i32 {
            for dx in -32..=32i32 {
                let theta = f64::from(dy).atan2(f64::from(dx)).to_degrees();
                // Bin k is centred on 20k + 10 degrees.
                let p = theta / 20.0 - 0.5;
                let mut lo = p.floor();
                let mut frac = ((p - lo) * 256.0).round() as i32;
                if frac == 256 {
                    lo += 1.0;
                    frac = 0;
                }
                let lo = (lo as i32).rem_euclid(HOG_BINS as i32);
                let hi = (lo + 1) % HOG_BINS as i32;
                t[dy as usize * TABLE_COLS + (dx + 32) as usize] =
                    ((lo << 12) | (hi << 8) | frac) as u16;
            }
        }
        t
    })
}

/// The orientation of a gradient as `(lower bin, upper bin, Q8 weight of
/// the upper bin)`, exactly as the feature code bins it.
pub fn orientation_bins(dx: i32, dy: i32) -> (usize, usize, u32) {
    let e = orientation_table()[table_index(dx, dy)];
    (
        usize::from(e >> 12),
        usize::from((e >> 8) & 15),
        u32::from(e & 255),
    )
}

/// Table index of a gradient with components in −255..=255.
#[inline(always)]
fn table_index(dx: i32, dy: i32) -> usize {
    // Fold into dy > 0 or (dy == 0, dx >= 0): unsigned orientation.
    let flip = dy < 0 || (dy == 0 && dx < 0);
    let (dx, dy) = if flip { (-dx, -dy) } else { (dx, dy) };
    let adx = dx.unsigned_abs();
    let ady = dy as u32;
    let bits = 32 - (adx | ady).leading_zeros();
    let s = bits.saturating_sub(5);
    // Round to nearest: (v + 2^(s-1)) >> s, at most (2^(s+5) - 1 + 2^(s-1)) >> s = 32.
    let half = (1u32 << s) >> 1;
    let rx = ((adx + half) >> s) as i32;
    let rx = if dx < 0 { -rx } else { rx };
    ((ady + half) >> s) as usize * TABLE_COLS + (rx + 32) as usize
}

/// Magnitude `max + 3/8·min` of a gradient (at most 350 for 8-bit pixels).
#[inline(always)]
pub fn magnitude(dx: i32, dy: i32) -> u32 {
    let (a, b) = (dx.unsigned_abs(), dy.unsigned_abs());
    let (mx, mn) = if a > b { (a, b) } else { (b, a) };
    mx + ((3 * mn) >> 3)
}

/// HOG scratch and the per-block work.
#[derive(Clone, Debug)]
pub struct Hog {
    cells: Vec<u32>,
    cell_sq: Vec<u64>,
    ncx: usize,
    ncy: usize,
    cell: usize,
    w: usize,
    h: usize,
    eps_sq: u64,
    table: &'static [u16; TABLE_LEN],
}

impl Hog {
    /// Scratch for `layout`.
    pub fn new(layout: &Layout) -> Self {
        let (ncx, ncy) = layout.hog_cells();
        let cell = usize::from(layout.hog_cell);
        let eps = (4 * cell * cell * 256) as u64;
        Hog {
            cells: vec![0; ncx * ncy * HOG_BINS],
            cell_sq: vec![0; ncx * ncy],
            ncx,
            ncy,
            cell,
            w: usize::from(layout.win_w),
            h: usize::from(layout.win_h),
            eps_sq: eps * eps,
            table: orientation_table(),
        }
    }

    /// Cell histograms of the last [`Hog::compute`], `ncx·ncy·9`, row-major.
    pub fn cells(&self) -> &[u32] {
        &self.cells
    }

    /// Fills the cell histograms from a bordered window (`stride = w + 2`).
    pub fn cell_histograms(&mut self, win: &[u8], stride: usize) {
        self.cells.fill(0);
        let (w, cell, ncx) = (self.w, self.cell, self.ncx);
        for y in 0..self.h {
            let up = &win[y * stride..y * stride + w + 2];
            let mid = &win[(y + 1) * stride..(y + 1) * stride + w + 2];
            let down = &win[(y + 2) * stride..(y + 2) * stride + w + 2];
            let row = (y / cell) * ncx * HOG_BINS;
            let hist = &mut self.cells[row..row + ncx * HOG_BINS];
            for x in 0..w {
                let dx = i32::from(mid[x + 2]) - i32::from(mid[x]);
                let dy = i32::from(down[x + 1]) - i32::from(up[x + 1]);
                let mag = magnitude(dx, dy);
                let e = u32::from(self.table[table_index(dx, dy)]);
                let frac = e & 255;
                let base = (x / cell) * HOG_BINS;
                let lo = base + (e >> 12) as usize;
                let hi = base + ((e >> 8) & 15) as usize;
                hist[lo] += mag * (256 - frac);
                hist[hi] += mag * frac;
            }
        }
        for (sq, h) in self
            .cell_sq
            .iter_mut()
            .zip(self.cells.chunks_exact(HOG_BINS))
        {
            *sq = h.iter().map(|&v| u64::from(v) * u64::from(v)).sum();
        }
    }

    /// Writes the normalised selected blocks (see the module doc) to `out`
    /// (`selected · 36` bytes); returns the bytes written.
    pub fn blocks(&self, selection: &[bool], out: &mut [u8]) -> usize {
        let (bx_n, by_n) = (self.ncx - 1, self.ncy - 1);
        let mut k = 0;
        for by in 0..by_n {
            for bx in 0..bx_n {
                if !selection.get(by * bx_n + bx).copied().unwrap_or(false) {
                    continue;
                }
                let Some(dst) = out.get_mut(k..k + BLOCK_DIM) else {
                    return k;
                };
                let c = [
                    by * self.ncx + bx,
                    by * self.ncx + bx + 1,
                    (by + 1) * self.ncx + bx,
                    (by + 1) * self.ncx + bx + 1,
                ];
                let sumsq: u64 = c.iter().map(|&i| self.cell_sq[i]).sum();
                let norm = (sumsq + self.eps_sq).isqrt().max(1);
                // Every v ≤ norm, so v · recip ≤ CLIP_SCALE · 2^16 < 2^27.
                let recip = ((CLIP_SCALE << 16) / norm) as u32;
                for (d, &ci) in dst.chunks_exact_mut(HOG_BINS).zip(c.iter()) {
                    let src = &self.cells[ci * HOG_BINS..(ci + 1) * HOG_BINS];
                    for (o, &v) in d.iter_mut().zip(src) {
                        *o = ((v * recip) >> 16).min(255) as u8;
                    }
                }
                k += BLOCK_DIM;
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_orientation_matches_atan2_within_the_reduction_error() {
        for dy in -255..=255 {
            for dx in -255..=255 {
                if dx == 0 && dy == 0 {
                    continue;
                }
                let (lo, hi, frac) = orientation_bins(dx, dy);
                let mut theta = f64::from(dy).atan2(f64::from(dx)).to_degrees();
                if theta < 0.0 {
                    theta += 180.0;
                }
                if theta >= 180.0 {
                    theta -= 180.0;
                }
                // Reconstruct the angle from the bins and compare on the circle.
                let got = (lo as f64 + 0.5 + f64::from(frac) / 256.0) * 20.0;
                let mut d = (got - theta).abs() % 180.0;
                if d > 90.0 {
                    d = 180.0 - d;
                }
                assert!(d < 2.6, "({dx},{dy}): {theta} vs {got}");
                assert_eq!(hi, (lo + 1) % HOG_BINS);
            }
        }
    }

    #[test]
    fn magnitude_is_close_to_euclidean() {
        for dy in -255..=255i32 {
            for dx in -255..=255i32 {
                let e = f64::from(dx * dx + dy * dy).sqrt();
                let m = f64::from(magnitude(dx, dy));
                assert!(m <= e * 1.07 + 1.0 && m >= e * 0.94 - 1.0, "({dx},{dy})");
            }
        }
    }

    /// Float reference: the same definition with atan2, exact norms.
    fn reference(win: &[u8], stride: usize, l: &Layout) -> Vec<f64> {
        let (ncx, ncy) = l.hog_cells();
        let c = usize::from(l.hog_cell);
        let mut cells = vec![0f64; ncx * ncy * HOG_BINS];
        for y in 0..usize::from(l.win_h) {
            for x in 0..usize::from(l.win_w) {
                let p = |xx: usize, yy: usize| f64::from(win[yy * stride + xx]);
                let dx = p(x + 2, y + 1) - p(x, y + 1);
                let dy = p(x + 1, y + 2) - p(x + 1, y);
                let mag = (dx * dx + dy * dy).sqrt();
                let mut t = dy.atan2(dx).to_degrees();
                if t < 0.0 {
                    t += 180.0;
                }
                let p = t / 20.0 - 0.5;
                let lo = p.floor();
                let f = p - lo;
                let lo = (lo as i64).rem_euclid(9) as usize;
                let base = ((y / c) * ncx + x / c) * HOG_BINS;
                cells[base + lo] += mag * (1.0 - f);
                cells[base + (lo + 1) % 9] += mag * f;
            }
        }
        let mut out = Vec::new();
        let eps = (4 * c * c) as f64;
        for by in 0..ncy - 1 {
            for bx in 0..ncx - 1 {
                let ids = [
                    by * ncx + bx,
                    by * ncx + bx + 1,
                    (by + 1) * ncx + bx,
                    (by + 1) * ncx + bx + 1,
                ];
                let ss: f64 = ids
                    .iter()
                    .flat_map(|&i| &cells[i * 9..i * 9 + 9])
                    .map(|v| v * v)
                    .sum();
                let n = (ss + eps * eps).sqrt();
                for &i in &ids {
                    for v in &cells[i * 9..i * 9 + 9] {
                        out.push((v / n).min(0.2) / 0.2);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn fixed_point_hog_tracks_the_float_reference() {
        let l = Layout::default_layout();
        let stride = usize::from(l.win_w) + 2;
        let n = stride * (usize::from(l.win_h) + 2);
        // A smooth body-like blob plus texture: deterministic.
        let win: Vec<u8> = (0..n)
            .map(|i| {
                let (x, y) = ((i % stride) as f64, (i / stride) as f64);
                let blob = if ((x - 17.0) / 7.0).powi(2) + ((y - 33.0) / 24.0).powi(2) < 1.0 {
                    60.0
                } else {
                    170.0
                };
                (blob + 20.0 * (x * 0.7 + y * 1.3).sin()) as u8
            })
            .collect();
        let mut hog = Hog::new(&l);
        hog.cell_histograms(&win, stride);
        let mut out = vec![0u8; l.hog_dim()];
        assert_eq!(hog.blocks(&l.hog_blocks, &mut out), l.hog_dim());
        let r = reference(&win, stride, &l);
        let mut worst = 0.0f64;
        let mut sum = 0.0;
        for (a, b) in out.iter().zip(&r) {
            let d = (f64::from(*a) / 255.0 - b).abs();
            worst = worst.max(d);
            sum += d;
        }
        let mean = sum / r.len() as f64;
        eprintln!("HOG fixed point vs float: mean |diff| {mean:.4}, worst {worst:.3}");
        // Magnitude approximation (≤ 7 %) and angle reduction bound the gap.
        assert!(mean < 0.02, "mean abs diff {mean}");
        assert!(worst < 0.35, "worst abs diff {worst}");
        assert!(out.contains(&255) && out.iter().any(|&v| v < 20));
    }
}
