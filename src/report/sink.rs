//! Report sinks: where encoded records go.
//!
//! Sinks live in the I/O thread. Each write is bounded in time (UDP never
//! blocks; serial writes time out; MQTT only queues for its own connection
//! thread), so one dead link delays the others by at most its timeout, and
//! the vision loop not at all.

use super::mqtt::{MqttConfig, MqttSettings, MqttSpec, MQTT_CREDENTIALS};
use super::record::Record;
use super::Counters;
use crate::config::Format;
use std::io::{self, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::sync::Arc;
use std::time::Duration;

/// A parsed `--report` value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SinkSpec {
    /// Standard output.
    Stdout,
    /// Append to a file.
    File(String),
    /// One record per datagram to `HOST:PORT`.
    Udp(String),
    /// A serial port at a baud rate.
    Serial {
        /// Device path.
        path: String,
        /// Baud rate.
        baud: u32,
    },
    /// An MQTT broker (`mqtt:HOST[:PORT]?topic=..&qos=..`).
    Mqtt(MqttSpec),
}

const SINK_FORMS: &str =
    "stdout, file:PATH, udp:HOST:PORT, serial:PATH?baud=N or mqtt:HOST[:PORT]?topic=T&..";

impl SinkSpec {
    /// Parses `stdout`, `file:PATH`, `udp:HOST:PORT`, `serial:PATH?baud=N`
    /// or `mqtt:HOST[:PORT]?...` (see [`MqttSpec::parse`]).
    ///
    /// The error is the reason only, without `s`: the caller names the
    /// value (a config key or an option) once, in front of it.
    pub fn parse(s: &str) -> Result<Self, String> {
        if s == "stdout" {
            return Ok(SinkSpec::Stdout);
        }
        let (scheme, rest) = s
            .split_once(':')
            .ok_or_else(|| format!("expected {SINK_FORMS}"))?;
        if let ("udp" | "mqtt", Some(after)) = (scheme, rest.strip_prefix("//")) {
            return Err(without_slashes(scheme, after));
        }
        if matches!(scheme, "udp" | "mqtt") && authority(rest).contains('@') {
            // Not echoed: the caller shows the value through `redacted`.
            return Err(match scheme {
                "udp" => "a UDP destination takes no user or password (expected udp:HOST:PORT)".into(),
                _ => format!("user names and passwords do not go in the sink (it is shown in process lists and logs): {MQTT_CREDENTIALS}"),
            });
        }
        if scheme == "mqtts" {
            // TLS is an option of `mqtt:`, not a scheme of its own.
            let fixed = without_slashes("mqtt", rest.strip_prefix("//").unwrap_or(rest));
            let tls = if rest.contains('?') {
                "&tls=true"
            } else {
                "?tls=true"
            };
            return Err(fixed.replacen(
                "`, without `//`",
                &format!("{tls}` (TLS is an mqtt: option)"),
                1,
            ));
        }
        // `file://x.jsonl` is the path `//x.jsonl`, which POSIX reads as
        // `/x.jsonl`: a file at the root, surely not what was meant
        // (`file:///abs` is the absolute path, as a URL would have it).
        if let ("file", Some(after)) = (scheme, rest.strip_prefix("//")) {
            if !after.is_empty() && !after.starts_with('/') {
                if authority(after).contains('@') {
                    return Err(
                        "`file://` with a user or password: a report file is a local path, \
                         write `file:PATH`"
                            .into(),
                    );
                }
                return Err(format!(
                    "`file://{after}` names `/{after}` at the root of the file system: \
                     write `file:{after}` for a path relative to the working directory, \
                     or `file:/{after}`"
                ));
            }
        }
        match scheme {
            "file" if rest.is_empty() => Err("expected file:PATH".into()),
            "file" => Ok(SinkSpec::File(rest.into())),
            "udp" => {
                let (host, port) = rest
                    .rsplit_once(':')
                    .filter(|(h, p)| !h.is_empty() && !p.is_empty())
                    .ok_or("expected udp:HOST:PORT")?;
                if port.parse::<u16>().map_or(true, |p| p == 0) {
                    return Err(format!(
                        "port `{port}` is not in 1..=65535 (expected udp:HOST:PORT)"
                    ));
                }
                udp_host_syntax(host)?;
                Ok(SinkSpec::Udp(rest.into()))
            }
            "serial" => {
                let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
                if path.is_empty() {
                    return Err("expected serial:/dev/ttyX?baud=N".into());
                }
                if path.starts_with("//") {
                    // A URL habit (the value itself is shown redacted).
                    return Err("write serial:/dev/ttyX?baud=N, without `//`".into());
                }
                if !path.starts_with('/') {
                    return Err(format!(
                        "serial device `{path}` is not an absolute path (expected serial:/dev/ttyX?baud=N)"
                    ));
                }
                let mut baud = 115_200;
                let pairs = crate::source::query_pairs(query)
                    .map_err(|k| format!("`{k}` given twice in `{query}`"))?;
                for (k, v) in pairs {
                    match (k, v.parse::<u32>()) {
                        ("baud", Ok(b)) if (300..=4_000_000).contains(&b) => baud = b,
                        ("baud", _) => {
                            return Err(format!("`baud={v}`: expected a rate in 300..=4000000"))
                        }
                        _ => return Err(format!("unknown serial option `{k}` (expected baud=N)")),
                    }
                }
                Ok(SinkSpec::Serial {
                    path: path.into(),
                    baud,
                })
            }
            "mqtt" => MqttSpec::parse(rest).map(SinkSpec::Mqtt),
            _ => Err(format!("unknown sink `{scheme}:` (expected {SINK_FORMS})")),
        }
    }
}

/// The host part of a sink's value after `scheme:` or `scheme://`: up to
/// the first `/` or `?`.
fn authority(rest: &str) -> &str {
    &rest[..rest.find(['/', '?']).unwrap_or(rest.len())]
}

/// `spec` as it may be shown in a log: a `user:password@` part (refused
/// by [`SinkSpec::parse`], but echoed by the error that says so) becomes
/// `***@`, in a URL-style value (`mqtt://u:p@host`, `file://u:p@x`) and in
/// the host of `udp:` and `mqtt:`. A `file:` path may hold an `@`: it is
/// shown as it is.
pub fn redacted(spec: &str) -> std::borrow::Cow<'_, str> {
    let (scheme, sep, rest) = match spec.split_once("://") {
        Some((scheme, rest)) => (scheme, "://", rest),
        None => match spec.split_once(':') {
            Some((scheme @ ("udp" | "mqtt"), rest)) => (scheme, ":", rest),
            _ => return spec.into(),
        },
    };
    match authority(rest).rfind('@') {
        Some(at) => format!("{scheme}{sep}***{}", &rest[at..]).into(),
        None => spec.into(),
    }
}

