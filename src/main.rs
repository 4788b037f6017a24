//! The `stature` command: see the README for every option.
#![deny(unsafe_code)]

use clap::{Args, Parser, Subcommand};
use stature::config::{Config, ConfigError, Format};
use stature::report::{self, sink, Reporter};
use stature::{exit, run, source};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// `eprintln!` that cannot panic: with stderr gone (a closed pipe, a full
/// disk behind `2>file`) there is nowhere left to tell, and the exit code
/// still says how the command ended. (`eprintln!` panics: exit 101.)
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

/// [`say!`] without the newline (progress lines that rewrite themselves).
macro_rules! say_part {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = write!(std::io::stderr(), $($arg)*);
    }};
}

#[global_allocator]
static GLOBAL: stature::alloc_count::CountingAlloc = stature::alloc_count::CountingAlloc;

#[derive(Parser)]
#[command(
    name = "stature",
    version,
    about = "Self-calibrating camera firmware that measures walking people's heights",
    after_help = "With no command, runs `demo` (what `cargo run --release` does)."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run the pipeline on a source and stream reports.
    Run(RunCmdArgs),
    /// Run the pipeline until calibrated (or --frames N) and write the installer snapshot PNG.
    Snapshot(SnapshotArgs),
    /// Run the full pipeline on the built-in demo scene and compare with the truth.
    Demo(DemoArgs),
    /// Print or check configuration files.
    Config(ConfigArgs),
    /// Train the region classifier and write its weight blob.
    Train(TrainArgs),
    /// Render a simulated scene to Y4M, its ground truth to JSON, or a frame to PNG.
    Sim(SimArgs),
}

#[derive(Args, Default)]
struct Verbosity {
    /// More log output on stderr (-v adds debug: calibration updates and
    /// final heights as they happen; -vv adds trace: a line per frame).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only errors on stderr.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
}

impl Verbosity {
    fn level(&self) -> log::LevelFilter {
        match (self.quiet, self.verbose) {
            (true, _) => log::LevelFilter::Error,
            (false, 0) => log::LevelFilter::Info,
            (false, 1) => log::LevelFilter::Debug,
            _ => log::LevelFilter::Trace,
        }
    }
}

#[derive(Args)]
struct RunCmdArgs {
    #[command(flatten)]
    run: RunArgs,
    /// Installer snapshot written when the run ends: the last frame with the
    /// horizon, the vertical vanishing direction, the tracks and the calibration.
    #[arg(long, value_name = "PATH.png")]
    snapshot: Option<PathBuf>,
}

#[derive(Args)]
struct SnapshotArgs {
    /// Where to write the PNG.
    #[arg(long, value_name = "PATH.png")]
    out: PathBuf,
    #[command(flatten)]
    run: RunArgs,
}

#[derive(Args)]
struct RunArgs {
    /// TOML configuration file (command-line options override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frame source: sim:NAME?seed=N, y4m:PATH, y4m:- or v4l2:/dev/videoN?width=..&height=..&fps=..&format=..
    #[arg(long)]
    source: Option<String>,
    /// Report sink (repeatable): stdout, file:PATH, udp:HOST:PORT, serial:/dev/ttyX?baud=N,
    /// mqtt:HOST[:PORT]?topic=T&qos=0|1&client_id=ID&tls=true&ca=FILE&ha_discovery=true
    /// (MQTT credentials only from the config file or STATURE_MQTT_USERNAME/STATURE_MQTT_PASSWORD)
    #[arg(long = "report")]
    reports: Vec<String>,
    /// Record encoding.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Calibration state file (resumed at start, written atomically).
    #[arg(long)]
    state: Option<PathBuf>,
    /// Stop after N frames.
    #[arg(long, allow_negative_numbers = true)]
    frames: Option<u64>,
    /// Classifier weight blob (default: the built-in weights).
    #[arg(long)]
    weights: Option<PathBuf>,
    #[command(flatten)]
    scale: ScaleArgs,
    #[command(flatten)]
    verbosity: Verbosity,
}

/// How heights get their metric scale (see `calibrate::ScaleMode`).
#[derive(Args, Default)]
#[group(multiple = false)]
struct ScaleArgs {
    /// Known camera mounting height in metres, instead of the prior on
    /// people's mean height (README "Where it stands" compares the two).
    #[arg(long, value_name = "METRES", allow_negative_numbers = true, value_parser = metres)]
    camera_height: Option<f64>,
    /// Height of the first person tracked (walk through alone), metres.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true, value_parser = metres)]
    reference_height: Option<f64>,
    /// Mean height of the people who pass (default 1.70), metres.
    #[arg(long, value_name = "METRES", allow_negative_numbers = true, value_parser = metres)]
    prior_height: Option<f64>,
}

/// A length in metres given on the command line: a finite number above 0
/// (the config ranges then apply).
fn metres(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(_) => Err("expected a length in metres above 0".into()),
        Err(e) => Err(format!("{e}")),
    }
}

impl ScaleArgs {
    /// The scale mode given on the command line replaces the file's: the
    /// other two ways of setting the scale are cleared. Returns the config
    /// key set and the option that set it.
    fn apply(&self, cfg: &mut Config) -> Option<(&'static str, &'static str)> {
        let c = &mut cfg.calibrate;
        if let Some(h) = self.camera_height {
            (c.camera_height_m, c.reference_height_m) = (h, 0.0);
            return Some(("calibrate.camera_height_m", "--camera-height"));
        }
        if let Some(h) = self.reference_height {
            (c.camera_height_m, c.reference_height_m) = (0.0, h);
            return Some(("calibrate.reference_height_m", "--reference-height"));
        }
        if let Some(h) = self.prior_height {
            (c.camera_height_m, c.reference_height_m, c.prior_height_m) = (0.0, 0.0, h);
            return Some(("calibrate.prior_height_m", "--prior-height"));
        }
        None
    }
}

