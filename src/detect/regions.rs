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
//! 4. Optionally, a region whose column profile (pixels per column) has a
//!    deep valley between two person-tall peaks is cut there: people
//!    walking side by side touch at a bag, a hand or a shadow and would
//!    otherwise make one region (see [`Labeller::set_split`]).
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
    /// Valley depth for splitting, Q8 fraction of the lower peak (0 = off).
    split_q8: u32,
    /// Scratch for splitting one region.
    cut: CutScratch,
    /// The runs of one part of a split region.
    part: Vec<Run>,
}

/// Scratch for finding the cut columns of one region.
#[derive(Debug)]
struct CutScratch {
    /// Column profile of one region (`width + 1` entries).
    hist: Vec<i32>,
    /// Prefix maxima of the profile.
    pmax: Vec<u32>,
    /// Top-most row of each column of one region, relative to its top.
    ctop: Vec<u16>,
    /// Cut columns of one region.
    cuts: Vec<u16>,
}

impl Labeller {
    /// Room for `runs` foreground runs per frame (more are dropped and
    /// counted), for masks up to `width` columns.
    pub fn new(runs: usize, width: usize) -> Self {
        Labeller {
            split_q8: 0,
            cut: CutScratch {
                hist: vec![0; width + 1],
                pmax: vec![0; width + 1],
                ctop: vec![0; width + 1],
                cuts: Vec::with_capacity(width),
            },
            part: Vec::with_capacity(runs),
            cap: runs,
            runs: Vec::with_capacity(runs),
            parent: Vec::with_capacity(runs),
            acc: Vec::with_capacity(runs),
            roots: Vec::with_capacity(runs),
            start: Vec::with_capacity(runs + 1),
            sorted: Vec::with_capacity(runs),
        }
    }

    /// Splits regions at column-profile valleys no deeper than `valley`
    /// times the lower of the two peaks beside them (0 = never). Both peaks
    /// must be at least half the region's height (an outstretched arm is not
    /// a person), the cut column must be empty over the top eighth of the
    /// region (at a stride the torso covers the crotch columns from near the
    /// top), and each part must keep `min_area` pixels.
    pub fn set_split(&mut self, valley: f64) {
        self.split_q8 = crate::qformat::q8(valley).min(256);
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
            if self.split_q8 > 0 && self.cut.find_cuts(runs, bbox, min_area, self.split_q8) {
                self.push_parts(begin..end, w, h, min_area, out);
                continue;
            }
            let region = Region {
                area: a.area,
                bbox,
                head,
                foot: foot(runs),
                touches_border: touches(bbox, w, h),
                split: false,
                loose_ends: false,
                core: 0..0,
                runs: 0..0,
            };
            // A full set counts the overflow itself.
            let _ = out.push(region, runs);
        }
    }

    /// Pushes the parts of the region whose runs are `sorted[range]`, cut at
    /// `cuts` (the cut column itself goes to neither part).
    fn push_parts(
        &mut self,
        range: core::ops::Range<usize>,
        w: usize,
        h: usize,
        min_area: u32,
        out: &mut RegionSet,
    ) {
        let cuts = &self.cut.cuts;
        for p in 0..=cuts.len() {
            let lo = if p == 0 {
                0
            } else {
                u32::from(cuts[p - 1]) + 1
            };
            let hi = if p == cuts.len() {
                u32::MAX
            } else {
                u32::from(cuts[p]).wrapping_sub(1)
            };
            if p < cuts.len() && cuts[p] == 0 {
                continue;
            }
            self.part.clear();
            for r in &self.sorted[range.clone()] {
                let (a, b) = (u32::from(r.x0).max(lo), u32::from(r.x1).min(hi));
                if a <= b {
                    self.part.push(Run {
                        y: r.y,
                        x0: a as u16,
                        x1: b as u16,
                    });
                }
            }
            if let Some(mut region) = region_of(&self.part, w, h) {
                region.split = true;
                if region.area >= min_area {
                    let _ = out.push(region, &self.part);
                }
            }
        }
    }
}

