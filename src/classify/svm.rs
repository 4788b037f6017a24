//! The linear SVM and its preloaded weight blob.
//!
//! `score = scale · Σ w_i·x_i + bias`, with `w_i` signed 8-bit weights and
//! `x_i` the `u8` features. The sum is exact in `i32`: at most
//! `dim · 255 · 128`, and [`MAX_DIM`] keeps that below 2^31.
//!
//! # Blob format, version 2 (all integers little-endian)
//!
//! | offset | bytes | field |
//! | ---: | ---: | --- |
//! | 0 | 8 | magic `STATSVM\0` |
//! | 8 | 2 | format version (2) |
//! | 10 | 2 | reserved, 0 |
//! | 12 | 4 | total blob length in bytes, checksum included |
//! | 16 | 2 | window width, px |
//! | 18 | 2 | window height, px |
//! | 20 | 2 | margin, Q8 of box height per side |
//! | 22 | 1 | HOG cell, px |
//! | 23 | 1 | HOG bins (9) |
//! | 24 | 1 | LBP cell, px |
//! | 25 | 1 | LBP bins (59) |
//! | 26 | 1 | LBP threshold, grey levels |
//! | 27 | 1 | fit: 0 = contain, 1 = height ([`Fit`]) |
//! | 28 | 1 | box-shape bins (0 or 8) |
//! | 29 | 1 | flags: bit 0 coarse HOG ([`Layout::hog_coarse`]), bit 1 square-root HOG ([`Layout::hog_sqrt`]), bit 2 foreground fill ([`Layout::mask_fill`]), others 0 |
//! | 30 | 1 | weight type: 1 = i8 |
//! | 31 | 1 | reserved, 0 |
//! | 32 | 4 | feature code version ([`FEATURE_VERSION`]) |
//! | 36 | 8 | feature layout hash ([`Layout::hash`]) |
//! | 44 | 4 | dimension |
//! | 48 | 4 | scale, f32 |
//! | 52 | 4 | bias, f32 |
//! | 56 | 2 | HOG blocks in the grid |
//! | 58 | 2 | LBP cells in the grid |
//! | 60 | ⌈blocks/8⌉ + ⌈cells/8⌉ | selection bitmaps (bit i%8 of byte i/8) |
//! | … | dimension | weights, i8 |
//! | end − 4 | 4 | CRC-32 (IEEE) of every byte before it |
//!
//! Version 1 (no fit and box-shape fields, feature code version 2) is
//! refused: its weights belong to features this build no longer computes.

use super::layout::{pack_bits, unpack_bits, Fit, Layout, FEATURE_VERSION, HOG_BINS, LBP_BINS};
use core::fmt;

/// First bytes of every weight blob.
pub const MAGIC: [u8; 8] = *b"STATSVM\0";
/// The blob format this build reads and writes.
pub const FORMAT_VERSION: u16 = 2;
/// Fixed header length before the selection bitmaps.
pub const HEADER_LEN: usize = 60;
/// Largest dimension accepted: keeps `dim · 255 · 128 < 2^31`.
pub const MAX_DIM: usize = 65_000;
/// Weight type code for signed 8-bit weights.
pub const WEIGHT_I8: u8 = 1;
/// The largest blob the format can describe: the header, both selection
/// bitmaps at their `u16` grid counts, [`MAX_DIM`] weights and the CRC
/// (about 80 KB; the shipped weights are a few KB).
pub const MAX_VALID_BLOB_BYTES: usize =
    HEADER_LEN + 2 * (u16::MAX as usize).div_ceil(8) + MAX_DIM + 4;
/// The largest file read as a weight blob: [`MAX_VALID_BLOB_BYTES`] with
/// room for a later format version, far below a mistyped path's video or
/// `/dev/zero`, which are refused after this many bytes.
pub const MAX_BLOB_BYTES: u64 = 256 << 10;