#[derive(Args)]
struct TrainArgs {
    /// Data folder (default: ../shared/data beside the crate).
    #[arg(long)]
    data: Option<PathBuf>,
    /// Where to write the weight blob.
    #[arg(long, default_value = "weights/classifier.bin")]
    out: PathBuf,
    /// Where to write the Markdown training report (default: stdout only).
    #[arg(long)]
    report: Option<PathBuf>,
    /// Seed of every random choice.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    seed: u64,
    /// Window size WxH in pixels, 8..=256 a side, each side a multiple of the HOG and LBP cells (default 32x64).
    #[arg(long)]
    window: Option<String>,
    /// Margin above and below the box, 1/256 of its height, 0..=256 (default 32).
    #[arg(long)]
    margin: Option<u16>,
    /// HOG cell side, pixels, 2..=32 dividing the window (default 4).
    #[arg(long, allow_negative_numbers = true)]
    hog_cell: Option<u8>,
    /// LBP cell side, pixels, 2..=32 dividing the window (default 8).
    #[arg(long, allow_negative_numbers = true)]
    lbp_cell: Option<u8>,
    /// LBP comparison offset, grey levels, 0..=64 (default 2; above that
    /// nearly every pattern is the same).
    #[arg(long, allow_negative_numbers = true)]
    lbp_threshold: Option<u8>,
    /// How the box maps to the window: height (crop a wide box's sides; default) or contain (shrink it whole).
    #[arg(long)]
    fit: Option<String>,
    /// Box-shape (width/height) features (default true).
    #[arg(long)]
    aspect: Option<bool>,
    /// Coarse HOG blocks, cells merged 2x2 (default true).
    #[arg(long)]
    coarse: Option<bool>,
    /// Square-root compression of the HOG values (default false).
    #[arg(long)]
    hog_sqrt: Option<bool>,
    /// Foreground-fill features from the detector's mask (default false).
    #[arg(long)]
    mask_fill: Option<bool>,
    /// Also train on the detector's own regions, labelled by the ground truth (default false).
    #[arg(long)]
    detected_regions: Option<bool>,
    /// Feature set: hog+lbp, hog or lbp.
    #[arg(long, default_value = "hog+lbp")]
    features: String,
    /// SVM C, 0.0001..=1000 (default: chosen by cross-validation).
    #[arg(long, allow_negative_numbers = true)]
    c: Option<f64>,
    /// Share of HOG blocks / LBP cells kept by weight magnitude, 0.01..=1 (Park et al.; default 0.5).
    #[arg(long, allow_negative_numbers = true)]
    select: Option<f64>,
    /// Use every n-th PETS training frame for the base set, 1..=600 (default 1).
    #[arg(long, allow_negative_numbers = true)]
    pets_stride: Option<u32>,
    /// Also evaluate on the held-out PETS frames (600-794) and sim seeds.
    #[arg(long)]
    eval: bool,
    /// Only evaluate this weight blob on the held-out data (no training).
    #[arg(long)]
    evaluate: Option<PathBuf>,
    /// Leave the simulated scenes out of training.
    #[arg(long)]
    no_sim: bool,
    /// Simulated training seeds, N,N,... or A..B (default 1..6).
    #[arg(long)]
    sim_seeds: Option<String>,
    /// Simulated seeds that contribute only their cars and dogs, N,N,... or A..B (default none).
    #[arg(long)]
    animal_seeds: Option<String>,
    /// Also train on the mirror image of every PETS and simulated person (default true).
    #[arg(long)]
    mirror: Option<bool>,
    /// Jittered boxes of each clean person per training frame, 1..=8 (default 1).
    #[arg(long, allow_negative_numbers = true)]
    persons: Option<usize>,
    /// Rounds of hard-negative mining, 0..=10 (default 1).
    #[arg(long, allow_negative_numbers = true)]
    mining_rounds: Option<usize>,
    /// Search every n-th simulated training frame for hard negatives, 0..=1000 (0: PETS only; default 0).
    #[arg(long, allow_negative_numbers = true)]
    mine_sim_stride: Option<u64>,
    /// Cost multiplier of a kind, KIND=X (person, background, group, fragment, car, dog); repeatable.
    #[arg(long = "weight")]
    weights: Vec<String>,
    /// Skip the cross-validation of the final set.
    #[arg(long)]
    no_final_cv: bool,
}

#[derive(Args)]
struct DemoArgs {
    /// Frames to run (default and at most: the whole demo clip, 750).
    #[arg(long, allow_negative_numbers = true)]
    frames: Option<u64>,
    #[command(flatten)]
    verbosity: Verbosity,
}

#[derive(Args)]
struct SimArgs {
    /// Describe the built-in scenes and exit.
    #[arg(long)]
    list: bool,
    /// Scene name (see --list).
    #[arg(long, default_value = "plaza")]
    scene: String,
    /// Seed of everything random in the scene.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    seed: u64,
    /// Clip length in frames, 1..=1000000 (default: the scene's).
    #[arg(long, allow_negative_numbers = true)]
    frames: Option<u64>,
    /// Write the clip as Y4M to this file (`-` for stdout).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write the ground truth as JSON to this file (`-` for stdout).
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Write one frame as PNG to this file (`-` for stdout).
    #[arg(long)]
    png: Option<PathBuf>,
    /// Frame written by --png.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    png_frame: u64,
    /// Draw the truth (boxes, head and foot points, horizon) on the PNG.
    #[arg(long, requires = "png")]
    annotate: bool,
}

#[derive(Args)]
struct ConfigArgs {
    /// Print the documented default configuration.
    #[arg(long, conflicts_with = "check")]
    print_defaults: bool,
    /// Check a configuration file and report the first problem, including
    /// what `run` would refuse at start-up (the state and snapshot paths,
    /// report files, serial ports, a UDP host, an MQTT CA file, a Y4M
    /// file's header, the memory for the frame size), as the user who runs
    /// the check.
    #[arg(long)]
    check: Option<PathBuf>,
    /// With --check: the keys and values only, not the start-up checks (for
    /// an installer that runs before the service's directories exist and
    /// not as the service's user).
    #[arg(long, requires = "check")]
    keys_only: bool,
}

fn main() {
    let cli = Cli::parse();
    let code = match cli.command {
        None => demo(DemoArgs {
            frames: None,
            verbosity: Verbosity::default(),
        }),
        Some(Command::Demo(a)) => demo(a),
        Some(Command::Run(a)) => run_cmd(a.run, a.snapshot.map(|p| ("--snapshot", p)), false),
        Some(Command::Snapshot(a)) => run_cmd(a.run, Some(("--out", a.out)), true),
        Some(Command::Config(a)) => config_cmd(a),
        Some(Command::Train(a)) => train_cmd(a),
        Some(Command::Sim(a)) => sim_cmd(a),
    };
    std::process::exit(code);
}

fn config_cmd(a: ConfigArgs) -> i32 {
    let Some(path) = a.check else {
        return print_out(stature::config::DEFAULTS_TOML).map_or_else(|code| code, |()| exit::OK);
    };
    let cfg = match Config::load(&path, "--check") {
        Ok(cfg) => cfg,
        Err(e) => {
            say!("error: {e}");
            return exit::BAD_INPUT;
        }
    };
    // A source this build lacks is exit code 3, as `run` says.
    if let Err(e) = source::check(&cfg.source.uri) {
        say!("error: {}: source.uri: {e}", path.display());
        return e.exit_code();
    }
    // What `run` would refuse at start-up, with its exit code: a config
    // that passes here and then stops the service helps nobody.
    let checked = if a.keys_only {
        // The environment is the service's, not this shell's: a password
        // with no user name in the file is legal only if it supplies one.
        let m = &cfg.report.mqtt;
        let mqtt_sink = cfg.report.sink_specs().is_ok_and(|specs| {
            specs
                .iter()
                .any(|s| matches!(s, stature::report::sink::SinkSpec::Mqtt(_)))
        });
        if mqtt_sink && !m.password.is_empty() && m.username.is_empty() {
            say!(
                "warning: {}: [report.mqtt] password without a username: the service's environment \
                 must set STATURE_MQTT_USERNAME, or run refuses it (exit code 2)",
                path.display()
            );
        }
        Ok(())
    } else {
        check_run_paths(&cfg)
            .map(|files| warn_of_unusable_state(&path, files.state.as_ref()))
            .and_then(|()| check_sinks(&cfg))
            .and_then(|()| check_source_memory(&cfg))
    };
    if let Err(r) = checked {
        say!("error: {}: {}", path.display(), r.message);
        return r.code;
    }
    if cfg.report.sinks.is_empty() {
        // `run` warns the same at start: allowed, rarely meant.
        say!(
            "warning: {}: report.sinks is empty: a run's records go nowhere",
            path.display()
        );
    }
    print_out(&format!("{}: ok\n", path.display())).map_or_else(|code| code, |()| exit::OK)
}

/// `config --check` on a state file a run would not resume from: a run
/// goes on without it (a corrupt one is set aside, an unreadable one left
/// alone), so these are warnings, but the installer checking a
/// configuration wants to know before the camera starts from nothing.
fn warn_of_unusable_state(
    config: &std::path::Path,
    state: Option<&stature::calibrate::state::StateFile>,
) {
    use stature::calibrate::state::StateError;
    let Some(st) = state else { return };
    match st.load() {
        Ok(_) => {}
        Err(e @ StateError::Corrupt(_)) => say!(
            "warning: {}: calibration state {}: {e}; a run would set it aside and start afresh",
            config.display(),
            st.path().display()
        ),
        Err(e) => say!(
            "warning: {}: calibration state {}: cannot read it ({e}); a run would keep no state",
            config.display(),
            st.path().display()
        ),
    }
}

