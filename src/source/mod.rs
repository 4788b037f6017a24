//! Frame sources: every source fills a caller-owned [`Frame`] in place.
//!
//! * `y4m:PATH`, `y4m:-`: recorded frames (the host-test path).
//! * `v4l2:/dev/videoN?width=W&height=H&fps=F&format=YUYV|NV12|GREY`: a camera.
//! * `sim:NAME?seed=N&frames=N`: the built-in simulated scene.

use crate::frame::{Frame, Size};
use core::fmt;

pub mod convert;
pub mod sim;
pub mod v4l2;
pub mod y4m;

/// What a source produces, known once it is open.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceInfo {
    /// Frame size.
    pub size: Size,
    /// Frames per second as a fraction (numerator, denominator).
    pub fps: (u32, u32),
    /// Human-readable description for the `hello` record.
    pub description: String,
    /// The source has no colour (a `Cmono` Y4M, a V4L2 `GREY` camera): its
    /// chroma planes are flat, so the chroma foreground test and the
    /// colour re-identification of tracks have nothing to go on.
    pub grey: bool,
}

impl SourceInfo {
    /// Frames per second as a float (0 when unknown).
    pub fn fps_f64(&self) -> f64 {
        if self.fps.1 == 0 {
            0.0
        } else {
            f64::from(self.fps.0) / f64::from(self.fps.1)
        }
    }
}

/// The outcome of asking a source for a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// The frame was filled.
    Frame,
    /// No frame now (a camera is reconnecting); ask again.
    Waiting,
    /// The stream ended cleanly.
    End,
}

/// Source health, reported in `status` records.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SourceState {
    /// Delivering frames.
    Streaming,
    /// Lost; trying to reopen.
    Reconnecting,
    /// Ended.
    Ended,
}

impl SourceState {
    /// Name used in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            SourceState::Streaming => "streaming",
            SourceState::Reconnecting => "reconnecting",
            SourceState::Ended => "ended",
        }
    }
}

/// Why a source failed.
#[derive(Debug)]
pub enum SourceError {
    /// The source text is not understood.
    Spec(String),
    /// The file, pipe or device could not be opened.
    Open {
        /// What was being opened.
        what: String,
        /// Why.
        error: std::io::Error,
    },
    /// The stream is malformed.
    Format {
        /// 0-based frame number where it went wrong (header: 0).
        frame: u64,
        /// Byte offset in the stream.
        offset: u64,
        /// What is wrong.
        what: String,
    },
    /// Reading failed.
    Io {
        /// 0-based frame being read.
        frame: u64,
        /// Why.
        error: std::io::Error,
    },
    /// This build lacks the source (e.g. `v4l2` feature off).
    Unsupported(&'static str),
    /// A stop was asked for (SIGINT/SIGTERM/SIGHUP) while the source was still
    /// opening, e.g. waiting on a pipe for its Y4M header.
    Stopped,
}

impl SourceError {
    /// Exit code for this error (see [`crate::exit`]).
    pub fn exit_code(&self) -> i32 {
        match self {
            SourceError::Open { .. } | SourceError::Unsupported(_) => crate::exit::UNAVAILABLE,
            // Asked for; not a failure.
            SourceError::Stopped => crate::exit::OK,
            _ => crate::exit::BAD_INPUT,
        }
    }
}

impl fmt::Display for SourceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SourceError::Spec(s) => write!(f, "bad source: {s}"),
            SourceError::Open { what, error } => write!(f, "cannot open {what}: {error}"),
            SourceError::Format {
                frame,
                offset,
                what,
            } => {
                write!(
                    f,
                    "malformed stream at frame {frame}, byte offset {offset}: {what}"
                )
            }
            SourceError::Io { frame, error } => write!(f, "read error at frame {frame}: {error}"),
            SourceError::Unsupported(s) => write!(f, "{s}"),
            SourceError::Stopped => write!(f, "stopped before the source had opened"),
        }
    }
}
impl std::error::Error for SourceError {}

/// A producer of frames.
pub trait FrameSource {
    /// Size, rate and description.
    fn info(&self) -> &SourceInfo;
    /// Fills `frame` with the next frame. `frame` must have the size from [`Self::info`].
    fn next_frame(&mut self, frame: &mut Frame) -> Result<Next, SourceError>;
    /// Current health.
    fn state(&self) -> SourceState {
        SourceState::Streaming
    }
    /// Frames in the whole stream, when known before it is read (a Y4M
    /// file, a simulated clip); `None` for a camera or a pipe.
    fn length(&self) -> Option<u64> {
        None
    }
}

/// Splits `scheme:rest?k=v&k=v` into its parts.
pub fn split_uri(uri: &str) -> Option<(&str, &str, &str)> {
    let (scheme, rest) = uri.split_once(':').unwrap_or((uri, ""));
    let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
    (!scheme.is_empty()).then_some((scheme, path, query))
}

