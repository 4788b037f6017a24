//! Deep shadows peeled off the bottom of the foreground.
//!
//! The luma shadow test calls a pixel shadow when it is darker than the
//! background by a ratio in `[shadow_min_ratio, shadow_max_ratio]`. The core
//! of a direct-sun shadow is darker than that near the feet (real umbrae are
//! 0.3–0.6 of the lit ground), so it stays foreground, joined to the feet:
//! the region's bottom rows and its foot point move into the shadow, toward
//! the camera and sideways with the sun (on the simulated plaza, mid and busy
//! scenes the region boxes of isolated walkers reach 1.5–4.8 px beyond the
//! truth on the shadow's side, which turns the calibration's roll). A single
//! pixel cannot tell that core from grey trousers: both are darker than the
//! paving with its chroma. The column can: trousers have shins and shoes
//! under them, a shadow on the ground has only more ground — or more shadow.
//!
//! So, bottom-up in every column: a foreground pixel with no foreground
//! under it (after this pass) is dropped when it is *deep shadow* — darker
//! than the background's heaviest mode by a ratio in `[lo, hi)` and without
//! a chroma change. The first pixel of any other kind (a shoe, a skin tone,
//! a coloured garment, something brighter) stops the peel in that column,
//! and everything above it stays. One pass over the mask words finds the
//! bottom ends; only those pixels, and the ones a peel uncovers, are tested.
//!
//! On by default at 0.58 (`detect.deep_shadow_min_ratio`; 0 turns it off):
//! measured, it improves roll, heights and box fit on the simulated runs
//! and heights on PETS, for +0.28 instructions per pixel at 1280×720
//! (bench/RESULTS.md, "Deep shadows peeled off the feet").

use super::background::Background;
use super::morphology::BitMask;
use crate::frame::Plane;

/// The deep-shadow luma ratio bounds, Q8.8 (`x·256` against `ratio·μ`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DeepShadow {
    /// Darkest deep shadow: `x ≥ lo·μ`.
    pub lo_q8: u32,
    /// Lightest: `x < hi·μ`.
    pub hi_q8: u32,
}

impl DeepShadow {
    /// From ratios in `(0, 1]`; `None` when `lo` is 0 (the pass is off).
    pub fn new(lo: f64, hi: f64) -> Option<Self> {
        (lo > 0.0).then(|| DeepShadow {
            lo_q8: crate::qformat::q8(lo),
            hi_q8: crate::qformat::q8(hi),
        })
    }

    /// Whether luma `x` over a background mean `mu` is in the deep-shadow
    /// band. `x·256 ≤ 65280` and `hi·μ ≤ 256·255`: every product fits `u32`.
    pub fn is_deep(&self, x: u8, mu: u8) -> bool {
        let (xs, m) = (u32::from(x) << 8, u32::from(mu));
        m > 0 && xs >= self.lo_q8 * m && xs < self.hi_q8 * m
    }
}