/// Why a weight blob was refused.
#[derive(Clone, Debug, PartialEq)]
pub enum WeightsError {
    /// Fewer bytes than the format needs.
    Truncated {
        /// Bytes needed at least.
        need: usize,
        /// Bytes present.
        got: usize,
    },
    /// Not a stature weight blob.
    BadMagic,
    /// A format version this build cannot read.
    UnsupportedVersion(u16),
    /// More bytes than the header declares.
    TrailingBytes {
        /// Declared length.
        declared: usize,
        /// Bytes present.
        got: usize,
    },
    /// The checksum does not match: the file is corrupt.
    Checksum {
        /// CRC stored in the blob.
        stored: u32,
        /// CRC of the bytes read.
        computed: u32,
    },
    /// Window or cell parameters this build does not support.
    Layout(String),
    /// Trained with a different feature code version.
    FeatureVersion {
        /// In the blob.
        blob: u32,
        /// In this build.
        build: u32,
    },
    /// The layout hash does not match the layout the header describes.
    LayoutHash {
        /// In the blob.
        stored: u64,
        /// Recomputed here.
        computed: u64,
    },
    /// The dimension does not match the layout.
    Dimension {
        /// In the blob.
        stored: usize,
        /// Implied by the layout.
        layout: usize,
    },
    /// Unknown weight type code.
    WeightType(u8),
    /// Scale or bias is not a finite number (or the scale is not positive).
    BadNumber(&'static str),
}

impl fmt::Display for WeightsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WeightsError::Truncated { need, got } => {
                write!(f, "truncated: {got} bytes, at least {need} needed")
            }
            WeightsError::BadMagic => write!(f, "not a stature weight blob (bad magic)"),
            WeightsError::UnsupportedVersion(v) => write!(
                f,
                "format version {v} is not supported (this build reads version {FORMAT_VERSION}; retrain with `stature train`)"
            ),
            WeightsError::TrailingBytes { declared, got } => {
                write!(f, "{got} bytes where the header declares {declared}")
            }
            WeightsError::Checksum { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:08x}, computed {computed:08x}): the blob is corrupt"
            ),
            WeightsError::Layout(s) => write!(f, "unsupported feature layout: {s}"),
            WeightsError::FeatureVersion { blob, build } => write!(
                f,
                "trained for feature code version {blob}, this build computes version {build}"
            ),
            WeightsError::LayoutHash { stored, computed } => write!(
                f,
                "feature layout hash mismatch (stored {stored:016x}, header implies {computed:016x})"
            ),
            WeightsError::Dimension { stored, layout } => write!(
                f,
                "dimension {stored} does not match the layout's {layout} features"
            ),
            WeightsError::WeightType(t) => write!(f, "unknown weight type {t}"),
            WeightsError::BadNumber(what) => write!(f, "{what} is not a usable number"),
        }
    }
}
impl std::error::Error for WeightsError {}

/// A quantised linear SVM over one feature layout.
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// The features it expects.
    pub layout: Layout,
    /// One weight per feature.
    pub weights: Vec<i8>,
    /// Score units per unit of the integer dot product.
    pub scale: f32,
    /// Score offset.
    pub bias: f32,
}

fn le16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn le32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

impl Model {
    /// Quantises float weights (`score = w·(x/255) + bias`) to i8 with one
    /// scale: the largest |w| maps to 127. `w.len()` must equal `layout.dim()`.
    pub fn quantise(layout: Layout, w: &[f32], bias: f32) -> Model {
        let max = w.iter().fold(0f32, |m, v| m.max(v.abs())).max(1e-12);
        let q = 127.0 / max;
        Model {
            weights: w
                .iter()
                .map(|v| (v * q).round().clamp(-127.0, 127.0) as i8)
                .collect(),
            scale: 1.0 / (q * 255.0),
            bias,
            layout,
        }
    }

    /// The integer dot product `Σ w_i·x_i` (exact; see the module doc).
    #[inline]
    pub fn dot(&self, x: &[u8]) -> i32 {
        // Chunks of 16 let the compiler use 16-bit multiplies with 32-bit
        // pairwise sums; |16 · 255 · 127| < 2^16 · 8, no overflow per chunk.
        let mut acc = 0i32;
        let mut wc = self.weights.chunks_exact(16);
        let mut xc = x.chunks_exact(16);
        for (w, x) in (&mut wc).zip(&mut xc) {
            let mut s = 0i32;
            for k in 0..16 {
                s += i32::from(w[k]) * i32::from(x[k]);
            }
            acc += s;
        }
        for (w, x) in wc.remainder().iter().zip(xc.remainder()) {
            acc += i32::from(*w) * i32::from(*x);
        }
        acc
    }