/// `config --check`'s part of what `run` checks once its source is open:
/// a Y4M file's header, and whether the frames fit the memory (at the size
/// a scene has, a `v4l2:` URI asks for or a Y4M file's header gives; a
/// pipe or device is not read, a camera not taken from a running service).
fn check_source_memory(cfg: &Config) -> Result<(), Refused> {
    match source::planned_size(&cfg.source.uri) {
        Ok(Some(size)) => check_memory(cfg, size),
        Ok(None) => Ok(()),
        Err(e) => Err(Refused {
            message: format!("source.uri: {e}"),
            code: e.exit_code(),
        }),
    }
}

/// Writes what a command prints to standard output. A write that fails (a
/// full disk behind a redirect, a closed pipe) is an output error like the
/// `stdout` sink's in `run`: a line on stderr and exit code 3, not the
/// panic (exit 101) of `print!`.
fn print_out(text: &str) -> Result<(), i32> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())
        .and_then(|()| out.flush())
        .map_err(|e| {
            say!("error: cannot write to standard output: {e}");
            exit::UNAVAILABLE
        })
}

/// A start-up check that failed: the message and the exit code.
struct Refused {
    message: String,
    code: i32,
}

/// The files a run writes, opened and checked before it reads a frame.
struct RunFiles {
    /// The state file, its lock taken (or found held by another process),
    /// for the run to keep: handed to the loop, not opened again, so that
    /// the lock is held from the check to the run's end.
    state: Option<stature::calibrate::state::StateFile>,
    /// The snapshot's temporary file, for the run to write.
    snapshot: Option<stature::snapshot::SnapshotFile>,
}

/// The paths a run writes, checked before it reads a frame (by `run` and
/// by `config --check`, which drops what it opened): the state file (its
/// lock is taken and a temporary file is created and removed beside it)
/// and the snapshot, whose temporary file is created now.
fn check_run_paths(cfg: &Config) -> Result<RunFiles, Refused> {
    let mut files = RunFiles {
        state: None,
        snapshot: None,
    };
    if !cfg.run.state.is_empty() {
        let path = std::path::Path::new(&cfg.run.state);
        let state = stature::calibrate::state::StateFile::open(path, run::state_capacity(cfg))
            .map_err(|e| Refused {
                message: format!("calibration state {}: {e}", path.display()),
                code: exit::UNAVAILABLE,
            })?;
        files.state = Some(state);
    }
    if !cfg.run.snapshot.is_empty() {
        let snapshot =
            stature::snapshot::SnapshotFile::create(std::path::Path::new(&cfg.run.snapshot))
                .map_err(|e| Refused {
                    message: e.to_string(),
                    code: exit::UNAVAILABLE,
                })?;
        files.snapshot = Some(snapshot);
    }
    Ok(files)
}

/// Whether the pipeline for `size` frames fits the memory the system (or
/// the service's cgroup) has room for; unknown room passes.
fn check_memory(cfg: &Config, size: stature::frame::Size) -> Result<(), Refused> {
    let need = run::memory_estimate(cfg, size);
    match run::memory_room() {
        Some(free) if need > free => Err(Refused {
            message: format!(
                "{}x{} frames need about {} MiB for the pipeline; {} MiB of memory is available \
                 (system or service limit; capture a smaller size)",
                size.width,
                size.height,
                need >> 20,
                free >> 20
            ),
            code: exit::UNAVAILABLE,
        }),
        _ => Ok(()),
    }
}

/// What `config --check` can know of the sinks without sending anything,
/// through the calls `run` makes at start-up: a UDP host resolves, an MQTT
/// sink's TLS roots (`ca=`) load. Files and serial ports are checked
/// without being opened for good (`sink::check_local`: that would create
/// the file or toggle the port's lines).
fn check_sinks(cfg: &Config) -> Result<(), Refused> {
    use stature::report::sink::{Sink, SinkSpec};
    let refused = |e: &dyn std::fmt::Display| Refused {
        message: format!("cannot open report sink: {e}"),
        code: exit::UNAVAILABLE,
    };
    let specs = cfg.report.sink_specs().map_err(|e| Refused {
        message: e.to_string(),
        code: exit::BAD_INPUT,
    })?;
    for spec in &specs {
        match spec {
            #[cfg(feature = "mqtt")]
            SinkSpec::Mqtt(m) => {
                let settings = mqtt_settings(cfg, m)?;
                stature::report::mqtt::link::check_local(&settings).map_err(|e| refused(&e))?;
            }
            // Without MQTT support, opening refuses at once, as in `run`.
            #[cfg(not(feature = "mqtt"))]
            SinkSpec::Mqtt(_) => {
                drop(Sink::open_with(spec, &cfg.report.mqtt).map_err(|e| refused(&e))?)
            }
            SinkSpec::Udp(_) => {
                drop(Sink::open_with(spec, &cfg.report.mqtt).map_err(|e| refused(&e))?)
            }
            SinkSpec::File(_) | SinkSpec::Serial { .. } => {
                stature::report::sink::check_local(spec).map_err(|e| refused(&e))?
            }
            SinkSpec::Stdout => {}
        }
    }
    Ok(())
}

/// What an `mqtt:` sink will run with (its URI over `[report.mqtt]`, the
/// environment's credentials over both), refused with exit code 2 when it
/// has a password without a user name: a configuration mistake wherever
/// it came from, the file or the environment.
#[cfg(feature = "mqtt")]
fn mqtt_settings(
    cfg: &Config,
    m: &stature::report::mqtt::MqttSpec,
) -> Result<stature::report::mqtt::MqttSettings, Refused> {
    let settings = stature::report::mqtt::MqttSettings::resolve(m, &cfg.report.mqtt, |k| {
        std::env::var(k).ok()
    });
    settings.check_credentials().map_err(|e| Refused {
        message: format!("cannot open report sink: {e}"),
        code: exit::BAD_INPUT,
    })?;
    Ok(settings)
}

/// A path option's value as the text a config value holds. A name that is
/// not UTF-8 is refused: `display()` would turn its bytes into U+FFFD and
/// the run would write a file of another name.
fn utf8_path(p: &std::path::Path, option: &str) -> Result<String, ConfigError> {
    p.to_str().map(str::to_string).ok_or_else(|| {
        ConfigError::invalid(
            option,
            p.display(),
            "a path that is not UTF-8 (the name would change)",
        )
    })
}

/// Builds the configuration from the file and the command line
/// (`snapshot`: the path given with `--snapshot` or `--out`, and which).
/// An error in a value the command line set names the option, not the
/// config key it lands in.
fn resolve_config(a: &RunArgs, snapshot: Option<(&str, &PathBuf)>) -> Result<Config, ConfigError> {
    let mut cfg = match &a.config {
        Some(p) => Config::load(p, "--config")?,
        None => Config::default(),
    };
    // (config key, option) for each value the command line set.
    let mut from_options: Vec<(&str, &str)> = Vec::new();
    if let Some(s) = &a.source {
        cfg.source.uri = s.clone();
        from_options.push(("source.uri", "--source"));
    }
    if !a.reports.is_empty() {
        cfg.report.sinks = a.reports.clone();
        from_options.push(("report.sinks", "--report"));
    }
    if let Some(f) = a.format {
        cfg.report.format = f;
    }
    if let Some(s) = &a.state {
        cfg.run.state = utf8_path(s, "--state")?;
        from_options.push(("run.state", "--state"));
    }
    if let Some(n) = a.frames {
        cfg.run.frames = n;
    }
    if let Some(w) = &a.weights {
        cfg.classify.weights = utf8_path(w, "--weights")?;
        from_options.push(("classify.weights", "--weights"));
    }
    if let Some((option, p)) = snapshot {
        cfg.run.snapshot = utf8_path(p, option)?;
        from_options.push(("run.snapshot", option));
    }
    from_options.extend(a.scale.apply(&mut cfg));
    if let Err(e) = cfg.validate() {
        return Err(match from_options.iter().find(|(key, _)| *key == e.key) {
            Some(&(_, option)) => e.set_by_option(option),
            None => e,
        });
    }
    Ok(cfg)
}

