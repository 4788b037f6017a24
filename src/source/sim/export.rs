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

/// The most image data one PNG `IDAT` chunk holds, bytes: what
/// [`write_png`] buffers of the compressed stream before writing it out.
/// 64 KiB keeps the chunks' own overhead (12 bytes each) under 0.02 %.
pub const PNG_CHUNK_BYTES: usize = 64 << 10;

/// Writes an RGB image as PNG, row by row: besides `rgb` it holds a few
/// rows, the compressor's state and one [`PNG_CHUNK_BYTES`] chunk (under
/// 1 MiB in all), where `Writer::write_image_data` held the whole
/// compressed image (up to the size of `rgb` again, twice that while its
/// buffer grows) until the end, which more than tripled what a large
/// installer snapshot costs on top of the frame.
pub fn write_png(out: impl Write, rgb: &[u8], width: usize, height: usize) -> io::Result<()> {
    if rgb.len() != width * height * 3 {
        return Err(io::Error::other(format!(
            "PNG of {width}x{height}: {} bytes of RGB, expected {}",
            rgb.len(),
            width * height * 3
        )));
    }
    // The png crate finishes the compressed stream when its stream writer
    // is dropped and discards an error writing its last bytes: the first
    // error is kept here and returned whatever the encoder says.
    let mut out = FirstError { out, error: None };
    let written = (|| {
        let mut enc = png::Encoder::new(&mut out, width as u32, height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header()?;
        let mut rows = wr.stream_writer_with_size(PNG_CHUNK_BYTES)?;
        for row in rgb.chunks_exact((width * 3).max(1)) {
            rows.write_all(row)?;
        }
        rows.finish()?;
        wr.finish()
    })();
    match (out.error, written) {
        (Some(e), _) => Err(e),
        (None, w) => w.map_err(io::Error::other),
    }
}

/// A writer that remembers its first error and refuses every write after
/// it, so that an error the caller of `out` ignores is still seen.
struct FirstError<W> {
    out: W,
    error: Option<io::Error>,
}

impl<W: Write> FirstError<W> {
    fn keep<T>(&mut self, r: io::Result<T>) -> io::Result<T> {
        r.map_err(|e| {
            // (`write_all` retries after an interrupted write: not an error.)
            if e.kind() == io::ErrorKind::Interrupted {
                return e;
            }
            let again = io::Error::new(e.kind(), e.to_string());
            self.error.get_or_insert(e);
            again
        })
    }

    fn failed(&self) -> Option<io::Error> {
        let e = self.error.as_ref()?;
        Some(io::Error::new(e.kind(), e.to_string()))
    }
}

impl<W: Write> Write for FirstError<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if let Some(e) = self.failed() {
            return Err(e);
        }
        let r = self.out.write(buf);
        self.keep(r)
    }

    fn flush(&mut self) -> io::Result<()> {
        if let Some(e) = self.failed() {
            return Err(e);
        }
        let r = self.out.flush();
        self.keep(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image that compresses badly (noise) or well (gradients).
    fn image(width: usize, height: usize, noisy: bool, seed: u64) -> Vec<u8> {
        let mut rng = super::super::math::Rng::new(seed);
        (0..width * height * 3)
            .map(|i| {
                if noisy {
                    (rng.next_u64() >> 56) as u8
                } else {
                    (i / 3 % width + i / (3 * width)) as u8
                }
            })
            .collect()
    }

    fn decode(png_bytes: &[u8]) -> (usize, usize, Vec<u8>) {
        let dec = png::Decoder::new(png_bytes);
        let mut reader = dec.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(info.color_type, png::ColorType::Rgb);
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        buf.truncate(info.buffer_size());
        (info.width as usize, info.height as usize, buf)
    }

    /// The lengths of the `IDAT` chunks of a PNG file.
    fn idat_lengths(png_bytes: &[u8]) -> Vec<usize> {
        let mut at = 8;
        let mut lengths = Vec::new();
        while at + 8 <= png_bytes.len() {
            let len = u32::from_be_bytes(png_bytes[at..at + 4].try_into().unwrap()) as usize;
            if &png_bytes[at + 4..at + 8] == b"IDAT" {
                lengths.push(len);
            }
            at += 12 + len;
        }
        lengths
    }

    #[test]
    fn png_decodes_to_the_pixels_written() {
        for (w, h) in [(1, 1), (37, 5), (5, 37), (300, 200)] {
            for noisy in [false, true] {
                let rgb = image(w, h, noisy, (w * h) as u64);
                let mut out = Vec::new();
                write_png(&mut out, &rgb, w, h).unwrap();
                assert_eq!(decode(&out), (w, h, rgb), "{w}x{h} noisy={noisy}");
            }
        }
        let e = write_png(Vec::new(), &[0; 11], 2, 2).unwrap_err();
        assert!(
            e.to_string().contains("11 bytes of RGB, expected 12"),
            "{e}"
        );
    }

    /// The compressed image goes out as it is made, one chunk at a time.
    /// Before, it was held whole and written as one `IDAT` chunk, which
    /// for a noisy 3584x3584 snapshot came to 115 MiB of peak memory on
    /// top of the 37 MiB image.
    #[test]
    fn png_is_streamed_in_bounded_chunks() {
        let (w, h) = (512, 512);
        let rgb = image(w, h, true, 7);
        let mut out = Vec::new();
        write_png(&mut out, &rgb, w, h).unwrap();
        let lengths = idat_lengths(&out);
        assert!(lengths.len() > 5, "{lengths:?}");
        assert!(lengths.iter().all(|&n| n <= PNG_CHUNK_BYTES), "{lengths:?}");
        assert_eq!(decode(&out), (w, h, rgb));
    }

    /// A writer that fails once, on the write that reaches byte `at`, and
    /// takes everything after it.
    struct FailOnce {
        at: usize,
        written: usize,
        failed: bool,
    }

    impl Write for FailOnce {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if !self.failed && self.written + buf.len() > self.at {
                self.failed = true;
                return Err(io::Error::other("disk full"));
            }
            self.written += buf.len();
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// A write error anywhere makes `write_png` fail, including in the
    /// last bytes of the compressed stream, which the png crate writes
    /// when its stream writer is dropped and whose error it discards.
    #[test]
    fn png_write_errors_are_never_lost() {
        let (w, h) = (64, 40);
        let rgb = image(w, h, true, 3);
        let mut whole = Vec::new();
        write_png(&mut whole, &rgb, w, h).unwrap();
        for at in 0..whole.len() {
            let mut out = FailOnce {
                at,
                written: 0,
                failed: false,
            };
            let r = write_png(&mut out, &rgb, w, h);
            assert!(out.failed, "{at}");
            let e = r.expect_err(&format!("failure at byte {at} of {}", whole.len()));
            assert!(e.to_string().contains("disk full"), "{at}: {e}");
        }
        // An interrupted write is retried, not an error.
        struct Interrupted(bool, Vec<u8>);
        impl Write for Interrupted {
            fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
                self.0 = !self.0;
                if self.0 {
                    return Err(io::ErrorKind::Interrupted.into());
                }
                self.1.extend_from_slice(buf);
                Ok(buf.len())
            }
            fn flush(&mut self) -> io::Result<()> {
                Ok(())
            }
        }
        let mut out = Interrupted(false, Vec::new());
        write_png(&mut out, &rgb, w, h).unwrap();
        assert_eq!(out.1, whole);
    }
}
