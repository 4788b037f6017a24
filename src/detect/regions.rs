//! Connected foreground regions (8-connectivity) from a packed mask, by
//! union-find over horizontal runs.
//!
//! 1. Runs are read row by row straight from the mask words (trailing-zero
//!    scans, no per-pixel loop).
//! 2. Each run is joined with the runs of the row above that touch it
//!    (column ranges overlapping or diagonal neighbours), a two-pointer merge
//!    of two sorted lists. Roots are always the lower run index, so a root
//!    is the region's first run in raster order, on its top row.
//! 3. Labels are flattened in one forward pass, per-region sums are
//!    accumulated, runs are grouped by region with a counting sort (keeping
//!    raster order), and regions of at least `min_area` pixels are pushed
//!    with their run-length masks.
//!
//! Head (paper eq. 5): the mean column of the top row's pixels, on the top
//! row. Foot: the mean position of the bottom-most 10 pixels, taken row by
//! row from the bottom; a row with more pixels than still needed contributes
//! that many pixels at its mean column (the central ones).

use super::morphology::BitMask;
use super::{BBox, Region, RegionSet, Run};

/// Pixels averaged for the foot point (paper eq. 5).
pub const FOOT_PIXELS: u32 = 10;

/// Per-root sums while labelling.
#[derive(Clone, Copy, Debug, Default)]
struct Acc {
    area: u32,
    x0: u16,
    x1: u16,
    y1: u16,
    /// Pixels on the top row and twice the sum of their columns.
    top_n: u32,
    top_sx2: u64,
    /// Compact region id, or `u32::MAX` while unassigned.
    id: u32,
}

/// Scratch for labelling, sized once for a run budget.
#[derive(Debug)]
pub struct Labeller {
    cap: usize,
    runs: Vec<Run>,
    parent: Vec<u32>,
    acc: Vec<Acc>,
    /// Roots in id order.
    roots: Vec<u32>,
    start: Vec<u32>,
    sorted: Vec<Run>,
}

impl Labeller {
    /// Room for `runs` foreground runs per frame (more are dropped and counted).
    pub fn new(runs: usize) -> Self {
        Labeller {
            cap: runs,
            runs: Vec::with_capacity(runs),
            parent: Vec::with_capacity(runs),
            acc: Vec::with_capacity(runs),
            roots: Vec::with_capacity(runs),
            start: Vec::with_capacity(runs + 1),
            sorted: Vec::with_capacity(runs),
        }
    }