/// `stature run`, and `stature snapshot` (`until_confident`: stop once
/// the calibration is confident enough to measure). `snapshot` is the
/// snapshot path given on the command line and the option that gave it.
fn run_cmd(a: RunArgs, snapshot: Option<(&str, PathBuf)>, until_confident: bool) -> i32 {
    stature::logger::init(a.verbosity.level());
    let cfg = match resolve_config(&a, snapshot.as_ref().map(|(o, p)| (*o, p))) {
        Ok(c) => c,
        Err(e) => {
            log::error!("{e}");
            return exit::BAD_INPUT;
        }
    };
    run_pipeline(&cfg, until_confident)
}

fn run_pipeline(cfg: &Config, until_confident: bool) -> i32 {
    if !cfg.board.name.is_empty() {
        log::info!("board profile {}", cfg.board.name);
    }
    // Installed before the source opens: a pipe may take its time to send
    // the Y4M header, and a signal meanwhile should end the run cleanly.
    let signals = stop_on_signals();
    // Says what is awaited (and, for tests, that the handlers are in place).
    log::info!("opening source {}", cfg.source.uri);
    match source::open_stoppable(&cfg.source.uri, Some(signals.wake.clone())) {
        Ok(mut s) => {
            // A file or a simulated clip shows how far the run is.
            let total = match (s.length(), cfg.run.frames) {
                (Some(n), 0) => Some(n),
                (Some(n), cap) => Some(n.min(cap)),
                (None, _) => None,
            };
            let mut shown;
            let src: &mut dyn source::FrameSource = match total {
                Some(total) if total > 0 => {
                    shown = Progress::new(s.as_mut(), total, ProgressStyle::Log);
                    &mut shown
                }
                _ => s.as_mut(),
            };
            run_source(cfg, src, &signals, &mut (None, Vec::new()), until_confident)
        }
        Err(source::SourceError::Stopped) => {
            log::info!("stopped by a signal before the source had sent its first frame");
            // A snapshot was asked for and there is none: a script's
            // `stature snapshot ... && upload` must not go on.
            if cfg.run.snapshot.is_empty() {
                exit::OK
            } else {
                log::error!(
                    "cannot write snapshot {}: no frame to draw (stopped before the first frame)",
                    cfg.run.snapshot
                );
                exit::UNAVAILABLE
            }
        }
        Err(e) => {
            log::error!("{e}");
            e.exit_code()
        }
    }
}

/// A flag that SIGINT, SIGTERM and SIGHUP set (the loop then stops after
/// the current frame and sends its final records). SIGHUP is the terminal
/// going away, e.g. an SSH session dropping during `stature snapshot`:
/// left at its default it killed the run with nothing final sent. A SIGHUP
/// the parent ignores (`nohup stature run ...`, a supervisor's choice) stays
/// ignored: the caller asked for the run to outlive its terminal.
fn stop_on_signals() -> Signals {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let stop = Arc::new(AtomicBool::new(false));
    let wake = Arc::new(AtomicBool::new(false));
    let hangup = (!ignored_from_start(SIGHUP)).then_some(SIGHUP);
    for sig in [Some(SIGINT), Some(SIGTERM), hangup].into_iter().flatten() {
        for flag in [&stop, &wake] {
            if let Err(e) = signal_hook::flag::register(sig, flag.clone()) {
                log::warn!("cannot install handler for signal {sig}: {e}");
            }
        }
    }
    Signals { stop, wake }
}

/// The flags the stop signals set.
struct Signals {
    /// Set by a signal only: the run was asked to stop.
    stop: Arc<AtomicBool>,
    /// Set by a signal, and by the report thread once no sink can deliver
    /// ([`stature::report::Counters::wake`]): a blocked source read gives
    /// up when it is set. Apart from `stop`, so that a reader leaving is
    /// never taken for a signal.
    wake: Arc<AtomicBool>,
}

/// Whether `sig` is ignored now, before any handler of ours: a disposition
/// inherited from the parent, as `nohup` sets for SIGHUP. Asked of the
/// kernel with sigaction(2), not read from /proc/self/status, because under
/// qemu-user (the emulated test runs) only the emulated call answers for
/// the guest.
#[allow(unsafe_code)]
fn ignored_from_start(sig: libc::c_int) -> bool {
    let mut current = std::mem::MaybeUninit::<libc::sigaction>::zeroed();
    // SAFETY: with a null new action sigaction(2) changes nothing and only
    // writes the current disposition into `current`, a valid writable
    // struct; all-zero bytes are a valid `sigaction` (integers, a bit mask
    // and a null handler), so it is initialised whether or not the call
    // succeeded.
    let (rc, current) = unsafe {
        let rc = libc::sigaction(sig, std::ptr::null(), current.as_mut_ptr());
        (rc, current.assume_init())
    };
    rc == 0 && current.sa_sigaction == libc::SIG_IGN
}

/// What the demo compares with the truth: final calibration and heights.
type Outcome = (
    Option<stature::report::record::Calibration>,
    Vec<stature::report::record::Height>,
);

