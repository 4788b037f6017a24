//! Pixel-format conversions into 4:2:0 planes (chroma averaged, rounded).

use crate::frame::{Frame, Size};

/// Planar 4:2:2 (Y, then U and V at half width, full height) to 4:2:0.
pub fn planar422_to_420(src: &[u8], size: Size, out: &mut Frame) {
    let (w, h) = (size.width, size.height);
    let cw = w.div_ceil(2);
    out.y.copy_from_slice(&src[..w * h]);
    let (u, v) = src[w * h..].split_at(cw * h);
    for (plane, dst) in [(u, &mut out.u), (v, &mut out.v)] {
        for (cy, row) in dst.chunks_exact_mut(cw).enumerate() {
            let r0 = &plane[2 * cy * cw..][..cw];
            let r1 = &plane[(2 * cy + 1).min(h - 1) * cw..][..cw];
            for ((d, &a), &b) in row.iter_mut().zip(r0).zip(r1) {
                *d = ((u16::from(a) + u16::from(b) + 1) >> 1) as u8;
            }
        }
    }
}

/// Planar 4:4:4 to 4:2:0 (2x2 box average; edges replicate for odd sizes).
pub fn planar444_to_420(src: &[u8], size: Size, out: &mut Frame) {
    let n = size.pixels();
    out.y.copy_from_slice(&src[..n]);
    downsample_2x2(&src[n..2 * n], size, &mut out.u);
    downsample_2x2(&src[2 * n..3 * n], size, &mut out.v);
}

/// Luma only: chroma set to neutral grey.
pub fn grey_to_420(src: &[u8], size: Size, out: &mut Frame) {
    out.y.copy_from_slice(&src[..size.pixels()]);
    out.u.fill(128);
    out.v.fill(128);
}

/// 2x2 box average of a full-size plane into a 4:2:0 chroma plane.
pub fn downsample_2x2(plane: &[u8], size: Size, dst: &mut [u8]) {
    let (w, h) = (size.width, size.height);
    let cw = w.div_ceil(2);
    for (cy, row) in dst.chunks_exact_mut(cw).enumerate() {
        let y0 = 2 * cy;
        let y1 = (y0 + 1).min(h - 1);
        for (cx, d) in row.iter_mut().enumerate() {
            let x0 = 2 * cx;
            let x1 = (x0 + 1).min(w - 1);
            let s = u16::from(plane[y0 * w + x0])
                + u16::from(plane[y0 * w + x1])
                + u16::from(plane[y1 * w + x0])
                + u16::from(plane[y1 * w + x1]);
            *d = ((s + 2) >> 2) as u8;
        }
    }
}

/// Packed YUYV (Y0 U Y1 V per pixel pair) to 4:2:0; chroma of row pairs averaged.
/// `stride` is the distance between rows in bytes (at least `2 * width`).
pub fn yuyv_to_420(src: &[u8], stride: usize, size: Size, out: &mut Frame) {
    let (w, h) = (size.width, size.height);
    let cw = w.div_ceil(2);
    for y in 0..h {
        let row = &src[y * stride..][..2 * w];
        for (x, d) in out.y[y * w..][..w].iter_mut().enumerate() {
            *d = row[2 * x];
        }
    }
    for cy in 0..h.div_ceil(2) {
        let r0 = &src[2 * cy * stride..][..2 * w];
        let r1 = &src[(2 * cy + 1).min(h - 1) * stride..][..2 * w];
        for cx in 0..w / 2 {
            let i = 4 * cx;
            out.u[cy * cw + cx] = ((u16::from(r0[i + 1]) + u16::from(r1[i + 1]) + 1) >> 1) as u8;
            out.v[cy * cw + cx] = ((u16::from(r0[i + 3]) + u16::from(r1[i + 3]) + 1) >> 1) as u8;
        }
        if w % 2 == 1 {
            // Odd width: YUYV cannot carry the last chroma sample; repeat its neighbour.
            out.u[cy * cw + cw - 1] = out.u[cy * cw + cw.saturating_sub(2)];
            out.v[cy * cw + cw - 1] = out.v[cy * cw + cw.saturating_sub(2)];
        }
    }
}

