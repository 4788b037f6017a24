//! Frames as planar Y, U, V (chroma 4:2:0), owned once and refilled in place.

/// Width and height of a frame in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
}

impl Size {
    /// Chroma plane size at 4:2:0 (rounded up for odd sizes).
    pub fn chroma(self) -> Size {
        Size {
            width: self.width.div_ceil(2),
            height: self.height.div_ceil(2),
        }
    }
    /// Number of luma pixels.
    pub fn pixels(self) -> usize {
        self.width * self.height
    }
}

/// A borrowed 8-bit image plane, rows `stride` bytes apart.
#[derive(Clone, Copy, Debug)]
pub struct Plane<'a> {
    /// Pixel bytes; `data.len() >= (height - 1) * stride + width`.
    pub data: &'a [u8],
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Distance between the starts of two rows, in bytes.
    pub stride: usize,
}

impl<'a> Plane<'a> {
    /// A tightly packed plane; `None` when `data` is too short.
    pub fn new(data: &'a [u8], width: usize, height: usize) -> Option<Self> {
        (data.len() >= width * height).then_some(Plane {
            data,
            width,
            height,
            stride: width,
        })
    }
    /// One row of pixels. Panics only if `y >= height` (a caller bug).
    #[inline]
    pub fn row(&self, y: usize) -> &'a [u8] {
        &self.data[y * self.stride..y * self.stride + self.width]
    }
    /// One pixel, `None` outside the plane.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> Option<u8> {
        (x < self.width && y < self.height).then(|| self.data[y * self.stride + x])
    }
}

/// One frame: three tightly packed planes allocated once at start-up.
#[derive(Clone, Debug)]
pub struct Frame {
    size: Size,
    /// Luma, `width * height` bytes.
    pub y: Vec<u8>,
    /// Cb at 4:2:0.
    pub u: Vec<u8>,
    /// Cr at 4:2:0.
    pub v: Vec<u8>,
    /// 0-based index of the frame in its stream.
    pub index: u64,
}

impl Frame {
    /// Allocates a black frame of the given size (the only allocation a
    /// frame ever makes).
    pub fn new(size: Size) -> Self {
        let c = size.chroma();
        Frame {
            size,
            y: vec![16; size.pixels()],
            u: vec![128; c.pixels()],
            v: vec![128; c.pixels()],
            index: 0,
        }
    }
    /// Frame size.
    pub fn size(&self) -> Size {
        self.size
    }
    /// Luma plane view.
    pub fn luma(&self) -> Plane<'_> {
        Plane {
            data: &self.y,
            width: self.size.width,
            height: self.size.height,
            stride: self.size.width,
        }
    }
    /// Cb plane view (4:2:0).
    pub fn cb(&self) -> Plane<'_> {
        let c = self.size.chroma();
        Plane {
            data: &self.u,
            width: c.width,
            height: c.height,
            stride: c.width,
        }
    }
    /// Cr plane view (4:2:0).
    pub fn cr(&self) -> Plane<'_> {
        let c = self.size.chroma();
        Plane {
            data: &self.v,
            width: c.width,
            height: c.height,
            stride: c.width,
        }
    }
}