fn run_source(
    cfg: &Config,
    src: &mut dyn source::FrameSource,
    signals: &Signals,
    outcome: &mut Outcome,
    until_confident: bool,
) -> i32 {
    let info = src.info().clone();
    // A frame size the board cannot hold is refused now, not by the OOM
    // killer later (which may pick another process).
    if let Err(r) = check_memory(cfg, info.size) {
        log::error!("{}", r.message);
        return r.code;
    }
    // The state and snapshot paths are checked before anything else starts.
    let (state, mut snapshot) = match check_run_paths(cfg) {
        Ok(files) => (
            files.state,
            files
                .snapshot
                .map(|f| stature::snapshot::Snapshot::with_file(cfg, &info, f, until_confident)),
        ),
        Err(r) => {
            log::error!("{}", r.message);
            return r.code;
        }
    };
    // Validated already; this cannot fail.
    let specs = match cfg.report.sink_specs() {
        Ok(s) => s,
        Err(e) => {
            log::error!("{e}");
            return exit::BAD_INPUT;
        }
    };
    if specs.is_empty() {
        // Allowed (a run for its state file or snapshot), but rarely meant.
        log::warn!("no report sinks (report.sinks is empty): the run's records go nowhere");
    }
    // Before any sink opens: the open's errors are all exit code 3.
    #[cfg(feature = "mqtt")]
    for spec in &specs {
        if let sink::SinkSpec::Mqtt(m) = spec {
            if let Err(r) = mqtt_settings(cfg, m) {
                log::error!("{}", r.message);
                return r.code;
            }
        }
    }
    let mut sinks = Vec::new();
    for spec in &specs {
        match sink::Sink::open_with(spec, &cfg.report.mqtt) {
            Ok(s) => sinks.push(s),
            Err(e) => {
                log::error!("cannot open report sink: {e}");
                return exit::UNAVAILABLE;
            }
        }
    }
    log::info!(
        "source {} ({}x{} at {:.2} fps)",
        info.description,
        info.size.width,
        info.size.height,
        info.fps_f64()
    );
    if cfg.report.format == stature::config::Format::Postcard
        && specs.iter().any(|s| matches!(s, sink::SinkSpec::Stdout))
        && std::io::IsTerminal::is_terminal(&std::io::stdout())
    {
        log::warn!(
            "report sink stdout: postcard records are binary and standard output is a \
             terminal: use --format json to read them, or redirect to a file or a program"
        );
    }
    if info.grey {
        log::warn!(
            "grey source: without colour the chroma foreground test and the colour \
             re-identification of tracks have nothing to go on; expect fewer and less \
             accurate heights than from a colour camera"
        );
    }
    let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    // When no sink can deliver any more, a quiet source's blocked read is
    // woken (through its own flag: `stop` stays the signals').
    let _ = counters.wake.set(signals.wake.clone());
    let stop = &*signals.stop;
    let io = report::spawn_io(rx, sinks, cfg.report.format, counters.clone());
    let opts = run::LoopOptions {
        max_frames: cfg.run.frames,
        status_interval_s: cfg.report.status_interval_s,
        stop,
        allocations: stature::alloc_count::allocations,
        state,
    };
    let mut summary = match snapshot.as_mut() {
        Some(s) => run::run_observed(cfg, src, &mut reporter, opts, s),
        None => run::run(cfg, src, &mut reporter, opts),
    };
    *outcome = (
        summary.calibration.take(),
        core::mem::take(&mut summary.heights),
    );
    // The sinks may still hold records (MQTT waits up to its
    // shutdown_timeout_s for an absent broker). The vision side is done and
    // the state and snapshot are written: a signal now ends the wait, also
    // one that came after the loop's last look (while they were written).
    let late_signal =
        stop.swap(false, Ordering::Relaxed) && summary.stopped_by != run::StopReason::Signal;
    let give_up = || late_signal || stop.load(Ordering::Relaxed);
    let dropped_final_tracks = reporter.finish_unless(Duration::from_secs(5), give_up);
    let waiting = std::time::Instant::now();
    let mut told = false;
    while !io.is_finished() {
        if give_up() {
            // The run's own summary line is below, after the tallies this
            // wait was for: say what the run did here instead.
            log::warn!(
                "{} frames, stopped by {}; then a signal stopped the wait for the report \
                 sinks: the records they still held were not delivered ({} dropped with \
                 the queue full, {} failed at a sink before)",
                summary.frames,
                summary.stopped_by,
                counters.dropped_queue.load(Ordering::Relaxed),
                counters.dropped_sink.load(Ordering::Relaxed),
            );
            return source_error_exit(summary.error).unwrap_or(exit::UNAVAILABLE);
        }
        if !told && waiting.elapsed() >= Duration::from_secs(1) {
            log::info!(
                "waiting for the report sinks to deliver what they hold (a signal ends the wait)"
            );
            told = true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let Ok(tallies) = io.join() else {
        log::error!("the report thread failed");
        return exit::INTERNAL;
    };
    // A sink that delivered nothing is a run whose reports nobody got
    // (a broker or port unreachable throughout): not a clean end.
    let mut silent_sink = false;
    for t in tallies.iter().filter(|t| t.lost > 0) {
        if t.lost_everything() {
            silent_sink = true;
            log::error!(
                "report sink {}: none of the run's {} records was delivered",
                t.name,
                t.records
            );
        } else {
            log::warn!(
                "report sink {}: {} of {} records not delivered",
                t.name,
                t.lost,
                t.records
            );
        }
    }
    // Per sink, what it delivered: an MQTT sink accepts a record before the
    // broker has it, so only its tally at the end knows.
    let mut delivered: Vec<String> = tallies
        .iter()
        .map(|t| format!("{} {} of {}", t.name, t.records - t.lost, t.records))
        .collect();
    if delivered.is_empty() {
        delivered.push("none (no sinks)".into());
    }
    log::info!(
        "{} frames, stopped by {}; records delivered: {}; {} dropped with the queue full",
        summary.frames,
        summary.stopped_by,
        delivered.join(", "),
        counters.dropped_queue.load(Ordering::Relaxed),
    );
    let finals = counters.dropped_finals.load(Ordering::Relaxed);
    if finals > 0 {
        log::warn!(
            "{finals} final record{} dropped with the queue full ({}): raise \
             report.held_finals (now {}) or report.queue (now {})",
            if finals == 1 { " was" } else { "s were" },
            match dropped_final_tracks.as_slice() {
                [] => "none of them a height".to_string(),
                ids => format!(
                    "final heights of track{} {}{}",
                    if ids.len() == 1 { "" } else { "s" },
                    ids.iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(", "),
                    if (finals as usize) > ids.len() {
                        ", and others"
                    } else {
                        ""
                    }
                ),
            },
            cfg.report.held_finals,
            cfg.report.queue
        );
    }
    if let Some(code) = source_error_exit(summary.error) {
        return code;
    }
    // (The snapshot's own error was logged when it failed.)
    if snapshot.is_some_and(|s| matches!(s.result, Some(Err(_)))) || silent_sink {
        exit::UNAVAILABLE
    } else {
        exit::OK
    }
}

/// The source error that ended a run, logged, and its exit code: a bad
/// stream stays the run's first problem (exit 2), whatever failed after it.
fn source_error_exit(error: Option<source::SourceError>) -> Option<i32> {
    error.map(|e| {
        log::error!("{e}");
        e.exit_code()
    })
}

fn demo(a: DemoArgs) -> i32 {
    use stature::source::sim::{demo, SimSource};
    stature::logger::init(a.verbosity.level());
    let mut cfg = Config::default();
    if let Some(n) = a.frames {
        cfg.run.frames = n;
    }
    let sim = match SimSource::open_uri(&cfg.source.uri) {
        Ok(s) => s,
        Err(e) => {
            say!("stature demo: {e}");
            return e.exit_code();
        }
    };
    let total = match cfg.run.frames {
        0 => sim.frames(),
        n => n.min(sim.frames()),
    };
    // `-q`: only errors on stderr (and the comparison table, the demo's result).
    let quiet = a.verbosity.quiet;
    if !quiet {
        say!(
            "stature demo: running the pipeline on {} ({} frames); records go to stdout",
            cfg.source.uri,
            total
        );
        if cfg.run.frames > sim.frames() {
            say!(
                "stature demo: the demo clip has {} frames, not the {} asked for \
                 (`stature run --source 'sim:plaza?seed=1&frames=N'` runs a longer one)",
                sim.frames(),
                cfg.run.frames
            );
        }
    }
    let mut sim = sim;
    let mut shown;
    let src: &mut dyn source::FrameSource = if quiet {
        &mut sim
    } else {
        shown = Progress::new(&mut sim, total, ProgressStyle::Demo);
        &mut shown
    };
    let mut outcome = (None, Vec::new());
    let signals = stop_on_signals();
    let code = run_source(&cfg, src, &signals, &mut outcome, false);
    let cast = sim.cast();
    // Each final height is matched to the person whose true foot is nearest
    // the track's last foot point in its last frame.
    let heights: Vec<demo::HeightEstimate> = outcome
        .1
        .iter()
        .map(|h| demo::HeightEstimate {
            track_id: h.track_id,
            height_m: f64::from(h.height_m),
            person_id: sim
                .person_at(
                    h.frame,
                    [f64::from(h.foot_px[0]), f64::from(h.foot_px[1])],
                    25.0,
                )
                .map(|m| m.id),
        })
        .collect();
    // The frames actually run: a signal may have stopped the demo early.
    let frames_run = sim.position().min(total);
    let calibration_missing = calibration_missing(frames_run, sim.frames());
    let table = demo::comparison_table(
        sim.scene_truth(),
        &cast,
        &demo::Estimates {
            calibration: outcome.0.as_ref(),
            calibration_missing: &calibration_missing,
            heights: &heights,
            heights_missing: "no person track was measured",
            frames_run,
        },
    );
    say_part!("{table}");
    code
}

/// Why the demo has no calibration after `run` of the scene's `scene`
/// frames (a shortened run may have stopped before enough people had
/// walked through alone).
fn calibration_missing(run: u64, scene: u64) -> String {
    if run < scene {
        format!("too few single-person observations in {run} frames of {scene}; run more frames")
    } else {
        format!("too few single-person observations in the scene's {run} frames")
    }
}

/// Shows `done` of `total` frames (called every `step` frames and at the
/// end): one line rewritten in place on a terminal; in a log (stderr not
/// a terminal) a line at every tenth of the way, so the log stays readable.
fn progress(what: &str, done: u64, total: u64, step: u64) {
    use std::io::IsTerminal;
    let pct = done * 100 / total.max(1);
    if std::io::stderr().is_terminal() {
        say_part!("\r{what}: frame {done}/{total} ({pct}%)");
        if done >= total {
            say!();
        }
    } else if done >= total || pct / 10 != (done.saturating_sub(step) * 100 / total.max(1)) / 10 {
        say!("{what}: frame {done}/{total} ({pct}%)");
    }
}

/// How [`Progress`] shows itself.
#[derive(Clone, Copy, PartialEq)]
enum ProgressStyle {
    /// `stature demo`: [`progress`] every 25 frames.
    Demo,
    /// `stature run` on a file: an info log line at every tenth of the
    /// way, at most one a second, so short runs stay quiet.
    Log,
}

/// Wraps a source of known length to show how far the run is.
struct Progress<'a> {
    inner: &'a mut dyn source::FrameSource,
    total: u64,
    done: u64,
    style: ProgressStyle,
    started: std::time::Instant,
    last_line: std::time::Instant,
}

impl<'a> Progress<'a> {
    fn new(inner: &'a mut dyn source::FrameSource, total: u64, style: ProgressStyle) -> Self {
        let now = std::time::Instant::now();
        Progress {
            inner,
            total,
            done: 0,
            style,
            started: now,
            last_line: now,
        }
    }

    fn show(&mut self) {
        match self.style {
            ProgressStyle::Demo if self.done % 25 == 0 || self.done == self.total => {
                progress("stature demo", self.done, self.total, 25)
            }
            ProgressStyle::Log => {
                let now = std::time::Instant::now();
                let quiet_for = now.duration_since(self.last_line).as_secs_f64();
                if progress_line_due(self.done, self.total, quiet_for) {
                    self.last_line = now;
                    let fps = self.done as f64 / now.duration_since(self.started).as_secs_f64();
                    log::info!(
                        "frame {} of {} ({} %), {fps:.1} frames/s",
                        self.done,
                        self.total,
                        self.done * 100 / self.total.max(1)
                    );
                }
            }
            ProgressStyle::Demo => {}
        }
    }
}

/// Whether `stature run` logs its progress after frame `done` of `total`:
/// at each tenth of the way but the end (the run's closing line says
/// that), and only if the last line is `quiet_for` ≥ 1 s old.
fn progress_line_due(done: u64, total: u64, quiet_for: f64) -> bool {
    let tenth = |n: u64| n * 10 / total.max(1);
    done > 0 && done < total && tenth(done) != tenth(done - 1) && quiet_for >= 1.0
}

impl source::FrameSource for Progress<'_> {
    fn info(&self) -> &source::SourceInfo {
        self.inner.info()
    }
    fn next_frame(
        &mut self,
        frame: &mut stature::frame::Frame,
    ) -> Result<source::Next, source::SourceError> {
        let r = self.inner.next_frame(frame);
        if let Ok(source::Next::Frame) = r {
            self.done += 1;
            self.show();
        }
        r
    }
    fn state(&self) -> source::SourceState {
        self.inner.state()
    }
    fn length(&self) -> Option<u64> {
        Some(self.total)
    }
}