impl CutScratch {
    /// Fills `cuts` with the columns where `runs` (one region, box `b`)
    /// should be cut; whether there is any.
    fn find_cuts(&mut self, runs: &[Run], b: BBox, min_area: u32, split_q8: u32) -> bool {
        let CutScratch {
            hist,
            pmax,
            ctop,
            cuts,
        } = self;
        cuts.clear();
        let (x0, wd, ht) = (usize::from(b.x0), b.width() as usize, b.height());
        // Two people side by side are at least about as wide as tall / 2.
        if 2 * wd < ht as usize || wd < 8 {
            return false;
        }
        let hist = &mut hist[..wd + 1];
        hist.fill(0);
        for r in runs {
            hist[usize::from(r.x0) - x0] += 1;
            hist[usize::from(r.x1) + 1 - x0] -= 1;
        }
        let mut acc = 0i32;
        for v in hist.iter_mut() {
            acc += *v;
            *v = acc;
        }
        // The top-most pixel of each column (runs are in raster order): at a
        // stride the torso covers the crotch columns from near the top, while
        // between two people the top of the region is empty.
        let ctop = &mut ctop[..wd];
        ctop.fill(u16::MAX);
        for r in runs {
            for t in &mut ctop[usize::from(r.x0) - x0..=usize::from(r.x1) - x0] {
                if *t == u16::MAX {
                    *t = r.y - b.y0;
                }
            }
        }
        let min_peak = (ht * SPLIT_MIN_PEAK_Q8) >> 8;
        let min_top = ((ht * SPLIT_EMPTY_TOP_Q8) >> 8).min(u32::from(u16::MAX)) as u16;
        let mut m = 0u32;
        for c in 0..wd {
            m = m.max(hist[c] as u32);
            pmax[c] = m;
        }
        // Right to left: suffix maximum on the fly; a candidate column is
        // a valley under both sides' peaks; each run of candidates yields
        // its lowest column.
        let (mut smax, mut best): (u32, Option<(u32, usize)>) = (0, None);
        let mut last_cut_area = 0u32;
        for c in (0..wd).rev() {
            let v = hist[c] as u32;
            smax = smax.max(v);
            let peak = pmax[c].min(smax);
            let cand = peak >= min_peak && (v << 8) <= split_q8 * peak && ctop[c] >= min_top;
            if cand {
                if best.is_none_or(|(bv, _)| v < bv) {
                    best = Some((v, c));
                }
            } else if let Some((_, bc)) = best.take() {
                // The part right of the cut must hold `min_area` pixels.
                let right: u32 = hist[bc + 1..wd].iter().map(|&h| h as u32).sum();
                if right - last_cut_area >= min_area {
                    cuts.push((x0 + bc) as u16);
                    last_cut_area = right;
                }
            }
        }
        // The leftmost part must hold `min_area` pixels too.
        if let Some(&c) = cuts.last() {
            let left: u32 = hist[..usize::from(c) - x0].iter().map(|&h| h as u32).sum();
            if left < min_area {
                cuts.pop();
            }
        }
        cuts.reverse();
        !cuts.is_empty()
    }
}

/// Smallest peak of a split region's column profile, Q8 fraction of its height.
const SPLIT_MIN_PEAK_Q8: u32 = 128;
/// A cut column is empty over at least this top part of the region, Q8.
const SPLIT_EMPTY_TOP_Q8: u32 = 32;

fn touches(b: BBox, w: usize, h: usize) -> bool {
    b.x0 == 0 || b.y0 == 0 || usize::from(b.x1) + 1 >= w || usize::from(b.y1) + 1 >= h
}