/// NV12 (Y plane, then interleaved U,V at 4:2:0) to planar 4:2:0.
/// `stride` applies to both the luma rows and the chroma rows.
pub fn nv12_to_420(src: &[u8], stride: usize, size: Size, out: &mut Frame) {
    let (w, h) = (size.width, size.height);
    let c = size.chroma();
    for y in 0..h {
        out.y[y * w..][..w].copy_from_slice(&src[y * stride..][..w]);
    }
    let uv = &src[h * stride..];
    for cy in 0..c.height {
        let row = &uv[cy * stride..][..2 * c.width];
        for cx in 0..c.width {
            out.u[cy * c.width + cx] = row[2 * cx];
            out.v[cy * c.width + cx] = row[2 * cx + 1];
        }
    }
}

/// GREY (8-bit luma) with a row stride to 4:2:0.
pub fn grey_strided_to_420(src: &[u8], stride: usize, size: Size, out: &mut Frame) {
    let w = size.width;
    for y in 0..size.height {
        out.y[y * w..][..w].copy_from_slice(&src[y * stride..][..w]);
    }
    out.u.fill(128);
    out.v.fill(128);
}

/// Bytes a packed frame of `fourcc` needs at `stride` (`None` for unknown formats).
pub fn required_bytes(fourcc: &[u8; 4], stride: usize, size: Size) -> Option<usize> {
    match fourcc {
        b"YUYV" => Some(stride * (size.height - 1) + 2 * size.width),
        b"NV12" => {
            Some(stride * (size.height + size.height.div_ceil(2) - 1) + 2 * size.chroma().width)
        }
        b"GREY" => Some(stride * (size.height - 1) + size.width),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yuyv_fixed_pattern() {
        // 4x2 image: Y = 10,11,12,13 / 20,21,22,23; U row0 = 100,102, row1 = 110,112; V = 200.. similarly.
        let src = [
            10, 100, 11, 200, 12, 102, 13, 202, //
            20, 110, 21, 210, 22, 112, 23, 212,
        ];
        let size = Size {
            width: 4,
            height: 2,
        };
        let mut f = Frame::new(size);
        yuyv_to_420(&src, 8, size, &mut f);
        assert_eq!(f.y, [10, 11, 12, 13, 20, 21, 22, 23]);
        assert_eq!(f.u, [105, 107]);
        assert_eq!(f.v, [205, 207]);
    }

    #[test]
    fn nv12_fixed_pattern_with_stride() {
        let size = Size {
            width: 2,
            height: 2,
        };
        // stride 4: two padding bytes per row.
        let src = [1, 2, 0, 0, 3, 4, 0, 0, 77, 88, 0, 0];
        let mut f = Frame::new(size);
        nv12_to_420(&src, 4, size, &mut f);
        assert_eq!(f.y, [1, 2, 3, 4]);
        assert_eq!((f.u[0], f.v[0]), (77, 88));
        assert_eq!(required_bytes(b"NV12", 4, size), Some(10));
    }

    #[test]
    fn grey_gets_neutral_chroma() {
        let size = Size {
            width: 3,
            height: 1,
        };
        let mut f = Frame::new(size);
        f.u.fill(0);
        grey_strided_to_420(&[5, 6, 7, 9], 4, size, &mut f);
        assert_eq!(f.y, [5, 6, 7]);
        assert!(f.u.iter().chain(&f.v).all(|&c| c == 128));
    }

    #[test]
    fn planar422_averages_row_pairs() {
        let size = Size {
            width: 2,
            height: 2,
        };
        let src = [0, 0, 0, 0, /* U */ 10, 30, /* V */ 50, 71];
        let mut f = Frame::new(size);
        planar422_to_420(&src, size, &mut f);
        assert_eq!((f.u[0], f.v[0]), (20, 61));
    }
}