fn sim_cmd(a: SimArgs) -> i32 {
    use source::sim::{export, scene, SimOptions, SimSource};
    use std::io::Write;
    if a.list {
        let mut list = String::new();
        for s in scene::scenes() {
            list.push_str(&format!("{:<6} {}\n", s.name, s.about));
        }
        return print_out(&list).map_or_else(|code| code, |()| exit::OK);
    }
    let Some(spec) = scene::find(&a.scene) else {
        say!(
            "error: unknown scene `{}` (see stature sim --list)",
            a.scene
        );
        return exit::BAD_INPUT;
    };
    if a.frames
        .is_some_and(|n| n == 0 || n > source::sim::MAX_FRAMES)
    {
        say!("error: --frames must be in 1..={}", source::sim::MAX_FRAMES);
        return exit::BAD_INPUT;
    }
    // Two outputs into one file (or both on stdout) would interleave.
    let outputs = [("--out", &a.out), ("--truth", &a.truth), ("--png", &a.png)];
    for (i, (o1, p1)) in outputs.iter().enumerate() {
        for (o2, p2) in &outputs[i + 1..] {
            if let (Some(p1), Some(p2)) = (p1, p2) {
                if same_output(p1, p2) {
                    say!(
                        "error: {o1} {} and {o2} {} name the same output",
                        p1.display(),
                        p2.display()
                    );
                    return exit::BAD_INPUT;
                }
            }
        }
    }
    let opts = SimOptions {
        seed: a.seed,
        frames: a.frames,
        ..SimOptions::default()
    };
    // A Y4M clip or the truth JSON under a PNG's name (or the truth under a clip's)
    // is a slip of the keyboard, refused like `--png x.y4m`.
    for (option, path, wrong) in [
        ("--out", &a.out, "png"),
        ("--truth", &a.truth, "png"),
        ("--truth", &a.truth, "y4m"),
    ] {
        if let Some(path) = path {
            if path
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case(wrong))
            {
                say!(
                    "error: {option} {}: a .{wrong} name for what is not {} (--out writes a Y4M clip, --truth JSON)",
                    path.display(),
                    if wrong == "png" { "a PNG" } else { "a Y4M clip" }
                );
                return exit::BAD_INPUT;
            }
        }
    }
    let mut sim = SimSource::new(spec, &opts);
    let fail = |what: &dyn std::fmt::Display, e: std::io::Error| {
        say!("error: {what}: {e}");
        exit::UNAVAILABLE
    };
    if let Some(path) = &a.png {
        if let Err(e) = stature::snapshot::check_path(path) {
            say!("error: --png {}: {e}", path.display());
            return exit::BAD_INPUT;
        }
        if a.png_frame >= sim.frames() {
            say!(
                "error: --png-frame {} is past the clip ({} frames)",
                a.png_frame,
                sim.frames()
            );
            return exit::BAD_INPUT;
        }
    }
    if a.out.is_none() && a.truth.is_none() && a.png.is_none() {
        say!("error: nothing to do: give --out, --truth, --png or --list");
        return exit::BAD_INPUT;
    }
    // Every output is opened before any is emptied or written, so a bad
    // path does not cost an existing clip or picture (`-`: standard
    // output, for the PNG too).
    let mut opened: Vec<SimOutput> = Vec::new();
    for (option, path) in [("--png", &a.png), ("--truth", &a.truth), ("--out", &a.out)] {
        let Some(path) = path else { continue };
        match SimOutput::open(path) {
            Ok(o) => opened.push(o),
            Err(e) => {
                for o in &opened {
                    o.forget();
                }
                return fail(&format_args!("{option} {}", path.display()), e);
            }
        }
    }
    let mut writers = Vec::new();
    for o in opened {
        match o.start() {
            Ok(w) => writers.push(w),
            Err((name, e)) => return fail(&name, e),
        }
    }
    if let Some(mut png) = a.png.as_ref().map(|_| writers.remove(0)) {
        let mut frame = stature::frame::Frame::new(source::FrameSource::info(&sim).size);
        sim.render(a.png_frame, &mut frame);
        let mut rgb = export::to_rgb(&frame);
        if a.annotate {
            export::annotate(&mut rgb, &sim);
        }
        // The error names the output (see `Named`).
        if let Err(e) =
            export::write_png(&mut png, &rgb, spec.width, spec.height).and_then(|()| png.flush())
        {
            say!("error: {e}");
            return exit::UNAVAILABLE;
        }
    }
    if a.out.is_none() && a.truth.is_none() {
        return exit::OK;
    }
    let mut truth = a.truth.as_ref().map(|_| writers.remove(0));
    let mut y4m = a.out.as_ref().map(|_| writers.remove(0));
    let total = sim.frames();
    let result = export::export(
        &mut sim,
        y4m.as_mut().map(|w| w as &mut dyn Write),
        truth.as_mut().map(|w| w as &mut dyn Write),
        |k| {
            if (k + 1) % 50 == 0 || k + 1 == total {
                progress("stature sim", k + 1, total, 50);
            }
        },
    )
    .and_then(|_| y4m.as_mut().map_or(Ok(()), |w| w.flush()))
    .and_then(|_| truth.as_mut().map_or(Ok(()), |w| w.flush()));
    match result {
        Ok(()) => exit::OK,
        // The error names the output (see `Named`).
        Err(e) => {
            say!("error: {e}");
            exit::UNAVAILABLE
        }
    }
}

