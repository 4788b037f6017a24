//! V4L2 capture: memory-mapped streaming with a few fixed buffers, converted
//! to 4:2:0 planes, with reconnection when the device disappears.
//!
//! The negotiated mode may differ from the request (drivers pick the nearest
//! size and rate); it is logged, and the frame size is fixed at open: a
//! reopened device that comes back at a different size is refused until it
//! returns to the original one, so buffers never change after start-up.

use super::{query_pairs, FrameSource, Next, SourceError, SourceInfo};
use crate::frame::Frame;

/// Requested capture mode.
#[derive(Clone, Debug, PartialEq)]
pub struct V4l2Spec {
    /// Device path, e.g. `/dev/video0`.
    pub path: String,
    /// Requested width.
    pub width: u32,
    /// Requested height.
    pub height: u32,
    /// Requested frames per second.
    pub fps: u32,
    /// Requested pixel format: `YUYV`, `NV12` or `GREY`.
    pub fourcc: [u8; 4],
    /// Memory-mapped buffers in the driver's queue.
    pub buffers: u32,
}

impl V4l2Spec {
    /// Parses `PATH` and `width=W&height=H&fps=F&format=YUYV|NV12|GREY&buffers=N`.
    pub fn parse(path: &str, query: &str) -> Result<Self, SourceError> {
        if !path.starts_with('/') {
            return Err(SourceError::Spec(format!(
                "v4l2 device `{path}` must be an absolute path like /dev/video0"
            )));
        }
        let mut spec = V4l2Spec {
            path: path.into(),
            width: 640,
            height: 480,
            fps: 15,
            fourcc: *b"YUYV",
            buffers: 4,
        };
        let pairs = query_pairs(query).map_err(|k| {
            SourceError::Spec(format!("v4l2 option `{k}` given twice in `{query}`"))
        })?;
        for (k, v) in pairs {
            let num = |lo: u32, hi: u32| -> Result<u32, SourceError> {
                v.parse::<u32>()
                    .ok()
                    .filter(|n| (lo..=hi).contains(n))
                    .ok_or_else(|| {
                        SourceError::Spec(format!(
                            "v4l2 option `{k}={v}`: expected an integer in {lo}..={hi}"
                        ))
                    })
            };
            match k {
                "width" => spec.width = num(16, 8192)?,
                "height" => spec.height = num(16, 8192)?,
                "fps" => spec.fps = num(1, 240)?,
                "buffers" => spec.buffers = num(2, 16)?,
                "format" => {
                    spec.fourcc = match v {
                        "YUYV" => *b"YUYV",
                        "NV12" => *b"NV12",
                        "GREY" => *b"GREY",
                        _ => {
                            return Err(SourceError::Spec(format!(
                                "v4l2 format `{v}`: expected YUYV, NV12 or GREY"
                            )))
                        }
                    }
                }
                _ => {
                    return Err(SourceError::Spec(format!(
                        "unknown v4l2 option `{k}` (width, height, fps, format, buffers)"
                    )))
                }
            }
        }
        Ok(spec)
    }
}

/// Whether this build can capture from V4L2 (the cargo feature `v4l2`).
pub const BUILT_IN: bool = cfg!(feature = "v4l2");

/// Why a `v4l2:` source is refused by a build without V4L2 support.
pub const NOT_BUILT_IN: &str = "this build has no V4L2 support (built without the `v4l2` feature)";

#[cfg(feature = "v4l2")]
pub use device::V4l2Source;

#[cfg(not(feature = "v4l2"))]
/// Placeholder when the `v4l2` feature is off: opening always fails.
pub struct V4l2Source {
    info: SourceInfo,
}

#[cfg(not(feature = "v4l2"))]
impl V4l2Source {
    /// Always refuses: this build has no V4L2 support.
    pub fn open(path: &str, query: &str) -> Result<Self, SourceError> {
        Self::from_spec(V4l2Spec::parse(path, query)?)
    }

    /// Always refuses: this build has no V4L2 support.
    pub fn from_spec(_spec: V4l2Spec) -> Result<Self, SourceError> {
        Err(SourceError::Unsupported(NOT_BUILT_IN))
    }
}