    /// The SVM score of a feature vector (positive: single person).
    pub fn score(&self, x: &[u8]) -> f32 {
        self.scale * self.dot(x) as f32 + self.bias
    }

    /// Serialises to the blob format (module doc).
    pub fn to_bytes(&self) -> Vec<u8> {
        let l = &self.layout;
        let mut b = Vec::with_capacity(HEADER_LEN + 64 + self.weights.len());
        b.extend_from_slice(&MAGIC);
        b.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        b.extend_from_slice(&0u16.to_le_bytes());
        b.extend_from_slice(&0u32.to_le_bytes()); // length, patched below
        l.extend_window_fields(&mut b);
        b.push(WEIGHT_I8);
        b.push(0);
        b.extend_from_slice(&FEATURE_VERSION.to_le_bytes());
        b.extend_from_slice(&l.hash().to_le_bytes());
        b.extend_from_slice(&(self.weights.len() as u32).to_le_bytes());
        b.extend_from_slice(&self.scale.to_le_bytes());
        b.extend_from_slice(&self.bias.to_le_bytes());
        b.extend_from_slice(&(l.hog_blocks.len() as u16).to_le_bytes());
        b.extend_from_slice(&(l.lbp_cells.len() as u16).to_le_bytes());
        b.extend_from_slice(&pack_bits(&l.hog_blocks));
        b.extend_from_slice(&pack_bits(&l.lbp_cells));
        b.extend(self.weights.iter().map(|&w| w as u8));
        let total = (b.len() + 4) as u32;
        b[12..16].copy_from_slice(&total.to_le_bytes());
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    }