/// Whether two output paths name one destination: both `-` (stdout), the
/// same spelling, or one existing file under two names.
fn same_output(a: &std::path::Path, b: &std::path::Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    if a == b {
        return true;
    }
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(ma), Ok(mb)) => (ma.dev(), ma.ino()) == (mb.dev(), mb.ino()),
        _ => false,
    }
}

/// An output of `stature sim`, opened but not yet emptied.
enum SimOutput {
    Stdout,
    File {
        file: std::fs::File,
        path: PathBuf,
        /// Created by the open: removed again if the other output fails.
        created: bool,
    },
}

impl SimOutput {
    fn open(path: &std::path::Path) -> std::io::Result<SimOutput> {
        if path.as_os_str() == "-" {
            return Ok(SimOutput::Stdout);
        }
        let existed = std::fs::symlink_metadata(path).is_ok();
        // No truncation yet: that waits until every output has opened.
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(|e| stature::replace::name_missing_dir(path, e))?;
        Ok(SimOutput::File {
            file,
            path: path.to_path_buf(),
            created: !existed,
        })
    }

    /// The other output failed: a file this open created is removed.
    fn forget(&self) {
        if let SimOutput::File {
            path,
            created: true,
            ..
        } = self
        {
            let _ = std::fs::remove_file(path);
        }
    }

    /// Empties a regular file (a FIFO or device is written as it is) and
    /// returns the buffered writer.
    fn start(self) -> Result<Named, (String, std::io::Error)> {
        match self {
            SimOutput::Stdout => Ok(Named {
                name: "standard output".into(),
                inner: Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
            }),
            SimOutput::File { file, path, .. } => {
                let name = path.display().to_string();
                let emptied =
                    file.metadata().and_then(
                        |m| {
                            if m.is_file() {
                                file.set_len(0)
                            } else {
                                Ok(())
                            }
                        },
                    );
                match emptied {
                    Ok(()) => Ok(Named {
                        name,
                        inner: Box::new(std::io::BufWriter::new(file)),
                    }),
                    Err(e) => Err((name, e)),
                }
            }
        }
    }
}

/// A writer whose errors name its destination (`sim` writes two at once,
/// and an error from the exporter alone would not say which failed).
struct Named {
    name: String,
    inner: Box<dyn std::io::Write>,
}

impl Named {
    fn named(&self, e: std::io::Error) -> std::io::Error {
        std::io::Error::new(e.kind(), format!("cannot write {}: {e}", self.name))
    }
}

impl std::io::Write for Named {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.inner.write(buf).map_err(|e| self.named(e))
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.inner.flush().map_err(|e| self.named(e))
    }
}

fn train_cmd(a: TrainArgs) -> i32 {
    use stature::classify::{eval, train};
    // Training takes minutes: each stage is logged as it starts.
    stature::logger::init(log::LevelFilter::Info);
    // Everything that can be refused is refused before the data is read
    // (a training run takes minutes): the options, then the outputs, then
    // the data folder.
    let Some(data_dir) = a.data.clone().or_else(stature::dataset::shared_data_dir) else {
        say!("error: no data folder (give --data DIR)");
        return exit::UNAVAILABLE;
    };
    if let Some(path) = &a.evaluate {
        let cfg = stature::classify::ClassifyConfig {
            weights: path.display().to_string(),
            ..Default::default()
        };
        let model = match cfg.load_model() {
            Ok(m) => m,
            Err(e) => {
                say!("error: {e}");
                return exit::BAD_INPUT;
            }
        };
        if let Err(e) = check_data_dir(&data_dir) {
            say!("error: {e}");
            return exit::UNAVAILABLE;
        }
        return match eval::evaluate_held_out(&data_dir, &model, a.seed) {
            Ok([ev, det]) => print_out(&format!(
                "{}\n{}\ndetected regions (the detector's own, labelled by the truth):\n{}",
                ev.table(),
                ev.det_table(),
                det.table()
            ))
            .map_or_else(|code| code, |()| exit::OK),
            // The data, or the ffmpeg that decodes its video, is missing.
            Err(e) => {
                say!("error: {e}");
                exit::UNAVAILABLE
            }
        };
    }
    let opts = match train_options(&a, data_dir) {
        Ok(o) => o,
        Err(e) => {
            say!("error: {e}");
            return exit::BAD_INPUT;
        }
    };
    let out = match stature::replace::probe(&a.out) {
        Ok(t) => t,
        Err(e) => {
            say!("error: --out {}: {e}", a.out.display());
            return exit::UNAVAILABLE;
        }
    };
    let report_path = match a.report.as_deref().map(stature::replace::probe).transpose() {
        Ok(t) => t,
        Err(e) => {
            let r = a.report.as_deref().unwrap_or(std::path::Path::new(""));
            say!("error: --report {}: {e}", r.display());
            return exit::UNAVAILABLE;
        }
    };
    if report_path.as_ref() == Some(&out) {
        say!(
            "error: --report {} is the weights file (--out): give another path",
            a.report.as_deref().unwrap_or(&out).display()
        );
        return exit::BAD_INPUT;
    }
    if let Err(e) = check_data_dir(&opts.data_dir) {
        say!("error: {e}");
        return exit::UNAVAILABLE;
    }
    let (model, report) = match train::train(&opts) {
        Ok(r) => r,
        // The options were checked above: what fails now is the data (a
        // file missing or unreadable, ffmpeg absent).
        Err(e) => {
            say!("error: {e}");
            return exit::UNAVAILABLE;
        }
    };
    // Both files are staged before either replaces its path: a failure
    // leaves the old weights and report together.
    let weights = model.to_bytes();
    let mut outputs: Vec<(&PathBuf, &[u8])> = Vec::new();
    if let Some(r) = &report_path {
        outputs.push((r, report.as_bytes()));
    }
    outputs.push((&out, &weights));
    let mut staged = Vec::new();
    for &(path, bytes) in &outputs {
        match stature::replace::Staged::write(path, bytes) {
            Ok(s) => staged.push((s, path)),
            // (The files staged so far are removed as `staged` drops.)
            Err(e) => {
                say!("error: cannot write {}: {e}", path.display());
                return exit::UNAVAILABLE;
            }
        }
    }
    for (s, path) in staged {
        if let Err(e) = s.commit() {
            say!("error: cannot write {}: {e}", path.display());
            return exit::UNAVAILABLE;
        }
    }
    for path in report_path.iter().chain([&out]) {
        say!("wrote {}", path.display());
    }
    // Printed last: a stdout that fails costs the printout, not the files.
    print_out(&report).map_or_else(|code| code, |()| exit::OK)
}