/// Peels deep-shadow pixels off the bottom of every column of `mask` (see
/// the module notes). `chroma_changed` marks the pixels whose chroma left
/// the background's (an empty mask: luma only). Returns how many pixels it
/// cleared.
pub fn peel(
    mask: &mut BitMask,
    luma: &Plane<'_>,
    background: &Background,
    chroma_changed: &BitMask,
    band: DeepShadow,
) -> u32 {
    let (h, wpr) = (mask.height(), mask.words_per_row());
    let changed = chroma_changed.words();
    let words = mask.words_mut();
    let mut cleared = 0;
    // Bottom row first: a row's ends depend on the row under it as peeled.
    for y in (0..h).rev() {
        let luma_row = luma.row(y);
        let (upto, under) = words.split_at_mut((y + 1) * wpr);
        let row = &mut upto[y * wpr..];
        let below = under.get(..wpr);
        let changed_row = &changed[y * wpr..(y + 1) * wpr];
        for (i, (word, &chroma)) in row.iter_mut().zip(changed_row).enumerate() {
            let mut ends = *word & !below.map_or(0, |b| b[i]) & !chroma;
            // Most words hold no foreground, or only pixels with foreground
            // under them.
            while ends != 0 {
                let bit = ends.trailing_zeros() as usize;
                ends &= ends - 1;
                let x = i * 64 + bit;
                if band.is_deep(luma_row[x], background.background_mean(x, y)) {
                    *word &= !(1u64 << bit);
                    cleared += 1;
                }
            }
        }
    }
    cleared
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::DetectConfig;
    use crate::frame::{Frame, Size};

    fn frame(w: usize, h: usize, y: Vec<u8>) -> Frame {
        let mut f = Frame::new(Size {
            width: w,
            height: h,
        });
        f.y = y;
        f
    }

    /// A 64×40 grey background (level 160) learnt for 60 frames, then one
    /// frame with `paint` applied; the raw foreground is everything painted.
    fn scene(paint: impl Fn(usize, usize) -> Option<u8>) -> (Background, Frame, BitMask) {
        let (w, h) = (64, 40);
        let cfg = DetectConfig::default();
        let mut bg = Background::new(&cfg, w, h);
        let mut mask = BitMask::new(w, h);
        let mut shadow = BitMask::new(w, h);
        let wpr = mask.words_per_row();
        let flat = frame(w, h, vec![160; w * h]);
        for _ in 0..60 {
            bg.apply(&flat, mask.words_mut(), shadow.words_mut(), wpr);
        }
        let mut y_plane = vec![160u8; w * h];
        let mut fg = BitMask::new(w, h);
        for y in 0..h {
            for x in 0..w {
                if let Some(v) = paint(x, y) {
                    y_plane[y * w + x] = v;
                    fg.set(x, y, true);
                }
            }
        }
        (bg, frame(w, h, y_plane), fg)
    }

    fn band() -> DeepShadow {
        DeepShadow::new(0.35, 0.95).unwrap()
    }

    #[test]
    fn a_shadow_under_the_shoes_goes_and_the_legs_stay() {
        // Legs (level 90, ratio 0.56: as dark as the shadow) in columns
        // 20..24 rows 5..30, black shoes (20) in rows 30..32, a shadow (90)
        // under and beside the shoes in rows 32..38, columns 18..40.
        let (bg, frame, mut fg) = scene(|x, y| match (x, y) {
            (20..=23, 5..=29) => Some(90),
            (20..=23, 30..=31) => Some(20),
            (18..=39, 32..=37) => Some(90),
            (24..=39, 28..=31) => Some(90),
            _ => None,
        });
        let none = BitMask::new(64, 40);
        let n = peel(&mut fg, &frame.luma(), &bg, &none, band());
        assert_eq!(n, 22 * 6 + 16 * 4);
        for y in 5..32 {
            for x in 20..24 {
                assert!(fg.get(x, y), "body pixel ({x}, {y}) lost");
            }
        }
        assert!((18..40).all(|x| (32..38).all(|y| !fg.get(x, y))));
        assert!((24..40).all(|x| (28..32).all(|y| !fg.get(x, y))));
    }

    #[test]
    fn a_chroma_change_or_a_bright_pixel_stops_the_peel() {
        // Column 10: deep-shadow grey all the way down. Column 11: the same
        // with a chroma change in its lowest pixel. Column 12: the same with
        // a brighter lowest pixel.
        let (bg, frame, mut fg) = scene(|x, y| match (x, y) {
            (10..=12, 10..=19) => Some(if x == 12 && y == 19 { 230 } else { 90 }),
            _ => None,
        });
        let mut chroma = BitMask::new(64, 40);
        chroma.set(11, 19, true);
        let n = peel(&mut fg, &frame.luma(), &bg, &chroma, band());
        assert_eq!(n, 10);
        assert!((10..20).all(|y| !fg.get(10, y)));
        assert!((10..20).all(|y| fg.get(11, y) && fg.get(12, y)));
    }

    #[test]
    fn the_ratio_is_off_or_darker_than_the_shadow_test() {
        let with = |r| DetectConfig {
            deep_shadow_min_ratio: r,
            ..DetectConfig::default()
        };
        assert!(with(0.0).validate().is_ok());
        assert!(with(0.58).validate().is_ok());
        assert!(with(0.7).validate().is_err(), "above shadow_min_ratio 0.65");
        assert!(with(0.05).validate().is_err());
    }

    #[test]
    fn the_band_is_half_open_and_needs_a_background() {
        let b = DeepShadow::new(0.5, 0.75).unwrap();
        assert!(b.is_deep(50, 100));
        assert!(!b.is_deep(49, 100));
        assert!(b.is_deep(74, 100));
        assert!(!b.is_deep(75, 100));
        assert!(!b.is_deep(0, 0));
        assert!(DeepShadow::new(0.0, 0.9).is_none());
    }
}
