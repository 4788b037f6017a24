//! Uniform local binary patterns (8 neighbours, radius 1) per cell.
//!
//! Bit `k` of a pixel's code is set when neighbour `k` is at least
//! `centre + threshold` (saturating), neighbours numbered clockwise from
//! the top-left: TL, T, TR, R, BR, B, BL, L. Codes with at most two 0/1
//! transitions around the circle ("uniform", 58 of them) get their own bin,
//! in ascending code order; the other 198 share bin 58.
//!
//! Every pixel of a cell votes once, so the L1 norm of a cell histogram is
//! the constant `cell²`: Wang et al.'s L1-sqrt normalisation reduces to a
//! table, `255 · sqrt(count / cell²)` rounded, with no division at run time.
//!
//! Codes are built a row at a time with branch-free compares (the compiler
//! vectorises them); only the histogram increments are scalar. Counts fit
//! `u16`: a cell has at most 32² = 1024 pixels.

use super::layout::{Layout, LBP_BINS};

/// Bin of every 8-bit code (see the module doc).
pub fn uniform_table() -> [u8; 256] {
    let mut t = [0u8; 256];
    let mut next = 0u8;
    for (code, e) in t.iter_mut().enumerate() {
        let c = code as u8;
        let transitions = (c ^ c.rotate_left(1)).count_ones();
        *e = if transitions <= 2 {
            next += 1;
            next - 1
        } else {
            (LBP_BINS - 1) as u8
        };
    }
    t
}

/// Counter slots per cell and bank: the 59 bins padded to 64, so a bin
/// masked with 63 indexes a fixed-size array without a bounds check.
const SLOTS: usize = 64;

/// LBP scratch and tables.
#[derive(Clone, Debug)]
pub struct Lbp {
    table: [u8; 256],
    /// `255 · sqrt(count / cell²)` for every count a cell can hold (at most
    /// 32² = 1024; larger entries are 255).
    sqrt_q: Box<[u8; 1025]>,
    counts: Vec<u16>,
    /// Per cell, two banks of [`SLOTS`] counters (even and odd columns).
    banks: Vec<u16>,
    codes: Vec<u8>,
    ncx: usize,
    cell: usize,
    w: usize,
    h: usize,
    threshold: u8,
}

impl Lbp {
    /// Scratch for `layout`.
    pub fn new(layout: &Layout) -> Self {
        let (ncx, ncy) = layout.lbp_grid();
        let cell = usize::from(layout.lbp_cell);
        let n = cell * cell;
        let mut sqrt_q = Box::new([255u8; 1025]);
        for (c, q) in sqrt_q.iter_mut().enumerate().take(n + 1) {
            *q = (255.0 * (c as f64 / n as f64).sqrt()).round() as u8;
        }
        Lbp {
            table: uniform_table(),
            sqrt_q,
            counts: vec![0; ncx * ncy * LBP_BINS],
            banks: vec![0; ncx * ncy * 2 * SLOTS],
            codes: vec![0; usize::from(layout.win_w)],
            ncx,
            cell,
            w: usize::from(layout.win_w),
            h: usize::from(layout.win_h),
            threshold: layout.lbp_threshold,
        }
    }

    /// Raw counts of the last [`Lbp::histograms`], `cells · 59`, row-major.
    pub fn counts(&self) -> &[u16] {
        &self.counts
    }

