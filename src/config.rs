//! Configuration: one TOML file with a section per stage, validated once at
//! start-up into plain values that size every buffer.
//!
//! Every key has a default (`stature config --print-defaults` prints the
//! documented defaults file, `config/defaults.toml`, which a test keeps
//! identical to [`Config::default`]). Command-line options override the
//! file. Unknown keys, bad types and out-of-range values are refused with
//! one line naming the key, the value and the accepted range.

use core::fmt;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// A configuration value that cannot be used.
#[derive(Clone, Debug, PartialEq)]
pub struct ConfigError {
    /// Dotted key, e.g. `detect.history`.
    pub key: String,
    /// The offending value as written.
    pub value: String,
    /// Why it was refused, e.g. `expected a value in 10..=100000`.
    pub reason: String,
    /// The reason to give instead when a command-line option set the
    /// value, if it differs (see [`ConfigError::unset_or`]).
    pub option_reason: Option<String>,
}

impl ConfigError {
    /// Builds an error for `key` = `value`, expecting `expected`.
    pub fn new(key: &str, value: impl fmt::Display, expected: impl fmt::Display) -> Self {
        Self::invalid(key, value, format_args!("expected {expected}"))
    }
    /// Builds an error for `key` = `value` with a complete reason.
    pub fn invalid(key: &str, value: impl fmt::Display, reason: impl fmt::Display) -> Self {
        let mut value = value.to_string();
        // A huge number as `1e308`, not as the 309 digits `Display` gives it.
        if value.len() > 24 {
            if let Ok(v) = value.parse::<f64>() {
                value = format!("{v:e}");
            }
        }
        ConfigError {
            key: key.into(),
            value,
            reason: reason.to_string(),
            option_reason: None,
        }
    }
    /// Builds an error for a key that 0 leaves unset, expecting 0 or
    /// `expected`. Only the config file writes that 0 (an option is given
    /// or left out, and the options for such keys refuse 0), so an option
    /// that set the key is told `expected` alone
    /// ([`ConfigError::set_by_option`]).
    pub fn unset_or(key: &str, value: impl fmt::Display, expected: impl fmt::Display) -> Self {
        ConfigError {
            option_reason: Some(format!("expected {expected}")),
            ..Self::new(key, value, format_args!("0 (unset) or {expected}"))
        }
    }
    /// The error for the same value given with the command-line `option`
    /// instead of in the config file: named by the option the user typed,
    /// with the reason that applies to it.
    pub fn set_by_option(mut self, option: &str) -> Self {
        self.key = option.into();
        if let Some(reason) = self.option_reason.take() {
            self.reason = reason;
        }
        self
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // A syntax error is the file's, not a key's (see `Config::load`).
        if let Some(file) = self.key.strip_prefix("(file) ") {
            return match self.value.as_str() {
                "" => write!(f, "config file `{file}`: {}", self.reason),
                v => write!(f, "config file `{file}`: `{v}`: {}", self.reason),
            };
        }
        let what = if self.key.starts_with('-') {
            "option"
        } else {
            "config key"
        };
        write!(f, "{what} `{}` = {}: {}", self.key, self.value, self.reason)
    }
}
impl std::error::Error for ConfigError {}

/// Checks that `value` lies in `range`, naming `key` otherwise.
pub fn check_range<T>(
    key: &str,
    value: T,
    range: core::ops::RangeInclusive<T>,
) -> Result<(), ConfigError>
where
    T: PartialOrd + fmt::Display + Copy,
{
    if range.contains(&value) {
        Ok(())
    } else {
        Err(ConfigError::new(
            key,
            value,
            format_args!("a value in {}..={}", range.start(), range.end()),
        ))
    }
}