#[cfg(not(feature = "v4l2"))]
impl FrameSource for V4l2Source {
    fn info(&self) -> &SourceInfo {
        &self.info
    }
    fn next_frame(&mut self, _frame: &mut Frame) -> Result<Next, SourceError> {
        Ok(Next::End)
    }
}

#[cfg(feature = "v4l2")]
mod device {
    use super::*;
    use crate::frame::Size;
    use crate::source::convert;
    use crate::source::SourceState;
    use std::time::{Duration, Instant};
    use v4l::buffer::Type;
    use v4l::io::mmap::Stream;
    use v4l::io::traits::CaptureStream;
    use v4l::video::capture::Parameters;
    use v4l::video::Capture;
    use v4l::{Device, FourCC};

    /// Longest wait for one frame before the device is considered lost.
    const FRAME_TIMEOUT: Duration = Duration::from_secs(3);
    /// Reconnection backoff bounds.
    const BACKOFF_MIN: Duration = Duration::from_millis(250);
    const BACKOFF_MAX: Duration = Duration::from_secs(8);

    struct Open {
        stream: Stream<'static>,
        // Kept so that the handle outlives the stream; dropped after it.
        _device: Device,
        fourcc: [u8; 4],
        stride: usize,
    }

    /// A V4L2 camera.
    pub struct V4l2Source {
        spec: V4l2Spec,
        info: SourceInfo,
        card: String,
        open: Option<Open>,
        state: SourceState,
        backoff: Duration,
        next_attempt: Instant,
        frames: u64,
        /// Buffers dropped for holding less than a frame.
        short: u64,
        /// Times the device was lost and reopened.
        pub reconnects: u64,
    }

    fn open_device(
        path: &str,
        spec: &V4l2Spec,
        want: Option<Size>,
    ) -> std::io::Result<(Open, Size, (u32, u32), String)> {
        use std::io::{Error, ErrorKind};
        let dev = Device::with_path(path)?;
        let caps = dev.query_caps()?;
        if !caps
            .capabilities
            .contains(v4l::capability::Flags::VIDEO_CAPTURE)
            || !caps
                .capabilities
                .contains(v4l::capability::Flags::STREAMING)
        {
            return Err(Error::new(
                ErrorKind::Unsupported,
                format!("{path} ({}) cannot stream video capture", caps.card),
            ));
        }
        let (w, h) = want.map_or((spec.width, spec.height), |s| {
            (s.width as u32, s.height as u32)
        });
        let mut fmt = dev.format()?;
        fmt.width = w;
        fmt.height = h;
        fmt.fourcc = FourCC::new(&spec.fourcc);
        let fmt = dev.set_format(&fmt)?;
        let size = Size {
            width: fmt.width as usize,
            height: fmt.height as usize,
        };
        if let Some(s) = want {
            if s != size {
                return Err(Error::new(
                    ErrorKind::InvalidData,
                    format!(
                        "device came back at {}x{}, stream is {}x{}",
                        size.width, size.height, s.width, s.height
                    ),
                ));
            }
        }
        let fourcc = fmt.fourcc.repr;
        let stride = fmt.stride as usize;
        if convert::required_bytes(&fourcc, stride.max(1), size).is_none() {
            return Err(Error::new(
                ErrorKind::Unsupported,
                format!(
                    "driver offered format {} (need YUYV, NV12 or GREY)",
                    fmt.fourcc
                ),
            ));
        }
        let params = dev
            .set_params(&Parameters::with_fps(spec.fps))
            .or_else(|_| dev.params())?;
        let fps = (
            params.interval.denominator,
            params.interval.numerator.max(1),
        );
        let mut stream = Stream::with_buffers(&dev, Type::VideoCapture, spec.buffers)?;
        stream.set_timeout(FRAME_TIMEOUT);
        log::info!(
            "v4l2: {path} ({}, driver {}) streaming {}x{} {} stride {} at {}/{} fps with {} buffers",
            caps.card, caps.driver, size.width, size.height, fmt.fourcc, stride, fps.0, fps.1, spec.buffers
        );
        Ok((
            Open {
                stream,
                _device: dev,
                fourcc,
                stride,
            },
            size,
            fps,
            caps.card,
        ))
    }

