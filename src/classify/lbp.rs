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
//! vectorises them); only the histogram increments are scalar.

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

/// LBP scratch and tables.
#[derive(Clone, Debug)]
pub struct Lbp {
    table: [u8; 256],
    sqrt_q: Vec<u8>,
    counts: Vec<u16>,
    bank: Vec<u16>,
    col_base: Vec<u16>,
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
        let sqrt_q = (0..=n)
            .map(|c| (255.0 * (c as f64 / n as f64).sqrt()).round() as u8)
            .collect();
        Lbp {
            table: uniform_table(),
            sqrt_q,
            counts: vec![0; ncx * ncy * LBP_BINS],
            bank: vec![0; ncx * ncy * LBP_BINS],
            col_base: (0..usize::from(layout.win_w))
                .map(|x| ((x / cell) * LBP_BINS) as u16)
                .collect(),
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
        self.counts.fill(0);
        self.bank.fill(0);
        let (w, t) = (self.w, self.threshold);
        for y in 0..self.h {
            let up = &win[y * stride..y * stride + w + 2];
            let mid = &win[(y + 1) * stride..(y + 1) * stride + w + 2];
            let down = &win[(y + 2) * stride..(y + 2) * stride + w + 2];
            let codes = &mut self.codes[..w];
            let centre = &mid[1..w + 1];
            let neighbours: [&[u8]; 8] = [
                &up[0..w],
                &up[1..w + 1],
                &up[2..w + 2],
                &mid[2..w + 2],
                &down[2..w + 2],
                &down[1..w + 1],
                &down[0..w],
                &mid[0..w],
            ];
            codes.fill(0);
            for (k, n) in neighbours.iter().enumerate() {
                for ((c, &p), &m) in codes.iter_mut().zip(n.iter()).zip(centre) {
                    *c |= u8::from(p >= m.saturating_add(t)) << k;
                }
            }
            // Even and odd columns count into two banks (summed below) so
            // runs of equal codes do not serialise on one counter.
            let row = (y / self.cell) * self.ncx * LBP_BINS;
            for (c, base) in codes.chunks_exact(2).zip(self.col_base.chunks_exact(2)) {
                self.counts
                    [row + usize::from(base[0]) + usize::from(self.table[usize::from(c[0])])] += 1;
                self.bank
                    [row + usize::from(base[1]) + usize::from(self.table[usize::from(c[1])])] += 1;
            }
        }
        for (c, b) in self.counts.iter_mut().zip(&self.bank) {
            *c += b;
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
                *o = self.sqrt_q.get(usize::from(c)).copied().unwrap_or(255);
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