/// The message for a URL-style `udp://..` or `mqtt://..`: these sinks take
/// `HOST:PORT` right after the colon, and `//` would become part of the
/// host name (a UDP destination that fails to resolve only when the run
/// starts). It shows the value as it should have been written.
fn without_slashes(scheme: &str, after: &str) -> String {
    let (authority, query) = match after.split_once('?') {
        Some((a, q)) => (a, Some(q)),
        None => (after, None),
    };
    // `mqtt://host:1883/` and `mqtt://user@host` are URL habits too.
    let authority = authority.trim_end_matches('/');
    let (credentials, host) = match authority.rsplit_once('@') {
        Some((_, h)) => (true, h),
        None => (false, authority),
    };
    let mut fixed = if host.is_empty() {
        match scheme {
            "udp" => "udp:HOST:PORT".to_string(),
            _ => "mqtt:HOST[:PORT]".to_string(),
        }
    } else {
        format!("{scheme}:{host}")
    };
    if let Some(q) = query.filter(|q| !q.is_empty()) {
        fixed = format!("{fixed}?{q}");
    }
    let mut msg = format!("write `{fixed}`, without `//`");
    if credentials {
        msg.push_str(
            " (credentials go in [report.mqtt] username/password or \
             STATURE_MQTT_USERNAME/STATURE_MQTT_PASSWORD)",
        );
    }
    msg
}

/// An open sink.
pub enum Sink {
    /// Standard output (its descriptor, written like a report file: a
    /// redirect to a file is one).
    Stdout(FileSink),
    /// An appended file.
    File(FileSink),
    /// A connected-less UDP socket and its destination.
    Udp(UdpSocket, SocketAddr),
    /// A serial port.
    Serial(SerialSink),
    /// An MQTT broker, served by its own connection thread.
    #[cfg(feature = "mqtt")]
    Mqtt(Box<super::mqtt::link::MqttSink>),
}

/// A report file, written one record per `write` call.
///
/// Unbuffered on purpose: records come a few per second, and a buffered
/// writer would report a full disk (`ENOSPC`) only at a later flush, for
/// records it had already accepted, so losses could not be counted per
/// record. Here every record that is not entirely in the file is an error
/// the I/O thread counts.
///
/// A record is in a regular file whole or not at all: a write cut short (a
/// full disk) is cut back off the file, so that a JSON Lines reader never
/// meets half a record glued to the next one, in this run or the next
/// run appending. Where that cannot be done (a pipe, a FIFO), the next
/// record first closes the fragment (see [`write_after_fragment`]).
pub struct FileSink {
    file: std::fs::File,
    /// The path, for logs.
    path: String,
    /// The last write failed part-way: the file may end in a fragment.
    torn: bool,
    /// A pipe or FIFO (standard output into `| consumer`, a `file:` FIFO):
    /// written only once it has room, else the record is not delivered.
    pipe: bool,
    /// Set while the pipe's reader is not reading.
    stall: Stall,
}

impl FileSink {
    /// `file`, opened to append; a regular file that ends inside a record
    /// (a power cut, a kill during a write, an older build) has that
    /// fragment closed before the first record.
    fn new(file: std::fs::File, path: String) -> FileSink {
        use std::os::unix::fs::FileTypeExt;
        let torn = ends_inside_a_record(&file);
        let pipe = file.metadata().is_ok_and(|m| m.file_type().is_fifo());
        FileSink {
            file,
            path,
            torn,
            pipe,
            stall: Stall::default(),
        }
    }

    fn write(&mut self, bytes: &[u8]) -> io::Result<()> {
        if !self.pipe {
            return self.write_now(bytes);
        }
        let mut stall = self.stall;
        let written = stall.write(|| {
            // Room for a record (POLLOUT: a free pipe buffer of a page, at
            // least `MAX_RECORD`), so the write below does not block.
            use rustix::event::{poll, PollFd, PollFlags, Timespec};
            let mut fds = [PollFd::new(&self.file, PollFlags::OUT)];
            let wait = Timespec {
                tv_sec: 0,
                tv_nsec: SERIAL_TIMEOUT.as_nanos() as _,
            };
            match poll(&mut fds, Some(&wait)) {
                Ok(0) => Err(io::ErrorKind::TimedOut.into()),
                // A reader gone shows as POLLERR; the write says EPIPE.
                Ok(_) | Err(rustix::io::Errno::INTR) => self.write_now(bytes),
                Err(e) => Err(e.into()),
            }
        });
        self.stall = stall;
        written
    }

    fn write_now(&mut self, bytes: &[u8]) -> io::Result<()> {
        // The length before this record, when the file is a regular one.
        let start = self
            .file
            .metadata()
            .ok()
            .filter(std::fs::Metadata::is_file)
            .map(|m| m.len());
        let file = &self.file;
        let cut = start.map(|s| move || file.set_len(s));
        write_whole(&mut &*file, &mut self.torn, bytes, cut)
    }
}

/// [`write_after_fragment`], and when a failed record may have left a
/// fragment and `cut` can put the output back to its length before the
/// record (a regular file's `ftruncate`, which needs no free space), it
/// does: nothing of the record is left, and a fragment from before is there
/// as it was.
fn write_whole<W: Write>(
    w: &mut W,
    torn: &mut bool,
    bytes: &[u8],
    cut: Option<impl FnOnce() -> io::Result<()>>,
) -> io::Result<()> {
    let was_torn = *torn;
    let written = write_after_fragment(w, torn, bytes);
    if written.is_err() && *torn && cut.is_some_and(|c| c().is_ok()) {
        *torn = was_torn;
    }
    written
}

/// Whether a regular file's last byte is no record separator (`\n` after
/// a JSON line, `0` after a COBS frame). Unknown (not readable, not a
/// regular file): no.
fn ends_inside_a_record(file: &std::fs::File) -> bool {
    use std::os::unix::fs::FileExt;
    let Some(len) = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len())
    else {
        return false;
    };
    if len == 0 {
        return false;
    }
    // The sink's descriptor only appends; read through /proc/self/fd.
    let mut last = [0u8; 1];
    let read = std::fs::File::open(format!(
        "/proc/self/fd/{}",
        std::os::fd::AsRawFd::as_raw_fd(file)
    ))
    .and_then(|r| r.read_exact_at(&mut last, len - 1));
    read.is_ok() && last[0] != b'\n' && last[0] != 0
}

