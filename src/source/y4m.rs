//! YUV4MPEG2 (Y4M) reader: 8-bit 4:2:0, 4:2:2, 4:4:4 and mono streams.
//!
//! The stream header is `YUV4MPEG2` followed by space-separated tags
//! (`W`, `H`, `F`, `I`, `A`, `C`, `X…`) and a newline; each frame is `FRAME`
//! (with optional tags) and a newline, then the planes. Frames are turned
//! into 4:2:0 planes on the way in; every buffer is allocated at open.

use super::{convert, FrameSource, Next, SourceError, SourceInfo};
use crate::frame::{Frame, Size};
use std::io::{self, BufRead, BufReader, Read};
use std::os::fd::AsFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// Longest header or frame-header line accepted, in bytes.
const MAX_LINE: usize = 4096;
/// Largest frame dimension accepted (keeps buffer sizes sane on bad input).
const MAX_DIM: usize = 16384;
/// Frame rates accepted from the `F` tag, frames per second. Track ages,
/// status cadence and the state-file interval are counted in stream time,
/// so a rate far outside what a camera records (`F4294967295:1` would mean
/// no status record ever; `F1:4294967295` one per frame) is a broken header.
const FPS_RANGE: (f64, f64) = (0.1, 1000.0);
/// Assumed when the header has no `F` tag (the rate of PAL and most
/// surveillance recordings); logged at open.
pub const DEFAULT_FPS: (u32, u32) = (25, 1);

/// Chroma layout of the stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chroma {
    /// 4:2:0 (any siting: `420jpeg`, `420mpeg2`, `420paldv`, `420`).
    C420,
    /// 4:2:2, chroma half width, full height.
    C422,
    /// 4:4:4, chroma full size.
    C444,
    /// Luma only.
    Mono,
}

impl Chroma {
    fn parse(tag: &str) -> Option<Chroma> {
        Some(match tag {
            "420" | "420jpeg" | "420mpeg2" | "420paldv" => Chroma::C420,
            "422" => Chroma::C422,
            "444" => Chroma::C444,
            "mono" => Chroma::Mono,
            _ => return None,
        })
    }
    /// Bytes of one frame's payload in this layout.
    pub fn frame_bytes(self, size: Size) -> usize {
        let luma = size.pixels();
        match self {
            Chroma::C420 => luma + 2 * size.chroma().pixels(),
            Chroma::C422 => luma + 2 * size.width.div_ceil(2) * size.height,
            Chroma::C444 => 3 * luma,
            Chroma::Mono => luma,
        }
    }
}

/// A parsed stream header.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// Frame size.
    pub size: Size,
    /// Frame rate (numerator, denominator); (0, 0) when absent.
    pub fps: (u32, u32),
    /// Chroma layout.
    pub chroma: Chroma,
    /// Interlacing tag as written (`p`, `t`, `b`, `m`, `?`), if any.
    pub interlace: Option<char>,
}

