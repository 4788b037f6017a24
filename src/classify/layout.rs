//! The feature layout: window size, cell sizes, block selection, and the
//! order in which features appear in the vector the SVM sees.
//!
//! # Feature vector (feature code version 3)
//!
//! A region's box is resampled to a `win_w`×`win_h` window (see
//! [`super::window`]; [`Layout::fit`] says how a box wider than the window
//! is handled). The vector is, in this order:
//!
//! 1. **HOG**: the window is cut into square cells of `hog_cell` pixels
//!    (`win_w / hog_cell` columns, `win_h / hog_cell` rows). Blocks are 2×2
//!    cells stepping one cell, numbered row-major. For every *selected*
//!    block, in block order: its cells top-left, top-right, bottom-left,
//!    bottom-right, each [`HOG_BINS`] unsigned orientation bins (bin `k`
//!    centred on `20°·k + 10°`, angle measured from +x toward +y, i.e. image
//!    down), block-normalised (see [`super::hog`]).
//! 2. **Coarse HOG** (when [`Layout::hog_coarse`]): the same cells
//!    summed 2×2 into cells twice the side, and every 2×2 block of those,
//!    normalised alike: a coarser view of the silhouette that tolerates
//!    pose and alignment the fine blocks do not.
//! 3. **LBP**: the window is cut into square cells of `lbp_cell` pixels,
//!    row-major. For every *selected* cell: [`LBP_BINS`] bins, the 58
//!    uniform 8-neighbour patterns in ascending code order, then one bin for
//!    all non-uniform patterns (see [`super::lbp`]).
//! 4. **Box shape** (when [`Layout::aspect_bins`] is not 0): the region
//!    box's width/height ratio, soft-binned over [`ASPECT_CENTRES_Q8`] (see
//!    [`super::window::aspect_features`]): the window hides how wide the
//!    box was, and a linear SVM can then learn that a box twice as wide as
//!    tall is no single person.
//! 5. **Foreground fill** (when [`Layout::mask_fill`]): the detector's
//!    cleaned foreground mask sampled over the same window (nearest pixel),
//!    cut into [`MASK_CELL`]-pixel cells row-major, each the share of its
//!    pixels that are foreground; then one feature that is 255 when a mask
//!    was given and 0 when not (still crops have no mask: their fill
//!    features are 0 and this one lets the bias tell them apart). The
//!    window shows texture; the fill shows the silhouette, which separates
//!    two people in one box (background between them) and a dog's body
//!    from a person's legs where gradients alone do not.
//!
//! Every feature is a `u8`, 255 meaning 1.0 of its normalised scale.
//! [`Layout::hash`] fingerprints all of this (plus [`FEATURE_VERSION`]) so a
//! weight blob trained for another layout is refused.

use core::fmt;

/// Orientation bins per HOG cell (unsigned gradients, 0°..180°).
pub const HOG_BINS: usize = 9;
/// Values per 2×2-cell HOG block.
pub const BLOCK_DIM: usize = 4 * HOG_BINS;
/// Bins per LBP cell: 58 uniform patterns plus one catch-all bin.
pub const LBP_BINS: usize = 59;
/// Bumped whenever feature arithmetic changes in a way the layout
/// parameters do not show (it feeds [`Layout::hash`]).
pub const FEATURE_VERSION: u32 = 3;
/// Centres of the box-shape bins, width/height in Q8 (0.22, 0.30, 0.40,
/// 0.52, 0.68, 0.90, 1.20, 1.60): people are 0.2–0.6, side-by-side groups
/// and fragments 0.5–1.6, cars 1.8 and more.
pub const ASPECT_CENTRES_Q8: [u32; 8] = [56, 77, 102, 133, 174, 230, 307, 410];
/// Side of the foreground-fill cells, window pixels (4 measured better
/// than 8 on the held-out sets: `bench/RESULTS.md`).
pub const MASK_CELL: usize = 4;

