//! Region box → fixed-size window on the Y plane (bilinear, fixed point).
//!
//! The window keeps the layout's aspect ratio. Its height is the box height
//! plus a margin above and below ([`Layout::margin_q8`]). With
//! [`Fit::Contain`], if the box (plus the same relative margin left and
//! right) is wider than that, the window grows to fit the width instead, so
//! a wide region (a group, a car) is shrunk whole rather than cropped; with
//! [`Fit::Height`] the sides are cropped instead. The box centre is the
//! window centre.
//!
//! The window is sampled with a one-pixel border, `(win_w + 2)` ×
//! `(win_h + 2)`, so that gradients and LBP codes exist at every window
//! pixel. Samples outside the plane repeat its edge pixels.

use super::layout::{Fit, Layout, ASPECT_CENTRES_Q8, MASK_CELL, MAX_WINDOW_SIDE};
use crate::detect::morphology::BitMask;
use crate::detect::BBox;
use crate::frame::Plane;

/// A window rectangle in source pixel coordinates, Q16.16 (pixel centres at
/// integers, so the left edge of pixel 0 is −0.5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WindowRect {
    /// Left edge, Q16.16 pixels.
    pub left: i64,
    /// Top edge, Q16.16 pixels.
    pub top: i64,
    /// Width, Q16.16 pixels.
    pub width: i64,
    /// Height, Q16.16 pixels.
    pub height: i64,
}

/// The window rectangle around `bbox` for `layout` (see the module doc).
pub fn window_rect(bbox: &BBox, layout: &Layout) -> WindowRect {
    let bw = i64::from(bbox.width());
    let bh = i64::from(bbox.height());
    let m = i64::from(layout.margin_q8);
    let (ww, wh) = (i64::from(layout.win_w), i64::from(layout.win_h));
    // Q8 sizes: box side × (1 + 2·margin). bh ≤ 65536, so ≤ 2^16·3·2^8 = 2^25.6.
    let mut height_q8 = bh * 256 + 2 * bh * m;
    let mut width_q8 = height_q8 * ww / wh;
    let need_w_q8 = bw * 256 + 2 * bw * m;
    if layout.fit == Fit::Contain && need_w_q8 > width_q8 {
        width_q8 = need_w_q8;
        height_q8 = width_q8 * wh / ww;
    }
    // Centre in Q16: (x0 + x1) / 2.
    let cx = (i64::from(bbox.x0) + i64::from(bbox.x1)) << 15;
    let cy = (i64::from(bbox.y0) + i64::from(bbox.y1)) << 15;
    WindowRect {
        left: cx - (width_q8 << 7),
        top: cy - (height_q8 << 7),
        width: width_q8 << 8,
        height: height_q8 << 8,
    }
}

/// Writes the box-shape features of `bbox` to `out` (one per entry of
/// [`ASPECT_CENTRES_Q8`]): the width/height ratio `r` in Q8 (integer
/// division, exact) votes 255 split linearly between the two nearest bin
/// centres, all of it to the end bin outside the centres' range.
pub fn aspect_features(bbox: &BBox, out: &mut [u8]) {
    out.fill(0);
    let n = ASPECT_CENTRES_Q8.len().min(out.len());
    if n == 0 {
        return;
    }
    // width ≤ 65536, so width · 256 < 2^25.
    let r = bbox.width() * 256 / bbox.height().max(1);
    let c = &ASPECT_CENTRES_Q8[..n];
    if r <= c[0] {
        out[0] = 255;
        return;
    }
    if r >= c[n - 1] {
        out[n - 1] = 255;
        return;
    }
    let k = c.iter().rposition(|&v| v <= r).unwrap_or(0);
    // 255 · (r − c_k) < 255 · 2^9: no overflow.
    let hi = (255 * (r - c[k]) + (c[k + 1] - c[k]) / 2) / (c[k + 1] - c[k]);
    out[k + 1] = hi as u8;
    out[k] = (255 - hi) as u8;
}