/// A serial port, written one record per `write` call.
///
/// A write that times out (the far end stopped reading, or flow control
/// holds the line) may have sent part of a record; like [`FileSink`], the
/// next record first closes that fragment, so the reader loses one record,
/// not two.
pub struct SerialSink {
    port: Box<dyn serialport::SerialPort>,
    /// The device, for logs.
    path: String,
    /// The last write failed part-way: the line may end in a fragment.
    torn: bool,
    /// Set while the far end is not reading.
    stall: Stall,
}

/// A byte stream that stopped taking records (a serial line whose far end
/// stopped reading, a pipe nobody drains). Once a write has timed out,
/// records fail at once, unwritten, until [`STALL_RETRY`] has passed; then
/// one write tries again. One stream shares the I/O thread with every
/// other sink: without this each record waited its full timeout (a
/// serial port 200 ms, a full pipe for ever), so the other sinks fell
/// behind, lost records once the queue filled, and the end of the run
/// waited on it (89 records took 15 s, past the service's stop timeout).
#[derive(Clone, Copy, Debug, Default)]
struct Stall {
    /// Until when records are failed unwritten.
    until: Option<std::time::Instant>,
}

/// How long a stalled stream is left alone before the next try.
const STALL_RETRY: Duration = Duration::from_secs(1);

impl Stall {
    /// Fails a record at once while the stream is left alone.
    fn check(&self, now: std::time::Instant) -> io::Result<()> {
        match self.until {
            Some(t) if now < t => Err(io::ErrorKind::TimedOut.into()),
            _ => Ok(()),
        }
    }

    /// Takes note of a write's outcome: a timeout (or a full non-blocking
    /// pipe) starts a pause, anything else ends it.
    fn note(&mut self, now: std::time::Instant, written: &io::Result<()>) {
        self.until = match written {
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                Some(now + STALL_RETRY)
            }
            _ => None,
        };
    }

    /// `write`, unless the stream is left alone; `write` is then noted.
    fn write(&mut self, write: impl FnOnce() -> io::Result<()>) -> io::Result<()> {
        let now = std::time::Instant::now();
        self.check(now)?;
        let written = write();
        self.note(std::time::Instant::now(), &written);
        written
    }
}

/// Writes one encoded record; `torn` says the previous write failed
/// part-way and may have left a fragment at the end of the output.
fn write_after_fragment<W: Write>(w: &mut W, torn: &mut bool, bytes: &[u8]) -> io::Result<()> {
    if *torn {
        // Close the fragment with the record separator (`\n` for JSON
        // Lines, `0` for COBS frames: each encoding ends in its own), so a
        // reader loses that one record and not the next as well.
        w.write_all(&bytes[bytes.len().saturating_sub(1)..])?;
        *torn = false;
    }
    // `write_all` does not say how far it got: a write that failed before
    // its first byte (a full disk, a serial line that timed out) leaves no
    // fragment, and closing one there would put an empty record in the stream.
    let mut sent = 0;
    while sent < bytes.len() {
        match w.write(&bytes[sent..]) {
            Ok(0) => {
                *torn = sent > 0;
                return Err(io::ErrorKind::WriteZero.into());
            }
            Ok(n) => sent += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => {
                *torn = sent > 0;
                return Err(e);
            }
        }
    }
    Ok(())
}

/// How long a serial write (or a wait for room in a pipe) may block
/// before the record is dropped.
const SERIAL_TIMEOUT: Duration = Duration::from_millis(200);

/// Whether `file` is the null device (the same character device as
/// `/dev/null`).
fn is_dev_null(file: &std::fs::File) -> bool {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    match (file.metadata(), std::fs::metadata("/dev/null")) {
        (Ok(f), Ok(null)) => f.file_type().is_char_device() && f.rdev() == null.rdev(),
        _ => false,
    }
}

impl Sink {
    /// Opens the sink (at start-up: resolving names and opening files may
    /// allocate). An `mqtt:` sink takes the default `[report.mqtt]` settings;
    /// see [`Sink::open_with`].
    pub fn open(spec: &SinkSpec) -> io::Result<Sink> {
        Sink::open_with(spec, &MqttConfig::default())
    }

    /// Opens the sink; an `mqtt:` sink merges its URI over `mqtt` (the
    /// config file's `[report.mqtt]`) and the `STATURE_MQTT_USERNAME` /
    /// `STATURE_MQTT_PASSWORD` environment variables over both.
    pub fn open_with(spec: &SinkSpec, mqtt: &MqttConfig) -> io::Result<Sink> {
        Ok(match spec {
            SinkSpec::Stdout => {
                use std::os::fd::AsFd;
                let fd = io::stdout()
                    .as_fd()
                    .try_clone_to_owned()
                    .map_err(|e| io::Error::new(e.kind(), format!("standard output: {e}")))?;
                let file = std::fs::File::from(fd);
                if is_dev_null(&file) {
                    // A service unit or a shell that closed standard output
                    // (`>&-`) leaves /dev/null there (the runtime reopens a
                    // closed fd 1 on it): every record would "arrive".
                    log::warn!(
                        "report sink stdout: standard output is /dev/null (redirected there, or \
                         closed), so the records written to it are discarded"
                    );
                }
                Sink::Stdout(FileSink::new(file, "stdout".into()))
            }
            SinkSpec::File(p) => Sink::File(FileSink::new(
                open_report_file(p).map_err(|e| file_error(p, e))?,
                p.clone(),
            )),
            SinkSpec::Udp(addr) => {
                let dest = udp_addresses(addr)
                    .map_err(|e| {
                        io::Error::new(e.kind(), format!("UDP destination `{addr}`: {e}"))
                    })?
                    .next()
                    .ok_or_else(|| {
                        io::Error::new(
                            io::ErrorKind::NotFound,
                            format!("UDP destination `{addr}` has no address"),
                        )
                    })?;
                let bind: SocketAddr = if dest.is_ipv4() {
                    "0.0.0.0:0".parse().unwrap()
                } else {
                    "[::]:0".parse().unwrap()
                };
                let sock = UdpSocket::bind(bind)?;
                sock.set_nonblocking(true)?;
                // A broadcast destination (255.255.255.255, a subnet's
                // .255: every listener on the segment) is refused by the
                // kernel with EACCES on every datagram unless asked for.
                if dest.is_ipv4() {
                    sock.set_broadcast(true)?;
                }
                Sink::Udp(sock, dest)
            }
            SinkSpec::Serial { path, baud } => {
                // The check first: it names what the path is (`/dev/null`:
                // "a mem device") where the open would say only "Not a
                // typewriter", and it opens nothing that is not a port.
                check_local(spec)?;
                let port = serialport::new(path, *baud)
                    .timeout(SERIAL_TIMEOUT)
                    .open()
                    .map_err(|e| serial_error(path, e))?;
                Sink::Serial(SerialSink {
                    port,
                    path: path.clone(),
                    torn: false,
                    stall: Stall::default(),
                })
            }
            SinkSpec::Mqtt(m) => {
                let settings = MqttSettings::resolve(m, mqtt, |k| std::env::var(k).ok());
                #[cfg(feature = "mqtt")]
                {
                    Sink::Mqtt(Box::new(super::mqtt::link::MqttSink::open(settings)?))
                }
                #[cfg(not(feature = "mqtt"))]
                {
                    return Err(io::Error::new(
                        io::ErrorKind::Unsupported,
                        format!(
                            "MQTT sink {}: this build has no MQTT support (rebuild with `--features mqtt`)",
                            settings.broker()
                        ),
                    ));
                }
            }
        })
    }