    fn find(&mut self, mut i: u32) -> u32 {
        while self.parent[i as usize] != i {
            let p = self.parent[i as usize];
            self.parent[i as usize] = self.parent[p as usize];
            i = p;
        }
        i
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi as usize] = lo;
        }
    }

    /// Extracts the runs of `mask`; returns how many did not fit.
    fn extract(&mut self, mask: &BitMask) -> u32 {
        self.runs.clear();
        let (w, wpr) = (mask.width(), mask.words_per_row());
        let mut dropped = 0u32;
        for y in 0..mask.height() {
            let row = mask.row(y);
            let mut x = 0usize;
            while let Some(s) = next_bit(row, x, wpr, false) {
                let e = next_bit(row, s, wpr, true).unwrap_or(w).min(w);
                if self.runs.len() < self.cap {
                    self.runs.push(Run {
                        y: y as u16,
                        x0: s as u16,
                        x1: (e - 1) as u16,
                    });
                } else {
                    dropped += 1;
                }
                x = e;
                if x >= w {
                    break;
                }
            }
        }
        dropped
    }

    /// Labels `mask` into `out` (not cleared: the caller does), keeping
    /// regions of at least `min_area` pixels.
    pub fn label(&mut self, mask: &BitMask, min_area: u32, out: &mut RegionSet) {
        out.runs_dropped += self.extract(mask);
        let n = self.runs.len();
        self.parent.clear();
        self.parent.extend(0..n as u32);
        // Join each row's runs with the touching runs of the row above.
        let mut prev = 0..0; // runs of row y-1
        let mut i = 0;
        while i < n {
            let y = self.runs[i].y;
            let mut j = i;
            while j < n && self.runs[j].y == y {
                j += 1;
            }
            if prev.end > prev.start && self.runs[prev.start].y + 1 == y {
                let (mut a, mut b) = (prev.start, i);
                while a < prev.end && b < j {
                    let (ra, rb) = (self.runs[a], self.runs[b]);
                    if u32::from(ra.x1) + 1 < u32::from(rb.x0) {
                        a += 1;
                    } else if u32::from(rb.x1) + 1 < u32::from(ra.x0) {
                        b += 1;
                    } else {
                        self.union(a as u32, b as u32);
                        if ra.x1 < rb.x1 {
                            a += 1;
                        } else {
                            b += 1;
                        }
                    }
                }
            }
            prev = i..j;
            i = j;
        }
        // Flatten (parents have lower indices) and accumulate per root.
        self.acc.clear();
        self.acc.resize(n, Acc::default());
        self.roots.clear();
        for k in 0..n {
            let p = self.parent[k] as usize;
            let root = if p == k { k } else { self.parent[p] as usize };
            self.parent[k] = root as u32;
            let r = self.runs[k];
            let len = u32::from(r.x1 - r.x0) + 1;
            let sx2 = u64::from(len) * (u64::from(r.x0) + u64::from(r.x1));
            let a = &mut self.acc[root];
            if root == k {
                *a = Acc {
                    area: 0,
                    x0: r.x0,
                    x1: r.x1,
                    y1: r.y,
                    top_n: 0,
                    top_sx2: 0,
                    id: u32::MAX,
                };
            }
            a.area += len;
            a.x0 = a.x0.min(r.x0);
            a.x1 = a.x1.max(r.x1);
            a.y1 = a.y1.max(r.y);
            if r.y == self.runs[root].y {
                a.top_n += len;
                a.top_sx2 += sx2;
            }
        }
        // Ids for the regions kept, in raster order of their first run.
        for k in 0..n {
            if self.parent[k] as usize == k && self.acc[k].area >= min_area {
                self.acc[k].id = self.roots.len() as u32;
                self.roots.push(k as u32);
            }
        }
        // Counting sort of the kept runs by region id.
        let m = self.roots.len();
        self.start.clear();
        self.start.resize(m + 1, 0);
        for k in 0..n {
            let id = self.acc[self.parent[k] as usize].id;
            if id != u32::MAX {
                self.start[id as usize + 1] += 1;
            }
        }
        for r in 0..m {
            self.start[r + 1] += self.start[r];
        }
        let kept = self.start[m] as usize;
        self.sorted.clear();
        self.sorted.resize(kept, Run::default());
        for k in 0..n {
            let id = self.acc[self.parent[k] as usize].id;
            if id != u32::MAX {
                let slot = &mut self.start[id as usize];
                self.sorted[*slot as usize] = self.runs[k];
                *slot += 1;
            }
        }
        // `start[r]` is now the end of region r; its start is `start[r-1]`.
        let (w, h) = (mask.width(), mask.height());
        for r in 0..m {
            let begin = if r == 0 {
                0
            } else {
                self.start[r - 1] as usize
            };
            let end = self.start[r] as usize;
            let runs = &self.sorted[begin..end];
            let root = self.roots[r] as usize;
            let a = self.acc[root];
            let y0 = self.runs[root].y;
            let bbox = BBox {
                x0: a.x0,
                y0,
                x1: a.x1,
                y1: a.y1,
            };
            let head = [
                (a.top_sx2 as f64 / (2.0 * f64::from(a.top_n))) as f32,
                f32::from(y0),
            ];
            let region = Region {
                area: a.area,
                bbox,
                head,
                foot: foot(runs),
                touches_border: a.x0 == 0
                    || y0 == 0
                    || usize::from(a.x1) + 1 >= w
                    || usize::from(a.y1) + 1 >= h,
                runs: 0..0,
            };
            // A full set counts the overflow itself.
            let _ = out.push(region, runs);
        }
    }
}

/// Mean position of the bottom-most [`FOOT_PIXELS`] pixels of a region's
/// runs (raster order).
fn foot(runs: &[Run]) -> [f32; 2] {
    let mut need = FOOT_PIXELS;
    let (mut sx2, mut sy, mut got) = (0f64, 0f64, 0u32);
    let mut i = runs.len();
    while i > 0 && need > 0 {
        let y = runs[i - 1].y;
        let mut j = i;
        let (mut n, mut rx2) = (0u32, 0u64);
        while j > 0 && runs[j - 1].y == y {
            let r = runs[j - 1];
            let len = u32::from(r.x1 - r.x0) + 1;
            n += len;
            rx2 += u64::from(len) * (u64::from(r.x0) + u64::from(r.x1));
            j -= 1;
        }
        let take = n.min(need);
        // `take` pixels at the row's mean column.
        sx2 += rx2 as f64 * f64::from(take) / f64::from(n);
        sy += f64::from(y) * f64::from(take);
        got += take;
        need -= take;
        i = j;
    }
    if got == 0 {
        return [0.0, 0.0];
    }
    [
        (sx2 / (2.0 * f64::from(got))) as f32,
        (sy / f64::from(got)) as f32,
    ]
}