impl Header {
    /// Parses the header line (without its newline).
    pub fn parse(line: &[u8]) -> Result<Header, String> {
        let text =
            std::str::from_utf8(line).map_err(|_| "header is not text (UTF-8)".to_string())?;
        // Otherwise the last tag carries the `\r` and is refused under a
        // name that looks valid (`C420jpeg`).
        if text.ends_with('\r') {
            return Err("header line ends with CR LF; Y4M lines end with LF alone".into());
        }
        let mut parts = text.split(' ').filter(|p| !p.is_empty());
        if parts.next() != Some("YUV4MPEG2") {
            return Err("missing YUV4MPEG2 signature".into());
        }
        let (mut w, mut h, mut fps, mut chroma, mut interlace) =
            (None, None, (0, 0), Chroma::C420, None);
        let mut seen = String::new();
        for tag in parts {
            // The key is one character; not always one byte (`X` tags may carry UTF-8).
            let (key, val) = tag.split_at(tag.chars().next().map_or(0, char::len_utf8));
            // Two `W` (or `F`, `C`...) tags leave the frame layout to
            // whichever the reader happens to keep; `X` may repeat.
            if key != "X" {
                if seen.contains(key) {
                    return Err(format!("header tag `{key}` given twice"));
                }
                seen.push_str(key);
            }
            match key {
                "W" => w = Some(parse_dim(val, "width")?),
                "H" => h = Some(parse_dim(val, "height")?),
                "F" => {
                    fps = parse_ratio(val)
                        .filter(|&(n, d)| {
                            let rate = f64::from(n) / f64::from(d);
                            d > 0 && (FPS_RANGE.0..=FPS_RANGE.1).contains(&rate)
                        })
                        .ok_or_else(|| {
                            format!(
                                "bad frame rate tag `F{val}` (expected N:D, a rate of {} to {} fps)",
                                FPS_RANGE.0, FPS_RANGE.1
                            )
                        })?
                }
                "A" => {
                    parse_ratio(val).ok_or_else(|| format!("bad aspect tag `A{val}`"))?;
                }
                "I" => {
                    let c = val.chars().next().filter(|c| "ptbm?".contains(*c) && val.len() == 1);
                    interlace = Some(c.ok_or_else(|| format!("bad interlace tag `I{val}`"))?);
                }
                "C" => {
                    chroma = Chroma::parse(val).ok_or_else(|| {
                        format!("unsupported colour space `C{val}` (supported: 420jpeg, 420mpeg2, 420paldv, 420, 422, 444, mono; 8-bit only)")
                    })?
                }
                "X" => {}
                _ => return Err(format!("unknown header tag `{tag}`")),
            }
        }
        let size = Size {
            width: w.ok_or("header has no width (W)")?,
            height: h.ok_or("header has no height (H)")?,
        };
        Ok(Header {
            size,
            fps,
            chroma,
            interlace,
        })
    }
}

fn parse_dim(val: &str, what: &str) -> Result<usize, String> {
    match val.parse::<usize>() {
        Ok(n) if (2..=MAX_DIM).contains(&n) => Ok(n),
        _ => Err(format!("bad {what} `{val}` (expected 2..={MAX_DIM})")),
    }
}

fn parse_ratio(val: &str) -> Option<(u32, u32)> {
    let (n, d) = val.split_once(':')?;
    Some((n.parse().ok()?, d.parse().ok()?))
}

/// How often a quiet pipe is checked for a stop request.
const STOP_POLL: Duration = Duration::from_millis(100);

/// A pipe (or terminal, FIFO, socket) read that gives up when `stop` is
/// set, instead of blocking until the writer sends a byte. A stop signal
/// delivered to this thread interrupts `poll` (never restarted), so it is
/// seen at once; the timeout covers a signal that lands on another thread
/// (the report thread) and a flag set by other code.
struct StopOnSignal<R> {
    inner: R,
    stop: Arc<AtomicBool>,
}

impl<R: Read + AsFd> Read for StopOnSignal<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        use rustix::event::{poll, PollFd, PollFlags, Timespec};
        let timeout = Timespec {
            tv_sec: 0,
            tv_nsec: STOP_POLL.as_nanos() as _,
        };
        loop {
            if self.stop.load(Ordering::Relaxed) {
                // Not `Interrupted`: `read_until` and `read_exact` retry that.
                return Err(io::ErrorKind::TimedOut.into());
            }
            let mut fds = [PollFd::new(&self.inner, PollFlags::IN)];
            match poll(&mut fds, Some(&timeout)) {
                // Readable, at end (HUP) or in error: `read` says which,
                // unless a stop came meanwhile. A signal that lands on
                // another thread does not interrupt this `poll`, and a
                // writer that closes at that moment would make the read
                // report an end (an "empty stream") where the user stopped.
                Ok(n) if n > 0 => {
                    if self.stop.load(Ordering::Relaxed) {
                        return Err(io::ErrorKind::TimedOut.into());
                    }
                    return self.inner.read(buf);
                }
                Ok(_) | Err(rustix::io::Errno::INTR) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }
}

/// `r` behind [`StopOnSignal`] when there is a stop flag and `r` is not a
/// regular file (which never blocks, so it is read directly).
fn stoppable<R: Read + AsFd + Send + 'static>(
    r: R,
    stop: &Option<Arc<AtomicBool>>,
) -> Box<dyn Read + Send> {
    use rustix::fs::{fstat, FileType};
    let regular = || fstat(&r).is_ok_and(|st| FileType::from_raw_mode(st.st_mode).is_file());
    match stop {
        Some(stop) if !regular() => Box::new(StopOnSignal {
            inner: r,
            stop: stop.clone(),
        }),
        _ => Box::new(r),
    }
}