/// The whole configuration.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    /// Where frames come from.
    pub source: SourceConfig,
    /// Where records go.
    pub report: ReportConfig,
    /// Loop limits and persistence.
    pub run: RunConfig,
    /// Background model and regions.
    pub detect: crate::detect::DetectConfig,
    /// Region classifier.
    pub classify: crate::classify::ClassifyConfig,
    /// Person tracker.
    pub track: crate::track::TrackConfig,
    /// Self-calibration.
    pub calibrate: crate::calibrate::CalibrateConfig,
    /// Height measurement.
    pub measure: crate::measure::MeasureConfig,
    /// The board this profile is for, and its resource caps.
    pub board: BoardConfig,
}

/// `[source]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SourceConfig {
    /// Frame source: `sim:NAME?seed=N`, `y4m:PATH`, `y4m:-` or `v4l2:/dev/videoN?...`.
    pub uri: String,
}

impl Default for SourceConfig {
    fn default() -> Self {
        SourceConfig {
            uri: "sim:plaza?seed=1".into(),
        }
    }
}

/// Record encoding on every sink.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// JSON Lines, one object per line (per datagram on UDP).
    Json,
    /// postcard-encoded records, COBS-framed (zero byte ends each record).
    Postcard,
}

/// `[report]`
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReportConfig {
    /// Sinks: `stdout`, `file:PATH`, `udp:HOST:PORT`, `serial:/dev/ttyX?baud=N`,
    /// `mqtt:HOST[:PORT]?topic=..`.
    pub sinks: Vec<String>,
    /// Encoding of every record.
    pub format: Format,
    /// Records the queue between the vision loop and the I/O thread holds.
    pub queue: usize,
    /// Final records held back by the loop while the queue is full.
    pub held_finals: usize,
    /// Seconds of stream time between `status` records.
    pub status_interval_s: f64,
    /// Settings of `mqtt:` sinks (`[report.mqtt]`).
    pub mqtt: crate::report::mqtt::MqttConfig,
}

impl Default for ReportConfig {
    fn default() -> Self {
        ReportConfig {
            sinks: vec!["stdout".into()],
            format: Format::Json,
            queue: 256,
            held_finals: 64,
            status_interval_s: 5.0,
            mqtt: Default::default(),
        }
    }
}

/// `[run]`
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Stop after this many frames (0 = until the source ends).
    pub frames: u64,
    /// Calibration state file (empty = none).
    pub state: String,
    /// Installer snapshot PNG written at the end of the run (empty = none).
    pub snapshot: String,
}

/// `[board]`: what a board profile (`board/*.toml`) says about its target.
/// The caps are enforced by the service manager (`board/install.sh` turns
/// them into systemd `MemoryMax=`/`CPUQuota=`), not by the loop, whose
/// buffers are sized by the frame size and the other sections.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoardConfig {
    /// Profile name, logged at start-up; empty on a workstation. ASCII
    /// letters, digits, `-` and `_` only.
    pub name: String,
    /// Memory cap for the service, MiB (0 = none).
    pub memory_max_mib: u32,
    /// CPU cap for the service, percent of one core (0 = none).
    pub cpu_quota_percent: u32,
}

