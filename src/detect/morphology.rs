//! Binary masks packed 64 pixels to a word, and square-element opening and
//! closing on them.
//!
//! A `(2r+1)²` square is separable: `r` one-pixel steps along the rows
//! (shifts and ANDs / ORs of whole words, with the neighbour words' edge
//! bits carried in) and `r` one-pixel steps across rows (ANDs / ORs of whole
//! rows). A step costs a handful of word operations per 64 pixels.
//!
//! Border rule: erosion treats the outside as foreground and dilation as
//! background, so a region touching the border is neither eaten nor grown
//! there (opening then closing leaves border-touching objects intact).

/// A `width`×`height` bit mask: bit `x % 64` of word `y·words_per_row + x / 64`.
/// Bits at `x ≥ width` are always 0.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BitMask {
    width: usize,
    height: usize,
    wpr: usize,
    words: Vec<u64>,
}

impl BitMask {
    /// An empty mask.
    pub fn new(width: usize, height: usize) -> Self {
        let wpr = width.div_ceil(64);
        BitMask {
            width,
            height,
            wpr,
            words: vec![0; wpr * height],
        }
    }
    /// Columns.
    pub fn width(&self) -> usize {
        self.width
    }
    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }
    /// Words per row.
    pub fn words_per_row(&self) -> usize {
        self.wpr
    }
    /// All words, row after row.
    pub fn words(&self) -> &[u64] {
        &self.words
    }
    /// All words, mutable. Writers must keep bits at `x ≥ width` clear.
    pub fn words_mut(&mut self) -> &mut [u64] {
        &mut self.words
    }
    /// One row's words.
    pub fn row(&self, y: usize) -> &[u64] {
        &self.words[y * self.wpr..(y + 1) * self.wpr]
    }
    /// One pixel (`false` outside).
    pub fn get(&self, x: usize, y: usize) -> bool {
        x < self.width && y < self.height && self.words[y * self.wpr + x / 64] >> (x % 64) & 1 != 0
    }
    /// Sets one pixel (ignored outside).
    pub fn set(&mut self, x: usize, y: usize, on: bool) {
        if x < self.width && y < self.height {
            let w = &mut self.words[y * self.wpr + x / 64];
            if on {
                *w |= 1 << (x % 64);
            } else {
                *w &= !(1 << (x % 64));
            }
        }
    }
    /// Set pixels.
    pub fn count(&self) -> u64 {
        self.words.iter().map(|w| u64::from(w.count_ones())).sum()
    }
    /// Copies another mask of the same size.
    pub fn copy_from(&mut self, other: &BitMask) {
        self.words.copy_from_slice(&other.words);
    }
    /// Mask of the valid bits of the last word of a row.
    fn tail(&self) -> u64 {
        match self.width % 64 {
            0 => u64::MAX,
            r => (1u64 << r) - 1,
        }
    }
}

/// One horizontal step on every row of `m`: `erode` keeps a pixel if both
/// neighbours are set, otherwise it sets a pixel if either is set.
fn horizontal(m: &mut BitMask, erode: bool) {
    let wpr = m.wpr;
    let tail = m.tail();
    // Outside the row: 1 for erosion, 0 for dilation.
    let edge = if erode { 1u64 } else { 0 };
    // Bit position of the first column beyond the image in the last word.
    let beyond = m.width % 64;
    for row in m.words.chunks_exact_mut(wpr) {
        let mut prev_top = edge; // bit 63 of the previous word, as bit 0
        for i in 0..wpr {
            let w = row[i];
            let mut next_low = if i + 1 < wpr { row[i + 1] & 1 } else { edge };
            let mut right = w >> 1;
            if i + 1 == wpr && beyond != 0 {
                // The right neighbour of the last column lies outside.
                right |= edge << (beyond - 1);
                next_low = 0;
            }
            let right = right | (next_low << 63);
            let left = (w << 1) | prev_top;
            prev_top = w >> 63;
            row[i] = if erode {
                w & left & right
            } else {
                w | left | right
            };
            if i + 1 == wpr {
                row[i] &= tail;
            }
        }
    }
}