    /// Writes one record: `bytes` is `record` already encoded in `format`.
    /// Byte-stream sinks write `bytes`; the MQTT sink routes by the
    /// record's kind and always publishes JSON.
    pub fn write(&mut self, record: &Record, bytes: &[u8], format: Format) -> io::Result<()> {
        match self {
            #[cfg(feature = "mqtt")]
            Sink::Mqtt(m) => m.write(record, bytes, format),
            _ => {
                let _ = (record, format);
                self.write_record(bytes)
            }
        }
    }

    /// Lets a sink that drops records on its own (MQTT, while the broker is
    /// away) count them in the run's counters.
    pub fn attach_counters(&mut self, counters: &Arc<Counters>) {
        match self {
            #[cfg(feature = "mqtt")]
            Sink::Mqtt(m) => m.attach_counters(counters.clone()),
            _ => {
                let _ = counters;
            }
        }
    }

    /// End of run: flushes, and lets a sink with a session end it cleanly
    /// (MQTT delivers held records within its shutdown timeout, publishes
    /// `offline` and disconnects).
    pub fn close(&mut self) -> io::Result<()> {
        let r = self.flush();
        #[cfg(feature = "mqtt")]
        if let Sink::Mqtt(m) = self {
            m.close();
        }
        r
    }

    /// Records this sink accepted and then lost on its own (an MQTT
    /// outbox that overflowed while the broker was away, or that still
    /// held records at the shutdown timeout). 0 for the byte-stream sinks,
    /// whose losses are the failed writes.
    pub fn lost_after_accepting(&self) -> u64 {
        match self {
            #[cfg(feature = "mqtt")]
            Sink::Mqtt(m) => m.dropped(),
            _ => 0,
        }
    }

    /// Writes one encoded record. An error means the record was not delivered.
    pub fn write_record(&mut self, bytes: &[u8]) -> io::Result<()> {
        match self {
            Sink::Stdout(f) | Sink::File(f) => f.write(bytes),
            Sink::Udp(sock, dest) => sock.send_to(bytes, *dest).map(|_| ()),
            Sink::Serial(s) => {
                let (port, torn) = (&mut s.port, &mut s.torn);
                s.stall.write(|| write_after_fragment(port, torn, bytes))
            }
            #[cfg(feature = "mqtt")]
            Sink::Mqtt(_) => Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "the MQTT sink needs the record itself: use Sink::write",
            )),
        }
    }

    /// Flushes buffered output (called when the queue runs empty).
    pub fn flush(&mut self) -> io::Result<()> {
        match self {
            Sink::Serial(s) => s.port.flush(),
            _ => Ok(()),
        }
    }

    /// The sink as logs name it, so that two sinks of a kind can be told
    /// apart: `stdout`, `file:PATH`, `udp:ADDRESS:PORT`, `serial:PATH`,
    /// `mqtt:HOST:PORT` (no options, no credentials).
    pub fn label(&self) -> String {
        match self {
            Sink::Stdout(_) => "stdout".into(),
            Sink::File(f) => format!("file:{}", f.path),
            Sink::Udp(_, dest) => format!("udp:{dest}"),
            Sink::Serial(s) => format!("serial:{}", s.path),
            #[cfg(feature = "mqtt")]
            Sink::Mqtt(m) => format!("mqtt:{}", m.broker()),
        }
    }
}

/// A `file:` sink's failure to open, naming the file.
fn file_error(path: &str, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("report file `{path}`: {e}"))
}

/// A `serial:` sink's failure to open, naming the port.
fn serial_error(path: &str, e: impl std::fmt::Display) -> io::Error {
    io::Error::new(
        io::ErrorKind::NotFound,
        format!("serial port `{path}`: {e}"),
    )
}

