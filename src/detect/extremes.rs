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

/// A region's end row as the extremes see it: its row and the column span
/// of its pixels there.
#[derive(Clone, Copy, Debug)]
struct End {
    y: u16,
    span: (usize, usize),
}

/// Refines `region`'s head and foot (whose runs are `runs`) from
/// `before_open`, the mask before the opening. Rows beyond the region are
/// taken while each has pixels within one column of the previous row's
/// found span.
pub fn refine(region: &mut Region, runs: &[Run], before_open: &BitMask, foot_pixels: u32) {
    let (Some(first), Some(last)) = (runs.first(), runs.last()) else {
        return;
    };
    let top = span(runs, first.y).map(|span| End { y: first.y, span });
    let bottom = span(runs, last.y).map(|span| End { y: last.y, span });
    extend(region, top, bottom, before_open, foot_pixels, |b| {
        b.add_runs(runs)
    });
}

/// Sets `region`'s head and foot from the pixels of its `runs` that
/// `inner` also holds (eq. 5 on that subset: its top-most row, the mean of
/// its bottom-most `foot_pixels` pixels), then refines them from
/// `before_open` as [`refine`] does (`refine = false`: no refinement).
/// The region keeps its own head and foot when `inner` holds none of its
/// pixels. Either way it is marked [`Region::loose_ends`] when its box
/// reaches more than [`end_tolerance`] rows beyond those ends.
///
/// Why: with `detect.open_vertical_radius` the regions come from the union
/// of the square opening and a vertical-line opening, which keeps distant
/// people's thin legs and arms (whole boxes) but also thin streaks above
/// heads and below feet, and those lengthen the head–foot extents the
/// calibration measures. `inner` is the square opening alone: the head and
/// foot rows are then the ones the square-only detector finds, while the
/// box, pixel count and runs are the union's.
pub fn from_subset(
    region: &mut Region,
    runs: &[Run],
    inner: &BitMask,
    before_open: &BitMask,
    foot_pixels: u32,
    refine: bool,
) {
    // Top: the first row with an inner pixel.
    let top = rows(runs).find_map(|row| {
        inner_pixels(row, inner).map(|(n, sx, a, b)| {
            (
                End {
                    y: row[0].y,
                    span: (a, b),
                },
                n,
                sx,
            )
        })
    });
    let Some((top, top_n, top_sx)) = top else {
        // Thin structures only: where a person would end is anyone's guess.
        region.loose_ends = true;
        return;
    };
    let mut base = BottomPixels::new(foot_pixels);
    let bottom = inner_bottom(runs, inner, &mut base);
    region.head = [(top_sx as f64 / f64::from(top_n)) as f32, f32::from(top.y)];
    if let Some(m) = base.mean() {
        region.foot = m;
    }
    let mut lowest = bottom.map(|e| usize::from(e.y));
    if refine {
        lowest = extend(region, Some(top), bottom, before_open, foot_pixels, |b| {
            inner_bottom(runs, inner, b);
        });
    }
    // Ends the union reaches far beyond the subset's: its rows are not the
    // person's ends either way (the square lost a part the union kept).
    let (y0, y1) = (usize::from(region.bbox.y0), usize::from(region.bbox.y1));
    let head_row = region.head[1] as usize;
    let tol = end_tolerance(y1 + 1 - y0);
    region.loose_ends = head_row > y0 + tol || lowest.is_some_and(|l| l + tol < y1);
}

/// Rows a region's box may reach beyond the head and foot rows taken from
/// the square opening before they count as loose (`box_rows`: its height).
/// [`MAX_ROWS`] (what the refinement itself may add) or 5 % of the box,
/// whichever is more (4 rows or 5 % measured the same, bench/RESULTS.md).
pub fn end_tolerance(box_rows: usize) -> usize {
    MAX_ROWS.max(box_rows / 20)
}

/// Adds the pixels of `runs` that `inner` holds to `b`, row by row from the
/// bottom up until it is full; the lowest row with such pixels.
fn inner_bottom(runs: &[Run], inner: &BitMask, b: &mut BottomPixels) -> Option<End> {
    let mut bottom = None;
    for row in rows(runs).rev() {
        if b.is_full() {
            break;
        }
        if let Some((n, sx, a, hi)) = inner_pixels(row, inner) {
            let y = row[0].y;
            bottom.get_or_insert(End { y, span: (a, hi) });
            b.add_row(f64::from(y), n, 2.0 * sx as f64);
        }
    }
    bottom
}

/// `runs` (sorted by row) grouped into rows, top to bottom.
fn rows(runs: &[Run]) -> core::slice::ChunkBy<'_, Run, impl FnMut(&Run, &Run) -> bool> {
    runs.chunk_by(|a, b| a.y == b.y)
}

/// The pixels of one row's runs that `inner` holds: count, sum of
/// columns, leftmost and rightmost column ([`row_pixels`] over the runs).
fn inner_pixels(row: &[Run], inner: &BitMask) -> Option<(u32, u64, usize, usize)> {
    row.iter().fold(None, |acc, r| {
        let y = usize::from(r.y);
        merge(
            acc,
            row_pixels(inner, y, usize::from(r.x0), usize::from(r.x1)),
        )
    })
}

/// Two rows' (or runs') pixel sums combined.
fn merge(
    a: Option<(u32, u64, usize, usize)>,
    b: Option<(u32, u64, usize, usize)>,
) -> Option<(u32, u64, usize, usize)> {
    match (a, b) {
        (Some((n, s, lo, hi)), Some((m, t, lo2, hi2))) => {
            Some((n + m, s + t, lo.min(lo2), hi.max(hi2)))
        }
        (x, None) | (None, x) => x,
    }
}

