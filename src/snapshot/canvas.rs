//! The RGB image a snapshot is drawn on: one buffer allocated when the
//! snapshot is set up, filled from a [`Frame`] and drawn on through
//! `embedded-graphics`' [`DrawTarget`] (lines, circles, rectangles, text).
//!
//! `embedded-graphics` rasterises every point of a primitive, inside the
//! image or not, so lines toward a vanishing point thousands of pixels away
//! are clipped to the image here first ([`clip`]), in floating point.

use crate::frame::{Frame, Size};
use crate::source::sim::export;
use core::convert::Infallible;
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{
    DrawTarget, OriginDimensions, Pixel, Point, Primitive, RgbColor, Size as EgSize,
};
use embedded_graphics::primitives::{Line, PrimitiveStyle, Rectangle};
use embedded_graphics::Drawable;
use std::io::{self, Write};

/// An 8-bit RGB image, row-major, `width × height × 3` bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Canvas {
    size: Size,
    rgb: Vec<u8>,
}

impl Canvas {
    /// A black image of `size` (the only allocation).
    pub fn new(size: Size) -> Self {
        Canvas {
            size,
            rgb: vec![0; size.pixels() * 3],
        }
    }

    /// Image size.
    pub fn size(&self) -> Size {
        self.size
    }

    /// The pixels, `[r, g, b]` per pixel, row-major.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    /// Replaces the image by `frame` converted to RGB (BT.601, as
    /// `stature sim --png` does). A frame of another size re-sizes the
    /// canvas first (which allocates; a run's frames all have one size).
    pub fn load(&mut self, frame: &Frame) {
        if frame.size() != self.size {
            *self = Canvas::new(frame.size());
        }
        export::rgb_into(frame, &mut self.rgb);
    }

    /// The colour at `(x, y)`, `None` outside the image.
    pub fn pixel(&self, x: i64, y: i64) -> Option<[u8; 3]> {
        let i = self.index(x, y)?;
        Some([self.rgb[i], self.rgb[i + 1], self.rgb[i + 2]])
    }

    fn index(&self, x: i64, y: i64) -> Option<usize> {
        let inside = x >= 0 && y >= 0 && (x as usize) < self.size.width;
        (inside && (y as usize) < self.size.height)
            .then(|| (y as usize * self.size.width + x as usize) * 3)
    }

    /// Darkens `area` to `keep`/256 of its brightness (a backdrop that keeps
    /// the scene visible under text).
    pub fn dim(&mut self, area: Rectangle, keep: u16) {
        let Some(br) = area.bottom_right() else {
            return;
        };
        for y in area.top_left.y.max(0)..=br.y {
            for x in area.top_left.x.max(0)..=br.x {
                let Some(i) = self.index(i64::from(x), i64::from(y)) else {
                    continue;
                };
                for c in &mut self.rgb[i..i + 3] {
                    *c = ((u16::from(*c) * keep) >> 8) as u8;
                }
            }
        }
    }

    /// Writes the image as PNG.
    pub fn write_png(&self, out: impl Write) -> io::Result<()> {
        export::write_png(out, &self.rgb, self.size.width, self.size.height)
    }

    /// Draws the segment `a`–`b` (pixel coordinates, any distance away)
    /// clipped to the image, `width` pixels wide, solid or dashed
    /// (`dash` = (on, off) lengths in pixels).
    pub fn segment(
        &mut self,
        a: [f64; 2],
        b: [f64; 2],
        colour: Rgb888,
        width: u32,
        dash: Option<(f64, f64)>,
    ) {
        let Some((a, b)) = clip(a, b, self.size) else {
            return;
        };
        let style = PrimitiveStyle::with_stroke(colour, width);
        let len = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt();
        let at = |t: f64| {
            let t = if len > 0.0 { (t / len).min(1.0) } else { 0.0 };
            point([a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t])
        };
        // Drawing on a canvas cannot fail (`Infallible`).
        match dash {
            None => {
                let _ = Line::new(point(a), point(b)).into_styled(style).draw(self);
            }
            Some((on, off)) => {
                let mut t = 0.0;
                while t < len {
                    let _ = Line::new(at(t), at(t + on)).into_styled(style).draw(self);
                    t += on + off;
                }
            }
        }
    }
}

/// Nearest integer pixel (coordinates are already clipped to the image).
pub fn point(p: [f64; 2]) -> Point {
    Point::new(p[0].round() as i32, p[1].round() as i32)
}

/// The part of segment `a`–`b` inside the image (Liang–Barsky against the
/// pixel centres' box), `None` when it misses the image or a coordinate is
/// not finite.
pub fn clip(a: [f64; 2], b: [f64; 2], size: Size) -> Option<([f64; 2], [f64; 2])> {
    if !a.iter().chain(b.iter()).all(|v| v.is_finite()) {
        return None;
    }
    let max = [size.width as f64 - 1.0, size.height as f64 - 1.0];
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..2 {
        // a + t d must satisfy 0 <= x_k <= max_k.
        for (p, q) in [(-d[k], a[k]), (d[k], max[k] - a[k])] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    t0 = t0.max(r);
                } else {
                    t1 = t1.min(r);
                }
            }
        }
    }
    (t0 <= t1).then(|| {
        let at = |t: f64| [a[0] + d[0] * t, a[1] + d[1] * t];
        (at(t0), at(t1))
    })
}

impl OriginDimensions for Canvas {
    fn size(&self) -> EgSize {
        EgSize::new(self.size.width as u32, self.size.height as u32)
    }
}

impl DrawTarget for Canvas {
    type Color = Rgb888;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<Rgb888>>,
    {
        for Pixel(p, c) in pixels {
            if let Some(i) = self.index(i64::from(p.x), i64::from(p.y)) {
                self.rgb[i..i + 3].copy_from_slice(&[c.r(), c.g(), c.b()]);
            }
        }
        Ok(())
    }
}