impl ReportConfig {
    /// Every sink parsed, in order; refuses a sink that does not parse, a
    /// stdout, file, UDP or serial sink given twice, and two `mqtt:` sinks
    /// with one client id.
    pub fn sink_specs(&self) -> Result<Vec<crate::report::sink::SinkSpec>, ConfigError> {
        use crate::report::sink::{redacted, SinkSpec};
        let specs = self
            .sinks
            .iter()
            .map(|s| {
                SinkSpec::parse(s).map_err(|e| ConfigError::invalid("report.sinks", redacted(s), e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        // The same stdout, file, UDP address or serial port twice: every record would reach
        // the consumer twice. (Two identical mqtt: sinks share a client id,
        // refused below with the fix to write.)
        let destinations: Vec<_> = specs.iter().map(destination).collect();
        for (i, d) in destinations.iter().enumerate() {
            if d.is_some() && destinations[..i].contains(d) {
                return Err(ConfigError::invalid(
                    "report.sinks",
                    redacted(&self.sinks[i]),
                    "given twice (each record would be sent twice there)",
                ));
            }
        }
        let mqtt_sinks: Vec<_> = self
            .sinks
            .iter()
            .zip(&specs)
            .filter_map(|(s, spec)| match spec {
                SinkSpec::Mqtt(m) => Some((s.as_str(), m.clone())),
                _ => None,
            })
            .collect();
        crate::report::mqtt::check_client_ids(&mqtt_sinks, &self.mqtt)
            .map_err(|(s, e)| ConfigError::invalid("report.sinks", s, e))?;
        for (s, m) in &mqtt_sinks {
            crate::report::mqtt::check_tls(m, &self.mqtt)
                .map_err(|e| ConfigError::invalid("report.sinks", s, e))?;
        }
        Ok(specs)
    }
}

/// Where a sink writes, for the duplicate check: file and serial paths as
/// the file system resolves them ([`resolved_path`]), a serial port
/// whatever its baud rate, a UDP destination as the address the sink will
/// send to (`localhost:9000` and `127.0.0.1:9000` are one; an IPv4-mapped
/// IPv6 address is its IPv4 one). `None` for MQTT. (A resolved path starts
/// with `/`, so it never equals `stdout` or a `udp:` key.)
fn destination(spec: &crate::report::sink::SinkSpec) -> Option<String> {
    use crate::report::sink::SinkSpec;
    use std::net::{IpAddr, SocketAddr};
    match spec {
        SinkSpec::Stdout => Some("stdout".into()),
        SinkSpec::File(path) | SinkSpec::Serial { path, .. } => Some(resolved_path(path)),
        SinkSpec::Udp(addr) => {
            // The sink sends to the first address (`Sink::open_with`); a
            // name that does not resolve now is compared as written (the
            // sink's own open reports it).
            let first = crate::report::sink::udp_addresses(addr)
                .ok()
                .and_then(|mut a| a.next());
            Some(match first {
                Some(SocketAddr::V6(a)) if a.ip().to_ipv4_mapped().is_some() => {
                    let v4 = a.ip().to_ipv4_mapped().map(IpAddr::V4);
                    format!(
                        "udp:{}",
                        SocketAddr::new(v4.unwrap_or(IpAddr::V6(*a.ip())), a.port())
                    )
                }
                Some(a) => format!("udp:{a}"),
                None => format!("udp:{addr}"),
            })
        }
        SinkSpec::Mqtt(_) => None,
    }
}

/// `path` as the file system resolves it: symbolic links and `.`/`..`
/// followed, so `a.jsonl`, `./a.jsonl` and a link to it are one file; a
/// file not created yet (also behind a dangling link, which a write
/// creates) is resolved through its directory; as written when neither
/// resolves.
fn resolved_path(path: &str) -> String {
    let followed = crate::replace::follow_links(Path::new(path)).map(|(p, _)| p);
    let p = followed.as_deref().unwrap_or(Path::new(path));
    std::fs::canonicalize(p)
        .or_else(|_| {
            Ok::<_, std::io::Error>(
                std::fs::canonicalize(crate::replace::dir_of(p))?
                    .join(p.file_name().unwrap_or_default()),
            )
        })
        .map_or_else(|_| path.to_string(), |p| p.display().to_string())
}

impl BoardConfig {
    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !self
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(ConfigError::new(
                "board.name",
                format_args!("{:?}", self.name),
                "letters, digits, `-` and `_` only",
            ));
        }
        if self.memory_max_mib != 0 {
            check_range("board.memory_max_mib", self.memory_max_mib, 16..=65536)?;
        }
        check_range("board.cpu_quota_percent", self.cpu_quota_percent, 0..=6400)
    }
}

/// The largest config file read: the documented defaults are a few KiB,
/// so anything this large is a mistyped path (a video, `/dev/zero`).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl Config {
    /// Parses TOML text; unknown keys and bad types are errors.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        let cfg: Config = toml::from_str(text).map_err(|e| parse_error(text, &e))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Reads and parses a TOML file; `option` is the command-line option
    /// that named it (`--config`, `--check`), which an unreadable file's
    /// error names. A file over [`MAX_CONFIG_BYTES`] is refused unread.
    pub fn load(path: &Path, option: &str) -> Result<Self, ConfigError> {
        let refused = |e: &dyn fmt::Display| {
            ConfigError::new(
                option,
                path.display(),
                format_args!("a readable TOML file ({e})"),
            )
        };
        let bytes = crate::replace::read_capped(path, MAX_CONFIG_BYTES).map_err(|e| match e {
            crate::replace::ReadError::TooLarge { .. } => {
                refused(&format_args!("{e}, too large to be a config file"))
            }
            e => refused(&e),
        })?;
        let text = String::from_utf8(bytes).map_err(|_| refused(&"not UTF-8 text"))?;
        Self::from_toml(&text).map_err(|mut e| {
            if e.key == "(file)" {
                e.key = format!("(file) {}", path.display());
            }
            e
        })
    }

    /// Checks every value against its accepted range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.source.uri.is_empty() {
            return Err(ConfigError::new(
                "source.uri",
                "\"\"",
                "a source such as sim:plaza or y4m:PATH",
            ));
        }
        check_range("report.queue", self.report.queue, 4..=65536)?;
        check_range("report.held_finals", self.report.held_finals, 1..=65536)?;
        check_range(
            "report.status_interval_s",
            self.report.status_interval_s,
            0.1..=3600.0,
        )?;
        let specs = self.report.sink_specs()?;
        self.report.mqtt.validate()?;
        // `stature sim --png -` is stdout; a run's stdout carries the records.
        if self.run.snapshot == "-" {
            return Err(ConfigError::invalid(
                "run.snapshot",
                "-",
                "`-` is not standard output here (it carries the run's records): give a file path ending in `.png`",
            ));
        }
        crate::snapshot::check_path(Path::new(&self.run.snapshot))
            .map_err(|e| ConfigError::invalid("run.snapshot", &self.run.snapshot, e))?;
        self.check_outputs_apart(&specs)?;
        self.detect.validate()?;
        self.classify.validate()?;
        self.track.validate()?;
        self.calibrate.validate()?;
        self.measure.validate()?;
        self.board.validate()?;
        Ok(())
    }
}