    /// Drops a dead stream without letting the `v4l` crate's panicking
    /// `Drop` (it panics on unexpected ioctl errors) take the process down.
    fn close_quietly(open: Open) {
        let hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || drop(open)));
        std::panic::set_hook(hook);
        if r.is_err() {
            log::warn!("v4l2: closing the lost device reported an error (ignored)");
        }
    }

    impl V4l2Source {
        /// Opens the device and negotiates the nearest supported mode.
        pub fn open(path: &str, query: &str) -> Result<Self, SourceError> {
            Self::from_spec(V4l2Spec::parse(path, query)?)
        }

        /// Opens the device `spec` names in the nearest supported mode.
        pub fn from_spec(spec: V4l2Spec) -> Result<Self, SourceError> {
            let (open, size, fps, card) =
                open_device(&spec.path, &spec, None).map_err(|error| SourceError::Open {
                    what: format!("V4L2 device `{}`", spec.path),
                    error,
                })?;
            let info = SourceInfo {
                size,
                fps,
                description: format!(
                    "v4l2:{} {card} {}x{} {}",
                    spec.path,
                    size.width,
                    size.height,
                    String::from_utf8_lossy(&open.fourcc)
                ),
                grey: &open.fourcc == b"GREY",
            };
            Ok(V4l2Source {
                spec,
                info,
                card,
                open: Some(open),
                state: SourceState::Streaming,
                backoff: BACKOFF_MIN,
                next_attempt: Instant::now(),
                frames: 0,
                short: 0,
                reconnects: 0,
            })
        }

        fn lose(&mut self, why: &std::io::Error) {
            log::warn!("v4l2: {} lost ({why}); reconnecting", self.spec.path);
            if let Some(open) = self.open.take() {
                close_quietly(open);
            }
            self.state = SourceState::Reconnecting;
            self.backoff = BACKOFF_MIN;
            self.next_attempt = Instant::now() + self.backoff;
        }

        /// Tries the configured path, then any capture device with the same card name.
        fn try_reconnect(&mut self) -> bool {
            let mut candidates = vec![self.spec.path.clone()];
            if let Ok(dir) = std::fs::read_dir("/dev") {
                // Only video nodes become strings: /dev holds hundreds of entries
                // and this runs at every retry while the camera is away.
                let mut others: Vec<String> = dir
                    .filter_map(|e| e.ok())
                    .filter(|e| e.file_name().as_encoded_bytes().starts_with(b"video"))
                    .map(|e| e.path().display().to_string())
                    .filter(|p| *p != self.spec.path)
                    .collect();
                others.sort();
                candidates.extend(others);
            }
            for (i, path) in candidates.iter().enumerate() {
                match open_device(path, &self.spec, Some(self.info.size)) {
                    Ok((open, _, _, card)) if i == 0 || card == self.card => {
                        log::info!("v4l2: reconnected on {path}");
                        self.open = Some(open);
                        self.state = SourceState::Streaming;
                        self.reconnects += 1;
                        return true;
                    }
                    Ok((open, ..)) => close_quietly(open),
                    Err(e) if i == 0 => log::debug!("v4l2: reopen {path}: {e}"),
                    Err(_) => {}
                }
            }
            false
        }
    }

    impl FrameSource for V4l2Source {
        fn info(&self) -> &SourceInfo {
            &self.info
        }

        fn state(&self) -> SourceState {
            self.state
        }

        fn next_frame(&mut self, frame: &mut Frame) -> Result<Next, SourceError> {
            if self.open.is_none() {
                let now = Instant::now();
                if now < self.next_attempt {
                    std::thread::sleep((self.next_attempt - now).min(Duration::from_millis(500)));
                    return Ok(Next::Waiting);
                }
                if !self.try_reconnect() {
                    self.backoff = (self.backoff * 2).min(BACKOFF_MAX);
                    self.next_attempt = Instant::now() + self.backoff;
                    return Ok(Next::Waiting);
                }
            }
            let size = self.info.size;
            let Some(open) = self.open.as_mut() else {
                return Ok(Next::Waiting);
            };
            let result = open.stream.next().map(|(buf, meta)| {
                let used = (meta.bytesused as usize).min(buf.len());
                let data = if used == 0 { buf } else { &buf[..used] };
                let stride = open.stride.max(1);
                match convert::required_bytes(&open.fourcc, stride, size) {
                    Some(n) if data.len() >= n => {
                        match &open.fourcc {
                            b"YUYV" => convert::yuyv_to_420(data, stride, size, frame),
                            b"NV12" => convert::nv12_to_420(data, stride, size, frame),
                            _ => convert::grey_strided_to_420(data, stride, size, frame),
                        }
                        None
                    }
                    need => Some((data.len(), need, stride)),
                }
            });
            match result {
                Ok(None) => {
                    frame.index = self.frames;
                    self.frames += 1;
                    Ok(Next::Frame)
                }
                Ok(Some((got, need, stride))) => {
                    self.short += 1;
                    // A driver that does this once does it at frame rate:
                    // the first with its sizes, then a count now and then.
                    if worth_telling(self.short) {
                        let s = if self.short == 1 { "" } else { "s" };
                        let (n, w, h) = (self.short, size.width, size.height);
                        match need {
                            Some(need) => log::warn!(
                                "v4l2: {n} short buffer{s} dropped so far (this one {got} bytes, \
                                 a {w}x{h} frame at stride {stride} needs {need}); {} frames \
                                 delivered",
                                self.frames
                            ),
                            None => log::warn!(
                                "v4l2: {n} buffer{s} dropped so far ({got} bytes: a {w}x{h} \
                                 frame at stride {stride} has no size this build can read); {} \
                                 frames delivered",
                                self.frames
                            ),
                        }
                    }
                    Ok(Next::Waiting)
                }
                Err(e) => {
                    self.lose(&e);
                    Ok(Next::Waiting)
                }
            }
        }
    }
}