/// Writes the foreground-fill features of `rect` (see the layout's part
/// 5) to `out` (`layout.mask_dim()` values): each window pixel takes the
/// mask pixel nearest its centre (outside the mask: background), mirrored
/// left to right when `flip` is set; a cell's value is
/// `round(255 · count / MASK_CELL²)`. With no mask every value is 0,
/// the last one included.
pub fn mask_features(
    mask: Option<&BitMask>,
    rect: &WindowRect,
    layout: &Layout,
    flip: bool,
    out: &mut [u8],
) {
    out.fill(0);
    let (cx, cy) = layout.mask_grid();
    let (Some(mask), true) = (mask, out.len() > cx * cy) else {
        return;
    };
    let (ww, wh) = (i64::from(layout.win_w), i64::from(layout.win_h));
    // Nearest source pixel of window coordinate `i` (centre at
    // `start + (i + ½)·extent / n`, Q16.16; |values| < 2^40, no overflow).
    let source = |start: i64, extent: i64, n: i64, i: i64| {
        let c = start + (2 * i + 1) * extent / (2 * n);
        (c + (1 << 15)) >> 16
    };
    // Source column of each window column (the window is at most
    // MAX_WINDOW_SIDE wide); negative ones clamp to usize::MAX, which
    // `BitMask::get` reads as background like any column off the mask.
    let mut columns = [0usize; MAX_WINDOW_SIDE as usize];
    for (i, c) in columns.iter_mut().enumerate().take(ww as usize) {
        let x = source(rect.left, rect.width, ww, i as i64);
        *c = usize::try_from(x).unwrap_or(usize::MAX);
    }
    for j in 0..wh {
        let Ok(y) = usize::try_from(source(rect.top, rect.height, wh, j)) else {
            continue;
        };
        let cell_row = j as usize / MASK_CELL * cx;
        for (i, &x) in columns.iter().enumerate().take(ww as usize) {
            if !mask.get(x, y) {
                continue;
            }
            let col = if flip { ww as usize - 1 - i } else { i };
            // At most MASK_CELL² = 16 per cell: fits a u8.
            out[cell_row + col / MASK_CELL] += 1;
        }
    }
    let full = (MASK_CELL * MASK_CELL) as u32;
    for v in &mut out[..cx * cy] {
        // count ≤ 16, so 255 · count < 2^12.
        *v = ((u32::from(*v) * 255 + full / 2) / full) as u8;
    }
    out[cx * cy] = 255;
}

/// One axis of the sampling grid: for each window coordinate (border
/// included), the first source index `a` (the second is `a + 1`) and the
/// Q8 weight of the second, 0..=256. Outside the plane the weight pins the
/// sample to the edge pixel.
#[derive(Clone, Debug, Default)]
struct Axis {
    a: Vec<u32>,
    frac: Vec<u32>,
}

impl Axis {
    fn with_len(n: usize) -> Self {
        Axis {
            a: vec![0; n],
            frac: vec![0; n],
        }
    }

    /// Fills the grid for an edge at `start` (Q16) with `n - 2` window
    /// pixels spanning `span` (Q16) over a source axis of `len ≥ 2` pixels.
    fn fill(&mut self, start: i64, span: i64, len: usize) {
        let n = self.a.len() as i64;
        let inner = n - 2;
        let last = len as i64 - 1;
        for i in 0..n {
            // Centre of window pixel i − 1 (the border is pixel −1); with
            // pixel centres at integers its floor is the left sample.
            let s = start + ((2 * (i - 1) + 1) * span).div_euclid(2 * inner);
            let ip = s >> 16;
            let (a, f) = if ip < 0 {
                (0, 0)
            } else if ip >= last {
                (last - 1, 256)
            } else {
                (ip, (s >> 8) & 255)
            };
            let k = i as usize;
            self.a[k] = a as u32;
            self.frac[k] = f as u32;
        }
    }
}

/// Widest run of source columns the vertical-first path blends (see
/// [`Sampler::sample`]); a power of two, so masked offsets need no bounds
/// check.
const SPAN: usize = 2048;

/// Resamples boxes into a bordered window; owns its scratch.
#[derive(Clone, Debug)]
pub struct Sampler {
    xs: Axis,
    ys: Axis,
    w: usize,
    h: usize,
    /// Per window column, its first source column minus the row's first.
    offs: Vec<u16>,
    /// Per window column, the Q8 weights of its two source columns.
    wx: [Vec<u16>; 2],
    /// One window row's two blended source columns per pixel.
    taps: [Vec<u16>; 2],
    /// The source columns of one window row blended vertically (Q8), one
    /// spare entry so that `offset + 1` stays inside.
    blend: Box<[u16; SPAN + 1]>,
}

impl Sampler {
    /// Scratch for windows of `layout`'s size.
    pub fn new(layout: &Layout) -> Self {
        let w = usize::from(layout.win_w);
        let h = usize::from(layout.win_h);
        Sampler {
            xs: Axis::with_len(w + 2),
            ys: Axis::with_len(h + 2),
            w,
            h,
            offs: vec![0; w + 2],
            wx: [vec![0; w + 2], vec![0; w + 2]],
            taps: [vec![0; w + 2], vec![0; w + 2]],
            blend: Box::new([0; SPAN + 1]),
        }
    }