/// One vertical step of distance `d`: `dst` row `y` from rows `y−d, y,
/// y+d` of `src`.
fn vertical(src: &BitMask, dst: &mut BitMask, erode: bool, d: usize) {
    let (wpr, h) = (src.wpr, src.height);
    for y in 0..h {
        let cur = &src.words[y * wpr..(y + 1) * wpr];
        // Outside rows: the row itself (neutral for both AND and OR).
        let up = if y >= d {
            &src.words[(y - d) * wpr..(y - d + 1) * wpr]
        } else {
            cur
        };
        let down = if y + d < h {
            &src.words[(y + d) * wpr..(y + d + 1) * wpr]
        } else {
            cur
        };
        let out = &mut dst.words[y * wpr..(y + 1) * wpr];
        for i in 0..wpr {
            out[i] = if erode {
                up[i] & cur[i] & down[i]
            } else {
                up[i] | cur[i] | down[i]
            };
        }
    }
}

/// `(2rx+1)×(2ry+1)` rectangle erosion or dilation of `m` in place (`tmp`: same size).
fn rect(m: &mut BitMask, tmp: &mut BitMask, rx: u32, ry: u32, erode: bool) {
    for _ in 0..rx {
        horizontal(m, erode);
    }
    // Vertical steps of growing distance: rows `y ± d` with `d ≤ S + 1`
    // (S = the half-height covered so far) reach every row within `S + d`,
    // so radius 6 takes steps of 1, 2, 3 rows instead of six of one. With
    // outside rows ignored this is exactly the radius-`ry` result up to the
    // borders too (checked against the byte-per-pixel reference below, and
    // by brute force for every radius ≤ 16 and height < 60).
    let mut covered = 0;
    while covered < ry {
        let d = (covered + 1).min(ry - covered);
        vertical(m, tmp, erode, d as usize);
        core::mem::swap(&mut m.words, &mut tmp.words);
        covered += d;
    }
}

/// Erosion by a `(2rx+1)×(2ry+1)` rectangle, in place; `tmp` is scratch of the same size.
pub fn erode(m: &mut BitMask, tmp: &mut BitMask, rx: u32, ry: u32) {
    rect(m, tmp, rx, ry, true);
}

/// Dilation by a `(2rx+1)×(2ry+1)` rectangle, in place; `tmp` is scratch of the same size.
pub fn dilate(m: &mut BitMask, tmp: &mut BitMask, rx: u32, ry: u32) {
    rect(m, tmp, rx, ry, false);
}

/// Opening (erode then dilate): removes specks narrower than the rectangle.
pub fn open(m: &mut BitMask, tmp: &mut BitMask, rx: u32, ry: u32) {
    erode(m, tmp, rx, ry);
    dilate(m, tmp, rx, ry);
}

/// The union of two openings of `m`: by the `(2r+1)²` square and by a
/// vertical line of `2v + 1` pixels (`v = 0`: the square alone; `r = 0`:
/// no opening). A pixel stays if the square fits around it or the line
/// does. Distant people's legs and hanging arms are one or two pixels
/// wide, thinner than the square, but upright; sensor and compression
/// specks, and the thin bridges that join two people walking side by
/// side, are neither. `vertical` and `tmp` are scratch of the same size;
/// with `v > 0`, `vertical` holds the square opening alone on return (the
/// head and foot rows are taken from it, [`super::extremes::from_subset`]).
pub fn open_keeping_vertical(
    m: &mut BitMask,
    vertical: &mut BitMask,
    tmp: &mut BitMask,
    r: u32,
    v: u32,
) {
    if r == 0 {
        return;
    }
    if v > 0 {
        vertical.copy_from(m);
        open(vertical, tmp, 0, v);
    }
    open(m, tmp, r, r);
    if v > 0 {
        // m = the line opening, vertical = the square's; then m = their union.
        core::mem::swap(&mut m.words, &mut vertical.words);
        for (w, &k) in m.words.iter_mut().zip(vertical.words.iter()) {
            *w |= k;
        }
    }
}

/// Closing (dilate then erode): fills holes and gaps narrower than the rectangle.
pub fn close(m: &mut BitMask, tmp: &mut BitMask, rx: u32, ry: u32) {
    dilate(m, tmp, rx, ry);
    erode(m, tmp, rx, ry);
}