/// How a region box becomes the window.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fit {
    /// The whole box (plus margin) fits inside the window: a box wider
    /// than the window's aspect widens the window, so a wide region is
    /// shrunk whole.
    Contain,
    /// The window height always follows the box height (plus margin); a
    /// wider box is cropped at the sides, so a person striding sideways
    /// keeps the scale of one walking toward the camera.
    Height,
}

impl Fit {
    /// Code in the blob header.
    pub fn code(self) -> u8 {
        match self {
            Fit::Contain => 0,
            Fit::Height => 1,
        }
    }
    /// From a blob header code.
    pub fn from_code(c: u8) -> Option<Fit> {
        match c {
            0 => Some(Fit::Contain),
            1 => Some(Fit::Height),
            _ => None,
        }
    }
}
/// Largest window side accepted, in pixels (bounds every scratch buffer and
/// the Q formats in [`super::hog`]).
pub const MAX_WINDOW_SIDE: u16 = 256;

/// A layout parameter outside what this build supports.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LayoutError(pub String);

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// The window geometry and feature layout a model was trained for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Window width, pixels.
    pub win_w: u16,
    /// Window height, pixels.
    pub win_h: u16,
    /// Margin added above and below the region box, in 1/256 of the box
    /// height (e.g. 43 ≈ 1/6: the person fills ~3/4 of the window height).
    pub margin_q8: u16,
    /// HOG cell side, pixels (divides both window sides).
    pub hog_cell: u8,
    /// LBP cell side, pixels (divides both window sides).
    pub lbp_cell: u8,
    /// LBP comparison offset: a neighbour sets its bit when it is at least
    /// this many grey levels brighter than the centre... or equal when 0
    /// (a small offset keeps codec noise on flat areas out of the codes).
    pub lbp_threshold: u8,
    /// How the box maps to the window.
    pub fit: Fit,
    /// Box-shape features: 0 (none) or `ASPECT_CENTRES_Q8.len()`.
    pub aspect_bins: u8,
    /// Coarse HOG: the cells summed 2×2 into cells of `2·hog_cell` px,
    /// and every 2×2 block of those (needs an even number of cells a side,
    /// at least 4).
    pub hog_coarse: bool,
    /// Square-root compression of the normalised HOG values, fine and
    /// coarse blocks (see [`super::hog`]; off in the shipped layout: it
    /// measured no gain, `bench/RESULTS.md`).
    pub hog_sqrt: bool,
    /// Foreground-fill features from the detector's mask (needs both
    /// window sides divisible by [`MASK_CELL`]).
    pub mask_fill: bool,

    /// One flag per HOG block (row-major): computed and fed to the SVM.
    pub hog_blocks: Vec<bool>,
    /// One flag per LBP cell (row-major).
    pub lbp_cells: Vec<bool>,
}

impl Layout {
    /// A layout with every block and cell selected, checked.
    pub fn full(
        win_w: u16,
        win_h: u16,
        margin_q8: u16,
        hog_cell: u8,
        lbp_cell: u8,
        lbp_threshold: u8,
    ) -> Result<Self, LayoutError> {
        let mut l = Layout {
            win_w,
            win_h,
            margin_q8,
            hog_cell,
            lbp_cell,
            lbp_threshold,
            fit: Fit::Contain,
            aspect_bins: 0,
            hog_coarse: false,
            hog_sqrt: false,
            mask_fill: false,
            hog_blocks: Vec::new(),
            lbp_cells: Vec::new(),
        };
        l.check_geometry()?;
        l.hog_blocks = vec![true; l.hog_block_count()];
        l.lbp_cells = vec![true; l.lbp_cell_count()];
        Ok(l)
    }

    /// The layout the shipped weights use: 32×64 window fitted to the box
    /// height with a margin of 32/256, 4-px HOG cells plus coarse blocks,
    /// 8-px LBP cells, box-shape features (chosen from the measurements in
    /// `bench/RESULTS.md`).
    pub fn default_layout() -> Self {
        // The parameters are constants inside the supported ranges.
        let mut l = Layout::full(32, 64, 32, 4, 8, 2).unwrap_or_else(|_| unreachable!());
        l.fit = Fit::Height;
        l.aspect_bins = ASPECT_CENTRES_Q8.len() as u8;
        l.hog_coarse = true;
        l
    }