/// The region made of `runs` (raster order), `None` when empty.
fn region_of(runs: &[Run], w: usize, h: usize) -> Option<Region> {
    let first = runs.first()?;
    let mut bbox = BBox {
        x0: first.x0,
        y0: first.y,
        x1: first.x1,
        y1: first.y,
    };
    let (mut area, mut top_n, mut top_sx2) = (0u32, 0u32, 0u64);
    for r in runs {
        let len = u32::from(r.x1 - r.x0) + 1;
        area += len;
        bbox.x0 = bbox.x0.min(r.x0);
        bbox.x1 = bbox.x1.max(r.x1);
        bbox.y1 = bbox.y1.max(r.y);
        if r.y == first.y {
            top_n += len;
            top_sx2 += u64::from(len) * (u64::from(r.x0) + u64::from(r.x1));
        }
    }
    Some(Region {
        area,
        bbox,
        head: [
            (top_sx2 as f64 / (2.0 * f64::from(top_n))) as f32,
            f32::from(first.y),
        ],
        foot: foot(runs),
        touches_border: touches(bbox, w, h),
        split: false,
        loose_ends: false,
        core: 0..0,
        runs: 0..0,
    })
}

/// The mean position of a region's bottom-most pixels (paper eq. 5),
/// accumulated row by row from the bottom up until `need` pixels are in.
#[derive(Clone, Copy, Debug)]
pub(super) struct BottomPixels {
    need: u32,
    sx2: f64,
    sy: f64,
    got: u32,
}

impl BottomPixels {
    /// Room for `need` pixels.
    pub(super) fn new(need: u32) -> Self {
        BottomPixels {
            need,
            sx2: 0.0,
            sy: 0.0,
            got: 0,
        }
    }
    /// Adds row `y` with `n` pixels whose columns sum to `sx2 / 2` (as many
    /// as are still needed, at the row's mean column).
    pub(super) fn add_row(&mut self, y: f64, n: u32, sx2: f64) {
        let take = n.min(self.need);
        if take == 0 {
            return;
        }
        self.sx2 += sx2 * f64::from(take) / f64::from(n);
        self.sy += y * f64::from(take);
        self.got += take;
        self.need -= take;
    }
    /// Adds the rows of `runs` (raster order) from the bottom up.
    pub(super) fn add_runs(&mut self, runs: &[Run]) {
        let mut i = runs.len();
        while i > 0 && self.need > 0 {
            let y = runs[i - 1].y;
            let (mut n, mut rx2) = (0u32, 0u64);
            while i > 0 && runs[i - 1].y == y {
                let r = runs[i - 1];
                let len = u32::from(r.x1 - r.x0) + 1;
                n += len;
                rx2 += u64::from(len) * (u64::from(r.x0) + u64::from(r.x1));
                i -= 1;
            }
            self.add_row(f64::from(y), n, rx2 as f64);
        }
    }
    /// Whether every pixel asked for is in.
    pub(super) fn is_full(&self) -> bool {
        self.need == 0
    }
    /// The mean `[u, v]`; `None` before any pixel.
    pub(super) fn mean(&self) -> Option<[f32; 2]> {
        (self.got > 0).then(|| {
            [
                (self.sx2 / (2.0 * f64::from(self.got))) as f32,
                (self.sy / f64::from(self.got)) as f32,
            ]
        })
    }
}

