//! HSV colour histograms straight from Y/U/V through one lookup table.
//!
//! The table maps a pixel's `(Y>>3, U>>3, V>>3)` (32 768 entries, built once)
//! to its histogram bin: saturated, bright enough pixels go to one of
//! `h_bins × s_bins` hue–saturation bins, the others (greys, dark) to one of
//! `v_bins` value bins, as in Pérez et al. 2002. Hue and saturation change
//! little with illumination, which is why the paper prefers HSV to RGB.

use crate::frame::Frame;

/// Most bins a histogram can have.
pub const MAX_BINS: usize = 64;

/// A normalised histogram (sums to 1, or all zero when empty).
pub type Hist = [f32; MAX_BINS];

/// The YUV→bin table.
#[derive(Clone, Debug)]
pub struct ColourTable {
    lut: Box<[u8]>,
    /// Bins in use.
    pub bins: usize,
}

impl ColourTable {
    /// Builds the table (BT.601 limited-range YCbCr to RGB, then HSV).
    pub fn new(h_bins: usize, s_bins: usize, v_bins: usize) -> Self {
        let bins = h_bins * s_bins + v_bins;
        let mut lut = vec![0u8; 1 << 15].into_boxed_slice();
        for yi in 0..32usize {
            for ui in 0..32usize {
                for vi in 0..32usize {
                    let y = (yi * 8 + 4) as f32;
                    let cb = (ui * 8 + 4) as f32 - 128.0;
                    let cr = (vi * 8 + 4) as f32 - 128.0;
                    let yy = 1.164 * (y - 16.0);
                    let r = (yy + 1.596 * cr).clamp(0.0, 255.0) / 255.0;
                    let g = (yy - 0.392 * cb - 0.813 * cr).clamp(0.0, 255.0) / 255.0;
                    let b = (yy + 2.017 * cb).clamp(0.0, 255.0) / 255.0;
                    let max = r.max(g).max(b);
                    let min = r.min(g).min(b);
                    let s = if max > 0.0 { (max - min) / max } else { 0.0 };
                    let bin = if s < 0.15 || max < 0.15 {
                        h_bins * s_bins + ((max * v_bins as f32) as usize).min(v_bins - 1)
                    } else {
                        let d = max - min;
                        let h = if max == r {
                            ((g - b) / d).rem_euclid(6.0)
                        } else if max == g {
                            (b - r) / d + 2.0
                        } else {
                            (r - g) / d + 4.0
                        } / 6.0;
                        let hb = ((h * h_bins as f32) as usize).min(h_bins - 1);
                        let sb = ((s * s_bins as f32) as usize).min(s_bins - 1);
                        hb * s_bins + sb
                    };
                    lut[(yi << 10) | (ui << 5) | vi] = bin as u8;
                }
            }
        }
        ColourTable { lut, bins }
    }

    /// Bin of the pixel at `(x, y)` (in the frame).
    #[inline]
    pub fn bin(&self, frame: &Frame, x: usize, y: usize) -> usize {
        let w = frame.size().width;
        let cw = frame.size().chroma().width;
        let yv = frame.y[y * w + x] as usize;
        let c = (y / 2) * cw + x / 2;
        let (u, v) = (frame.u[c] as usize, frame.v[c] as usize);
        self.lut[((yv >> 3) << 10) | ((u >> 3) << 5) | (v >> 3)] as usize
    }

    /// Histogram of the box centred at `(cx, cy)` of size `w × h`, sampled
    /// on a grid of at most 8 × 16 points (the inner 80 % of the width, to
    /// leave out background at the sides). Empty when off-image.
    pub fn histogram(&self, frame: &Frame, cx: f32, cy: f32, w: f32, h: f32, out: &mut Hist) {
        out.fill(0.0);
        let (fw, fh) = (frame.size().width as f32, frame.size().height as f32);
        let mut n = 0u32;
        for j in 0..16 {
            let y = cy - 0.5 * h + (j as f32 + 0.5) * h / 16.0;
            if !(0.0..fh).contains(&y) {
                continue;
            }
            for i in 0..8 {
                let x = cx - 0.4 * w + (i as f32 + 0.5) * 0.8 * w / 8.0;
                if !(0.0..fw).contains(&x) {
                    continue;
                }
                out[self.bin(frame, x as usize, y as usize)] += 1.0;
                n += 1;
            }
        }
        if n > 0 {
            let k = 1.0 / n as f32;
            for b in out.iter_mut() {
                *b *= k;
            }
        }
    }
}

/// Bhattacharyya coefficient of two normalised histograms (1 = identical).
pub fn bhattacharyya(a: &Hist, b: &Hist) -> f32 {
    a.iter().zip(b.iter()).map(|(x, y)| (x * y).sqrt()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Size;

    #[test]
    fn colours_fall_in_distinct_bins_and_greys_in_value_bins() {
        let t = ColourTable::new(8, 4, 4);
        let mut f = Frame::new(Size {
            width: 4,
            height: 2,
        });
        // Saturated red (Y 81, U 90, V 240), blue (41, 240, 110), mid grey.
        let px = [
            (81u8, 90u8, 240u8),
            (41, 240, 110),
            (126, 128, 128),
            (235, 128, 128),
        ];
        let mut bins = [0; 4];
        for (i, &(y, u, v)) in px.iter().enumerate() {
            f.y[i] = y;
            f.u[i / 2] = u;
            f.v[i / 2] = v;
            // 4:2:0: columns 2i and 2i+1 share chroma; test one pixel per chroma sample.
        }
        for (k, &(y, u, v)) in px.iter().enumerate() {
            let mut g = Frame::new(Size {
                width: 2,
                height: 2,
            });
            g.y.fill(y);
            g.u.fill(u);
            g.v.fill(v);
            bins[k] = t.bin(&g, 0, 0);
        }
        assert_ne!(bins[0], bins[1]);
        assert!(bins[0] < 32 && bins[1] < 32, "{bins:?}");
        assert!(
            bins[2] >= 32 && bins[3] >= 32 && bins[2] != bins[3],
            "{bins:?}"
        );
        let mut h = [0.0; MAX_BINS];
        t.histogram(&f, 2.0, 1.0, 4.0, 2.0, &mut h);
        assert!((h.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert!((bhattacharyya(&h, &h) - 1.0).abs() < 1e-5);
    }
}