/// The `k=v` pairs of a query string, or `Err` with the first key it
/// gives twice (`seed=1&seed=2`): which one was meant is anyone's guess,
/// so no parser keeps the last.
pub fn query_pairs(query: &str) -> Result<impl Iterator<Item = (&str, &str)>, &str> {
    let pairs = || {
        query
            .split('&')
            .filter(|p| !p.is_empty())
            .map(|p| p.split_once('=').unwrap_or((p, "")))
    };
    let keys = || pairs().map(|(k, _)| k);
    match keys()
        .enumerate()
        .find(|&(i, k)| keys().take(i).any(|e| e == k))
    {
        Some((_, k)) => Err(k),
        None => Ok(pairs()),
    }
}

/// A source URI split by scheme, its parts parsed ([`parse`]).
enum Spec<'a> {
    /// `y4m:PATH` (`-` for standard input).
    Y4m(&'a str),
    /// `v4l2:DEVICE?QUERY`.
    V4l2(v4l2::V4l2Spec),
    /// `sim:SCENE?QUERY`.
    Sim(&'static sim::scene::SceneSpec, sim::SimOptions),
}

/// Splits `uri` by scheme and checks what can be checked without opening
/// anything: the scheme, a y4m path, the v4l2 and sim options, the scene.
fn parse(uri: &str) -> Result<Spec<'_>, SourceError> {
    let (scheme, path, query) =
        split_uri(uri).ok_or_else(|| SourceError::Spec(format!("`{uri}`: expected SCHEME:...")))?;
    match scheme {
        "y4m" if path.is_empty() => {
            Err(SourceError::Spec(format!("`{uri}`: y4m needs a file path")))
        }
        "y4m" if query.is_empty() => Ok(Spec::Y4m(path)),
        // y4m takes no options, so a `?` may be part of a file name.
        "y4m" => {
            let whole = &uri[uri.find(':').map_or(0, |i| i + 1)..];
            if std::path::Path::new(whole).exists() {
                Ok(Spec::Y4m(whole))
            } else {
                Err(SourceError::Spec(format!(
                    "`{uri}`: y4m takes no options (and no file `{whole}` exists)"
                )))
            }
        }
        "v4l2" => v4l2::V4l2Spec::parse(path, query).map(Spec::V4l2),
        "sim" => Ok(Spec::Sim(
            sim::scene_named(path)?,
            sim::SimOptions::parse(query)?,
        )),
        // No scheme at all: say which URI it likely meant (a file name,
        // standard input, a camera device, a scene name).
        _ if !uri.contains(':') => {
            let looks_like_file = uri == "-"
                || uri.contains('/')
                || std::path::Path::new(uri)
                    .extension()
                    .is_some_and(|e| e.eq_ignore_ascii_case("y4m"));
            let meant = if uri.starts_with("/dev/video") {
                Some("v4l2")
            } else if looks_like_file {
                Some("y4m")
            } else if sim::scene_named(uri).is_ok() {
                Some("sim")
            } else {
                None
            };
            Err(SourceError::Spec(match meant {
                Some(m) => format!("`{uri}` has no scheme: write `{m}:{uri}`"),
                None => {
                    format!("`{uri}` has no scheme (expected y4m:FILE, v4l2:DEVICE or sim:SCENE)")
                }
            }))
        }
        _ => Err(SourceError::Spec(format!(
            "`{uri}`: unknown scheme `{scheme}` (expected y4m, v4l2 or sim)"
        ))),
    }
}

/// Checks a source URI without opening anything (what `stature config
/// --check` can say before a run): also that this build has the source,
/// a `v4l2:` one only with the `v4l2` feature ([`SourceError::Unsupported`],
/// as [`open`] says). Whether the file or device is there is only known
/// when [`open`] tries.
pub fn check(uri: &str) -> Result<(), SourceError> {
    match parse(uri)? {
        Spec::V4l2(_) if !v4l2::BUILT_IN => Err(SourceError::Unsupported(v4l2::NOT_BUILT_IN)),
        _ => Ok(()),
    }
}

/// The file a `y4m:` source reads (`-`: standard input); `None` for any
/// other source or a URI that does not parse.
pub fn y4m_path(uri: &str) -> Option<&str> {
    match parse(uri) {
        Ok(Spec::Y4m(path)) => Some(path),
        _ => None,
    }
}

/// The frame size a run of `uri` will get, as far as it is known without
/// taking the source from anyone (for `stature config --check`'s memory
/// check): a scene's size, the size a `v4l2:` URI asks for (the driver may
/// give another; `run` checks what it got), a Y4M file's header (read, so
/// a missing file or a bad header fails as `run` would). `None` for
/// standard input and for a FIFO or device at a `y4m:` path: reading
/// would take frames from whoever feeds it.
pub fn planned_size(uri: &str) -> Result<Option<Size>, SourceError> {
    Ok(match parse(uri)? {
        Spec::Sim(scene, _) => Some(Size {
            width: scene.width,
            height: scene.height,
        }),
        Spec::V4l2(spec) => Some(Size {
            width: spec.width as usize,
            height: spec.height as usize,
        }),
        Spec::Y4m("-") => None,
        Spec::Y4m(path) => match std::fs::metadata(path) {
            Ok(m) if !m.is_file() && !m.is_dir() => None,
            _ => Some(y4m::Y4mSource::open(path)?.info().size),
        },
    })
}

