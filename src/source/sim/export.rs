//! Host-side writers for `stature sim`: the clip as Y4M (readable by
//! [`crate::source::y4m`]), the ground truth as JSON, and PNG snapshots
//! (optionally annotated with the truth).

use super::{ObjectTruth, SimSource};
use crate::frame::Frame;
use crate::source::{FrameSource, Next};
use serde::Serialize;
use std::io::{self, Write};

/// The Y4M stream header for a source's frames (4:2:0, progressive, square pixels).
pub fn y4m_header(src: &SimSource) -> String {
    let info = src.info();
    format!(
        "YUV4MPEG2 W{} H{} F{}:{} Ip A1:1 C420jpeg\n",
        info.size.width, info.size.height, info.fps.0, info.fps.1
    )
}

/// Writes one frame (`FRAME` line and the three planes).
pub fn write_y4m_frame(out: &mut dyn Write, frame: &Frame) -> io::Result<()> {
    out.write_all(b"FRAME\n")?;
    out.write_all(&frame.y)?;
    out.write_all(&frame.u)?;
    out.write_all(&frame.v)
}

#[derive(Serialize)]
struct FrameTruth<'a> {
    frame: u64,
    objects: &'a [ObjectTruth],
}

/// Renders the whole clip, writing the Y4M stream and/or the truth JSON
/// (`{"scene":..,"cast":[..],"frames":[{"frame":k,"objects":[..]},..]}`).
/// `progress` is called after every frame with its index.
pub fn export(
    src: &mut SimSource,
    mut y4m: Option<&mut dyn Write>,
    mut truth: Option<&mut dyn Write>,
    mut progress: impl FnMut(u64),
) -> io::Result<()> {
    let mut frame = Frame::new(src.info().size);
    if let Some(out) = y4m.as_deref_mut() {
        out.write_all(y4m_header(src).as_bytes())?;
    }
    if let Some(out) = truth.as_deref_mut() {
        out.write_all(b"{\"scene\":")?;
        serde_json::to_writer(&mut *out, src.scene_truth())?;
        out.write_all(b",\"cast\":")?;
        serde_json::to_writer(&mut *out, &src.cast())?;
        out.write_all(b",\"frames\":[\n")?;
    }
    src.seek(0);
    let mut first = true;
    loop {
        match src.next_frame(&mut frame) {
            Ok(Next::Frame) => {}
            Ok(_) => break,
            Err(e) => return Err(io::Error::other(e.to_string())),
        }
        if let Some(out) = y4m.as_deref_mut() {
            write_y4m_frame(out, &frame)?;
        }
        if let Some(out) = truth.as_deref_mut() {
            if !first {
                out.write_all(b",\n")?;
            }
            first = false;
            serde_json::to_writer(
                &mut *out,
                &FrameTruth {
                    frame: frame.index,
                    objects: src.truth(),
                },
            )?;
        }
        progress(frame.index);
    }
    if let Some(out) = truth {
        out.write_all(b"\n]}\n")?;
    }
    Ok(())
}

/// Converts a frame to 8-bit RGB (BT.601, limited range), `width*height*3` bytes.
pub fn to_rgb(frame: &Frame) -> Vec<u8> {
    let mut rgb = vec![0; frame.size().pixels() * 3];
    rgb_into(frame, &mut rgb);
    rgb
}

/// [`to_rgb`] into a caller-owned buffer of at least `width*height*3` bytes
/// (no allocation; the installer snapshot reuses one buffer).
pub fn rgb_into(frame: &Frame, rgb: &mut [u8]) {
    let size = frame.size();
    let cw = size.chroma().width;
    for (i, px) in rgb.chunks_exact_mut(3).take(size.pixels()).enumerate() {
        let (y, x) = (i / size.width, i % size.width);
        let l = 1.164 * (frame.y[i] as f64 - 16.0);
        let ci = (y / 2) * cw + x / 2;
        let (u, v) = (frame.u[ci] as f64 - 128.0, frame.v[ci] as f64 - 128.0);
        for (out, c) in px
            .iter_mut()
            .zip([l + 1.596 * v, l - 0.392 * u - 0.813 * v, l + 2.017 * u])
        {
            *out = c.round().clamp(0.0, 255.0) as u8;
        }
    }
}

/// Sets one pixel of an RGB image (ignored outside it).
type Plot = dyn FnMut(i64, i64, [u8; 3], &mut [u8]);

/// Draws the truth over an RGB image: boxes (green people, orange others), head-foot
/// segments, head and foot points, and the horizon (cyan) where it crosses the image.
pub fn annotate(rgb: &mut [u8], src: &SimSource) {
    let (w, h) = (src.spec().width, src.spec().height);
    let mut put = move |x: i64, y: i64, c: [u8; 3], rgb: &mut [u8]| {
        if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
            let i = (y as usize * w + x as usize) * 3;
            rgb[i..i + 3].copy_from_slice(&c);
        }
    };
    let line = |a: [f64; 2], b: [f64; 2], c: [u8; 3], rgb: &mut [u8], put: &mut Plot| {
        let n = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil() as usize).clamp(1, 100_000);
        for i in 0..=n {
            let t = i as f64 / n as f64;
            put(
                (a[0] + (b[0] - a[0]) * t).round() as i64,
                (a[1] + (b[1] - a[1]) * t).round() as i64,
                c,
                rgb,
            );
        }
    };
    let hz = src.scene_truth().horizon;
    if hz[1].abs() > 1e-9 {
        let v = |u: f64| -(hz[0] * u + hz[2]) / hz[1];
        line(
            [0.0, v(0.0)],
            [w as f64 - 1.0, v(w as f64 - 1.0)],
            [0, 220, 255],
            rgb,
            &mut put,
        );
    }
    for o in src.truth() {
        let c = if o.kind == super::people::Kind::Person {
            [40, 255, 40]
        } else {
            [255, 160, 0]
        };
        let [x0, y0, x1, y1] = o.bbox.map(|v| v as f64);
        for (a, b) in [
            ([x0, y0], [x1, y0]),
            ([x1, y0], [x1, y1]),
            ([x1, y1], [x0, y1]),
            ([x0, y1], [x0, y0]),
        ] {
            line(a, b, c, rgb, &mut put);
        }
        line(o.head_px, o.foot_px, [255, 255, 0], rgb, &mut put);
        for (p, col) in [(o.head_px, [255, 0, 0]), (o.foot_px, [0, 0, 255])] {
            for dy in -2..=2 {
                for dx in -2..=2 {
                    put(p[0].round() as i64 + dx, p[1].round() as i64 + dy, col, rgb);
                }
            }
        }
    }
}

/// Writes an RGB image as PNG.
pub fn write_png(out: impl Write, rgb: &[u8], width: usize, height: usize) -> io::Result<()> {
    let mut enc = png::Encoder::new(out, width as u32, height as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut wr = enc.write_header().map_err(io::Error::other)?;
    wr.write_image_data(rgb).map_err(io::Error::other)?;
    wr.finish().map_err(io::Error::other)
}