/// Reads Y4M frames from a file or standard input.
pub struct Y4mSource {
    reader: Box<dyn BufRead + Send>,
    /// Set by a signal handler; a quiet pipe's read then gives up.
    stop: Option<Arc<AtomicBool>>,
    header: Header,
    info: SourceInfo,
    /// Raw frame payload when it is not already 4:2:0.
    scratch: Vec<u8>,
    line: Vec<u8>,
    offset: u64,
    frames: u64,
    ended: bool,
    /// Size of the file in bytes (a regular file; `None` for a pipe).
    file_len: Option<u64>,
    /// Bytes of the stream header line.
    header_len: u64,
}

impl Y4mSource {
    /// Opens `path` (`-` for standard input) and reads its header.
    pub fn open(path: &str) -> Result<Self, SourceError> {
        Self::open_stoppable(path, None)
    }

    /// [`Y4mSource::open`], and when `stop` is given, a read from a pipe,
    /// FIFO or terminal gives up once `stop` is set: the header read
    /// fails with [`SourceError::Stopped`], a frame read returns
    /// [`Next::Waiting`] (the caller, seeing its flag, stops). Regular
    /// files never block, so they are read directly.
    pub fn open_stoppable(path: &str, stop: Option<Arc<AtomicBool>>) -> Result<Self, SourceError> {
        let (reader, name, file_len) = if path == "-" {
            (stoppable(io::stdin(), &stop), "y4m:- (stdin)".into(), None)
        } else {
            // Non-blocking, so that opening a FIFO does not wait for its
            // writer (a stop signal could not end that wait); reads block
            // again once it is open.
            let f = {
                use std::os::unix::fs::OpenOptionsExt;
                std::fs::OpenOptions::new()
                    .read(true)
                    .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
                    .open(path)
            }
            .and_then(|f| {
                // Linux opens a directory for reading and fails only the
                // first read: a bad stream (exit code 2), not a file that
                // cannot be opened.
                if f.metadata()?.is_dir() {
                    return Err(io::Error::new(
                        io::ErrorKind::IsADirectory,
                        "it is a directory",
                    ));
                }
                let flags = rustix::fs::fcntl_getfl(&f)?;
                rustix::fs::fcntl_setfl(&f, flags - rustix::fs::OFlags::NONBLOCK)?;
                Ok(f)
            })
            .map_err(|error| SourceError::Open {
                what: format!("Y4M file `{path}`"),
                error,
            })?;
            let len = f.metadata().ok().filter(|m| m.is_file()).map(|m| m.len());
            (stoppable(f, &stop), format!("y4m:{path}"), len)
        };
        let mut source = Self::from_reader_stoppable(reader, name, stop.clone()).map(|mut s| {
            s.file_len = file_len;
            s
        });
        if let (Err(SourceError::Io { .. }), Some(true)) =
            (&source, stop.as_ref().map(|s| s.load(Ordering::Relaxed)))
        {
            source = Err(SourceError::Stopped);
        }
        source
    }

    /// Reads the header from any reader; `name` describes it in reports.
    pub fn from_reader(reader: Box<dyn Read + Send>, name: String) -> Result<Self, SourceError> {
        Self::from_reader_stoppable(reader, name, None)
    }

