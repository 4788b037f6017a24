//! Configuration values (`f64`) into the unsigned Q-formats the per-pixel
//! code works in, through the `fixed` crate: round to nearest, saturate at
//! the format's range (a negative value is 0) instead of wrapping. Done
//! once at start-up; the per-pixel loops then see plain integers, which
//! is what their SIMD lanes are written for.
//!
//! Rounding is to the nearest with ties to even (`fixed`'s rule), so a
//! value exactly halfway between two steps may land one step below where
//! `f64::round` (ties away from zero) would put it.

use fixed::types::extra::{LeEqU32, U1, U16, U8};
use fixed::FixedU32;

/// `v` in unsigned Q(32−F).F, as its raw bits; NaN (refused by config
/// validation anyway) gives 0.
fn raw<F: LeEqU32>(v: f64) -> u32 {
    if v.is_nan() {
        0
    } else {
        FixedU32::<F>::saturating_from_num(v).to_bits()
    }
}

/// `v` in Q31.1 (halves).
pub fn q1(v: f64) -> u32 {
    raw::<U1>(v)
}

/// `v` in Q24.8 (1.0 = 256).
pub fn q8(v: f64) -> u32 {
    raw::<U8>(v)
}

/// `v` in Q16.16 (1.0 = 65536).
pub fn q16(v: f64) -> u32 {
    raw::<U16>(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_to_nearest_and_saturates() {
        assert_eq!(q8(0.58), 148); // 148.48
        assert_eq!(q8(0.65), 166); // 166.4
        assert_eq!(q16(0.002), 131); // 131.072
        assert_eq!(q16(0.9), 58982); // 58982.4
        assert_eq!(q1(7.3), 15); // 14.6
        assert_eq!(q8(-1.0), 0);
        assert_eq!(q8(f64::NAN), 0);
        assert_eq!(q16(1e12), u32::MAX);
        // Ties go to even, where `f64::round` goes up.
        assert_eq!(q8(1.5 / 256.0), 2);
        assert_eq!(q8(2.5 / 256.0), 2);
    }
}
