//! A small stderr logger: level and seconds since start on every line.
//! Reports go to stdout; logs never do.
//!
//! Under systemd, stderr is a stream into the journal, which stores every
//! line at the unit's default priority unless the line starts with a
//! syslog `<N>` prefix (which it strips). Without one, `journalctl -p err`
//! showed none of the errors, so when stderr is the journal's stream the
//! lines carry that prefix.

use log::{Level, LevelFilter, Log, Metadata, Record};
use std::io::Write;
use std::sync::OnceLock;
use std::time::Instant;

struct StderrLogger {
    start: Instant,
    /// Prefix lines with the syslog priority (stderr is the journal).
    journal: bool,
}

static LOGGER: OnceLock<StderrLogger> = OnceLock::new();

/// A log line assembled in a fixed buffer and written with one `write(2)`
/// (a longer line goes out in buffer-sized pieces). Formatted straight
/// into unbuffered stderr, a line took 15–25 writes, and a terminal or log
/// file that another process writes to as well (ffmpeg decoding beside
/// the run, a second stature) could get pieces of two lines mixed.
/// Allocates nothing.
///
/// The message part ([`Line::message`]) is written defanged: a line break
/// in it (a file name holding one, a multi-line error) continues on a
/// line marked `    | ` (after the journal's priority prefix, if any, so
/// journald files it at the same level), and other control characters
/// are written as `\xNN` (an escape sequence in a file name would
/// otherwise reach the terminal).
struct Line<W: Write> {
    out: W,
    buf: [u8; 1024],
    len: usize,
    /// Within the message: defang what is written (see above).
    message: bool,
    /// The journal's priority prefix, repeated on continuation lines.
    priority: Option<u8>,
}

impl<W: Write> Line<W> {
    fn new(out: W) -> Self {
        Line {
            out,
            buf: [0; 1024],
            len: 0,
            message: false,
            priority: None,
        }
    }

    /// Appends bytes as they are.
    fn raw(&mut self, mut b: &[u8]) {
        while !b.is_empty() {
            if self.len == self.buf.len() {
                self.flush();
            }
            let n = b.len().min(self.buf.len() - self.len);
            self.buf[self.len..self.len + n].copy_from_slice(&b[..n]);
            self.len += n;
            b = &b[n..];
        }
    }

    /// Writes what is buffered (errors are dropped: a log line has
    /// nowhere else to go).
    fn flush(&mut self) {
        let _ = self.out.write_all(&self.buf[..self.len]);
        self.len = 0;
    }
}

impl<W: Write> std::fmt::Write for Line<W> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        if !self.message {
            self.raw(s.as_bytes());
            return Ok(());
        }
        let mut rest = s;
        while let Some(i) = rest.find(|c: char| c.is_control() && c != '\t') {
            self.raw(&rest.as_bytes()[..i]);
            let c = rest[i..].chars().next().unwrap_or('\0');
            if c == '\n' {
                self.raw(b"\n");
                if let Some(p) = self.priority {
                    self.raw(&[b'<', b'0' + p, b'>']);
                }
                self.raw(b"    | ");
            } else {
                let mut hex = [0u8; 12];
                let n = {
                    let mut w = &mut hex[..];
                    let _ = write!(w, "\\x{:02x}", u32::from(c));
                    12 - w.len()
                };
                self.raw(&hex[..n]);
            }
            rest = &rest[i + c.len_utf8()..];
        }
        self.raw(rest.as_bytes());
        Ok(())
    }
}

/// The syslog priority journald files a line of `level` under.
pub fn syslog_priority(level: Level) -> u8 {
    match level {
        Level::Error => 3,
        Level::Warn => 4,
        Level::Info => 6,
        Level::Debug | Level::Trace => 7,
    }
}

/// Whether stderr is the journal's stream: systemd sets `JOURNAL_STREAM` to
/// `DEVICE:INODE` of the stream it connects, and a child that redirected
/// stderr elsewhere (a pipe, a file) inherits the variable but not the
/// stream, hence the comparison.
pub fn is_journal_stream(journal_stream: Option<&str>, stderr_dev_ino: Option<(u64, u64)>) -> bool {
    let (Some(var), Some((dev, ino))) = (journal_stream, stderr_dev_ino) else {
        return false;
    };
    let Some((d, i)) = var.trim().split_once(':') else {
        return false;
    };
    d.parse() == Ok(dev) && i.parse() == Ok(ino)
}