/// Mean position of the bottom-most [`FOOT_PIXELS`] pixels of a region's
/// runs (raster order).
fn foot(runs: &[Run]) -> [f32; 2] {
    let mut b = BottomPixels::new(FOOT_PIXELS);
    b.add_runs(runs);
    b.mean().unwrap_or([0.0, 0.0])
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

    /// Each region's runs cover exactly its pixels, in row order.
    fn assert_runs_cover_regions(out: &RegionSet) {
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
                let mut l = Labeller::new(w * h, w);
                let mut out = RegionSet::with_capacity(w * h, w * h);
                l.label(&m, 1, &mut out);
                let mut got: Vec<(u32, BBox)> =
                    out.regions().iter().map(|r| (r.area, r.bbox)).collect();
                got.sort_by_key(|r| (r.1.y0, r.1.x0, r.0));
                assert_eq!(got, reference(&m), "{w}x{h} density {density}");
                assert_runs_cover_regions(&out);
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
        let mut l = Labeller::new(64, 10);
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
        let mut few_runs = Labeller::new(3, 10);
        let mut out = RegionSet::with_capacity(4, 64);
        few_runs.label(&m, 1, &mut out);
        assert_eq!(out.runs_dropped, 4);
    }

    /// A region's core is the part of its runs another mask holds, as
    /// runs (a run can break in two); without room reserved, or for a
    /// region with no core pixels, the axis runs are the region's own.
    #[test]
    fn cores_are_the_inner_parts_of_the_runs() {
        let m = mask_from(&["..######..", "..######..", "..##..##..", ".........."]);
        let inner = mask_from(&["...###....", "..#..#.#..", "..........", ".........."]);
        let mut l = Labeller::new(64, 10);
        let mut out = RegionSet::with_capacity(4, 64).with_core(64);
        l.label(&m, 1, &mut out);
        out.fill_core(&inner);
        let r = out.regions()[0].clone();
        let core: Vec<(u16, u16, u16)> = out
            .axis_runs_of(&r)
            .iter()
            .map(|r| (r.y, r.x0, r.x1))
            .collect();
        assert_eq!(core, [(0, 3, 5), (1, 2, 2), (1, 5, 5), (1, 7, 7)]);
        let own = out.runs_of(&r).len();
        out.fill_core(&BitMask::new(10, 4));
        let r = out.regions()[0].clone();
        assert_eq!(out.axis_runs_of(&r).len(), own, "no core: its own runs");
        let mut none = RegionSet::with_capacity(4, 64);
        l.label(&m, 1, &mut none);
        none.fill_core(&inner);
        let r = none.regions()[0].clone();
        assert_eq!(none.axis_runs_of(&r).len(), own, "no room: its own runs");
    }

    /// Two tall blobs joined at the bottom (people side by side touching
    /// at a bag) are cut into two regions with their own head and foot; a
    /// walker whose legs are apart, and a region too narrow, are not.
    #[test]
    fn side_by_side_people_are_split_and_a_stride_is_not() {
        let mut rows = Vec::new();
        for y in 0..20 {
            // Columns 2..=6 and 12..=16 are two bodies; rows 16..=18 join them.
            let mut r = String::new();
            for x in 0..20 {
                let body = (2..=6).contains(&x) || (12..=16).contains(&x);
                let bridge = (16..=18).contains(&y) && (2..=16).contains(&x);
                r.push(if (body && (1..=18).contains(&y)) || bridge {
                    '#'
                } else {
                    '.'
                });
            }
            rows.push(r);
        }
        let refs: Vec<&str> = rows.iter().map(|s| s.as_str()).collect();
        let m = mask_from(&refs);
        let mut l = Labeller::new(256, 20);
        let mut out = RegionSet::with_capacity(8, 256);
        l.label(&m, 5, &mut out);
        assert_eq!(out.regions().len(), 1, "without splitting: one region");
        assert!(!out.regions()[0].split);
        l.set_split(0.55);
        out.clear();
        l.label(&m, 5, &mut out);
        let r = out.regions();
        assert_eq!(r.len(), 2, "{r:?}");
        assert!(r[0].bbox.x1 < r[1].bbox.x0);
        assert!(r[0].split && r[1].split);
        assert_eq!((r[0].head, r[1].head), ([4.0, 1.0], [14.0, 1.0]));
        assert_runs_cover_regions(&out);
        // A walker: torso columns 4..=10 on rows 0..=9, legs apart below.
        let mut rows = Vec::new();
        for y in 0..20 {
            let mut r = String::new();
            for x in 0..16 {
                let on = if y < 10 {
                    (4..=10).contains(&x)
                } else {
                    (2..=4).contains(&x) || (10..=12).contains(&x)
                };
                r.push(if on { '#' } else { '.' });
            }
            rows.push(r);
        }
        let refs: Vec<&str> = rows.iter().map(|s| s.as_str()).collect();
        out.clear();
        l.label(&mask_from(&refs), 5, &mut out);
        assert_eq!(out.regions().len(), 1, "a stride is not cut");
    }
}