/// Sets the pixels of `weak` that have a set pixel of `m` within `reach`
/// rows above and within `reach` rows below in the same column (rows are
/// processed top-down, so filled pixels count for the rows below). Only
/// words where `weak` has bits are visited: cost ∝ weak words × `reach`.
pub fn fill_between(m: &mut BitMask, weak: &BitMask, reach: usize) {
    let (wpr, h) = (m.wpr, m.height);
    if reach == 0 {
        return;
    }
    for y in 1..h.saturating_sub(1) {
        for j in 0..wpr {
            let wk = weak.words[y * wpr + j] & !m.words[y * wpr + j];
            if wk == 0 {
                continue;
            }
            let mut up = 0u64;
            for k in 1..=reach.min(y) {
                up |= m.words[(y - k) * wpr + j];
                if wk & !up == 0 {
                    break;
                }
            }
            let cand = wk & up;
            if cand == 0 {
                continue;
            }
            let mut down = 0u64;
            for k in 1..=reach.min(h - 1 - y) {
                down |= m.words[(y + k) * wpr + j];
                if cand & !down == 0 {
                    break;
                }
            }
            m.words[y * wpr + j] |= cand & down;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Byte-per-pixel reference with the same border rule.
    fn reference(src: &[bool], w: usize, h: usize, rx: i64, ry: i64, erode: bool) -> Vec<bool> {
        let mut out = vec![false; w * h];
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let mut acc = erode;
                for dy in -ry..=ry {
                    for dx in -rx..=rx {
                        let (xx, yy) = (x + dx, y + dy);
                        let v = if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            erode
                        } else {
                            src[(yy * w as i64 + xx) as usize]
                        };
                        if erode {
                            acc &= v;
                        } else {
                            acc |= v;
                        }
                    }
                }
                out[(y * w as i64 + x) as usize] = acc;
            }
        }
        out
    }

    /// A weak gap between set pixels above and below is filled; weak
    /// pixels with a set pixel on one side only, or farther than `reach`,
    /// are not.
    #[test]
    fn fill_between_bridges_vertical_gaps_only() {
        let (w, h) = (70, 20);
        let mut m = BitMask::new(w, h);
        let mut weak = BitMask::new(w, h);
        for y in 0..h {
            // Column 3: set at rows 2 and 8, weak between (a grey jacket).
            // Column 66: set at row 2 only, weak below (a ground shadow).
            // Column 40: set at rows 2 and 15, weak between (too far apart).
            m.set(3, y, y == 2 || y == 8);
            weak.set(3, y, (3..8).contains(&y));
            m.set(66, y, y == 2);
            weak.set(66, y, (3..10).contains(&y));
            m.set(40, y, y == 2 || y == 15);
            weak.set(40, y, (3..15).contains(&y));
        }
        fill_between(&mut m, &weak, 6);
        for y in 0..h {
            assert_eq!(m.get(3, y), (2..=8).contains(&y), "col 3 row {y}");
            assert_eq!(m.get(66, y), y == 2, "col 66 row {y}");
            assert_eq!(m.get(40, y), y == 2 || y == 15, "col 40 row {y}");
        }
    }

    /// A two-pixel leg hanging from a body survives; a speck and a
    /// one-row bridge between two bodies do not; the square alone would
    /// have taken the leg too.
    #[test]
    fn opening_keeps_thin_upright_limbs_only() {
        let (w, h) = (80, 30);
        let mut m = BitMask::new(w, h);
        let fill = |m: &mut BitMask, x0: usize, x1: usize, y0: usize, y1: usize| {
            for y in y0..y1 {
                for x in x0..x1 {
                    m.set(x, y, true);
                }
            }
        };
        fill(&mut m, 10, 20, 2, 14); // body
        fill(&mut m, 13, 15, 14, 24); // leg, 2 px wide, 10 tall
        fill(&mut m, 40, 50, 2, 14); // a second body
        fill(&mut m, 20, 40, 8, 9); // one-row bridge between them
        fill(&mut m, 60, 62, 20, 22); // 2x2 speck
        fill(&mut m, 70, 72, 20, 23); // 2x3 speck: shorter than the line
        let (mut v, mut tmp) = (BitMask::new(w, h), BitMask::new(w, h));
        let mut square = BitMask::new(w, h);
        square.copy_from(&m);
        open_keeping_vertical(&mut square, &mut v, &mut tmp, 1, 0);
        open_keeping_vertical(&mut m, &mut v, &mut tmp, 1, 2);
        for y in 14..24 {
            assert!(m.get(13, y) && m.get(14, y), "leg row {y}");
            assert!(!square.get(13, y), "the square alone takes the leg");
        }
        for x in 21..39 {
            assert!(!m.get(x, 8), "bridge column {x}");
        }
        assert_eq!(m.count(), 10 * 12 * 2 + 2 * 10, "bodies and leg only");
    }

    /// The union of openings equals the byte reference of both openings.
    #[test]
    fn opening_keeping_vertical_matches_byte_reference() {
        let mut s: u32 = 11;
        for &(w, h) in &[(70, 20), (130, 9), (64, 33)] {
            let px: Vec<bool> = (0..w * h)
                .map(|_| {
                    s ^= s << 13;
                    s ^= s >> 17;
                    s ^= s << 5;
                    s % 16 < 10
                })
                .collect();
            let open_ref = |rx: i64, ry: i64| {
                let e = reference(&px, w, h, rx, ry, true);
                reference(&e, w, h, rx, ry, false)
            };
            for (r, v) in [(1u32, 1u32), (1, 2), (2, 3), (1, 0)] {
                let mut m = BitMask::new(w, h);
                for y in 0..h {
                    for x in 0..w {
                        m.set(x, y, px[y * w + x]);
                    }
                }
                let (mut vm, mut tmp) = (BitMask::new(w, h), BitMask::new(w, h));
                open_keeping_vertical(&mut m, &mut vm, &mut tmp, r, v);
                let sq = open_ref(i64::from(r), i64::from(r));
                let line = if v > 0 {
                    open_ref(0, i64::from(v))
                } else {
                    vec![false; w * h]
                };
                for y in 0..h {
                    for x in 0..w {
                        let i = y * w + x;
                        assert_eq!(
                            m.get(x, y),
                            sq[i] || line[i],
                            "{w}x{h} r={r} v={v} ({x},{y})"
                        );
                        if v > 0 {
                            // The square opening alone is handed back.
                            assert_eq!(vm.get(x, y), sq[i], "square {w}x{h} r={r} v={v}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn packed_ops_match_byte_reference() {
        let mut s: u32 = 7;
        let sizes = [
            (64, 5),
            (70, 9),
            (130, 7),
            (200, 12),
            (1, 3),
            (63, 4),
            (70, 40),
        ];
        // Vertical radii beyond 3 exercise the growing step distances.
        let radii = [
            (1, 1),
            (2, 2),
            (3, 3),
            (2, 6),
            (1, 4),
            (0, 7),
            (2, 13),
            (1, 16),
        ];
        for &(w, h) in &sizes {
            for density in [3u32, 8, 13] {
                let px: Vec<bool> = (0..w * h)
                    .map(|_| {
                        s ^= s << 13;
                        s ^= s >> 17;
                        s ^= s << 5;
                        s % 16 < density
                    })
                    .collect();
                for &(rx, ry) in &radii {
                    for erode in [true, false] {
                        let mut m = BitMask::new(w, h);
                        let mut tmp = BitMask::new(w, h);
                        for y in 0..h {
                            for x in 0..w {
                                m.set(x, y, px[y * w + x]);
                            }
                        }
                        rect(&mut m, &mut tmp, rx, ry, erode);
                        let want = reference(&px, w, h, i64::from(rx), i64::from(ry), erode);
                        for y in 0..h {
                            for x in 0..w {
                                assert_eq!(
                                    m.get(x, y),
                                    want[y * w + x],
                                    "{w}x{h} r={rx},{ry} erode={erode} at ({x},{y})"
                                );
                            }
                        }
                        // Tail bits stay clear.
                        for y in 0..h {
                            assert_eq!(m.row(y)[m.wpr - 1] & !m.tail(), 0);
                        }
                    }
                }
            }
        }
    }
}