impl Log for StderrLogger {
    fn enabled(&self, m: &Metadata<'_>) -> bool {
        m.level() <= log::max_level()
    }
    fn log(&self, r: &Record<'_>) {
        if !self.enabled(r.metadata()) {
            return;
        }
        let t = self.start.elapsed();
        let level = match r.level() {
            Level::Error => "ERROR",
            Level::Warn => "WARN ",
            Level::Info => "INFO ",
            Level::Debug => "DEBUG",
            Level::Trace => "TRACE",
        };
        // Held for the whole line: two threads' lines never interleave.
        let mut line = Line::new(std::io::stderr().lock());
        use std::fmt::Write as _;
        if self.journal {
            let p = syslog_priority(r.level());
            line.priority = Some(p);
            let _ = write!(line, "<{p}>");
        }
        let _ = write!(line, "[{:>9.3}s {level}] ", t.as_secs_f64());
        line.message = true;
        let _ = write!(line, "{}", r.args());
        line.message = false;
        line.raw(b"\n");
        line.flush();
    }
    fn flush(&self) {}
}

/// Installs the logger (idempotent) at `level`.
pub fn init(level: LevelFilter) {
    let logger = LOGGER.get_or_init(|| {
        // The field types differ between targets (32-bit ARM, musl): the
        // casts are no-ops only on some of them.
        #[allow(clippy::unnecessary_cast)]
        let stat = rustix::fs::fstat(std::io::stderr())
            .ok()
            .map(|s| (s.st_dev as u64, s.st_ino as u64));
        let var = std::env::var("JOURNAL_STREAM").ok();
        StderrLogger {
            start: Instant::now(),
            journal: is_journal_stream(var.as_deref(), stat),
        }
    });
    let _ = log::set_logger(logger);
    log::set_max_level(level);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts the writes a line takes.
    struct Writes(Vec<usize>);

    impl Write for &mut Writes {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.0.push(b.len());
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_log_line_is_one_write_and_a_long_one_a_few() {
        use std::fmt::Write as _;
        let mut w = Writes(Vec::new());
        let mut line = Line::new(&mut w);
        let (t, level, n) = (1.5, "INFO ", 42);
        writeln!(line, "[{t:>9.3}s {level}] frame {n}").unwrap();
        line.flush();
        let whole = format!("[{t:>9.3}s {level}] frame {n}\n");
        assert_eq!(w.0, [whole.len()]);
        let mut w = Writes(Vec::new());
        let mut line = Line::new(&mut w);
        let long = "x".repeat(2500);
        writeln!(line, "{long}").unwrap();
        line.flush();
        assert_eq!(w.0, [1024, 1024, 453]);
    }

    /// Before: a line break in a message (a file name holding one) began
    /// what read as a new log line, at the journal's default priority, and
    /// an escape sequence in a file name reached the terminal.
    #[test]
    fn a_message_cannot_forge_a_line_or_reach_the_terminal() {
        use std::fmt::Write as _;
        let mut out = Vec::new();
        let mut line = Line::new(&mut out);
        line.priority = Some(3);
        write!(line, "<3>[    0.000s ERROR] ").unwrap();
        line.message = true;
        let name = "a\n[    1.000s INFO ] fine\u{1b}[2J\tb";
        write!(line, "cannot open `{name}`").unwrap();
        line.message = false;
        line.raw(b"\n");
        line.flush();
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "<3>[    0.000s ERROR] cannot open `a\n<3>    | [    1.000s INFO ] fine\\x1b[2J\tb`\n"
        );
    }

    #[test]
    fn the_journal_stream_is_recognised_only_as_stderr_itself() {
        assert!(is_journal_stream(Some("8:12345"), Some((8, 12345))));
        assert!(is_journal_stream(Some("8:12345\n"), Some((8, 12345))));
        // Inherited, but stderr was redirected (`stature run 2>log`).
        assert!(!is_journal_stream(Some("8:12345"), Some((8, 999))));
        assert!(!is_journal_stream(Some("9:12345"), Some((8, 12345))));
        assert!(!is_journal_stream(None, Some((8, 12345))));
        assert!(!is_journal_stream(Some("8:12345"), None));
        assert!(!is_journal_stream(Some("garbage"), Some((8, 12345))));
        assert_eq!(syslog_priority(Level::Error), 3);
        assert_eq!(syslog_priority(Level::Warn), 4);
        assert_eq!(syslog_priority(Level::Info), 6);
    }
}