/// What can be known of a `file:` or `serial:` sink without opening it
/// for good (`config --check`): opening would create the file, or toggle
/// a serial port's modem lines and reset the board on the other end. The
/// errors read as [`Sink::open_with`]'s. Other sinks: nothing to check.
///
/// - file: an existing one is opened for appending, without creating or
///   writing anything (a FIFO is left alone: its reader may start after
///   the check); a missing one needs a writable directory.
/// - serial: the path is a character device this process may read and
///   write.
pub fn check_local(spec: &SinkSpec) -> io::Result<()> {
    use rustix::fs::{access, Access};
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    match spec {
        SinkSpec::File(p) => {
            let named = |e: io::Error| file_error(p, e);
            // Where a write lands: the end of a chain of links (a
            // dangling link's write creates its target).
            let (target, meta) = crate::replace::follow_links(p.as_ref()).map_err(named)?;
            match meta {
                Some(m) if m.file_type().is_fifo() => Ok(()),
                Some(_) => std::fs::OpenOptions::new()
                    .append(true)
                    .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
                    .open(p)
                    .map(drop)
                    .map_err(named),
                // `new/` names a directory, which open(2) does not create.
                None if target.as_os_str().as_encoded_bytes().ends_with(b"/") => Err(named(
                    io::Error::from_raw_os_error(rustix::io::Errno::ISDIR.raw_os_error()),
                )),
                None => access(
                    crate::replace::dir_of(&target),
                    Access::WRITE_OK | Access::EXEC_OK,
                )
                .map_err(|e| named(crate::replace::name_missing_dir(&target, e.into()))),
            }
        }
        SinkSpec::Serial { path, .. } => {
            let named = |e: io::Error| serial_error(path, e);
            use std::os::unix::fs::MetadataExt;
            let m = std::fs::metadata(path).map_err(named)?;
            if !m.file_type().is_char_device() {
                return Err(named(io::Error::other("not a serial device")));
            }
            let (major, minor) = (rustix::fs::major(m.rdev()), rustix::fs::minor(m.rdev()));
            // /dev/tty (the controlling terminal: none under a service)
            // and /dev/ptmx (a new pseudo-terminal nothing reads).
            if major == 5 && (minor == 0 || minor == 2) {
                return Err(named(io::Error::other("not a serial device")));
            }
            // The kernel's class of the device (`/dev/null` is `mem`). A
            // node with no entry has no driver behind it (a stale
            // /dev/ttyUSB0), except pseudo-terminals (majors 136-143),
            // which sysfs does not list; without sysfs nothing is known.
            let class = std::fs::read_link(format!("/sys/dev/char/{major}:{minor}/subsystem"));
            match class.ok().as_deref().and_then(|c| c.file_name()) {
                Some(c) if c == "tty" => {}
                Some(c) => {
                    return Err(named(io::Error::other(format!(
                        "not a serial device (a {} device)",
                        c.to_string_lossy()
                    ))))
                }
                None if (136..=143).contains(&major)
                    || !std::path::Path::new("/sys/dev/char").is_dir() => {}
                None => {
                    return Err(named(io::Error::other(format!(
                        "no device driver behind it (character device {major}:{minor})"
                    ))))
                }
            }
            access(path.as_str(), Access::READ_OK | Access::WRITE_OK).map_err(|e| named(e.into()))
        }
        SinkSpec::Stdout | SinkSpec::Udp(_) | SinkSpec::Mqtt(_) => Ok(()),
    }
}

/// Opens a report file for appending. Non-blocking, so that a FIFO with
/// no reader is an error now (`ENXIO`) rather than an open that waits
/// forever and that no signal ends; a full FIFO then fails a write (the
/// record is lost at this sink and counted) instead of stalling the I/O
/// thread, and with it the end of the run. Regular files ignore the flag.
fn open_report_file(path: &str) -> io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
        .open(path)
        .map_err(|e| {
            use std::os::unix::fs::FileTypeExt;
            let fifo = || std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo());
            // (ENXIO also comes from a socket or a device with nothing behind it.)
            if e.raw_os_error() == Some(rustix::io::Errno::NXIO.raw_os_error()) && fifo() {
                io::Error::new(
                    e.kind(),
                    "it is a FIFO that nothing reads: start the reader first",
                )
            } else if e.kind() == io::ErrorKind::NotFound {
                // Through a link, the missing directory is the target's
                // (as `config --check` names it).
                let path = std::path::Path::new(path);
                let target = crate::replace::follow_links(path).map(|(t, _)| t);
                crate::replace::name_missing_dir(target.as_deref().unwrap_or(path), e)
            } else {
                e
            }
        })
}

/// A `udp:` host that no lookup could resolve, said as the user's typing
/// mistake (exit code 2) rather than as a name the network did not know
/// (exit code 3): an IPv6 address that is not in brackets or does not
/// parse, or a name with characters no host name has.
fn udp_host_syntax(host: &str) -> Result<(), String> {
    if let Some(inner) = host.strip_prefix('[') {
        let addr = inner.strip_suffix(']').ok_or_else(|| {
            format!("`{host}`: an IPv6 address goes in brackets (expected udp:[ADDRESS]:PORT)")
        })?;
        // A link-local address may name its interface (`fe80::1%eth0`).
        let ip = addr.split_once('%').map_or(addr, |(ip, _)| ip);
        return ip
            .parse::<std::net::Ipv6Addr>()
            .map(drop)
            .map_err(|_| format!("`{addr}` is not an IPv6 address (expected udp:[ADDRESS]:PORT)"));
    }
    if host.contains(':') {
        return Err(format!(
            "`{host}`: an IPv6 address goes in brackets (expected udp:[ADDRESS]:PORT)"
        ));
    }
    match host
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_')))
    {
        Some(c) => Err(format!(
            "host `{host}` holds {c:?}, which no host name or address does (expected udp:HOST:PORT)"
        )),
        None => Ok(()),
    }
}

/// The addresses of a `udp:` destination `HOST:PORT`. A bracketed IPv6
/// host is resolved without its brackets, so that a link-local address
/// with its interface (`[fe80::1%eth0]:5000`), which the standard
/// library's address parser does not read, goes to the system resolver,
/// which does.
pub fn udp_addresses(addr: &str) -> io::Result<std::vec::IntoIter<SocketAddr>> {
    let bracketed = addr
        .strip_prefix('[')
        .and_then(|rest| rest.rsplit_once("]:"))
        .and_then(|(host, port)| Some((host, port.parse::<u16>().ok()?)));
    match bracketed {
        Some((host, port)) if host.contains('%') => (host, port).to_socket_addrs(),
        _ => addr.to_socket_addrs(),
    }
}

#[cfg(test)]
mod tests {
    /// Before: "failed to lookup address information" for a scoped
    /// link-local destination.
    #[test]
    fn a_link_local_udp_destination_names_its_interface() {
        use super::udp_addresses;
        use std::net::SocketAddr;
        let a: Vec<SocketAddr> = udp_addresses("[fe80::1%lo]:5000").unwrap().collect();
        match a.first() {
            Some(SocketAddr::V6(v6)) => {
                assert_eq!(v6.port(), 5000);
                assert_eq!(v6.ip().segments()[0], 0xfe80);
                assert_ne!(v6.scope_id(), 0, "the interface's index");
            }
            other => panic!("{other:?}"),
        }
        // Everything else as before.
        assert_eq!(
            udp_addresses("[::1]:9").unwrap().next(),
            Some("[::1]:9".parse().unwrap())
        );
        assert_eq!(
            udp_addresses("127.0.0.1:9").unwrap().next(),
            Some("127.0.0.1:9".parse().unwrap())
        );
        assert!(udp_addresses("[fe80::1%no-such-if9]:5000").is_err());
    }