/// The refinement proper: rows of `before_open` beyond the `top` and
/// `bottom` ends; the foot is eq. 5 over the rows found below (lowest
/// first) followed by what `base` adds (the pixels from the bottom end up).
/// Returns the lowest row the foot's pixels reach.
fn extend(
    region: &mut Region,
    top: Option<End>,
    bottom: Option<End>,
    before_open: &BitMask,
    foot_pixels: u32,
    base: impl FnOnce(&mut BottomPixels),
) -> Option<usize> {
    let mut lowest = bottom.map(|e| usize::from(e.y));
    // Below: eq. 5 over the recovered rows (lowest first), then the region's.
    if let Some(e) = bottom {
        let mut ext = [(0usize, 0u32, 0u64); MAX_ROWS];
        let mut n_ext = 0;
        beyond(before_open, e.y, e.span, false, |y, n, sx| {
            ext[n_ext] = (y, n, sx);
            n_ext += 1;
        });
        if n_ext > 0 {
            lowest = Some(ext[n_ext - 1].0);
            let mut b = BottomPixels::new(foot_pixels);
            for &(y, n, sx) in ext[..n_ext].iter().rev() {
                b.add_row(y as f64, n, 2.0 * sx as f64);
            }
            base(&mut b);
            if let Some(m) = b.mean() {
                region.foot = m;
            }
        }
    }
    // Above: the topmost row reached becomes the head row.
    if let Some(e) = top {
        let mut top = None;
        beyond(before_open, e.y, e.span, true, |y, n, sx| {
            top = Some((y, n, sx))
        });
        if let Some((y, n, sx)) = top {
            region.head = [(sx as f64 / f64::from(n)) as f32, y as f32];
        }
    }
    lowest
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

    /// A body on rows 10..=40 (cols 20..=25) with a 1-px streak above the
    /// head (rows 4..=9) and a 2-px one below the feet (rows 41..=50) in
    /// the union's runs; the square opening (`inner`) has the body only.
    fn streaked() -> (Vec<Run>, BitMask, BitMask) {
        let (mut inner, mut union) = (BitMask::new(64, 64), BitMask::new(64, 64));
        let mut runs = Vec::new();
        for y in 4..=9u16 {
            runs.push(Run { y, x0: 23, x1: 23 });
            union.set(23, usize::from(y), true);
        }
        for y in 10..=40u16 {
            runs.push(Run { y, x0: 20, x1: 25 });
            for x in 20..=25 {
                inner.set(x, usize::from(y), true);
                union.set(x, usize::from(y), true);
            }
        }
        for y in 41..=50u16 {
            runs.push(Run { y, x0: 21, x1: 22 });
            union.set(21, usize::from(y), true);
            union.set(22, usize::from(y), true);
        }
        (runs, inner, union)
    }

    /// The box of [`streaked`]'s union.
    const UNION_BOX: BBox = BBox {
        x0: 20,
        y0: 4,
        x1: 25,
        y1: 50,
    };

    #[test]
    fn subset_extremes_ignore_the_unions_streaks() {
        let (runs, inner, union) = streaked();
        let mut r = Region {
            head: [23.0, 4.0],
            foot: [21.5, 49.5],
            bbox: UNION_BOX,
            ..Default::default()
        };
        from_subset(&mut r, &runs, &inner, &union, 10, false);
        assert_eq!(r.head, [22.5, 10.0]);
        // The box reaches 6 rows above the head, 10 below the foot row.
        assert!(r.loose_ends);
        // Bottom 10 inner pixels: all 6 of row 40, 4 of row 39.
        assert!((r.foot[1] - (40.0 * 6.0 + 39.0 * 4.0) / 10.0).abs() < 1e-4);
        assert!((r.foot[0] - 22.5).abs() < 1e-4, "{:?}", r.foot);
    }

    /// With refinement the subset's ends are refined exactly as a region
    /// that had only the subset's runs would be: up to [`MAX_ROWS`] rows of
    /// the mask before the opening.
    #[test]
    fn subset_extremes_refine_like_the_subset_region() {
        let (runs, inner, union) = streaked();
        let mut r = Region {
            bbox: UNION_BOX,
            ..Default::default()
        };
        from_subset(&mut r, &runs, &inner, &union, 10, true);
        // Head 2 rows under the box top (within 4), the foot's lowest row
        // (44) 6 above its bottom: loose.
        assert!(r.loose_ends);
        r.loose_ends = false;
        r.bbox.y1 = 47;
        from_subset(&mut r, &runs, &inner, &union, 10, true);
        assert!(!r.loose_ends, "within 4 rows at both ends");
        let body: Vec<Run> = runs
            .iter()
            .copied()
            .filter(|r| (10..=40).contains(&r.y))
            .collect();
        let mut alone = Region::default();
        refine(&mut alone, &body, &union, 10);
        assert_eq!(r.head, alone.head);
        assert_eq!(r.foot, alone.foot);
        // Four rows up the 1-px streak, four down the 2-px one.
        assert_eq!(r.head, [23.0, 6.0]);
        let fy = (44.0 * 2.0 + 43.0 * 2.0 + 42.0 * 2.0 + 41.0 * 2.0 + 40.0 * 2.0) / 10.0;
        assert!((r.foot[1] - fy).abs() < 1e-4, "{:?}", r.foot);
    }

    #[test]
    fn no_subset_pixels_keep_the_regions_points() {
        let (runs, _, union) = streaked();
        let mut r = Region {
            head: [23.0, 4.0],
            foot: [21.5, 49.5],
            ..Default::default()
        };
        let before = r.clone();
        from_subset(&mut r, &runs, &BitMask::new(64, 64), &union, 10, true);
        assert_eq!((r.head, r.foot), (before.head, before.foot));
        assert!(r.loose_ends);
    }
}