    /// Parses and checks a blob; every failure is a [`WeightsError`].
    pub fn from_bytes(b: &[u8]) -> Result<Model, WeightsError> {
        let need = HEADER_LEN + 4;
        if b.len() < 8 || b[..8] != MAGIC {
            return if b.len() < 8 && MAGIC.starts_with(b) {
                Err(WeightsError::Truncated { need, got: b.len() })
            } else {
                Err(WeightsError::BadMagic)
            };
        }
        if b.len() < need {
            return Err(WeightsError::Truncated { need, got: b.len() });
        }
        let version = le16(b, 8);
        if version != FORMAT_VERSION {
            return Err(WeightsError::UnsupportedVersion(version));
        }
        let declared = le32(b, 12) as usize;
        if b.len() < declared || declared < need {
            return Err(WeightsError::Truncated {
                need: declared.max(need),
                got: b.len(),
            });
        }
        if b.len() > declared {
            return Err(WeightsError::TrailingBytes {
                declared,
                got: b.len(),
            });
        }
        let body = &b[..declared - 4];
        let stored = le32(b, declared - 4);
        let computed = crc32fast::hash(body);
        if stored != computed {
            return Err(WeightsError::Checksum { stored, computed });
        }
        if b[23] as usize != HOG_BINS || b[25] as usize != LBP_BINS {
            return Err(WeightsError::Layout(format!(
                "{} HOG bins and {} LBP bins (this build: {HOG_BINS} and {LBP_BINS})",
                b[23], b[25]
            )));
        }
        if b[30] != WEIGHT_I8 {
            return Err(WeightsError::WeightType(b[30]));
        }
        let fv = le32(b, 32);
        if fv != FEATURE_VERSION {
            return Err(WeightsError::FeatureVersion {
                blob: fv,
                build: FEATURE_VERSION,
            });
        }
        let mut layout = Layout::full(le16(b, 16), le16(b, 18), le16(b, 20), b[22], b[24], b[26])
            .map_err(|e| WeightsError::Layout(e.0))?;
        layout.fit = Fit::from_code(b[27])
            .ok_or_else(|| WeightsError::Layout(format!("unknown fit code {}", b[27])))?;
        layout.aspect_bins = b[28];
        if b[29] & !7 != 0 {
            return Err(WeightsError::Layout(format!(
                "unknown layout flags {:#04x}",
                b[29]
            )));
        }
        layout.hog_coarse = b[29] & 1 != 0;
        layout.hog_sqrt = b[29] & 2 != 0;
        layout.mask_fill = b[29] & 4 != 0;
        let (nb, nc) = (le16(b, 56) as usize, le16(b, 58) as usize);
        if nb != layout.hog_block_count() || nc != layout.lbp_cell_count() {
            return Err(WeightsError::Layout(format!(
                "{nb} HOG blocks and {nc} LBP cells, the window implies {} and {}",
                layout.hog_block_count(),
                layout.lbp_cell_count()
            )));
        }
        let (sb, sc) = (nb.div_ceil(8), nc.div_ceil(8));
        let dim = le32(b, 44) as usize;
        let weights_at = HEADER_LEN + sb + sc;
        if body.len() < weights_at {
            return Err(WeightsError::Truncated {
                need: weights_at + 4,
                got: b.len(),
            });
        }
        layout.hog_blocks = unpack_bits(&b[HEADER_LEN..HEADER_LEN + sb], nb);
        layout.lbp_cells = unpack_bits(&b[HEADER_LEN + sb..weights_at], nc);
        let computed = layout.hash();
        let stored = u64::from_le_bytes(b[36..44].try_into().unwrap_or([0; 8]));
        if stored != computed {
            return Err(WeightsError::LayoutHash { stored, computed });
        }
        layout.validate().map_err(|e| WeightsError::Layout(e.0))?;
        if dim != layout.dim() || dim > MAX_DIM {
            return Err(WeightsError::Dimension {
                stored: dim,
                layout: layout.dim(),
            });
        }
        if body.len() != weights_at + dim {
            return Err(WeightsError::Dimension {
                stored: body.len().saturating_sub(weights_at),
                layout: dim,
            });
        }
        let scale = f32::from_le_bytes(b[48..52].try_into().unwrap_or([0; 4]));
        let bias = f32::from_le_bytes(b[52..56].try_into().unwrap_or([0; 4]));
        if !(scale.is_finite() && scale > 0.0) {
            return Err(WeightsError::BadNumber("scale"));
        }
        if !bias.is_finite() {
            return Err(WeightsError::BadNumber("bias"));
        }
        Ok(Model {
            layout,
            weights: body[weights_at..].iter().map(|&v| v as i8).collect(),
            scale,
            bias,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Model {
        let l = Layout::default_layout();
        let w: Vec<f32> = (0..l.dim())
            .map(|i| ((i * 37 % 101) as f32 - 50.0) / 50.0)
            .collect();
        Model::quantise(l, &w, -0.25)
    }

    #[test]
    fn the_read_cap_holds_any_valid_blob() {
        assert!((MAX_VALID_BLOB_BYTES as u64) < MAX_BLOB_BYTES);
        assert!(model().to_bytes().len() <= MAX_VALID_BLOB_BYTES);
    }

    #[test]
    fn round_trip() {
        let m = model();
        let b = m.to_bytes();
        assert_eq!(Model::from_bytes(&b).unwrap(), m);
    }

    #[test]
    fn the_committed_blob_reserialises_byte_for_byte() {
        // Pins the blob format: the writer must produce exactly what the
        // trainer committed (weights/classifier.bin).
        let blob = crate::classify::BUILTIN_WEIGHTS;
        assert!(Model::from_bytes(blob).unwrap().to_bytes() == blob);
    }

    #[test]
    fn every_truncation_is_refused() {
        let b = model().to_bytes();
        for n in 0..b.len() {
            assert!(Model::from_bytes(&b[..n]).is_err(), "{n} bytes accepted");
        }
    }

    #[test]
    fn every_single_bit_flip_is_refused() {
        let b = model().to_bytes();
        for i in 0..b.len() {
            let mut c = b.clone();
            c[i] ^= 0x10;
            assert!(Model::from_bytes(&c).is_err(), "flip at {i} accepted");
        }
    }

    #[test]
    fn dot_matches_float() {
        let m = model();
        let x: Vec<u8> = (0..m.weights.len()).map(|i| (i * 13 % 256) as u8).collect();
        let exact: i64 = m
            .weights
            .iter()
            .zip(&x)
            .map(|(&w, &v)| i64::from(w) * i64::from(v))
            .sum();
        assert_eq!(i64::from(m.dot(&x)), exact);
    }
}
