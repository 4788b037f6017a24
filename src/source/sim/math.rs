//! Platform-independent arithmetic for the simulator: a small PRNG, sine and
//! cosine from a fixed polynomial, and the projection the renderer uses.
//!
//! Everything that can change a pixel goes through these helpers, never
//! through the platform `libm` (whose last-ulp results differ between C
//! libraries), so a scene and seed give the same bytes everywhere. Only
//! `+ - * /` and `sqrt` are used (all correctly rounded in IEEE 754), and
//! never `mul_add`.

use crate::camera::Camera;

/// π, as used everywhere in the simulator.
pub const PI: f64 = core::f64::consts::PI;

/// SplitMix64: turns any 64-bit value into a well-mixed one (seeding, hashing).
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A 32-bit hash of integer lattice coordinates (texture cells, noise).
#[inline]
pub fn hash2(seed: u64, x: i64, y: i64) -> u32 {
    (mix64(seed ^ mix64((x as u64) ^ (y as u64).rotate_left(32))) >> 32) as u32
}

/// xoshiro256** generator, seeded through SplitMix64.
#[derive(Clone, Debug)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// A generator for `seed` (any value, including 0).
    pub fn new(seed: u64) -> Self {
        let mut z = seed;
        let mut s = [0u64; 4];
        for v in &mut s {
            z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
            *v = mix64(z);
        }
        Rng { s }
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let result = self.s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = self.s[1] << 17;
        self.s[2] ^= self.s[0];
        self.s[3] ^= self.s[1];
        self.s[1] ^= self.s[2];
        self.s[0] ^= self.s[3];
        self.s[2] ^= t;
        self.s[3] = self.s[3].rotate_left(45);
        result
    }

    /// Uniform in `[0, 1)`.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Uniform integer in `0..n` (`n > 0`).
    pub fn below(&mut self, n: u64) -> u64 {
        // The modulo bias is below 2^-40 for the small n used here.
        self.next_u64() % n.max(1)
    }

    /// True with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.uniform() < p
    }

    /// Approximately standard normal (Irwin–Hall sum of 12 uniforms, tails cut at ±6):
    /// no logarithm, so it is bit-identical on every platform.
    ///
    /// The sum is the one `s += uniform()` twelve times gives, bit for bit,
    /// computed on integers: each uniform is `k·2⁻⁵³` with `k < 2⁵³`, so
    /// every float partial sum is the exact integer sum rounded to 53
    /// significant bits, half to even, which `round_to_53_bits` does.
    /// Without a float unit (and under emulation, where each float
    /// operation is a library call) this is several times cheaper, and
    /// the noise table of a scene is one draw per pixel.
    pub fn normal(&mut self) -> f64 {
        // Units of 2⁻⁵³; twelve terms below 2⁵³ each stay below 2⁵⁷.
        let mut k: u64 = 0;
        for _ in 0..12 {
            k = round_to_53_bits(k + (self.next_u64() >> 11));
        }
        // `k` has at most 53 significant bits: the conversion is exact.
        k as f64 * (1.0 / (1u64 << 53) as f64) - 6.0
    }
}

/// `x` rounded to its 53 most significant bits, ties to even: what IEEE
/// double addition does to an exact sum of integers in the same units.
fn round_to_53_bits(x: u64) -> u64 {
    let bits = 64 - x.leading_zeros();
    if bits <= 53 {
        return x;
    }
    let shift = bits - 53;
    let (q, rem, half) = (x >> shift, x & ((1u64 << shift) - 1), 1u64 << (shift - 1));
    let q = if rem > half || (rem == half && q & 1 == 1) {
        q + 1
    } else {
        q
    };
    // q + 1 may carry into bit 54: a power of two, still exact.
    q << shift
}