    fn check_geometry(&self) -> Result<(), LayoutError> {
        let side_ok = |s: u16| (8..=MAX_WINDOW_SIDE).contains(&s);
        if !side_ok(self.win_w) || !side_ok(self.win_h) {
            return Err(LayoutError(format!(
                "window {}x{} outside 8..={MAX_WINDOW_SIDE} pixels a side",
                self.win_w, self.win_h
            )));
        }
        for (name, c) in [("HOG", self.hog_cell), ("LBP", self.lbp_cell)] {
            if !(2..=32).contains(&c)
                || self.win_w % u16::from(c) != 0
                || self.win_h % u16::from(c) != 0
            {
                return Err(LayoutError(format!(
                    "{name} cell {c} px does not tile the {}x{} window (2..=32 px, dividing both sides)",
                    self.win_w, self.win_h
                )));
            }
        }
        if self.win_w / u16::from(self.hog_cell) < 2 || self.win_h / u16::from(self.hog_cell) < 2 {
            return Err(LayoutError("fewer than 2x2 HOG cells".into()));
        }
        if self.aspect_bins != 0 && usize::from(self.aspect_bins) != ASPECT_CENTRES_Q8.len() {
            return Err(LayoutError(format!(
                "{} box-shape bins (this build: 0 or {})",
                self.aspect_bins,
                ASPECT_CENTRES_Q8.len()
            )));
        }
        let (cx, cy) = self.hog_cells();
        if self.hog_coarse && (cx % 2 != 0 || cy % 2 != 0 || cx < 4 || cy < 4) {
            return Err(LayoutError(format!(
                "coarse HOG needs an even number of cells a side, at least 4 ({cx}x{cy})"
            )));
        }
        let cell = MASK_CELL as u16;
        if self.mask_fill && (self.win_w % cell != 0 || self.win_h % cell != 0) {
            return Err(LayoutError(format!(
                "foreground fill needs window sides divisible by {MASK_CELL} ({}x{})",
                self.win_w, self.win_h
            )));
        }
        if self.margin_q8 > 256 {
            return Err(LayoutError(format!(
                "margin {}/256 of the box height exceeds 1",
                self.margin_q8
            )));
        }
        Ok(())
    }

    /// Checks the parameters and that the selections have the right length.
    pub fn validate(&self) -> Result<(), LayoutError> {
        self.check_geometry()?;
        if self.hog_blocks.len() != self.hog_block_count()
            || self.lbp_cells.len() != self.lbp_cell_count()
        {
            return Err(LayoutError(
                "block selection does not match the grid".into(),
            ));
        }
        if self.hog_dim() + self.coarse_dim() + self.lbp_dim() == 0 {
            return Err(LayoutError("no block or cell selected".into()));
        }
        Ok(())
    }