/// The data folder, checked before training or evaluation starts: a
/// missing one is unavailable input (exit code 3), like a source file.
fn check_data_dir(dir: &std::path::Path) -> Result<(), String> {
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => Err(format!("data folder {}: not a directory", dir.display())),
        Err(e) => Err(format!("data folder {}: {e}", dir.display())),
    }
}

/// Refuses a numeric option outside `range` (also NaN), naming the option,
/// the value and the range: the config's range check, worded for a
/// command-line option.
fn in_range<T: PartialOrd + std::fmt::Display + Copy>(
    option: &str,
    value: Option<T>,
    range: std::ops::RangeInclusive<T>,
) -> Result<(), String> {
    match value {
        Some(v) => stature::config::check_range(option, v, range)
            .map_err(|e| format!("{option} {}: {}", e.value, e.reason)),
        None => Ok(()),
    }
}

/// The training recipe ([`train::TrainOptions::new`] on the default layout)
/// with the options given on the command line applied.
fn train_options(
    a: &TrainArgs,
    data_dir: PathBuf,
) -> Result<stature::classify::train::TrainOptions, String> {
    use stature::classify::layout::{Fit, Layout, ASPECT_CENTRES_Q8};
    use stature::classify::train;
    // Each numeric option's range: outside it the trainer would write a
    // useless classifier (C = 0 or NaN, nothing selected) or run empty.
    in_range("--c", a.c, 0.0001..=1000.0)?;
    in_range("--select", a.select, 0.01..=1.0)?;
    in_range(
        "--pets-stride",
        a.pets_stride,
        1..=train::PETS_TRAIN_LAST + 1,
    )?;
    in_range("--persons", a.persons, 1..=8)?;
    in_range("--mining-rounds", a.mining_rounds, 0..=10)?;
    in_range("--mine-sim-stride", a.mine_sim_stride, 0..=1000)?;
    in_range("--margin", a.margin, 0..=256)?;
    in_range("--hog-cell", a.hog_cell, 2..=32)?;
    in_range("--lbp-cell", a.lbp_cell, 2..=32)?;
    in_range("--lbp-threshold", a.lbp_threshold, 0..=64)?;
    let d = Layout::default_layout();
    let (w, h) = match &a.window {
        None => (d.win_w, d.win_h),
        Some(win) => win
            .split_once('x')
            .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
            .ok_or_else(|| format!("--window {win}: expected WxH, e.g. 32x64"))?,
    };
    let mut layout = Layout::full(
        w,
        h,
        a.margin.unwrap_or(d.margin_q8),
        a.hog_cell.unwrap_or(d.hog_cell),
        a.lbp_cell.unwrap_or(d.lbp_cell),
        a.lbp_threshold.unwrap_or(d.lbp_threshold),
    )
    .map_err(|e| e.to_string())?;
    layout.fit = match a.fit.as_deref() {
        None => d.fit,
        Some("height") => Fit::Height,
        Some("contain") => Fit::Contain,
        Some(f) => return Err(format!("--fit {f}: expected height or contain")),
    };
    layout.aspect_bins = match a.aspect {
        None => d.aspect_bins,
        Some(true) => ASPECT_CENTRES_Q8.len() as u8,
        Some(false) => 0,
    };
    layout.hog_coarse = a.coarse.unwrap_or(d.hog_coarse);
    layout.hog_sqrt = a.hog_sqrt.unwrap_or(d.hog_sqrt);
    layout.mask_fill = a.mask_fill.unwrap_or(d.mask_fill);
    match a.features.as_str() {
        "hog+lbp" => {}
        "hog" => layout.lbp_cells.fill(false),
        "lbp" => layout.hog_blocks.fill(false),
        f => return Err(format!("--features {f}: expected hog+lbp, hog or lbp")),
    }
    layout.validate().map_err(|e| e.to_string())?;
    let mut o = train::TrainOptions::new(data_dir, layout);
    o.seed = a.seed;
    o.c = a.c;
    o.eval = a.eval;
    o.skip_final_cv = a.no_final_cv;
    if let Some(s) = a.select {
        o.select = s;
    }
    if let Some(s) = a.pets_stride {
        o.pets_stride = s;
    }
    if let Some(s) = &a.sim_seeds {
        o.sim_seeds = train::parse_seeds(s).map_err(|e| format!("--sim-seeds {e}"))?;
    }
    if a.no_sim {
        o.sim_seeds.clear();
    }
    if let Some(s) = &a.animal_seeds {
        o.animal_seeds = train::parse_seeds(s).map_err(|e| format!("--animal-seeds {e}"))?;
    }
    if let Some(d) = a.detected_regions {
        o.detected_regions = d;
    }
    if let Some(m) = a.mirror {
        o.mirror = m;
    }
    if let Some(p) = a.persons {
        o.persons_per_frame = p;
    }
    if let Some(r) = a.mining_rounds {
        o.mining_rounds = r;
    }
    if let Some(s) = a.mine_sim_stride {
        o.mine_sim_stride = s;
    }
    for w in &a.weights {
        o.kind_weights.set(w).map_err(|e| format!("--weight {e}"))?;
    }
    train::check_options(&o)?;
    Ok(o)
}

#[cfg(test)]
mod tests {
    use super::{calibration_missing, progress_line_due};

    #[test]
    fn a_short_demo_without_calibration_suggests_more_frames() {
        let short = calibration_missing(50, 600);
        assert_eq!(
            short,
            "too few single-person observations in 50 frames of 600; run more frames"
        );
        let whole = calibration_missing(600, 600);
        assert!(!whole.contains("run more"), "{whole}");
        // Before: a stub classifier was blamed, long after the real one came.
        assert!(!short.contains("stub") && !whole.contains("stub"));
    }

    #[test]
    fn progress_is_logged_at_each_tenth_at_most_once_a_second() {
        let due = |total: u64, quiet_for: f64| -> Vec<u64> {
            (1..=total)
                .filter(|&d| progress_line_due(d, total, quiet_for))
                .collect()
        };
        assert_eq!(due(100, 5.0), [10, 20, 30, 40, 50, 60, 70, 80, 90]);
        // 795 frames (the PETS clip): the first frame of each tenth.
        assert_eq!(due(795, 5.0), [80, 159, 239, 318, 398, 477, 557, 636, 716]);
        // Fewer frames than tenths: a line a frame, never at the end.
        assert_eq!(due(3, 5.0), [1, 2]);
        // A fast run says nothing between its start and its closing line.
        assert!(due(795, 0.5).is_empty());
        assert!(!progress_line_due(0, 0, 5.0) && !progress_line_due(1, 1, 5.0));
    }
}