impl Config {
    /// The state file, the snapshot and the `file:` sinks must be different
    /// files: the state loader would call a record stream corrupt and set
    /// it aside, and two files replaced through one `PATH.stature-tmp`
    /// overwrite each other. None of them may be a file the run reads (the
    /// Y4M source, the weights): the state would set the video aside and
    /// take its place, a report sink would append records to it. A `file:`
    /// sink is not the file standard output already writes to when a
    /// `stdout` sink is there too (every record twice, interleaved).
    fn check_outputs_apart(
        &self,
        specs: &[crate::report::sink::SinkSpec],
    ) -> Result<(), ConfigError> {
        use crate::report::sink::SinkSpec;
        let mut outputs: Vec<(&str, &str)> = Vec::new();
        if !self.run.state.is_empty() {
            outputs.push(("run.state", &self.run.state));
        }
        if !self.run.snapshot.is_empty() {
            outputs.push(("run.snapshot", &self.run.snapshot));
        }
        for spec in specs {
            if let SinkSpec::File(path) = spec {
                outputs.push(("report.sinks", path));
            }
        }
        // A value as the user wrote it: a sink with its scheme.
        let written = |(key, path): (&str, &str)| match key {
            "report.sinks" => format!("file:{path}"),
            _ => path.to_string(),
        };
        let ids: Vec<FileId> = outputs.iter().map(|(_, p)| FileId::of_path(p)).collect();
        for (i, id) in ids.iter().enumerate() {
            if let Some(j) = ids[..i].iter().position(|e| e == id) {
                let other = match outputs[j].0 {
                    "report.sinks" => "a report.sinks file",
                    k => k,
                };
                return Err(ConfigError::invalid(
                    outputs[i].0,
                    written(outputs[i]),
                    format!(
                        "the same file as {other} `{}` (each would overwrite the other)",
                        written(outputs[j])
                    ),
                ));
            }
        }
        // (what the file is to the run, why it must not be an output, it)
        let mut inputs: Vec<(String, &str, FileId)> = Vec::new();
        let read = "the run would write over what it reads";
        match crate::source::y4m_path(&self.source.uri) {
            Some("-") => {
                if let Some(id) = FileId::of_stdio(std::io::stdin()) {
                    inputs.push(("the standard input source.uri reads".into(), read, id));
                }
            }
            Some(path) => inputs.push((
                format!("the source.uri Y4M file `{path}`"),
                read,
                FileId::of_path(path),
            )),
            None => {}
        }
        if !self.classify.weights.is_empty() {
            inputs.push((
                format!("the classify.weights file `{}`", self.classify.weights),
                read,
                FileId::of_path(&self.classify.weights),
            ));
        }
        let twice = "every record would be written to it twice";
        if specs.iter().any(|s| matches!(s, SinkSpec::Stdout)) {
            if let Some(id) = FileId::of_stdio(std::io::stdout()) {
                let what = "the file standard output (a stdout sink) writes to".into();
                inputs.push((what, twice, id));
            }
        }
        for (&output, id) in outputs.iter().zip(&ids) {
            if let Some((what, why, _)) = inputs.iter().find(|(_, _, i)| i == id) {
                // Only a file sink doubles the records; a snapshot or a
                // state file would be interleaved with them.
                let why = match output.0 {
                    "run.snapshot" if *why == twice => {
                        "the image and the records would be mixed in it"
                    }
                    "run.state" if *why == twice => {
                        "the state and the records would be mixed in it"
                    }
                    _ => why,
                };
                return Err(ConfigError::invalid(
                    output.0,
                    written(output),
                    format!("the same file as {what} ({why})"),
                ));
            }
        }
        Ok(())
    }
}