    /// Stride of the bordered window (`win_w + 2`).
    pub fn stride(&self) -> usize {
        self.w + 2
    }

    /// Bytes of the bordered window.
    pub fn len(&self) -> usize {
        (self.w + 2) * (self.h + 2)
    }

    /// Always false: a window has at least 10×10 bytes.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Samples `rect` of `luma` into `out` (`len()` bytes, row stride
    /// `stride()`), bilinear in Q8 weights. Per window row the two source
    /// rows are first blended vertically, `v = p·(256 − fy) + q·fy` (≤
    /// 255·256, exact in `u16`), over the contiguous run of source columns
    /// the window reads (a loop the compiler vectorises); then each window
    /// pixel is `(v_a·(256 − fx) + v_{a+1}·fx + 2^15) >> 16` (at most
    /// 255·2^16, rounding to nearest). That is the same integer as the
    /// four-tap form, which is kept for windows reading more than
    /// `SPAN` (2,048) source columns. Returns `false` (and leaves `out` alone)
    /// for a plane under 2×2 pixels or a short `out`.
    pub fn sample(&mut self, luma: Plane<'_>, rect: &WindowRect, out: &mut [u8]) -> bool {
        if luma.width < 2 || luma.height < 2 || out.len() < self.len() {
            return false;
        }
        self.xs.fill(rect.left, rect.width, luma.width);
        self.ys.fill(rect.top, rect.height, luma.height);
        // xs.a is non-decreasing and every a + 1 is inside the plane.
        let first = self.xs.a[0] as usize;
        let end = self.xs.a[self.w + 1] as usize + 2;
        if end - first > SPAN {
            self.sample_four_tap(luma, out);
            return true;
        }
        let [wx0, wx1] = &mut self.wx;
        for (((o, w0), w1), (&a, &f)) in self
            .offs
            .iter_mut()
            .zip(wx0.iter_mut())
            .zip(wx1.iter_mut())
            .zip(self.xs.a.iter().zip(&self.xs.frac))
        {
            *o = (a as usize - first) as u16;
            (*w0, *w1) = ((256 - f) as u16, f as u16);
        }
        let stride = self.stride();
        for (j, row_out) in out.chunks_exact_mut(stride).take(self.h + 2).enumerate() {
            let ya = self.ys.a[j] as usize;
            let (Some(ra), Some(rb)) = (
                luma.row(ya).get(first..end),
                luma.row(ya + 1).get(first..end),
            ) else {
                continue;
            };
            let fy = self.ys.frac[j] as u16;
            let gy = 256 - fy;
            for ((v, &p), &q) in self.blend.iter_mut().zip(ra).zip(rb) {
                *v = u16::from(p) * gy + u16::from(q) * fy;
            }
            // Gather the two taps of every pixel (scalar loads), then blend
            // them in a loop the compiler vectorises.
            let [t0, t1] = &mut self.taps;
            for ((a, b), &k) in t0.iter_mut().zip(t1.iter_mut()).zip(&self.offs) {
                let k = usize::from(k) & (SPAN - 1);
                (*a, *b) = (self.blend[k], self.blend[k + 1]);
            }
            let [w0, w1] = &self.wx;
            for (((o, &a), &b), (&w0, &w1)) in row_out
                .iter_mut()
                .zip(t0.iter())
                .zip(t1.iter())
                .zip(w0.iter().zip(w1))
            {
                let v = u32::from(a) * u32::from(w0) + u32::from(b) * u32::from(w1);
                *o = ((v + (1 << 15)) >> 16) as u8;
            }
        }
        true
    }

