//! The `stature` command: see the README for every option.

use clap::{Args, Parser, Subcommand};
use stature::config::{Config, ConfigError, Format};
use stature::report::{self, sink, Reporter};
use stature::{exit, run, source};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

#[global_allocator]
static GLOBAL: stature::alloc_count::CountingAlloc = stature::alloc_count::CountingAlloc;

#[derive(Parser)]
#[command(
    name = "stature",
    version,
    about = "Self-calibrating camera firmware that measures walking people's heights"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Run the pipeline on a source and stream reports.
    Run(RunArgs),
    /// Run the full pipeline on the built-in demo scene and compare with the truth.
    Demo(DemoArgs),
    /// Print or check configuration files.
    Config(ConfigArgs),
}

#[derive(Args, Default)]
struct Verbosity {
    /// More log output on stderr (-v info+debug, -vv trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only errors on stderr.
    #[arg(short, long, global = true)]
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
struct RunArgs {
    /// TOML configuration file (command-line options override it).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frame source: sim:NAME?seed=N, y4m:PATH, y4m:- or v4l2:/dev/videoN?width=..&height=..&fps=..&format=..
    #[arg(long)]
    source: Option<String>,
    /// Report sink (repeatable): stdout, file:PATH, udp:HOST:PORT, serial:/dev/ttyX?baud=N
    #[arg(long = "report")]
    reports: Vec<String>,
    /// Record encoding.
    #[arg(long, value_enum)]
    format: Option<Format>,
    /// Calibration state file (resumed at start, written atomically).
    #[arg(long)]
    state: Option<PathBuf>,
    /// Stop after N frames.
    #[arg(long)]
    frames: Option<u64>,
    #[command(flatten)]
    verbosity: Verbosity,
}

#[derive(Args)]
struct DemoArgs {
    /// Frames to run (default: the whole scene).
    #[arg(long)]
    frames: Option<u64>,
    #[command(flatten)]
    verbosity: Verbosity,
}

#[derive(Args)]
struct ConfigArgs {
    /// Print the documented default configuration.
    #[arg(long, conflicts_with = "check")]
    print_defaults: bool,
    /// Check a configuration file and report the first problem.
    #[arg(long)]
    check: Option<PathBuf>,
}

fn main() {
    let cli = Cli::parse();
    let code = match cli.command {
        None => demo(DemoArgs {
            frames: None,
            verbosity: Verbosity::default(),
        }),
        Some(Command::Demo(a)) => demo(a),
        Some(Command::Run(a)) => run_cmd(a),
        Some(Command::Config(a)) => config_cmd(a),
    };
    std::process::exit(code);
}

fn config_cmd(a: ConfigArgs) -> i32 {
    if let Some(path) = a.check {
        return match Config::load(&path) {
            Ok(_) => {
                println!("{}: ok", path.display());
                exit::OK
            }
            Err(e) => {
                eprintln!("error: {e}");
                exit::BAD_INPUT
            }
        };
    }
    print!("{}", stature::config::DEFAULTS_TOML);
    exit::OK
}

/// Builds the configuration from the file and the command line.
fn resolve_config(a: &RunArgs) -> Result<Config, ConfigError> {
    let mut cfg = match &a.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    if let Some(s) = &a.source {
        cfg.source.uri = s.clone();
    }
    if !a.reports.is_empty() {
        cfg.report.sinks = a.reports.clone();
    }
    if let Some(f) = a.format {
        cfg.report.format = f;
    }
    if let Some(s) = &a.state {
        cfg.run.state = s.display().to_string();
    }
    if let Some(n) = a.frames {
        cfg.run.frames = n;
    }
    cfg.validate()?;
    Ok(cfg)
}

fn run_cmd(a: RunArgs) -> i32 {
    stature::logger::init(a.verbosity.level());
    let cfg = match resolve_config(&a) {
        Ok(c) => c,
        Err(e) => {
            log::error!("{e}");
            return exit::BAD_INPUT;
        }
    };
    run_pipeline(&cfg)
}

fn run_pipeline(cfg: &Config) -> i32 {
    if !cfg.board.name.is_empty() {
        log::info!("board profile {}", cfg.board.name);
    }
    let mut src = match source::open(&cfg.source.uri) {
        Ok(s) => s,
        Err(e) => {
            log::error!("{e}");
            return e.exit_code();
        }
    };
    let mut sinks = Vec::new();
    for spec in &cfg.report.sinks {
        // Validated already; parse cannot fail here.
        let spec = match sink::SinkSpec::parse(spec) {
            Ok(s) => s,
            Err(e) => {
                log::error!("{e}");
                return exit::BAD_INPUT;
            }
        };
        match sink::Sink::open(&spec) {
            Ok(s) => sinks.push(s),
            Err(e) => {
                log::error!("cannot open report sink: {e}");
                return exit::UNAVAILABLE;
            }
        }
    }
    let info = src.info().clone();
    log::info!(
        "source {} ({}x{} at {:.2} fps)",
        info.description,
        info.size.width,
        info.size.height,
        info.fps_f64()
    );
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(sig, stop.clone()) {
            log::warn!("cannot install handler for signal {sig}: {e}");
        }
    }
    let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let io = report::spawn_io(rx, sinks, cfg.report.format, counters.clone());
    let opts = run::LoopOptions {
        max_frames: cfg.run.frames,
        status_interval_s: cfg.report.status_interval_s,
        stop: &stop,
        allocations: stature::alloc_count::allocations,
    };
    let summary = run::run(cfg, src.as_mut(), &mut reporter, &opts);
    reporter.finish(Duration::from_secs(5));
    if io.join().is_err() {
        log::error!("the report thread failed");
        return exit::INTERNAL;
    }
    log::info!(
        "{} frames, stopped by {:?}, {} records delivered, {} dropped",
        summary.frames,
        summary.stopped_by,
        counters
            .delivered
            .load(std::sync::atomic::Ordering::Relaxed),
        counters.dropped()
    );
    match summary.error {
        Some(e) => {
            log::error!("{e}");
            e.exit_code()
        }
        None => exit::OK,
    }
}

fn demo(a: DemoArgs) -> i32 {
    stature::logger::init(a.verbosity.level());
    let mut cfg = Config::default();
    if let Some(n) = a.frames {
        cfg.run.frames = n;
    }
    match source::open(&cfg.source.uri) {
        Ok(_) => run_pipeline(&cfg),
        Err(e) => {
            eprintln!("stature demo: {e}.");
            eprintln!("Missing stages: simulated scene (issue 4), detection (5), classification (6), tracking/calibration/heights (7).");
            eprintln!("Run on recorded frames instead: stature run --source y4m:FILE");
            exit::OK
        }
    }
}