/// What makes two paths one file: its device and inode when it exists
/// (hard links, `/dev/stdout`), else where a write would create it.
#[derive(PartialEq, Eq)]
enum FileId {
    Inode(u64, u64),
    Path(String),
}

impl FileId {
    fn of_path(path: &str) -> FileId {
        match std::fs::metadata(path) {
            Ok(m) => {
                use std::os::unix::fs::MetadataExt;
                FileId::Inode(m.dev(), m.ino())
            }
            Err(_) => FileId::Path(resolved_path(path)),
        }
    }

    /// A standard stream's file, when it is a file or a pipe (a terminal
    /// or `/dev/null` may be shared harmlessly).
    fn of_stdio(fd: impl std::os::fd::AsFd) -> Option<FileId> {
        use rustix::fs::FileType;
        let st = rustix::fs::fstat(fd).ok()?;
        matches!(
            FileType::from_raw_mode(st.st_mode),
            FileType::RegularFile | FileType::Fifo
        )
        .then(|| FileId::Inode(st.st_dev as u64, st.st_ino as u64))
    }
}

/// Turns a TOML error into one line naming the dotted key and the value.
fn parse_error(text: &str, e: &toml::de::Error) -> ConfigError {
    let msg = e.message().trim().replace('\n', " ");
    let Some(span) = e.span() else {
        return ConfigError::invalid("(file)", "", msg);
    };
    let start = span.start.min(text.len());
    let line_start = text[..start].rfind('\n').map_or(0, |i| i + 1);
    let line_no = text[..start].matches('\n').count() + 1;
    let line = text[line_start..].lines().next().unwrap_or("");
    // The innermost [table] header above the offending line.
    let table = text[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && !l.starts_with("[["))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    // A key TOML could read: bare (letters, digits, `_`, `-`, dotted) or
    // quoted. Anything else before the `=` is the line's syntax, not a key.
    let readable_key = |k: &str| {
        let k = k.trim();
        !k.is_empty()
            && (k.starts_with(['"', '\''])
                || k.chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | ' ')))
            && !k.contains("  ")
            && k.split('.').all(|part| !part.trim().contains(' '))
    };
    match line.split_once('=') {
        Some((k, v)) if !line.trim_start().starts_with('[') && readable_key(k) => {
            let key = match table {
                Some(t) => format!("{t}.{}", k.trim()),
                None => k.trim().to_string(),
            };
            ConfigError::invalid(&key, v.trim(), format_args!("{msg} (line {line_no})"))
        }
        _ => ConfigError::invalid(
            "(file)",
            line.trim(),
            format_args!("{msg} (line {line_no})"),
        ),
    }
}

