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
use super::regions::BottomPixels;
use super::{Region, Run};

/// Rows searched beyond a region's bottom or top row.
pub const MAX_ROWS: usize = 4;

/// The pixels of row `y` of `mask` in columns `lo..=hi`: how many, the
/// sum of their columns, and the first and last column (`None`: none).
fn row_pixels(mask: &BitMask, y: usize, lo: usize, hi: usize) -> Option<(u32, u64, usize, usize)> {
    let (mut n, mut sx, mut a, mut b) = (0u32, 0u64, usize::MAX, 0);
    for x in lo..=hi.min(mask.width().saturating_sub(1)) {
        if mask.get(x, y) {
            n += 1;
            sx += x as u64;
            a = a.min(x);
            b = b.max(x);
        }
    }
    (n > 0).then_some((n, sx, a, b))
}

/// Rows of `mask` continuing a region beyond row `from` (upward with
/// `up`), each with pixels within one column of the previous row's:
/// `f(row, pixels, column sum)` for each, nearest first, at most
/// [`MAX_ROWS`].
fn beyond(
    mask: &BitMask,
    from: u16,
    span: (usize, usize),
    up: bool,
    mut f: impl FnMut(usize, u32, u64),
) {
    let (mut a, mut b) = span;
    let mut y = usize::from(from);
    for _ in 0..MAX_ROWS {
        y = match (up, y) {
            (true, 0) => return,
            (true, _) => y - 1,
            (false, _) if y + 1 >= mask.height() => return,
            (false, _) => y + 1,
        };
        let Some((n, sx, fa, fb)) = row_pixels(mask, y, a.saturating_sub(1), b + 1) else {
            return;
        };
        f(y, n, sx);
        (a, b) = (fa, fb);
    }
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
    // Below: eq. 5 over the recovered rows (lowest first), then the region's.
    if let Some(s) = span(runs, last.y) {
        let mut ext = [(0usize, 0u32, 0u64); MAX_ROWS];
        let mut n_ext = 0;
        beyond(before_open, last.y, s, false, |y, n, sx| {
            ext[n_ext] = (y, n, sx);
            n_ext += 1;
        });
        if n_ext > 0 {
            let mut b = BottomPixels::new(foot_pixels);
            for &(y, n, sx) in ext[..n_ext].iter().rev() {
                b.add_row(y as f64, n, 2.0 * sx as f64);
            }
            b.add_runs(runs);
            if let Some(m) = b.mean() {
                region.foot = m;
            }
        }
    }
    // Above: the topmost row reached becomes the head row.
    if let Some(s) = span(runs, first.y) {
        let mut top = None;
        beyond(before_open, first.y, s, true, |y, n, sx| {
            top = Some((y, n, sx))
        });
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