/// Opens a source URI (`y4m:PATH`, `v4l2:/dev/videoN?...`, `sim:SCENE?...`).
pub fn open(uri: &str) -> Result<Box<dyn FrameSource + Send>, SourceError> {
    open_stoppable(uri, None)
}

/// [`open`], with the flag a signal handler sets to stop the run: a Y4M
/// pipe that has gone quiet is then given up instead of waited on (the
/// header read fails with [`SourceError::Stopped`], a frame read returns
/// [`Next::Waiting`]). Cameras and the simulation never block for long.
pub fn open_stoppable(
    uri: &str,
    stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
) -> Result<Box<dyn FrameSource + Send>, SourceError> {
    Ok(match parse(uri)? {
        Spec::Y4m(path) => Box::new(y4m::Y4mSource::open_stoppable(path, stop)?),
        Spec::V4l2(spec) => Box::new(v4l2::V4l2Source::from_spec(spec)?),
        Spec::Sim(scene, opts) => Box::new(sim::SimSource::new(scene, &opts)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planned_sizes_come_from_the_uri_without_opening_a_device() {
        let size = |uri| planned_size(uri).unwrap();
        assert_eq!(
            size("sim:busy?seed=3"),
            Some(Size {
                width: 1280,
                height: 720
            })
        );
        // No such device here: the size asked for is known all the same.
        assert_eq!(
            size("v4l2:/dev/video97?width=1920&height=1080&fps=10&format=YUYV"),
            Some(Size {
                width: 1920,
                height: 1080
            })
        );
        assert_eq!(size("y4m:-"), None);
        assert!(planned_size("y4m:/nonexistent/a.y4m").is_err());
    }

    #[test]
    fn a_bare_path_is_shown_the_uri_to_write() {
        let e = check("/tmp/a.y4m").unwrap_err().to_string();
        assert!(e.contains("write `y4m:/tmp/a.y4m`"), "{e}");
        let e = check("/dev/video0").unwrap_err().to_string();
        assert!(e.contains("write `v4l2:/dev/video0`"), "{e}");
        let e = check("rtsp://cam").unwrap_err().to_string();
        assert!(e.contains("unknown scheme `rtsp`"), "{e}");
        // Before: "unknown scheme `clip.y4m`" for a file in the working
        // directory, and the same for standard input.
        let e = check("clip.y4m").unwrap_err().to_string();
        assert!(e.contains("write `y4m:clip.y4m`"), "{e}");
        let e = check("CLIP.Y4M").unwrap_err().to_string();
        assert!(e.contains("write `y4m:CLIP.Y4M`"), "{e}");
        let e = check("-").unwrap_err().to_string();
        assert!(e.contains("write `y4m:-`"), "{e}");
        let e = check("plaza").unwrap_err().to_string();
        assert!(e.contains("write `sim:plaza`"), "{e}");
        let e = check("clip").unwrap_err().to_string();
        assert!(e.contains("`clip` has no scheme (expected y4m:FILE"), "{e}");
    }

    /// Before: "y4m takes no options" for a file named `a?b.y4m`.
    #[test]
    fn a_y4m_file_name_may_hold_a_question_mark() {
        let dir = std::env::temp_dir().join(format!("stature-y4m-q-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("a?b.y4m");
        std::fs::write(&file, b"").unwrap();
        let uri = format!("y4m:{}", file.display());
        let parsed = parse(&uri);
        let _ = std::fs::remove_dir_all(&dir);
        assert!(
            matches!(parsed, Ok(Spec::Y4m(p)) if p == file.to_str().unwrap()),
            "{uri}"
        );
        let e = check("y4m:/nonexistent/a.y4m?loop=1")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("y4m takes no options (and no file `/nonexistent/a.y4m?loop=1` exists)"),
            "{e}"
        );
    }

    /// Before: the last of two values won, silently.
    #[test]
    fn an_option_given_twice_is_refused_everywhere() {
        assert_eq!(query_pairs("seed=1&frames=5&seed=2").err(), Some("seed"));
        let pairs: Vec<_> = query_pairs("seed=1&frames=5").unwrap().collect();
        assert_eq!(pairs, [("seed", "1"), ("frames", "5")]);
        let sim = check("sim:plaza?seed=1&seed=2").unwrap_err().to_string();
        assert!(sim.contains("`seed` given twice"), "{sim}");
        let cam = parse("v4l2:/dev/video0?width=640&width=320").err().unwrap();
        assert!(cam.to_string().contains("`width` given twice"), "{cam}");
        use crate::report::sink::SinkSpec;
        let serial = SinkSpec::parse("serial:/dev/ttyS0?baud=9600&baud=115200").unwrap_err();
        assert!(
            serial.to_string().contains("`baud` given twice"),
            "{serial}"
        );
        let mqtt = SinkSpec::parse("mqtt:b?qos=1&qos=0").unwrap_err();
        assert!(mqtt.to_string().contains("`qos` given twice"), "{mqtt}");
    }
}