/// The documented defaults file printed by `stature config --print-defaults`.
pub const DEFAULTS_TOML: &str = include_str!("../config/defaults.toml");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_that_is_not_key_equals_value_is_the_files_syntax_not_a_key() {
        // "config key `not toml at all` = ==" named a key that is not one.
        let e = Config::from_toml("not toml at all ===\n").unwrap_err();
        assert_eq!(e.key, "(file)", "{e}");
        assert!(e.to_string().contains("(line 1)"), "{e}");
        // A readable key with a bad value is still that key's error.
        let e = Config::from_toml("[detect]\nhistory = 10 0\n").unwrap_err();
        assert_eq!(e.key, "detect.history", "{e}");
        let e = Config::from_toml("[run]\n\"frames\" = \"x\"\n").unwrap_err();
        assert_eq!(e.key, "run.\"frames\"", "{e}");
    }

    #[test]
    fn documented_defaults_are_the_real_defaults() {
        let parsed = Config::from_toml(DEFAULTS_TOML).expect("defaults file parses");
        assert_eq!(parsed, Config::default());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = Config::from_toml("[report]\nqueue_size = 3\n").unwrap_err();
        assert!(e.to_string().contains("queue_size"), "{e}");
    }

    #[test]
    fn an_option_is_not_offered_the_files_unset_value() {
        let e = ConfigError::unset_or("calibrate.camera_height_m", 0.1, "a value in 0.5..=100");
        assert_eq!(
            e.to_string(),
            "config key `calibrate.camera_height_m` = 0.1: expected 0 (unset) or a value in 0.5..=100"
        );
        assert_eq!(
            e.set_by_option("--camera-height").to_string(),
            "option `--camera-height` = 0.1: expected a value in 0.5..=100"
        );
        let e = ConfigError::new("run.state", "x", "a file").set_by_option("--state");
        assert_eq!(e.to_string(), "option `--state` = x: expected a file");
    }

    #[test]
    fn an_unreadable_file_is_named_by_the_option_that_gave_it() {
        let e = Config::load(Path::new("/nonexistent.toml"), "--check").unwrap_err();
        assert!(
            e.to_string().starts_with(
                "option `--check` = /nonexistent.toml: expected a readable TOML file ("
            ),
            "{e}"
        );
    }

    #[test]
    fn one_file_or_port_under_two_spellings_is_one_sink() {
        let dir = crate::scratch::fresh_dir("dup-sinks");
        let file = dir.join("a.jsonl");
        std::fs::write(&file, "").unwrap();
        let link = dir.join("link.jsonl");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(&file, &link).unwrap();
        // A link to a file not created yet: the first write creates it.
        std::os::unix::fs::symlink("later.jsonl", dir.join("dangling.jsonl")).unwrap();
        let d = dir.display();
        let sinks = |a: String, b: String| ReportConfig {
            sinks: vec![a, b],
            ..ReportConfig::default()
        };
        for (a, b) in [
            (format!("file:{d}/a.jsonl"), format!("file:{d}/./a.jsonl")),
            (format!("file:{d}/a.jsonl"), format!("file:{d}/link.jsonl")),
            // Not created yet: resolved through its directory.
            (
                format!("file:{d}/new.jsonl"),
                format!(
                    "file:{d}/../{}/new.jsonl",
                    dir.file_name().unwrap().to_string_lossy()
                ),
            ),
            (
                format!("file:{d}/later.jsonl"),
                format!("file:{d}/dangling.jsonl"),
            ),
            (
                format!("serial:{d}/a.jsonl?baud=9600"),
                format!("serial:{d}/link.jsonl?baud=115200"),
            ),
            (
                format!("file:{d}/a.jsonl"),
                format!("serial:{d}/a.jsonl?baud=9600"),
            ),
        ] {
            let e = sinks(a.clone(), b.clone()).sink_specs().expect_err(&b);
            assert!(e.to_string().contains("given twice"), "{a} {b}: {e}");
        }
        let (a, b) = (format!("file:{d}/a.jsonl"), format!("file:{d}/b.jsonl"));
        assert!(sinks(a, b).sink_specs().is_ok());
    }

    #[test]
    fn one_udp_destination_under_two_names_is_one_sink() {
        use std::net::ToSocketAddrs;
        // Whichever address the resolver gives first (127.0.0.1 or ::1).
        let localhost = ("localhost", 19000)
            .to_socket_addrs()
            .unwrap()
            .next()
            .unwrap();
        for (a, b) in [
            (format!("udp:{localhost}"), "udp:localhost:19000"),
            ("udp:127.0.0.1:19000".into(), "udp:[::ffff:127.0.0.1]:19000"),
        ] {
            let r = ReportConfig {
                sinks: vec![a.clone(), b.into()],
                ..ReportConfig::default()
            };
            let e = r.sink_specs().expect_err(b);
            assert!(e.to_string().contains("given twice"), "{a} {b}: {e}");
        }
        let r = ReportConfig {
            sinks: vec!["udp:127.0.0.1:19000".into(), "udp:127.0.0.1:19001".into()],
            ..ReportConfig::default()
        };
        assert!(r.sink_specs().is_ok());
    }

    #[test]
    fn state_snapshot_and_file_sinks_are_different_files() {
        let dir = crate::scratch::fresh_dir("outputs-apart");
        let d = dir.display();
        let with = |state: &str, snapshot: &str, sink: &str| {
            let mut c = Config::default();
            c.run.state = state.into();
            c.run.snapshot = snapshot.into();
            c.report.sinks = vec![sink.into()];
            c.validate()
        };
        let e = with(&format!("{d}/x.jsonl"), "", &format!("file:{d}/./x.jsonl")).unwrap_err();
        assert_eq!(e.key, "report.sinks");
        assert!(e.to_string().contains("the same file as run.state"), "{e}");
        let e = with(&format!("{d}/x.png"), &format!("{d}/x.png"), "stdout").unwrap_err();
        assert_eq!(e.key, "run.snapshot");
        let e = with("", &format!("{d}/s.png"), &format!("file:{d}/s.png")).unwrap_err();
        assert!(
            e.to_string().contains("the same file as run.snapshot"),
            "{e}"
        );
        with(
            &format!("{d}/st.json"),
            &format!("{d}/s.png"),
            &format!("file:{d}/r.jsonl"),
        )
        .unwrap();
    }

    #[test]
    fn out_of_range_names_key_and_range() {
        let e = Config::from_toml("[report]\nqueue = 1\n").unwrap_err();
        assert_eq!(e.key, "report.queue");
        assert!(e.to_string().contains("4..=65536"), "{e}");
        let e = Config::from_toml("[calibrate]\ncamera_height_m = 1e308\n").unwrap_err();
        assert!(e.to_string().contains("= 1e308: expected"), "{e}");
    }
}