/// Sine from range reduction and a degree-17 Taylor polynomial (|error| < 1e-13).
pub fn sin(x: f64) -> f64 {
    if !x.is_finite() {
        return 0.0;
    }
    let two_pi = 2.0 * PI;
    // Reduce to [-π, π].
    let mut r = x - two_pi * (x / two_pi).round();
    // Fold to [-π/2, π/2] with sin(π - r) = sin(r).
    if r > PI / 2.0 {
        r = PI - r;
    } else if r < -PI / 2.0 {
        r = -PI - r;
    }
    let r2 = r * r;
    // sin r = r - r³·q(r²) with q = 1/3! - r²/5! + r⁴/7! - ... - r¹⁴/17!, in Horner form.
    let mut q = 1.0 / 355_687_428_096_000.0; // 1/17!
    q = 1.0 / 1_307_674_368_000.0 - q * r2; // 1/15!
    q = 1.0 / 6_227_020_800.0 - q * r2; // 1/13!
    q = 1.0 / 39_916_800.0 - q * r2; // 1/11!
    q = 1.0 / 362_880.0 - q * r2; // 1/9!
    q = 1.0 / 5_040.0 - q * r2; // 1/7!
    q = 1.0 / 120.0 - q * r2; // 1/5!
    q = 1.0 / 6.0 - q * r2; // 1/3!
    r - r * r2 * q
}

/// Cosine, `sin(x + π/2)`.
pub fn cos(x: f64) -> f64 {
    sin(x + PI / 2.0)
}

/// Degrees to radians (plain multiplication, as `f64::to_radians`).
pub fn rad(deg: f64) -> f64 {
    deg * (PI / 180.0)
}

/// Smooth step from 0 at `e0` to 1 at `e1`.
pub fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The pinhole projection the renderer uses: the same model and
/// conventions as [`Camera`], with the rotation built from [`sin`]/[`cos`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proj {
    /// World-to-camera rotation, row-major.
    pub r: [[f64; 3]; 3],
    /// Focal length, pixels.
    pub f: f64,
    /// Principal point.
    pub pu: f64,
    /// Principal point.
    pub pv: f64,
    /// Camera height, metres.
    pub h: f64,
}

impl Proj {
    /// Builds the projection for `f` px, tilt and roll in degrees, height in metres, W×H pixels.
    pub fn new(f: f64, tilt_deg: f64, roll_deg: f64, height: f64, w: usize, h: usize) -> Self {
        let (st, ct) = (sin(rad(tilt_deg)), cos(rad(tilt_deg)));
        let (sr, cr) = (sin(rad(roll_deg)), cos(rad(roll_deg)));
        // rolled · pitched, as in `Camera::rotation`.
        let p = [[1.0, 0.0, 0.0], [0.0, -st, -ct], [0.0, ct, -st]];
        let q = [[cr, sr, 0.0], [-sr, cr, 0.0], [0.0, 0.0, 1.0]];
        let mut r = [[0.0; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = q[i][0] * p[0][j] + q[i][1] * p[1][j] + q[i][2] * p[2][j];
            }
        }
        Proj {
            r,
            f,
            pu: (w as f64 - 1.0) / 2.0,
            pv: (h as f64 - 1.0) / 2.0,
            h: height,
        }
    }

    /// The equivalent [`Camera`].
    pub fn camera(&self, tilt_deg: f64, roll_deg: f64) -> Camera {
        Camera {
            f: self.f,
            tilt: rad(tilt_deg),
            roll: rad(roll_deg),
            height: self.h,
            principal: [self.pu, self.pv],
        }
    }

    /// Camera-frame coordinates of a world point.
    #[inline]
    pub fn to_cam(&self, p: [f64; 3]) -> [f64; 3] {
        let (x, y, z) = (p[0], p[1], p[2] - self.h);
        let r = &self.r;
        [
            r[0][0] * x + r[0][1] * y + r[0][2] * z,
            r[1][0] * x + r[1][1] * y + r[1][2] * z,
            r[2][0] * x + r[2][1] * y + r[2][2] * z,
        ]
    }

