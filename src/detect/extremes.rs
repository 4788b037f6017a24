//! Head and foot rows given back what the opening took.
//!
//! The morphological opening that removes specks (radius `open_radius`)
//! also removes every part of a person thinner than `2r + 1` pixels. Near
//! the camera that is nothing; far away it is the ankles and shoes, and the
//! crown of the head. So the foot of eq. 5 rises and the head sinks by a
//! pixel or two on small people only: extents come out a few percent short
//! far away and right near by, which the horizon fit reads as a horizon
//! closer to the people (bench/RESULTS.md, "End to end"). The pixels are
//! still in the mask before the opening: below a region's bottom row (and
//! above its top row) within its bottom (top) columns, this looks for them
//! row by row and, when found, recomputes the foot as eq. 5 does (mean of
//! the bottom-most [`super::regions::FOOT_PIXELS`] pixels) and moves the
//! head up to the topmost row found.

use super::morphology::BitMask;
use super::{Region, Run};

/// Rows searched beyond a region's bottom or top row.
pub const MAX_ROWS: usize = 4;

/// Pixels of row `y` of `mask` in columns `a..=b`, and the sum of their
/// columns.
fn row_pixels(mask: &BitMask, y: usize, a: usize, b: usize) -> (u32, u64) {
    let (mut n, mut sx) = (0u32, 0u64);
    for x in a..=b.min(mask.width().saturating_sub(1)) {
        if mask.get(x, y) {
            n += 1;
            sx += x as u64;
        }
    }
    (n, sx)
}