    fn from_reader_stoppable(
        reader: Box<dyn Read + Send>,
        name: String,
        stop: Option<Arc<AtomicBool>>,
    ) -> Result<Self, SourceError> {
        let mut reader: Box<dyn BufRead + Send> =
            Box::new(BufReader::with_capacity(1 << 16, reader));
        let mut line = Vec::with_capacity(MAX_LINE);
        let n = read_line(&mut reader, &mut line)
            .map_err(|error| SourceError::Io { frame: 0, error })?;
        if n == 0 && stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed)) {
            // A stop and the writer's close came together.
            return Err(SourceError::Stopped);
        }
        if n == 0 {
            return Err(SourceError::Format {
                frame: 0,
                offset: 0,
                what: "empty stream (no Y4M header)".into(),
            });
        }
        if line.last() != Some(&b'\n') {
            let what = if n >= MAX_LINE {
                format!("header line longer than {MAX_LINE} bytes")
            } else {
                "header line not terminated (the stream ends inside it)".into()
            };
            return Err(SourceError::Format {
                frame: 0,
                offset: n as u64,
                what,
            });
        }
        let header = Header::parse(&line[..n - 1]).map_err(|what| SourceError::Format {
            frame: 0,
            offset: 0,
            what,
        })?;
        // Allocated before `run`'s memory check, which needs the header's
        // size: a size the memory cannot hold is exit 3, not an abort.
        let mut scratch = Vec::new();
        if header.chroma != Chroma::C420 {
            let bytes = header.chroma.frame_bytes(header.size);
            scratch
                .try_reserve_exact(bytes)
                .map_err(|e| SourceError::Open {
                    what: format!("{name}: a {bytes}-byte frame buffer"),
                    error: std::io::Error::new(std::io::ErrorKind::OutOfMemory, e.to_string()),
                })?;
            scratch.resize(bytes, 0);
        }
        let info = SourceInfo {
            size: header.size,
            fps: if header.fps.1 == 0 {
                log::warn!(
                    "{name}: no frame rate tag (F) in the Y4M header; assuming {} fps",
                    DEFAULT_FPS.0
                );
                DEFAULT_FPS
            } else {
                header.fps
            },
            description: format!(
                "{name} {}x{} {:?}",
                header.size.width, header.size.height, header.chroma
            ),
            grey: matches!(header.chroma, Chroma::Mono),
        };
        Ok(Y4mSource {
            reader,
            stop,
            header,
            info,
            scratch,
            line,
            offset: n as u64,
            frames: 0,
            ended: false,
            file_len: None,
            header_len: n as u64,
        })
    }

    /// The parsed stream header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Whether a stop was asked for (a read error then means the read gave up).
    fn stopping(&self) -> bool {
        self.stop
            .as_ref()
            .is_some_and(|s| s.load(Ordering::Relaxed))
    }

    fn fail(&self, what: String) -> SourceError {
        SourceError::Format {
            frame: self.frames,
            offset: self.offset,
            what,
        }
    }
}

/// Reads up to and including `\n`, at most [`MAX_LINE`] bytes; returns the count.
fn read_line(r: &mut dyn BufRead, line: &mut Vec<u8>) -> io::Result<usize> {
    line.clear();
    r.take(MAX_LINE as u64).read_until(b'\n', line)
}

/// The start of `line` as it can be shown in a message: its first 16
/// bytes, those other than printable ASCII and spaces as `.`.
fn shown(line: &[u8]) -> String {
    line.iter()
        .take(16)
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '.'
            }
        })
        .collect()
}