    /// Pixel of a world point and its depth along the optical axis; `None` behind the camera.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> Option<([f64; 2], f64)> {
        let c = self.to_cam(p);
        (c[2] > 1e-6).then(|| {
            (
                [
                    self.pu + self.f * c[0] / c[2],
                    self.pv + self.f * c[1] / c[2],
                ],
                c[2],
            )
        })
    }

    /// World direction of the ray through pixel `(u, v)` (not normalised).
    #[inline]
    pub fn ray(&self, u: f64, v: f64) -> [f64; 3] {
        let (x, y, z) = (u - self.pu, v - self.pv, self.f);
        let r = &self.r;
        // Rᵀ · (x, y, z).
        [
            r[0][0] * x + r[1][0] * y + r[2][0] * z,
            r[0][1] * x + r[1][1] * y + r[2][1] * z,
            r[0][2] * x + r[1][2] * y + r[2][2] * z,
        ]
    }

    /// Ground point `(x, y)` seen at pixel `(u, v)`; `None` at or above the horizon.
    pub fn ground(&self, u: f64, v: f64) -> Option<[f64; 2]> {
        let d = self.ray(u, v);
        (d[2] < -1e-9).then(|| {
            let t = -self.h / d[2];
            [t * d[0], t * d[1]]
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_is_the_float_sum_bit_for_bit() {
        // The float form the integer one replaces.
        fn float_normal(r: &mut Rng) -> f64 {
            let mut s = 0.0;
            for _ in 0..12 {
                s += r.uniform();
            }
            s - 6.0
        }
        for seed in [0u64, 1, 42, u64::MAX] {
            let (mut a, mut b) = (Rng::new(seed), Rng::new(seed));
            for i in 0..200_000 {
                let (x, y) = (a.normal(), float_normal(&mut b));
                assert_eq!(x.to_bits(), y.to_bits(), "seed {seed} draw {i}: {x} vs {y}");
            }
        }
        // Ties and carries: exact sums just past 2⁵³ units.
        let two53 = 1u64 << 53;
        for k in [
            two53,
            two53 + 1,
            two53 + 2,
            two53 + 3,
            (two53 << 3) - 1,
            (two53 << 3) + 12,
        ] {
            // The conversion rounds by the same IEEE rule; the rounded
            // value converts exactly.
            assert_eq!(
                (round_to_53_bits(k) as f64).to_bits(),
                (k as f64).to_bits(),
                "{k}"
            );
        }
    }

    // The reference is deliberately the platform's own sine and cosine (at
    // 1e-12 their last-ulp differences between C libraries do not matter).
    #[allow(clippy::disallowed_methods)]
    #[test]
    fn sine_matches_std_closely() {
        let mut x = -20.0;
        while x < 20.0 {
            assert!((sin(x) - x.sin()).abs() < 1e-12, "sin {x}");
            assert!((cos(x) - x.cos()).abs() < 1e-12, "cos {x}");
            x += 0.0137;
        }
    }

    #[test]
    fn projection_agrees_with_camera() {
        let p = Proj::new(700.0, 23.0, -4.0, 4.5, 640, 480);
        let c = p.camera(23.0, -4.0);
        for w in [[1.0, 8.0, 0.0], [-3.0, 20.0, 1.7], [0.5, 5.0, 2.0]] {
            let (a, _) = p.project(w).unwrap();
            let b = c.project(w).unwrap();
            assert!((a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9);
            let g = p.ground(a[0], a[1]);
            if w[2] == 0.0 {
                let g = g.unwrap();
                assert!((g[0] - w[0]).abs() < 1e-9 && (g[1] - w[1]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn rng_is_reproducible_and_normal_has_unit_spread() {
        let mut a = Rng::new(7);
        let mut b = Rng::new(7);
        let mut c = Rng::new(8);
        let (mut same, mut s, mut s2) = (true, 0.0, 0.0);
        for _ in 0..20_000 {
            same &= a.next_u64() == b.next_u64();
            let n = c.normal();
            s += n;
            s2 += n * n;
        }
        assert!(same);
        let mean = s / 20_000.0;
        let sd = (s2 / 20_000.0 - mean * mean).sqrt();
        assert!(mean.abs() < 0.03 && (sd - 1.0).abs() < 0.03, "{mean} {sd}");
    }
}