/// First column `≥ from` whose bit is set (`clear = false`) or clear
/// (`clear = true`); `None` when there is none in the row's words.
fn next_bit(row: &[u64], from: usize, wpr: usize, clear: bool) -> Option<usize> {
    let mut i = from / 64;
    if i >= wpr {
        return None;
    }
    let flip = if clear { u64::MAX } else { 0 };
    let mut word = (row[i] ^ flip) & (u64::MAX << (from % 64));
    loop {
        if word != 0 {
            return Some(i * 64 + word.trailing_zeros() as usize);
        }
        i += 1;
        if i >= wpr {
            return None;
        }
        word = row[i] ^ flip;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask_from(rows: &[&str]) -> BitMask {
        let mut m = BitMask::new(rows[0].len(), rows.len());
        for (y, r) in rows.iter().enumerate() {
            for (x, c) in r.bytes().enumerate() {
                m.set(x, y, c == b'#');
            }
        }
        m
    }

    /// Flood-fill reference: region areas and boxes, sorted.
    fn reference(m: &BitMask) -> Vec<(u32, BBox)> {
        let (w, h) = (m.width(), m.height());
        let mut seen = vec![false; w * h];
        let mut out = Vec::new();
        for y0 in 0..h {
            for x0 in 0..w {
                if !m.get(x0, y0) || seen[y0 * w + x0] {
                    continue;
                }
                let mut stack = vec![(x0, y0)];
                seen[y0 * w + x0] = true;
                let mut area = 0;
                let mut b = BBox {
                    x0: x0 as u16,
                    y0: y0 as u16,
                    x1: x0 as u16,
                    y1: y0 as u16,
                };
                while let Some((x, y)) = stack.pop() {
                    area += 1;
                    b.x0 = b.x0.min(x as u16);
                    b.x1 = b.x1.max(x as u16);
                    b.y0 = b.y0.min(y as u16);
                    b.y1 = b.y1.max(y as u16);
                    for dy in -1i64..=1 {
                        for dx in -1i64..=1 {
                            let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                            if xx >= 0 && yy >= 0 && (xx as usize) < w && (yy as usize) < h {
                                let (xx, yy) = (xx as usize, yy as usize);
                                if m.get(xx, yy) && !seen[yy * w + xx] {
                                    seen[yy * w + xx] = true;
                                    stack.push((xx, yy));
                                }
                            }
                        }
                    }
                }
                out.push((area, b));
            }
        }
        out.sort_by_key(|r| (r.1.y0, r.1.x0, r.0));
        out
    }

    #[test]
    fn labels_match_flood_fill_on_random_masks() {
        let mut s: u32 = 99;
        for &(w, h) in &[(70, 40), (130, 20), (64, 64), (200, 9)] {
            for density in [4u32, 7, 9] {
                let mut m = BitMask::new(w, h);
                for y in 0..h {
                    for x in 0..w {
                        s ^= s << 13;
                        s ^= s >> 17;
                        s ^= s << 5;
                        m.set(x, y, s % 16 < density);
                    }
                }
                let mut l = Labeller::new(w * h);
                let mut out = RegionSet::with_capacity(w * h, w * h);
                l.label(&m, 1, &mut out);
                let mut got: Vec<(u32, BBox)> =
                    out.regions().iter().map(|r| (r.area, r.bbox)).collect();
                got.sort_by_key(|r| (r.1.y0, r.1.x0, r.0));
                assert_eq!(got, reference(&m), "{w}x{h} density {density}");
                // Runs cover exactly the region's pixels.
                for r in out.regions() {
                    let px: u32 = out
                        .runs_of(r)
                        .iter()
                        .map(|q| u32::from(q.x1 - q.x0) + 1)
                        .sum();
                    assert_eq!(px, r.area);
                    assert!(out.runs_of(r).windows(2).all(|q| q[0].y <= q[1].y));
                }
            }
        }
    }

    #[test]
    fn head_foot_area_filter_and_overflow() {
        let m = mask_from(&[
            "..........",
            "....##....",
            "...####...",
            "...####...",
            "..######..",
            "..#....#..",
            "..........",
            "#.........",
        ]);
        let mut l = Labeller::new(64);
        let mut out = RegionSet::with_capacity(4, 64);
        l.label(&m, 2, &mut out);
        assert_eq!(out.regions().len(), 1, "the single pixel is dropped");
        let r = &out.regions()[0];
        assert_eq!(r.area, 2 + 4 + 4 + 6 + 2);
        assert_eq!(
            r.bbox,
            BBox {
                x0: 2,
                y0: 1,
                x1: 7,
                y1: 5
            }
        );
        assert_eq!(r.head, [4.5, 1.0]);
        // Bottom 10: row 5 (2 px at mean 4.5), row 4 (6 px, mean 4.5), 2 of row 3.
        assert!((r.foot[0] - 4.5).abs() < 1e-6);
        let fy = (2.0 * 5.0 + 6.0 * 4.0 + 2.0 * 3.0) / 10.0;
        assert!((r.foot[1] - fy).abs() < 1e-6, "{:?}", r.foot);
        assert!(!r.touches_border);

        let mut small = RegionSet::with_capacity(0, 64);
        l.label(&m, 1, &mut small);
        assert_eq!(small.overflow, 2);
        let mut few_runs = Labeller::new(3);
        let mut out = RegionSet::with_capacity(4, 64);
        few_runs.label(&m, 1, &mut out);
        assert_eq!(out.runs_dropped, 4);
    }
}