/// Columns `[min x0, max x1]` of the runs on row `y` (runs sorted by row).
fn span(runs: &[Run], y: u16) -> Option<(usize, usize)> {
    let mut out: Option<(usize, usize)> = None;
    for r in runs.iter().filter(|r| r.y == y) {
        let (a, b) = (usize::from(r.x0), usize::from(r.x1));
        out = Some(out.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
    }
    out
}

/// Refines `region`'s head and foot (whose runs are `runs`) from
/// `before_open`, the mask before the opening. Rows beyond the region are
/// taken while each has pixels within one column of the previous row's
/// found span.
pub fn refine(region: &mut Region, runs: &[Run], before_open: &BitMask, foot_pixels: u32) {
    let (Some(first), Some(last)) = (runs.first(), runs.last()) else {
        return;
    };
    let h = before_open.height();
    // Below: collect (row, n, sum x) of the extension, bottom-most last.
    let mut ext = [(0usize, 0u32, 0u64); MAX_ROWS];
    let mut n_ext = 0;
    if let Some((mut a, mut b)) = span(runs, last.y) {
        let mut y = usize::from(last.y) + 1;
        while n_ext < MAX_ROWS && y < h {
            let (lo, hi) = (a.saturating_sub(1), b + 1);
            let (n, sx) = row_pixels(before_open, y, lo, hi);
            if n == 0 {
                break;
            }
            ext[n_ext] = (y, n, sx);
            n_ext += 1;
            // The next row continues under what was found here.
            let (mut fa, mut fb) = (usize::MAX, 0);
            for x in lo..=hi.min(before_open.width().saturating_sub(1)) {
                if before_open.get(x, y) {
                    fa = fa.min(x);
                    fb = fb.max(x);
                }
            }
            (a, b) = (fa, fb);
            y += 1;
        }
    }
    if n_ext > 0 {
        // Eq. 5 over the extension rows (lowest first), then the region's.
        let mut need = foot_pixels;
        let (mut sx2, mut sy, mut got) = (0f64, 0f64, 0u32);
        for &(y, n, sx) in ext[..n_ext].iter().rev() {
            let take = n.min(need);
            sx2 += 2.0 * sx as f64 * f64::from(take) / f64::from(n);
            sy += y as f64 * f64::from(take);
            got += take;
            need -= take;
            if need == 0 {
                break;
            }
        }
        let mut i = runs.len();
        while need > 0 && i > 0 {
            let y = runs[i - 1].y;
            let (mut n, mut rx2) = (0u32, 0u64);
            while i > 0 && runs[i - 1].y == y {
                let r = runs[i - 1];
                let len = u32::from(r.x1 - r.x0) + 1;
                n += len;
                rx2 += u64::from(len) * (u64::from(r.x0) + u64::from(r.x1));
                i -= 1;
            }
            let take = n.min(need);
            sx2 += rx2 as f64 * f64::from(take) / f64::from(n);
            sy += f64::from(y) * f64::from(take);
            got += take;
            need -= take;
        }
        if got > 0 {
            region.foot = [
                (sx2 / (2.0 * f64::from(got))) as f32,
                (sy / f64::from(got)) as f32,
            ];
        }
    }
    // Above: the topmost row reached becomes the head row.
    if let Some((mut a, mut b)) = span(runs, first.y) {
        let mut y = usize::from(first.y);
        let mut top: Option<(usize, u32, u64)> = None;
        for _ in 0..MAX_ROWS {
            if y == 0 {
                break;
            }
            y -= 1;
            let (lo, hi) = (a.saturating_sub(1), b + 1);
            let (n, sx) = row_pixels(before_open, y, lo, hi);
            if n == 0 {
                break;
            }
            top = Some((y, n, sx));
            let (mut fa, mut fb) = (usize::MAX, 0);
            for x in lo..=hi.min(before_open.width().saturating_sub(1)) {
                if before_open.get(x, y) {
                    fa = fa.min(x);
                    fb = fb.max(x);
                }
            }
            (a, b) = (fa, fb);
        }
        if let Some((y, n, sx)) = top {
            region.head = [(sx as f64 / f64::from(n)) as f32, y as f32];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::BBox;

    /// A region of a 6-wide body on rows 10..=40 and a 2-wide ankle on
    /// rows 41..=43 that only the mask before the opening still has.
    #[test]
    fn eroded_feet_and_crown_come_back() {
        let mut m = BitMask::new(64, 64);
        let mut runs = Vec::new();
        for y in 10..=40u16 {
            runs.push(Run { y, x0: 20, x1: 25 });
            for x in 20..=25 {
                m.set(x, usize::from(y), true);
            }
        }
        for y in 41..=43 {
            m.set(22, y, true);
            m.set(23, y, true);
        }
        // The crown: one row of 2 pixels above the top.
        m.set(22, 9, true);
        m.set(23, 9, true);
        let mut r = Region {
            area: 31 * 6,
            bbox: BBox {
                x0: 20,
                y0: 10,
                x1: 25,
                y1: 40,
            },
            head: [22.5, 10.0],
            foot: [22.5, 39.5],
            ..Default::default()
        };
        refine(&mut r, &runs, &m, 10);
        // Bottom 10 pixels: rows 43, 42, 41 (2 each) and 4 of row 40.
        let fy = (43.0 * 2.0 + 42.0 * 2.0 + 41.0 * 2.0 + 40.0 * 4.0) / 10.0;
        assert!((r.foot[1] - fy).abs() < 1e-4, "{:?}", r.foot);
        assert!((r.foot[0] - 22.5).abs() < 1e-4, "{:?}", r.foot);
        assert_eq!(r.head, [22.5, 9.0]);
    }

    #[test]
    fn nothing_beyond_the_region_changes_nothing() {
        let mut m = BitMask::new(32, 32);
        let runs: Vec<Run> = (5..=20u16).map(|y| Run { y, x0: 3, x1: 8 }).collect();
        for r in &runs {
            for x in 3..=8 {
                m.set(x, usize::from(r.y), true);
            }
        }
        // A speck far to the side below the region does not count.
        m.set(20, 21, true);
        let mut r = Region {
            head: [5.5, 5.0],
            foot: [5.5, 19.7],
            ..Default::default()
        };
        let before = r.clone();
        refine(&mut r, &runs, &m, 10);
        assert_eq!(r, before);
    }
}