/// Whether the `n`th occurrence of a repeated problem is logged: the 1st,
/// 10th, 100th, 1000th, ... (a log line a second at most for a problem
/// that comes at frame rate, and rarer as it goes on).
#[cfg_attr(not(feature = "v4l2"), allow(dead_code))]
fn worth_telling(n: u64) -> bool {
    n > 0 && 10u64.pow(n.ilog10()) == n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_repeated_problem_is_told_at_powers_of_ten() {
        let told: Vec<u64> = (0..=20_000).filter(|&n| worth_telling(n)).collect();
        assert_eq!(told, [1, 10, 100, 1000, 10_000]);
    }

    #[test]
    fn spec_parses_and_refuses_bad_options() {
        let s = V4l2Spec::parse("/dev/video2", "width=1280&height=720&fps=25&format=NV12").unwrap();
        assert_eq!(
            (s.width, s.height, s.fps, &s.fourcc),
            (1280, 720, 25, b"NV12")
        );
        for (p, q, want) in [
            ("video0", "", "absolute"),
            ("/dev/video0", "format=MJPG", "MJPG"),
            ("/dev/video0", "fps=0", "fps=0"),
            ("/dev/video0", "zoom=2", "unknown v4l2 option"),
        ] {
            let e = V4l2Spec::parse(p, q).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
    }

    #[test]
    fn a_check_says_whether_this_build_has_v4l2() {
        let checked = crate::source::check("v4l2:/dev/video0?width=640");
        if BUILT_IN {
            assert!(checked.is_ok(), "{checked:?}");
        } else {
            let e = checked.unwrap_err();
            assert_eq!(e.exit_code(), crate::exit::UNAVAILABLE, "{e}");
            assert_eq!(e.to_string(), NOT_BUILT_IN);
        }
        // A bad spec is a bad spec either way.
        let e = crate::source::check("v4l2:/dev/video0?fps=0").unwrap_err();
        assert_eq!(e.exit_code(), crate::exit::BAD_INPUT, "{e}");
    }

    #[test]
    fn missing_device_is_unavailable_not_a_panic() {
        let e = V4l2Source::open("/dev/video-does-not-exist", "")
            .err()
            .unwrap();
        assert_eq!(e.exit_code(), crate::exit::UNAVAILABLE, "{e}");
    }
}