    /// Accepts `room` bytes, then fails like a full disk until given more.
    struct FullDisk {
        data: Vec<u8>,
        room: usize,
    }

    impl Write for FullDisk {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            let n = b.len().min(self.room);
            if n == 0 {
                return Err(io::Error::from_raw_os_error(28));
            }
            self.data.extend_from_slice(&b[..n]);
            self.room -= n;
            Ok(n)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_record_cut_by_a_full_disk_costs_only_itself() {
        let mut disk = FullDisk {
            data: Vec::new(),
            room: 20,
        };
        let mut torn = false;
        let rec = |n: u32| format!("{{\"type\":\"bye\",\"frame\":{n}}}\n");
        assert!(write_after_fragment(&mut disk, &mut torn, rec(1).as_bytes()).is_err());
        assert!(torn);
        assert!(write_after_fragment(&mut disk, &mut torn, rec(2).as_bytes()).is_err());
        disk.room = 1000; // space freed
        write_after_fragment(&mut disk, &mut torn, rec(3).as_bytes()).unwrap();
        write_after_fragment(&mut disk, &mut torn, rec(4).as_bytes()).unwrap();
        let text = String::from_utf8(disk.data).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        // The fragment of record 1 is a line of its own; 3 and 4 are whole.
        assert_eq!(
            lines,
            [
                &rec(1)[..20],
                &rec(3)[..rec(3).len() - 1],
                &rec(4)[..rec(4).len() - 1]
            ]
        );
    }
    #[test]
    fn a_record_refused_whole_leaves_no_empty_record() {
        let mut disk = FullDisk {
            data: Vec::new(),
            room: 0,
        };
        let mut torn = false;
        let rec = |n: u32| format!("{{\"type\":\"bye\",\"frame\":{n}}}\n");
        assert!(write_after_fragment(&mut disk, &mut torn, rec(1).as_bytes()).is_err());
        assert!(!torn, "nothing of record 1 went out");
        disk.room = 1000;
        write_after_fragment(&mut disk, &mut torn, rec(2).as_bytes()).unwrap();
        assert_eq!(String::from_utf8(disk.data).unwrap(), rec(2));
    }

    use super::*;

    /// A report file on a full file system: a record that does not fit is
    /// cut back off (before: its first part stayed, and the next record,
    /// of this run once space came back or of the next run appending, was
    /// glued onto it, so a JSON Lines reader lost both).
    #[test]
    fn a_record_cut_by_a_full_disk_is_cut_back_off_a_file() {
        let disk = std::cell::RefCell::new(FullDisk {
            data: Vec::new(),
            room: 40,
        });
        let rec = |n: u32| format!("{{\"type\":\"bye\",\"frame\":{n}}}\n");
        let mut torn = false;
        let mut write = |n: u32| {
            let start = disk.borrow().data.len();
            let cut = || {
                disk.borrow_mut().data.truncate(start);
                Ok(())
            };
            write_whole(&mut DiskRef(&disk), &mut torn, rec(n).as_bytes(), Some(cut))
        };
        write(1).unwrap();
        assert!(write(2).is_err(), "record 2 does not fit");
        assert!(write(3).is_err(), "nor does record 3");
        disk.borrow_mut().room = 1000;
        write(4).unwrap();
        let text = String::from_utf8(disk.into_inner().data).unwrap();
        assert_eq!(text, rec(1) + &rec(4));
    }

    /// A stream whose write timed out is left alone for `STALL_RETRY`
    /// (records fail at once, unwritten), then tried again; a write that
    /// goes through ends the pause, any other failure does not start one.
    #[test]
    fn a_stalled_stream_is_left_alone_then_tried_again() {
        let t0 = std::time::Instant::now();
        let ms = |n| t0 + Duration::from_millis(n);
        let mut stall = Stall::default();
        assert!(stall.check(t0).is_ok());
        stall.note(ms(200), &Err(io::ErrorKind::TimedOut.into()));
        for t in [200, 700, 1199] {
            let e = stall.check(ms(t)).unwrap_err();
            assert_eq!(e.kind(), io::ErrorKind::TimedOut, "{t} ms");
        }
        assert!(stall.check(ms(1200)).is_ok(), "tried again");
        stall.note(ms(1200), &Ok(()));
        assert!(stall.check(ms(1201)).is_ok());
        // A full non-blocking FIFO is a stall; a reader gone is not.
        stall.note(ms(1300), &Err(io::ErrorKind::WouldBlock.into()));
        assert!(stall.check(ms(1400)).is_err());
        stall.note(ms(2300), &Err(io::ErrorKind::BrokenPipe.into()));
        assert!(stall.check(ms(2301)).is_ok());
        // Through `write`: a pause skips the write itself.
        let mut stall = Stall::default();
        let mut tries = 0;
        let mut timed_out = || {
            tries += 1;
            Err(io::ErrorKind::TimedOut.into())
        };
        assert!(stall.write(&mut timed_out).is_err());
        assert!(stall.write(&mut timed_out).is_err());
        assert_eq!(tries, 1, "the second record was not written");
    }

    /// Standard output into a pipe nobody reads: a record waits for room
    /// at most `SERIAL_TIMEOUT`, then the pipe is left alone, so one
    /// stalled reader cannot hold up the I/O thread (before: the write
    /// blocked until the reader read, for ever).
    #[test]
    fn a_full_pipe_fails_records_instead_of_blocking() {
        let (r, w) = rustix::pipe::pipe().unwrap();
        let mut sink = FileSink::new(std::fs::File::from(w), "pipe".into());
        assert!(sink.pipe);
        let rec = [b'x'; 1000];
        let mut failed = 0;
        // 64 KiB of pipe: a few hundred records fill it many times over.
        for _ in 0..300 {
            if sink.write(&rec).is_err() {
                failed += 1;
            }
        }
        assert!(failed > 200, "{failed} of 300 records failed");
        drop(r);
    }

    /// A file left ending inside a record (a power cut during a write, an
    /// older build) has that fragment closed before the first record.
    #[test]
    fn a_report_file_ending_inside_a_record_is_closed_first() {
        let dir = crate::scratch::fresh_dir("sink-fragment-at-open");
        let path = dir.join("r.jsonl");
        let rec = |n: u32| format!("{{\"type\":\"bye\",\"frame\":{n}}}\n");
        for (before, torn) in [(rec(0) + "{\"type\":\"hel", true), (rec(0), false)] {
            std::fs::write(&path, &before).unwrap();
            let file = open_report_file(path.to_str().unwrap()).unwrap();
            let mut sink = FileSink::new(file, "r".into());
            assert_eq!(sink.torn, torn, "{before}");
            sink.write(rec(1).as_bytes()).unwrap();
            let text = std::fs::read_to_string(&path).unwrap();
            let last = text.lines().last().unwrap();
            assert_eq!(format!("{last}\n"), rec(1), "{text}");
        }
    }