    /// The same samples, four taps per pixel (for very wide windows).
    fn sample_four_tap(&self, luma: Plane<'_>, out: &mut [u8]) {
        let stride = self.stride();
        for (j, row_out) in out.chunks_exact_mut(stride).take(self.h + 2).enumerate() {
            let ya = self.ys.a[j] as usize;
            let (ra, rb) = (luma.row(ya), luma.row(ya + 1));
            let fy = self.ys.frac[j];
            for ((o, &xa), &fx) in row_out.iter_mut().zip(&self.xs.a).zip(&self.xs.frac) {
                let xa = xa as usize;
                let (Some(p), Some(q)) = (ra.get(xa..xa + 2), rb.get(xa..xa + 2)) else {
                    continue;
                };
                let v0 = u32::from(p[0]) * (256 - fy) + u32::from(q[0]) * fy;
                let v1 = u32::from(p[1]) * (256 - fy) + u32::from(q[1]) * fy;
                *o = ((v0 * (256 - fx) + v1 * fx + (1 << 15)) >> 16) as u8;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn foreground_fill_counts_the_mask_under_each_cell() {
        let mut l = Layout::default_layout();
        l.mask_fill = true;
        l.validate().unwrap();
        assert_eq!(l.mask_dim(), 8 * 16 + 1);
        // A box 140x224: the window is 140x280 px (margin 28 px above and
        // below), 4.375 source px per window px. The mask fills the box's
        // left half, so window rows 6..=57 and columns 0..=15 see it.
        let b = BBox {
            x0: 130,
            y0: 100,
            x1: 269,
            y1: 323,
        };
        let filled = |xs: core::ops::RangeInclusive<usize>,
                      ys: core::ops::RangeInclusive<usize>| {
            let mut m = BitMask::new(400, 400);
            for y in ys {
                for x in xs.clone() {
                    m.set(x, y, true);
                }
            }
            m
        };
        let mask = filled(130..=199, 100..=323);
        let rect = window_rect(&b, &l);
        let mut out = vec![7u8; l.mask_dim()];
        mask_features(Some(&mask), &rect, &l, false, &mut out);
        // Cell rows 1 and 14 hold two filled window rows of four: 255·8/16.
        for row in 0..16 {
            let want = match row {
                0 | 15 => 0,
                1 | 14 => 128,
                _ => 255,
            };
            let cells = &out[row * 8..row * 8 + 8];
            assert_eq!(
                cells,
                [want, want, want, want, 0, 0, 0, 0],
                "cell row {row}"
            );
        }
        assert_eq!(out[128], 255, "mask given");
        let mut flipped = vec![0u8; l.mask_dim()];
        mask_features(Some(&mask), &rect, &l, true, &mut flipped);
        for row in 0..16 {
            let r = &out[row * 8..row * 8 + 8];
            assert!(r.iter().rev().eq(flipped[row * 8..row * 8 + 8].iter()));
        }
        mask_features(None, &rect, &l, false, &mut out);
        assert!(out.iter().all(|&v| v == 0), "no mask: all zero");
        // A box running off the mask: what is outside counts as background.
        let edge = BBox {
            x0: 380,
            y0: 350,
            x1: 399,
            y1: 399,
        };
        let full = filled(0..=399, 0..=399);
        mask_features(Some(&full), &window_rect(&edge, &l), &l, false, &mut out);
        assert_eq!(out[0], 255);
        // Window rows 56, 57 and columns 24, 25 are the last on the image
        // (source rows and columns 398, 399): 2x2 of cell (row 14, column
        // 6)'s 4x4 pixels; the cells below and right of it are off it.
        assert_eq!(out[14 * 8 + 6], 64, "cell on the image's corner");
        assert_eq!(out[14 * 8 + 7], 0);
        assert_eq!(out[15 * 8 + 6], 0);
        assert_eq!(out[13 * 8 + 5], 255);
    }

    fn contain() -> Layout {
        Layout::full(32, 64, 43, 4, 8, 2).unwrap()
    }

    #[test]
    fn tall_box_gets_vertical_margin_and_aspect() {
        let l = contain();
        let b = BBox {
            x0: 100,
            y0: 50,
            x1: 129,
            y1: 145,
        };
        let r = window_rect(&b, &l);
        let h = r.height as f64 / 65536.0;
        let w = r.width as f64 / 65536.0;
        assert!((h - 96.0 * (1.0 + 2.0 * 43.0 / 256.0)).abs() < 0.01, "{h}");
        assert!((w * 2.0 - h).abs() < 0.01);
        // Centred on the box.
        let cx = (r.left as f64 + r.width as f64 / 2.0) / 65536.0;
        assert!((cx - 114.5).abs() < 0.01, "{cx}");
    }

    #[test]
    fn wide_box_widens_the_window_or_is_cropped() {
        let b = BBox {
            x0: 0,
            y0: 0,
            x1: 199,
            y1: 49,
        };
        let r = window_rect(&b, &contain());
        assert!(r.width >= 200 << 16);
        assert_eq!(r.height, r.width * 2);
        let mut l = contain();
        l.fit = Fit::Height;
        let r = window_rect(&b, &l);
        let h = r.height as f64 / 65536.0;
        assert!((h - 50.0 * (1.0 + 2.0 * 43.0 / 256.0)).abs() < 0.01, "{h}");
        assert_eq!(r.height, r.width * 2);
        // Still centred on the box.
        let cx = (r.left as f64 + r.width as f64 / 2.0) / 65536.0;
        assert!((cx - 99.5).abs() < 0.01, "{cx}");
    }

    #[test]
    fn identity_scale_copies_pixels() {
        // A 34x66 box region sampled at scale 1 must reproduce the pixels.
        let l = Layout::full(32, 64, 0, 4, 8, 0).unwrap();
        let (w, h) = (80usize, 100usize);
        let data: Vec<u8> = (0..w * h).map(|i| (i * 7 % 251) as u8).collect();
        let plane = Plane::new(&data, w, h).unwrap();
        let b = BBox {
            x0: 10,
            y0: 20,
            x1: 41,
            y1: 83,
        };
        let mut s = Sampler::new(&l);
        let mut out = vec![0; s.len()];
        assert!(s.sample(plane, &window_rect(&b, &l), &mut out));
        for j in 0..66 {
            for i in 0..34 {
                assert_eq!(out[j * 34 + i], data[(19 + j) * w + 9 + i], "({i},{j})");
            }
        }
    }

    /// Both sampling paths (vertical-first, and four taps for windows
    /// reading more than `SPAN` columns) give exactly the four-tap bilinear
    /// value, on boxes shrunk, enlarged and reaching past the plane.
    #[test]
    fn samples_match_the_four_tap_definition() {
        let l = contain();
        let (w, h) = (3000usize, 300usize);
        let data: Vec<u8> = (0..w * h)
            .map(|i| ((i % w) * 13 + (i / w) * 7 + (i * i) % 17) as u8)
            .collect();
        let plane = Plane::new(&data, w, h).unwrap();
        let mut s = Sampler::new(&l);
        let mut out = vec![0; s.len()];
        let boxes = [
            (100, 20, 150, 170),    // shrunk
            (500, 100, 510, 119),   // enlarged
            (2980, 280, 2999, 299), // past the corner
            (10, 100, 2990, 140),   // wide: more than SPAN columns
        ];
        for (x0, y0, x1, y1) in boxes {
            let b = BBox { x0, y0, x1, y1 };
            let r = window_rect(&b, &l);
            assert!(s.sample(plane, &r, &mut out));
            let (xs, ys) = (&s.xs, &s.ys);
            for j in 0..66 {
                for i in 0..34 {
                    let (xa, ya) = (xs.a[i] as usize, ys.a[j] as usize);
                    let (fx, fy) = (xs.frac[i], ys.frac[j]);
                    let p = |x: usize, y: usize| u32::from(data[y * w + x]);
                    let top = p(xa, ya) * (256 - fx) + p(xa + 1, ya) * fx;
                    let bot = p(xa, ya + 1) * (256 - fx) + p(xa + 1, ya + 1) * fx;
                    let want = ((top * (256 - fy) + bot * fy + (1 << 15)) >> 16) as u8;
                    assert_eq!(out[j * 34 + i], want, "box {b:?} ({i},{j})");
                }
            }
        }
    }

    #[test]
    fn aspect_features_split_between_neighbouring_centres() {
        let mut f = [0u8; 8];
        let bx = |w: u16, h: u16| BBox {
            x0: 0,
            y0: 0,
            x1: w - 1,
            y1: h - 1,
        };
        // Narrower than the first centre, wider than the last: one bin.
        aspect_features(&bx(10, 100), &mut f);
        assert_eq!(f, [255, 0, 0, 0, 0, 0, 0, 0]);
        aspect_features(&bx(300, 100), &mut f);
        assert_eq!(f, [0, 0, 0, 0, 0, 0, 0, 255]);
        // Exactly on a centre (0.40 = 102/256 of 256 px height).
        aspect_features(&bx(102, 256), &mut f);
        assert_eq!(f, [0, 0, 255, 0, 0, 0, 0, 0]);
        // Halfway between 0.40 and 0.52 (r = 117.5 → 117 or 118): split.
        aspect_features(&bx(118, 256), &mut f);
        assert_eq!(f[2..4].iter().map(|&v| u32::from(v)).sum::<u32>(), 255);
        assert!((120..=135).contains(&f[3]), "{f:?}");
        // Monotone: a wider box moves weight to wider bins.
        let mut centre = |w| {
            aspect_features(&bx(w, 100), &mut f);
            f.iter()
                .enumerate()
                .map(|(k, &v)| k as f64 * f64::from(v))
                .sum::<f64>()
        };
        assert!((20..160).all(|w| centre(w) <= centre(w + 1)));
    }
}