/// Reads exactly `buf.len()` bytes; returns how many arrived before end of stream.
fn read_full(r: &mut dyn Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

impl FrameSource for Y4mSource {
    fn info(&self) -> &SourceInfo {
        &self.info
    }

    fn next_frame(&mut self, frame: &mut Frame) -> Result<Next, SourceError> {
        match self.read_frame(frame) {
            // The read gave up for a stop; what it had read of the frame
            // is lost, so the stream cannot go on.
            Err(SourceError::Io { .. }) if self.stopping() => {
                self.ended = true;
                Ok(Next::Waiting)
            }
            other => other,
        }
    }

    /// From the file's size, taking every frame header to be a bare
    /// `FRAME` line (frame parameters, rare, make it an overestimate).
    fn length(&self) -> Option<u64> {
        let per_frame = self.header.chroma.frame_bytes(self.header.size) as u64 + 6;
        Some(self.file_len?.saturating_sub(self.header_len) / per_frame)
    }
}

impl Y4mSource {
    fn read_frame(&mut self, frame: &mut Frame) -> Result<Next, SourceError> {
        if self.ended {
            return Ok(Next::End);
        }
        let io_err = |frames, error| SourceError::Io {
            frame: frames,
            error,
        };
        let n = read_line(&mut self.reader, &mut self.line).map_err(|e| io_err(self.frames, e))?;
        if n == 0 {
            self.ended = true;
            return Ok(Next::End);
        }
        // The stream ends within a frame header: `FRAME`, part of it, or
        // it and its tags, without the newline (before, a bare `FRAME`
        // here was refused as "expected `FRAME` marker, found `FRAME`").
        let cut_short = self.line.last() != Some(&b'\n')
            && n < MAX_LINE
            && (b"FRAME".starts_with(&self.line) || self.line.starts_with(b"FRAME "));
        if cut_short {
            self.ended = true;
            return Err(self.fail(format!(
                "truncated frame header: the stream ends after `{}` without the newline that ends it",
                shown(&self.line)
            )));
        }
        if !self.line.starts_with(b"FRAME") || !matches!(self.line.get(5), Some(b' ' | b'\n')) {
            return Err(self.fail(format!(
                "expected `FRAME` marker, found `{}`",
                shown(&self.line)
            )));
        }
        if self.line.last() != Some(&b'\n') {
            return Err(self.fail(format!("frame header line longer than {MAX_LINE} bytes")));
        }
        self.offset += n as u64;
        let size = self.header.size;
        if frame.size() != size {
            return Err(self.fail(format!(
                "frame buffer is {:?}, stream is {:?}",
                frame.size(),
                size
            )));
        }
        let expected = self.header.chroma.frame_bytes(size);
        let got = if self.header.chroma == Chroma::C420 {
            let mut got = 0;
            for plane in [&mut frame.y, &mut frame.u, &mut frame.v] {
                let n = read_full(&mut self.reader, plane).map_err(|e| io_err(self.frames, e))?;
                got += n;
                if n < plane.len() {
                    break;
                }
            }
            got
        } else {
            read_full(&mut self.reader, &mut self.scratch).map_err(|e| io_err(self.frames, e))?
        };
        if got < expected {
            self.ended = true;
            return Err(self.fail(format!("truncated frame: {got} of {expected} bytes")));
        }
        match self.header.chroma {
            Chroma::C420 => {}
            Chroma::C422 => convert::planar422_to_420(&self.scratch, size, frame),
            Chroma::C444 => convert::planar444_to_420(&self.scratch, size, frame),
            Chroma::Mono => convert::grey_to_420(&self.scratch, size, frame),
        }
        self.offset += expected as u64;
        frame.index = self.frames;
        self.frames += 1;
        Ok(Next::Frame)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stream(header: &str, frames: &[Vec<u8>]) -> Vec<u8> {
        let mut s = header.as_bytes().to_vec();
        for f in frames {
            s.extend_from_slice(b"FRAME\n");
            s.extend_from_slice(f);
        }
        s
    }

    fn source(bytes: Vec<u8>) -> Result<Y4mSource, SourceError> {
        Y4mSource::from_reader(Box::new(io::Cursor::new(bytes)), "test".into())
    }

    #[test]
    fn reads_420jpeg_with_x_tag() {
        // Y 4×2, then Cb and Cr 2×1 each.
        let payload: Vec<u8> = (0..4 * 2 + 2 * 2).map(|i| i as u8).collect();
        let mut s = source(stream(
            "YUV4MPEG2 W4 H2 F10:1 Ip A0:0 C420jpeg XYSCSS=420JPEG\n",
            &[payload.clone(), payload],
        ))
        .unwrap();
        assert_eq!(
            s.info().size,
            Size {
                width: 4,
                height: 2
            }
        );
        assert_eq!(s.info().fps, (10, 1));
        let mut f = Frame::new(s.info().size);
        assert_eq!(s.next_frame(&mut f).unwrap(), Next::Frame);
        assert_eq!(f.y, (0..8).collect::<Vec<u8>>());
        assert_eq!(f.u, vec![8, 9]);
        assert_eq!(f.v, vec![10, 11]);
        assert_eq!(s.next_frame(&mut f).unwrap(), Next::Frame);
        assert_eq!(f.index, 1);
        assert_eq!(s.next_frame(&mut f).unwrap(), Next::End);
    }

    #[test]
    fn frame_rates_in_range_are_kept_and_a_missing_one_is_assumed() {
        for (tag, want) in [
            (" F30000:1001", (30000, 1001)),
            (" F1:10", (1, 10)),
            ("", DEFAULT_FPS),
        ] {
            let h = format!("YUV4MPEG2 W2 H2{tag}\n");
            let s = source(stream(&h, &[vec![0; 6]])).unwrap();
            assert_eq!(s.info().fps, want, "{h:?}");
        }
    }

    #[test]
    fn reads_444_and_mono_as_420() {
        let mut p = vec![50u8; 4];
        p.extend([10, 20, 30, 40]); // U: averages to 25
        p.extend([200; 4]);
        let mut s = source(stream("YUV4MPEG2 W2 H2 C444\n", &[p])).unwrap();
        let mut f = Frame::new(s.info().size);
        s.next_frame(&mut f).unwrap();
        assert_eq!((f.u[0], f.v[0]), (25, 200));
        let mut s = source(stream("YUV4MPEG2 W2 H2 Cmono\n", &[vec![7; 4]])).unwrap();
        s.next_frame(&mut f).unwrap();
        assert_eq!((f.y[3], f.u[0]), (7, 128));
    }

    #[test]
    fn truncated_frame_names_frame_and_offset() {
        let mut bytes = stream("YUV4MPEG2 W4 H2\n", &[vec![0; 12]]);
        bytes.extend_from_slice(b"FRAME\n\x01\x02");
        let mut s = source(bytes).unwrap();
        let mut f = Frame::new(s.info().size);
        s.next_frame(&mut f).unwrap();
        let e = s.next_frame(&mut f).unwrap_err().to_string();
        assert!(
            e.contains("frame 1") && e.contains("offset 40") && e.contains("truncated"),
            "{e}"
        );
    }

    #[test]
    fn garbage_between_frames_is_reported() {
        let mut bytes = stream("YUV4MPEG2 W4 H2\n", &[vec![0; 12]]);
        bytes.extend_from_slice(b"JUNKJUNK\n");
        let mut s = source(bytes).unwrap();
        let mut f = Frame::new(s.info().size);
        s.next_frame(&mut f).unwrap();
        let e = s.next_frame(&mut f).unwrap_err().to_string();
        assert!(
            e.contains("expected `FRAME`") && e.contains("JUNKJUNK"),
            "{e}"
        );
    }

    #[test]
    fn a_stream_cut_within_a_frame_header_says_so() {
        for (tail, shown) in [
            (&b"FRAME"[..], "`FRAME`"),
            (b"FRA", "`FRA`"),
            (b"FRAME Ip", "`FRAME Ip`"),
        ] {
            let mut bytes = stream("YUV4MPEG2 W4 H2\n", &[vec![0; 12]]);
            bytes.extend_from_slice(tail);
            let mut s = source(bytes).unwrap();
            let mut f = Frame::new(s.info().size);
            s.next_frame(&mut f).unwrap();
            let e = s.next_frame(&mut f).unwrap_err().to_string();
            assert_eq!(
                e,
                format!(
                    "malformed stream at frame 1, byte offset 34: truncated frame header: \
                     the stream ends after {shown} without the newline that ends it"
                )
            );
            assert_eq!(s.next_frame(&mut f).unwrap(), Next::End);
        }
    }

    #[test]
    fn bad_headers_are_refused_with_reasons() {
        for (h, want) in [
            ("YUV4MPEG W4 H2\n", "signature"),
            ("YUV4MPEG2 H2\n", "width"),
            ("YUV4MPEG2 W4 H0\n", "height"),
            ("YUV4MPEG2 W4 H2 C420p10\n", "420p10"),
            ("YUV4MPEG2 W4 H2 Fx\n", "frame rate"),
            ("YUV4MPEG2 W4 H2 F0:0\n", "frame rate"),
            ("YUV4MPEG2 W4 H2 F25:0\n", "frame rate"),
            ("YUV4MPEG2 W4 H2 F4294967295:1\n", "0.1 to 1000 fps"),
            ("YUV4MPEG2 W4 H2 F1:4294967295\n", "0.1 to 1000 fps"),
            ("YUV4MPEG2 W4 H2 F1:11\n", "frame rate"),
            ("YUV4MPEG2 W4 H2 W8\n", "`W` given twice"),
            ("YUV4MPEG2 W4 H2 F25:1 C420 F30:1\n", "`F` given twice"),
            ("YUV4MPEG2 W4 H2 C420jpeg\r\n", "CR LF"),
            ("YUV4MPEG2 W4 H2 Q1\n", "unknown header tag"),
            ("YUV4MPEG2 W4 H2", "not terminated"),
            ("", "empty"),
        ] {
            let e = source(h.as_bytes().to_vec()).err().expect(h).to_string();
            assert!(e.contains(want), "{h:?}: {e}");
        }
        // Before: "not terminated" for a line that is, only too long.
        let long = format!("YUV4MPEG2 W4 H2 F25:1 {}\n", "X".repeat(200_000));
        let e = source(long.into_bytes()).err().unwrap().to_string();
        assert!(e.contains("header line longer than 4096 bytes"), "{e}");
        let mut bytes = b"YUV4MPEG2 W4 H2 F25:1 C420\nFRAME ".to_vec();
        bytes.extend(std::iter::repeat_n(b'X', 5000));
        bytes.push(b'\n');
        let mut s = source(bytes).unwrap();
        let e = s
            .next_frame(&mut Frame::new(s.info().size))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("frame header line longer than 4096 bytes"),
            "{e}"
        );
    }

    /// Before: a stop that came while the writer closed the pipe was
    /// read as the stream's end ("empty stream", exit code 2) about once in
    /// twelve tries, when the signal landed on another thread.
    #[test]
    fn a_stop_beside_a_closed_pipe_is_a_stop_not_an_empty_stream() {
        // The read got past the flag check before the stop and found the
        // writer gone: the end of the pipe, with the flag set by then.
        let stop = Arc::new(AtomicBool::new(true));
        let (reader, writer) = std::io::pipe().unwrap();
        drop(writer);
        let r =
            Y4mSource::from_reader_stoppable(Box::new(reader), "pipe".into(), Some(stop.clone()));
        assert!(matches!(r, Err(SourceError::Stopped)), "{:?}", r.err());
        // With no stop, the same pipe is an empty stream.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(writer);
        stop.store(false, Ordering::Relaxed);
        let r = Y4mSource::from_reader_stoppable(
            stoppable(reader, &Some(stop.clone())),
            "pipe".into(),
            Some(stop),
        );
        let e = r.err().unwrap().to_string();
        assert!(e.contains("empty stream"), "{e}");
    }

    #[test]
    fn a_file_knows_its_length_a_stream_does_not() {
        let payload = vec![7u8; 4 * 2 + 2 * 2];
        let bytes = stream("YUV4MPEG2 W4 H2 F25:1 C420\n", &vec![payload; 5]);
        let dir = crate::scratch::fresh_dir("y4m-len");
        let path = dir.join("clip.y4m");
        std::fs::write(&path, &bytes).unwrap();
        let mut s = Y4mSource::open(path.to_str().unwrap()).unwrap();
        assert_eq!(s.length(), Some(5));
        let mut f = Frame::new(s.info().size);
        let mut n = 0;
        while s.next_frame(&mut f).unwrap() == Next::Frame {
            n += 1;
        }
        assert_eq!(n, 5);
        // A cut last frame is not counted.
        std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
        assert_eq!(
            Y4mSource::open(path.to_str().unwrap()).unwrap().length(),
            Some(4)
        );
        assert_eq!(source(bytes).unwrap().length(), None);
    }

    #[test]
    fn missing_file_is_an_open_error() {
        let e = Y4mSource::open("/nonexistent/clip.y4m").err().unwrap();
        assert_eq!(e.exit_code(), crate::exit::UNAVAILABLE);
    }

    #[test]
    fn a_directory_is_an_open_error() {
        let dir = std::env::temp_dir();
        let e = Y4mSource::open(dir.to_str().unwrap()).err().unwrap();
        assert_eq!(e.exit_code(), crate::exit::UNAVAILABLE, "{e}");
        assert_eq!(
            e.to_string(),
            format!(
                "cannot open Y4M file `{}`: it is a directory",
                dir.display()
            )
        );
    }
}