    /// `&RefCell<FullDisk>` as a writer (the test's cut-back needs the
    /// disk while the write holds it).
    struct DiskRef<'a>(&'a std::cell::RefCell<FullDisk>);

    impl Write for DiskRef<'_> {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            self.0.borrow_mut().write(b)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn specs_parse() {
        assert_eq!(SinkSpec::parse("stdout"), Ok(SinkSpec::Stdout));
        assert_eq!(
            SinkSpec::parse("udp:127.0.0.1:9000"),
            Ok(SinkSpec::Udp("127.0.0.1:9000".into()))
        );
        assert_eq!(
            SinkSpec::parse("serial:/dev/ttyS0?baud=9600"),
            Ok(SinkSpec::Serial {
                path: "/dev/ttyS0".into(),
                baud: 9600
            })
        );
        assert_eq!(
            SinkSpec::parse("file:/tmp/x.jsonl"),
            Ok(SinkSpec::File("/tmp/x.jsonl".into()))
        );
        assert!(matches!(
            SinkSpec::parse("mqtt:broker:1883?topic=stature/cam1&qos=1"),
            Ok(SinkSpec::Mqtt(m)) if m.host == "broker" && m.port == Some(1883)
        ));
        for ok in [
            "udp:[::1]:9",
            "udp:[fe80::1%eth0]:5000",
            "udp:10.0.0.255:9",
            "udp:collector.lan:9",
            "udp:my_host-2:9",
        ] {
            assert!(SinkSpec::parse(ok).is_ok(), "{ok}");
        }
        // Before: a lookup error and exit code 3, as if the network had
        // not known the name.
        for (bad, why) in [
            ("udp:[::1:5000", "goes in brackets"),
            ("udp:::1:5000", "goes in brackets"),
            ("udp:[::g]:5000", "is not an IPv6 address"),
            ("udp:a b:5000", "holds ' '"),
            ("udp:host/x:5000", "holds '/'"),
        ] {
            let e = SinkSpec::parse(bad).unwrap_err();
            assert!(e.contains(why), "{bad}: {e}");
        }
        for bad in [
            "udp:host",
            "udp:host:0",
            "udp::9",
            "serial:ttyS0",
            "serial:/dev/ttyS0?baud=1",
            "tcp:x:1",
            "mqtt:",
            "mqtt:host:0",
            "mqtt:host?user=x",
            "file:",
            "nope",
        ] {
            assert!(SinkSpec::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn url_style_slashes_are_refused_with_the_form_to_write() {
        for (bad, reason) in [
            (
                "mqtt://127.0.0.1:1883",
                "write `mqtt:127.0.0.1:1883`, without `//`",
            ),
            ("mqtt://broker", "write `mqtt:broker`, without `//`"),
            (
                "mqtt://broker:1883/?topic=a/b&qos=1",
                "write `mqtt:broker:1883?topic=a/b&qos=1`, without `//`",
            ),
            ("mqtt://[::1]:1883", "write `mqtt:[::1]:1883`, without `//`"),
            ("mqtt://", "write `mqtt:HOST[:PORT]`, without `//`"),
            (
                "udp://127.0.0.1:9000",
                "write `udp:127.0.0.1:9000`, without `//`",
            ),
            ("udp://", "write `udp:HOST:PORT`, without `//`"),
        ] {
            assert_eq!(SinkSpec::parse(bad).unwrap_err(), reason, "{bad}");
        }
        let e = SinkSpec::parse("mqtt://cam:secret@broker").unwrap_err();
        assert!(
            e.starts_with("write `mqtt:broker`, without `//` (credentials go in"),
            "{e}"
        );
        assert!(!e.contains("secret"), "{e}");
        assert_eq!(
            redacted("mqtt://cam:secret@broker:1883?topic=t"),
            "mqtt://***@broker:1883?topic=t"
        );
        assert_eq!(redacted("mqtt:broker?topic=a@b"), "mqtt:broker?topic=a@b");
        assert_eq!(redacted("udp://h:9/x@y"), "udp://h:9/x@y");
        // Without `//` too: the host of udp: and mqtt: holds no `@`.
        for (spec, shown) in [
            ("mqtt:admin:hunter2@broker.lan", "mqtt:***@broker.lan"),
            ("mqtt:user@localhost?qos=1", "mqtt:***@localhost?qos=1"),
            ("udp:u:s3cret@localhost:9000", "udp:***@localhost:9000"),
            ("file://u:s3cret@x", "file://***@x"),
            ("file:/var/log/a@b.jsonl", "file:/var/log/a@b.jsonl"),
        ] {
            assert_eq!(redacted(spec), shown);
            let e = SinkSpec::parse(spec);
            if spec.starts_with("file:/var") {
                assert!(e.is_ok(), "a path may hold an @: {e:?}");
            } else {
                let e = e.unwrap_err();
                assert!(!e.contains("s3cret") && !e.contains("hunter2"), "{e}");
                assert!(e.contains("user") && e.contains("password"), "{e}");
            }
        }
        assert_eq!(
            SinkSpec::parse("mqtts://broker:8883").unwrap_err(),
            "write `mqtt:broker:8883?tls=true` (TLS is an mqtt: option)"
        );
        assert_eq!(
            SinkSpec::parse("mqtts:broker").unwrap_err(),
            "write `mqtt:broker?tls=true` (TLS is an mqtt: option)"
        );
        assert_eq!(
            SinkSpec::parse("mqtts://broker?topic=t").unwrap_err(),
            "write `mqtt:broker?topic=t&tls=true` (TLS is an mqtt: option)"
        );
        let e = SinkSpec::parse("file://x.jsonl").unwrap_err();
        assert!(
            e.contains("names `/x.jsonl` at the root") && e.contains("write `file:x.jsonl`"),
            "{e}"
        );
        // A file or serial path may start with `//` (POSIX reads it as `/`).
        assert_eq!(
            SinkSpec::parse("file:///tmp/x.jsonl"),
            Ok(SinkSpec::File("///tmp/x.jsonl".into()))
        );
    }

    #[test]
    fn a_bad_spec_is_named_once_with_one_reason() {
        let form = "mqtt:HOST[:PORT][?topic=T&qos=0|1&client_id=ID&tls=true|false&ca=FILE&ha_discovery=true|false]";
        for (bad, reason) in [
            ("udp:", "expected udp:HOST:PORT"),
            ("udp:host", "expected udp:HOST:PORT"),
            ("udp:host:", "expected udp:HOST:PORT"),
            (
                "udp:host:notaport",
                "port `notaport` is not in 1..=65535 (expected udp:HOST:PORT)",
            ),
            ("serial:", "expected serial:/dev/ttyX?baud=N"),
            (
                "serial://dev/ttyS0",
                "write serial:/dev/ttyX?baud=N, without `//`",
            ),
            (
                "serial:ttyS0",
                "serial device `ttyS0` is not an absolute path (expected serial:/dev/ttyX?baud=N)",
            ),
            (
                "serial:/dev/ttyS0?baud=x",
                "`baud=x`: expected a rate in 300..=4000000",
            ),
            (
                "serial:/dev/ttyS0?parity=odd",
                "unknown serial option `parity` (expected baud=N)",
            ),
            ("file:", "expected file:PATH"),
            ("mqtt:", &format!("expected {form}")),
            ("mqtt:h:", &format!("expected {form}")),
            ("mqtt:h:0", "port `0` is not in 1..=65535"),
            ("mqtt:h?qos=7", "`qos=7`: expected 0 or 1"),
            ("mqtt:h?tls=maybe", "`tls=maybe`: expected true or false (or 1/0, yes/no)"),
            ("mqtt:h?ca=", "`ca=`: expected the path of a PEM file"),
            (
                "mqtt:h?bogus=1",
                "unknown mqtt option `bogus` (expected topic, qos, client_id, tls, ca or ha_discovery)",
            ),
            (
                "bogus:x",
                "unknown sink `bogus:` (expected stdout, file:PATH, udp:HOST:PORT, serial:PATH?baud=N or mqtt:HOST[:PORT]?topic=T&..)",
            ),
            (
                "nope",
                "expected stdout, file:PATH, udp:HOST:PORT, serial:PATH?baud=N or mqtt:HOST[:PORT]?topic=T&..",
            ),
        ] {
            assert_eq!(SinkSpec::parse(bad).unwrap_err(), reason, "{bad}");
            // As the user sees it: the value once, then the reason.
            let mut cfg = crate::config::Config::default();
            cfg.report.sinks = vec![bad.into()];
            assert_eq!(
                cfg.validate().unwrap_err().to_string(),
                format!("config key `report.sinks` = {bad}: {reason}")
            );
        }
    }

    #[test]
    fn a_check_follows_links_and_names_what_a_run_would_refuse() {
        let dir = crate::scratch::fresh_dir("sink-check");
        let d = dir.display();
        let check =
            |s: String| check_local(&SinkSpec::parse(&s).unwrap()).map_err(|e| e.to_string());
        std::os::unix::fs::symlink(dir.join("nodir/x.jsonl"), dir.join("into-nothing")).unwrap();
        std::os::unix::fs::symlink("later.jsonl", dir.join("later-link")).unwrap();
        let e = check(format!("file:{d}/into-nothing")).unwrap_err();
        let missing = format!("directory {d}/nodir does not exist");
        assert!(e.contains(&missing), "{e}");
        // The run's open says the same (the link's target's directory).
        let spec = SinkSpec::parse(&format!("file:{d}/into-nothing")).unwrap();
        let e = Sink::open(&spec).err().unwrap().to_string();
        assert!(e.contains(&missing), "{e}");
        assert_eq!(check(format!("file:{d}/later-link")), Ok(()));
        let e = check(format!("file:{d}/new/")).unwrap_err();
        assert!(e.contains("Is a directory"), "{e}");
        assert_eq!(check(format!("file:{d}/new.jsonl")), Ok(()));
        // Nothing was created.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
        for (port, why) in [
            ("/dev/null", "(a mem device)"),
            ("/dev/ptmx", "not a serial device"),
            ("/dev/tty", "not a serial device"),
        ] {
            let e = check(format!("serial:{port}?baud=9600")).unwrap_err();
            assert!(e.contains(why), "{port}: {e}");
            // The run's open says the same (it said "Not a typewriter").
            let spec = SinkSpec::parse(&format!("serial:{port}?baud=9600")).unwrap();
            let e = Sink::open(&spec).err().unwrap().to_string();
            assert!(e.contains(why), "{port}: {e}");
        }
        // A pseudo-terminal: no sysfs entry, and a serial port all the same.
        use rustix::pty::{grantpt, openpt, ptsname, unlockpt, OpenptFlags};
        let master = openpt(OpenptFlags::RDWR | OpenptFlags::NOCTTY).unwrap();
        grantpt(&master).unwrap();
        unlockpt(&master).unwrap();
        let name = ptsname(&master, Vec::new()).unwrap();
        assert_eq!(
            check(format!("serial:{}?baud=9600", name.to_string_lossy())),
            Ok(())
        );
    }

    #[test]
    fn a_fifo_nothing_reads_is_refused_at_open_and_one_that_is_read_works() {
        let dir = crate::scratch::fresh_dir("sink-fifo");
        let fifo = dir.join("records");
        crate::scratch::mkfifo(&fifo);
        let path = fifo.to_str().unwrap().to_string();
        // Before: the open waited for a reader, and no signal ended it.
        let e = Sink::open(&SinkSpec::File(path.clone())).err().unwrap();
        assert!(e.to_string().contains("a FIFO that nothing reads"), "{e}");
        let reader = std::thread::spawn({
            let fifo = fifo.clone();
            move || std::fs::read_to_string(fifo).unwrap()
        });
        // The reader's open completes once a writer is there: retry until
        // then, for at most 10 s.
        let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
        let mut sink = loop {
            match Sink::open(&SinkSpec::File(path.clone())) {
                Ok(s) => break s,
                Err(e) if std::time::Instant::now() > deadline => panic!("no reader came: {e}"),
                Err(_) => std::thread::sleep(std::time::Duration::from_millis(5)),
            }
        };
        assert_eq!(sink.label(), format!("file:{path}"));
        sink.write_record(b"{\"type\":\"bye\"}\n").unwrap();
        drop(sink);
        assert_eq!(reader.join().unwrap(), "{\"type\":\"bye\"}\n");
    }
}