    /// HOG cell columns and rows.
    pub fn hog_cells(&self) -> (usize, usize) {
        let c = usize::from(self.hog_cell);
        (usize::from(self.win_w) / c, usize::from(self.win_h) / c)
    }
    /// HOG block columns and rows (2×2 cells, stride one cell).
    pub fn hog_block_grid(&self) -> (usize, usize) {
        let (cx, cy) = self.hog_cells();
        (cx - 1, cy - 1)
    }
    /// Number of HOG blocks in the grid (selected or not).
    pub fn hog_block_count(&self) -> usize {
        let (bx, by) = self.hog_block_grid();
        bx * by
    }
    /// LBP cell columns and rows.
    pub fn lbp_grid(&self) -> (usize, usize) {
        let c = usize::from(self.lbp_cell);
        (usize::from(self.win_w) / c, usize::from(self.win_h) / c)
    }
    /// Number of LBP cells in the grid (selected or not).
    pub fn lbp_cell_count(&self) -> usize {
        let (cx, cy) = self.lbp_grid();
        cx * cy
    }
    /// Selected HOG blocks.
    pub fn selected_blocks(&self) -> usize {
        self.hog_blocks.iter().filter(|&&b| b).count()
    }
    /// Selected LBP cells.
    pub fn selected_lbp_cells(&self) -> usize {
        self.lbp_cells.iter().filter(|&&b| b).count()
    }
    /// Length of the (fine) HOG part of the vector.
    pub fn hog_dim(&self) -> usize {
        self.selected_blocks() * BLOCK_DIM
    }
    /// Coarse HOG blocks (see [`Layout::hog_coarse`]).
    pub fn coarse_blocks(&self) -> usize {
        if !self.hog_coarse {
            return 0;
        }
        let (cx, cy) = self.hog_cells();
        (cx / 2 - 1) * (cy / 2 - 1)
    }
    /// Length of the coarse HOG part of the vector.
    pub fn coarse_dim(&self) -> usize {
        self.coarse_blocks() * BLOCK_DIM
    }
    /// Length of the LBP part of the vector.
    pub fn lbp_dim(&self) -> usize {
        self.selected_lbp_cells() * LBP_BINS
    }
    /// Foreground-fill cells (columns, rows); (0, 0) when off.
    pub fn mask_grid(&self) -> (usize, usize) {
        if !self.mask_fill {
            return (0, 0);
        }
        (
            usize::from(self.win_w) / MASK_CELL,
            usize::from(self.win_h) / MASK_CELL,
        )
    }
    /// Length of the foreground-fill part of the vector (cells plus the
    /// "mask given" feature).
    pub fn mask_dim(&self) -> usize {
        let (cx, cy) = self.mask_grid();
        if self.mask_fill {
            cx * cy + 1
        } else {
            0
        }
    }
    /// Flags byte of the header: bit 0 coarse HOG, bit 1 square-root HOG,
    /// bit 2 foreground fill (the other bits are 0).
    pub fn flags(&self) -> u8 {
        u8::from(self.hog_coarse) | u8::from(self.hog_sqrt) << 1 | u8::from(self.mask_fill) << 2
    }
    /// Feature vector length.
    pub fn dim(&self) -> usize {
        self.hog_dim()
            + self.coarse_dim()
            + self.lbp_dim()
            + usize::from(self.aspect_bins)
            + self.mask_dim()
    }

    /// Canonical bytes that define the layout (what [`Layout::hash`] hashes
    /// and what the weight blob stores after its header).
    pub fn canonical_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(32 + (self.hog_blocks.len() + self.lbp_cells.len()) / 8);
        b.extend_from_slice(&FEATURE_VERSION.to_le_bytes());
        self.extend_window_fields(&mut b);
        b.extend_from_slice(&pack_bits(&self.hog_blocks));
        b.extend_from_slice(&pack_bits(&self.lbp_cells));
        b
    }

    /// Window size, margin, cell sizes, bin counts, LBP threshold, fit,
    /// box-shape bins and the coarse flags, little endian (14 bytes):
    /// part of the canonical bytes and of the weight blob's header.
    pub fn extend_window_fields(&self, b: &mut Vec<u8>) {
        b.extend_from_slice(&self.win_w.to_le_bytes());
        b.extend_from_slice(&self.win_h.to_le_bytes());
        b.extend_from_slice(&self.margin_q8.to_le_bytes());
        b.extend_from_slice(&[
            self.hog_cell,
            HOG_BINS as u8,
            self.lbp_cell,
            LBP_BINS as u8,
            self.lbp_threshold,
            self.fit.code(),
            self.aspect_bins,
            self.flags(),
        ]);
    }

    /// One line for reports: sizes, selection, dimension and hash.
    pub fn describe(&self) -> String {
        format!(
            "window {}x{} ({:?} fit), margin {}/256, HOG cell {} ({} of {} blocks, {} coarse), LBP cell {} ({} of {} cells, threshold {}), {} box-shape bins{}{}, dim {}, layout hash {:016x}",
            self.win_w,
            self.win_h,
            self.fit,
            self.margin_q8,
            self.hog_cell,
            self.selected_blocks(),
            self.hog_block_count(),
            self.coarse_blocks(),
            self.lbp_cell,
            self.selected_lbp_cells(),
            self.lbp_cell_count(),
            self.lbp_threshold,
            self.aspect_bins,
            if self.hog_sqrt { ", square-root HOG" } else { "" },
            if self.mask_fill { ", foreground fill" } else { "" },
            self.dim(),
            self.hash()
        )
    }

    /// FNV-1a (64-bit) of [`Layout::canonical_bytes`].
    pub fn hash(&self) -> u64 {
        fnv1a64(&self.canonical_bytes())
    }
}