    /// Counts the codes of a bordered window (`stride = w + 2`) per cell.
    pub fn histograms(&mut self, win: &[u8], stride: usize) {
        // `banks` is all zero here: it starts so and the fold below clears
        // what it reads.
        let (w, t, cell) = (self.w, self.threshold, self.cell);
        let row_slots = self.ncx * 2 * SLOTS;
        for y in 0..self.h {
            let Some(rows) = win.get(y * stride..y * stride + 2 * stride + w + 2) else {
                break;
            };
            let (up, mid, down) = (rows, &rows[stride..], &rows[2 * stride..]);
            // Nine slices of exactly `w` pixels: no bounds checks in the
            // loop, which the compiler vectorises (byte compares).
            let (tl, tp, tr) = (&up[..w], &up[1..w + 1], &up[2..w + 2]);
            let (l, c, r) = (&mid[..w], &mid[1..w + 1], &mid[2..w + 2]);
            let (bl, bt, br) = (&down[..w], &down[1..w + 1], &down[2..w + 2]);
            let codes = &mut self.codes[..w];
            for x in 0..w {
                let m = c[x].saturating_add(t);
                codes[x] = u8::from(tl[x] >= m)
                    | u8::from(tp[x] >= m) << 1
                    | u8::from(tr[x] >= m) << 2
                    | u8::from(r[x] >= m) << 3
                    | u8::from(br[x] >= m) << 4
                    | u8::from(bt[x] >= m) << 5
                    | u8::from(bl[x] >= m) << 6
                    | u8::from(l[x] >= m) << 7;
            }
            // Even and odd columns count into two banks (summed below) so
            // runs of equal codes do not serialise on one counter.
            let banks = &mut self.banks[(y / cell) * row_slots..(y / cell + 1) * row_slots];
            for (bank, cc) in banks
                .chunks_exact_mut(2 * SLOTS)
                .zip(codes.chunks_exact(cell))
            {
                let Ok(bank) = <&mut [u16; 2 * SLOTS]>::try_from(bank) else {
                    continue;
                };
                let mut pairs = cc.chunks_exact(2);
                for p in &mut pairs {
                    bank[usize::from(self.table[usize::from(p[0])]) & (SLOTS - 1)] += 1;
                    bank[SLOTS + (usize::from(self.table[usize::from(p[1])]) & (SLOTS - 1))] += 1;
                }
                for &code in pairs.remainder() {
                    bank[usize::from(self.table[usize::from(code)]) & (SLOTS - 1)] += 1;
                }
            }
        }
        for (c, b) in self
            .counts
            .chunks_exact_mut(LBP_BINS)
            .zip(self.banks.chunks_exact_mut(2 * SLOTS))
        {
            for (k, o) in c.iter_mut().enumerate() {
                *o = b[k] + b[SLOTS + k];
            }
            b.fill(0);
        }
    }

    /// Writes the selected cells' L1-sqrt-normalised histograms to `out`
    /// (`selected · 59` bytes); returns the bytes written.
    pub fn features(&self, selection: &[bool], out: &mut [u8]) -> usize {
        let mut k = 0;
        for (cell, &sel) in self.counts.chunks_exact(LBP_BINS).zip(selection) {
            if !sel {
                continue;
            }
            let Some(dst) = out.get_mut(k..k + LBP_BINS) else {
                return k;
            };
            for (o, &c) in dst.iter_mut().zip(cell) {
                *o = self.sqrt_q[usize::from(c).min(1024)];
            }
            k += LBP_BINS;
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fifty_eight_uniform_codes() {
        let t = uniform_table();
        let uniform = t.iter().filter(|&&b| b < 58).count();
        assert_eq!(uniform, 58);
        assert_eq!(t[0], 0);
        assert_eq!(t[255], 57);
        assert_eq!(t[0b0101_0101], 58);
    }

    #[test]
    fn codes_match_a_naive_reference() {
        let l = Layout::default_layout();
        let stride = usize::from(l.win_w) + 2;
        let rows = usize::from(l.win_h) + 2;
        let mut s = 12345u32;
        let win: Vec<u8> = (0..stride * rows)
            .map(|_| {
                s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
                (s >> 24) as u8
            })
            .collect();
        let mut lbp = Lbp::new(&l);
        lbp.histograms(&win, stride);
        let table = uniform_table();
        let (ncx, _) = l.lbp_grid();
        let mut naive = vec![0u16; lbp.counts().len()];
        let off: [(isize, isize); 8] = [
            (-1, -1),
            (0, -1),
            (1, -1),
            (1, 0),
            (1, 1),
            (0, 1),
            (-1, 1),
            (-1, 0),
        ];
        for y in 0..usize::from(l.win_h) {
            for x in 0..usize::from(l.win_w) {
                let at = |dx: isize, dy: isize| {
                    win[((y as isize + 1 + dy) as usize) * stride + (x as isize + 1 + dx) as usize]
                };
                let c = u16::from(at(0, 0)) + u16::from(l.lbp_threshold);
                let mut code = 0u8;
                for (k, (dx, dy)) in off.iter().enumerate() {
                    if u16::from(at(*dx, *dy)) >= c.min(255) {
                        code |= 1 << k;
                    }
                }
                let cell = (y / 8) * ncx + x / 8;
                naive[cell * LBP_BINS + usize::from(table[usize::from(code)])] += 1;
            }
        }
        assert_eq!(lbp.counts(), &naive[..]);
        let mut out = vec![0; l.selected_lbp_cells() * LBP_BINS];
        assert_eq!(lbp.features(&l.lbp_cells, &mut out), out.len());
        // A cell where one bin takes all 64 votes would give 255; sums of
        // squares of the normalised values are 1 per cell (L1-sqrt).
        for cell in out.chunks_exact(LBP_BINS) {
            let ss: f64 = cell.iter().map(|&v| (f64::from(v) / 255.0).powi(2)).sum();
            assert!((ss - 1.0).abs() < 0.05, "{ss}");
        }
    }
}