/// Packs flags into bytes, bit `i % 8` of byte `i / 8`.
pub fn pack_bits(flags: &[bool]) -> Vec<u8> {
    let mut out = vec![0u8; flags.len().div_ceil(8)];
    for (i, &f) in flags.iter().enumerate() {
        if f {
            out[i / 8] |= 1 << (i % 8);
        }
    }
    out
}

/// Unpacks `n` flags packed by [`pack_bits`].
pub fn unpack_bits(bytes: &[u8], n: usize) -> Vec<bool> {
    (0..n)
        .map(|i| bytes.get(i / 8).is_some_and(|b| b & (1 << (i % 8)) != 0))
        .collect()
}

/// FNV-1a, 64-bit: a stable fingerprint (not a defence against tampering;
/// the blob's CRC-32 catches corruption).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_layout_dimensions() {
        let l = Layout::default_layout();
        assert_eq!(l.hog_cells(), (8, 16));
        assert_eq!(l.hog_block_count(), 7 * 15);
        assert_eq!(l.lbp_cell_count(), 4 * 8);
        assert_eq!(l.coarse_blocks(), 3 * 7);
        assert_eq!(l.dim(), 105 * 36 + 21 * 36 + 32 * 59 + 8);
        l.validate().unwrap();
    }

    #[test]
    fn unsupported_options_are_refused() {
        let mut l = Layout::default_layout();
        l.aspect_bins = 5;
        assert!(l.validate().is_err());
        // 24x48 with 4-px cells: 6x12 cells, coarse needs an even count...
        let mut l = Layout::full(24, 48, 32, 4, 8, 2).unwrap();
        l.hog_coarse = true;
        assert!(l.validate().is_ok());
        // ...which 20x40 (5x10 cells) does not have.
        let mut l = Layout::full(20, 40, 32, 4, 4, 2).unwrap();
        l.hog_coarse = true;
        assert!(l.validate().is_err());
        assert!(Fit::from_code(2).is_none());
        assert_eq!(Fit::from_code(Fit::Height.code()), Some(Fit::Height));
    }

    #[test]
    fn bad_geometry_is_refused() {
        assert!(Layout::full(30, 64, 43, 4, 8, 2).is_err());
        assert!(Layout::full(32, 64, 43, 4, 7, 2).is_err());
        assert!(Layout::full(32, 64, 300, 4, 8, 2).is_err());
        assert!(Layout::full(4, 64, 43, 4, 8, 2).is_err());
    }

    #[test]
    fn hash_sees_selection_changes() {
        let a = Layout::default_layout();
        let mut b = a.clone();
        b.hog_blocks[3] = false;
        assert_ne!(a.hash(), b.hash());
        for change in [
            |l: &mut Layout| l.fit = Fit::Contain,
            |l: &mut Layout| l.aspect_bins = 0,
            |l: &mut Layout| l.hog_coarse = false,
            |l: &mut Layout| l.hog_sqrt = true,
            |l: &mut Layout| l.mask_fill = true,
        ] {
            let mut c = a.clone();
            change(&mut c);
            assert_ne!(a.hash(), c.hash());
        }
        assert_eq!(
            unpack_bits(&pack_bits(&b.hog_blocks), b.hog_blocks.len()),
            b.hog_blocks
        );
    }
}
