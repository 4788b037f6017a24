//! The `stature` binary as a user runs it: options, config files, sources,
//! sinks, exit codes and messages.

use stature::frame::Size;
use std::io::Write;
use std::process::{Command, Stdio};

use crate::common;
use crate::common::stature_bin;

/// A synthetic clip of `frames` frames written to `dir/name`.
fn write_clip(dir: &std::path::Path, name: &str, frames: usize) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(
        &p,
        common::synthetic_y4m(
            Size {
                width: 64,
                height: 48,
            },
            frames,
        ),
    )
    .unwrap();
    p
}

fn records(stdout: &[u8]) -> Vec<serde_json::Value> {
    stdout
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .map(|l| serde_json::from_slice(l).expect("stdout holds only JSON records"))
        .collect()
}

use crate::common::run_stature as run;

#[test]
fn y4m_file_streams_hello_status_bye_to_stdout_and_udp() {
    let dir = common::fresh_dir("cli-y4m_file_streams_hello_status_bye_to_stdout_and_udp");
    let clip = write_clip(&dir, "a.y4m", 30);
    let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    udp.set_read_timeout(Some(std::time::Duration::from_secs(5)))
        .unwrap();
    let port = udp.local_addr().unwrap().port();
    let out = run(&[
        "run",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--report",
        &format!("udp:127.0.0.1:{port}"),
        "--report",
        "stdout",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let recs = records(&out.stdout);
    let kinds: Vec<&str> = recs.iter().map(|r| r["type"].as_str().unwrap()).collect();
    assert_eq!(kinds.first(), Some(&"hello"));
    assert_eq!(kinds.last(), Some(&"bye"));
    assert!(kinds.contains(&"status"));
    assert_eq!(recs[0]["width"], 64);
    assert_eq!(recs[0]["fps"], 25.0);
    assert_eq!(recs.last().unwrap()["frames"], 30);
    // `frame` is an index: the records made after the last frame carry 29.
    for r in &recs {
        assert!(r["frame"].as_u64().unwrap() < 30, "{r}");
    }
    assert_eq!(recs.last().unwrap()["frame"], 29);
    let last_status = recs.iter().rev().find(|r| r["type"] == "status").unwrap();
    assert_eq!(last_status["frame"], 29);
    assert_eq!(last_status["frames"], 30);
    let mut buf = [0u8; 2048];
    let n = udp.recv(&mut buf).unwrap();
    let first: serde_json::Value = serde_json::from_slice(&buf[..n]).unwrap();
    assert_eq!(first, recs[0], "UDP carries the same records");
}

/// `stature run --source y4m:- -q` with every standard stream piped.
/// `stature run` reading a pipe, with SIGHUP at its default disposition:
/// a test harness started under `nohup` (or a supervisor that ignores
/// hangups) passes the ignored SIGHUP on, and stature rightly keeps a
/// hangup ignored that its parent ignored (`sighup_ignored_by_the_parent_stays_ignored`).
fn run_from_stdin() -> std::process::Child {
    run_from_stdin_with(&["-q"])
}

/// [`run_from_stdin`] with `extra` arguments instead of `-q`.
fn run_from_stdin_with(extra: &[&str]) -> std::process::Child {
    Command::new("env")
        .args(["--default-signal=HUP", stature_bin()])
        .args(["run", "--source", "y4m:-"])
        .args(extra)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn stdin_source_reads_a_pipe() {
    let dir = common::fresh_dir("cli-stdin_source_reads_a_pipe");
    let clip = std::fs::read(write_clip(&dir, "b.y4m", 12)).unwrap();
    let mut child = run_from_stdin();
    child.stdin.take().unwrap().write_all(&clip).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(records(&out.stdout).last().unwrap()["frames"], 12);
}

#[test]
fn frame_limit_stops_early_with_bye() {
    let dir = common::fresh_dir("cli-frame_limit_stops_early_with_bye");
    let clip = write_clip(&dir, "c.y4m", 20);
    let out = run(&[
        "run",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--frames",
        "7",
    ]);
    assert!(out.status.success());
    let recs = records(&out.stdout);
    assert_eq!(recs.last().unwrap()["type"], "bye");
    assert_eq!(recs.last().unwrap()["frames"], 7);
}

/// Standard output closed (`>&-`) or sent to /dev/null: the runtime puts
/// /dev/null at fd 1, so a `stdout` sink "delivers" every record to
/// nowhere. The run says so (and goes on: a benchmark may mean it); with
/// a pipe there it says nothing of the kind.
#[test]
fn a_stdout_sink_on_dev_null_is_named_in_a_warning() {
    let dir = common::fresh_dir("cli-a_stdout_sink_on_dev_null_is_named_in_a_warning");
    let clip = write_clip(&dir, "c.y4m", 3);
    let source = format!("y4m:{}", clip.display());
    let warning = "standard output is /dev/null";
    let closed = Command::new("sh")
        .arg("-c")
        .arg("exec \"$0\" run --source \"$1\" --report stdout >&-")
        .arg(stature_bin())
        .arg(&source)
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&closed.stderr);
    assert!(closed.status.success(), "{log}");
    assert!(log.contains(warning), "{log}");
    let null = Command::new(stature_bin())
        .args(["run", "--source", &source, "--report", "stdout"])
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&null.stderr);
    assert!(null.status.success() && log.contains(warning), "{log}");
    let piped = run(&["run", "--source", &source, "--report", "stdout"]);
    let log = String::from_utf8_lossy(&piped.stderr);
    assert!(piped.status.success() && !log.contains(warning), "{log}");
    assert_eq!(records(&piped.stdout).last().unwrap()["type"], "bye");
}

#[test]
fn truncated_stream_is_exit_2_with_frame_and_offset_and_final_records() {
    let dir =
        common::fresh_dir("cli-truncated_stream_is_exit_2_with_frame_and_offset_and_final_records");
    let clip = write_clip(&dir, "d.y4m", 5);
    let mut bytes = std::fs::read(&clip).unwrap();
    bytes.truncate(bytes.len() - 100);
    std::fs::write(&clip, bytes).unwrap();
    let out = run(&["run", "--source", &format!("y4m:{}", clip.display())]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("frame 4") && err.contains("byte offset") && err.contains("truncated"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    let recs = records(&out.stdout);
    assert_eq!(
        recs.last().unwrap()["type"],
        "status",
        "final status still sent, no bye after an error"
    );
    assert_eq!(recs.last().unwrap()["source"], "ended");
}

#[test]
fn bad_inputs_give_one_clear_line_and_the_right_exit_code() {
    let dir = common::fresh_dir("cli-bad_inputs_give_one_clear_line_and_the_right_exit_code");
    let good = write_clip(&dir, "e.y4m", 2);
    let src = format!("y4m:{}", good.display());
    let bad_toml = dir.join("bad.toml");
    std::fs::write(&bad_toml, "[report]\nqueue = 2\n").unwrap();
    let unknown = dir.join("unknown.toml");
    std::fs::write(&unknown, "[detect]\nhistroy = 5\n").unwrap();
    let garbage = dir.join("garbage.y4m");
    std::fs::write(&garbage, b"GIF89a not a y4m\n").unwrap();
    let both_scales = dir.join("both.toml");
    std::fs::write(
        &both_scales,
        "[calibrate]\ncamera_height_m = 3.0\nreference_height_m = 1.8\n",
    )
    .unwrap();
    let small_camera = dir.join("small-camera.toml");
    std::fs::write(&small_camera, "[calibrate]\ncamera_height_m = 0.1\n").unwrap();
    let syntax = dir.join("syntax.toml");
    std::fs::write(&syntax, "[source\n").unwrap();
    let dir_open_error = format!(
        "cannot open Y4M file `{}`: it is a directory",
        dir.display()
    );
    let cases: Vec<(Vec<String>, i32, &str)> = vec![
        (
            vec![
                "--source".into(),
                src.clone(),
                "--state".into(),
                "/dev/null".into(),
            ],
            3,
            "calibration state /dev/null: not a regular file",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--state".into(),
                "/nonexistent-dir/x.state".into(),
            ],
            3,
            // The directory, not the file, is what is missing.
            "cannot create /nonexistent-dir/x.state.stature-lock: directory /nonexistent-dir does not exist",
        ),
        (
            vec!["--config".into(), both_scales.display().to_string()],
            2,
            "not both",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--camera-height".into(),
                "0.01".into(),
            ],
            2,
            // Named by the option typed, not the config key it sets, and
            // not offered 0 (unset), which the option refuses (before:
            // "expected 0 (unset) or a value in 0.5..=100").
            "option `--camera-height` = 0.01: expected a value in 0.5..=100\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--reference-height".into(),
                "3".into(),
            ],
            2,
            "option `--reference-height` = 3: expected a value in 0.5..=2.5\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--prior-height".into(),
                "0.2".into(),
            ],
            2,
            "option `--prior-height` = 0.2: expected a value in 0.5..=2.5\n",
        ),
        // In the file, 0 is how the key is left unset.
        (
            vec!["--config".into(), small_camera.display().to_string()],
            2,
            "config key `calibrate.camera_height_m` = 0.1: expected 0 (unset) or a value in 0.5..=100\n",
        ),
        (
            vec!["--config".into(), syntax.display().to_string()],
            2,
            "config file `",
        ),
        (
            vec!["--source".into(), "y4m:/nonexistent/x.y4m".into()],
            3,
            "cannot open Y4M file",
        ),
        // Before: opened, then "read error at frame 0: Is a directory", exit 2.
        (
            vec!["--source".into(), format!("y4m:{}", dir.display())],
            3,
            dir_open_error.as_str(),
        ),
        (
            vec!["--source".into(), format!("y4m:{}", garbage.display())],
            2,
            "YUV4MPEG2 signature",
        ),
        (
            vec!["--source".into(), "rtsp://cam".into()],
            2,
            "unknown scheme",
        ),
        (
            vec!["--source".into(), "v4l2:/dev/video-nope".into()],
            3,
            "V4L2",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "tcp:1.2.3.4:5".into(),
            ],
            2,
            "option `--report` = tcp:1.2.3.4:5: unknown sink `tcp:`",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "file:/nonexistent-dir/x.jsonl".into(),
            ],
            3,
            "report file `/nonexistent-dir/x.jsonl`: directory /nonexistent-dir does not exist",
        ),
        // URL-style `//` (before: a confusing "expected mqtt:HOST.." for
        // MQTT, and a UDP destination `//127.0.0.1:9000` that failed to
        // resolve only once the run started, exit code 3).
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "mqtt://127.0.0.1:1883".into(),
            ],
            2,
            "= mqtt://127.0.0.1:1883: write `mqtt:127.0.0.1:1883`, without `//`\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "udp://127.0.0.1:9000".into(),
            ],
            2,
            "= udp://127.0.0.1:9000: write `udp:127.0.0.1:9000`, without `//`\n",
        ),
        // The password of a URL-style sink is not echoed into the log.
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "mqtt://cam:Pa55word@127.0.0.1:1883".into(),
            ],
            2,
            "= mqtt://***@127.0.0.1:1883: write `mqtt:127.0.0.1:1883`, without `//` (credentials go in",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "file://x.jsonl".into(),
            ],
            2,
            "names `/x.jsonl` at the root of the file system",
        ),
        // Two MQTT sinks with one client id would take turns on a broker
        // (before: accepted, each dropped whenever the other connected).
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "mqtt:127.0.0.1:1".into(),
                "--report".into(),
                "mqtt:127.0.0.1:2".into(),
            ],
            2,
            "= mqtt:127.0.0.1:2: same MQTT client id `stature-",
        ),
        // A huge length is shown as written (before: 309 digits).
        (
            vec!["--camera-height".into(), "1e308".into()],
            2,
            "option `--camera-height` = 1e308: expected a value in 0.5..=100",
        ),
        // The same sink twice sent every record twice.
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "stdout".into(),
                "--report".into(),
                "stdout".into(),
            ],
            2,
            "= stdout: given twice (each record would be sent twice there)",
        ),
        // A bad sink is named once, with one reason (before: "expected
        // `udp:host`: expected udp:HOST:PORT"), and by the option that
        // gave it (before: the config key `report.sinks`).
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "udp:host".into(),
            ],
            2,
            "option `--report` = udp:host: expected udp:HOST:PORT\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "file:".into(),
            ],
            2,
            "= file:: expected file:PATH\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "serial:/dev/ttyS0?baud=x".into(),
            ],
            2,
            "= serial:/dev/ttyS0?baud=x: `baud=x`: expected a rate in 300..=4000000\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "mqtt:h?qos=7".into(),
            ],
            2,
            "= mqtt:h?qos=7: `qos=7`: expected 0 or 1\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "mqtt:h?bogus=1".into(),
            ],
            2,
            "= mqtt:h?bogus=1: unknown mqtt option `bogus` (expected topic, qos, client_id, tls, ca or ha_discovery)\n",
        ),
        (
            vec![
                "--source".into(),
                src.clone(),
                "--report".into(),
                "bogus:x".into(),
            ],
            2,
            "= bogus:x: unknown sink `bogus:` (expected stdout,",
        ),
        (
            vec!["--config".into(), "/nonexistent.toml".into()],
            2,
            "readable TOML",
        ),
        (
            vec!["--config".into(), bad_toml.display().to_string()],
            2,
            "report.queue",
        ),
        (
            vec!["--config".into(), unknown.display().to_string()],
            2,
            "histroy",
        ),
    ];
    for (args, code, want) in cases {
        let mut full = vec!["run".to_string()];
        full.extend(args.iter().cloned());
        let out = Command::new(stature_bin())
            .args(&full)
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.lines().filter(|l| l.contains("ERROR")).count() == 1,
            "{args:?}: one error line expected: {err}"
        );
    }
    // A negative count is a bad value, not an unknown flag (before:
    // "unexpected argument '-1' found").
    let out = run(&["run", "--frames", "-1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("invalid value '-1' for '--frames"), "{err}");
}

#[test]
fn printed_defaults_check_clean_and_postcard_format_is_binary() {
    let dir = common::fresh_dir("cli-printed_defaults_check_clean_and_postcard_format_is_binary");
    let out = run(&["config", "--print-defaults"]);
    assert!(out.status.success());
    let p = dir.join("defaults.toml");
    std::fs::write(&p, &out.stdout).unwrap();
    let check = run(&["config", "--check", &p.display().to_string()]);
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stderr)
    );
    let clip = write_clip(&dir, "f.y4m", 3);
    let out = run(&[
        "run",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--format",
        "postcard",
        "-q",
    ]);
    assert!(out.status.success());
    assert_eq!(
        out.stdout.last(),
        Some(&0),
        "COBS frames end with a zero byte"
    );
    let frames = out
        .stdout
        .split(|&b| b == 0)
        .filter(|f| !f.is_empty())
        .count();
    assert!(frames >= 3, "hello, status, bye: {frames}");
}

/// One run stopped by `signal` (a `kill` option such as `-TERM`).
fn signal_stops_cleanly_with_bye(signal: &str) {
    // A pipe that stays open: the run waits for frames until the signal.
    let mut child = run_from_stdin();
    let mut stdin = child.stdin.take().unwrap();
    let clip = common::synthetic_y4m(
        Size {
            width: 64,
            height: 48,
        },
        4,
    );
    stdin.write_all(&clip).unwrap();
    stdin.flush().unwrap();
    // The hello record comes after the signal handlers are installed; a
    // signal sent before would kill the process (slow start-ups, e.g.
    // under qemu-user on a loaded machine, did outlast a fixed sleep).
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut hello = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut hello).unwrap();
    assert!(hello.contains("\"hello\""), "{hello}");
    let pid = child.id().to_string();
    assert!(Command::new("kill")
        .args([signal, &pid])
        .status()
        .unwrap()
        .success());
    // The pipe stays open and quiet: the blocked read must give up by itself.
    let status = wait_at_most(&mut child, std::time::Duration::from_secs(60))
        .unwrap_or_else(|| panic!("the process ignored {signal} while its pipe was quiet"));
    assert!(status.success(), "{signal}: {status:?}");
    let mut rest = hello.into_bytes();
    std::io::Read::read_to_end(&mut stdout, &mut rest).unwrap();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{signal}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let recs = records(&rest);
    assert_eq!(recs.last().unwrap()["type"], "bye");
    assert!(recs.last().unwrap()["frames"].as_u64().unwrap() <= 4);
    let status = recs.iter().rev().find(|r| r["type"] == "status").unwrap();
    assert_eq!(status["source"], "ended");
    drop(stdin);
}

/// `stature run | head -1` on a camera or a live pipe: once the only
/// sink's reader has gone, no record can reach anyone, so the run stops by
/// itself (it used to run until the source ended, which a camera never
/// does), exit 0 as for a filter whose reader had enough.
#[test]
fn a_run_whose_only_reader_left_stops_by_itself() {
    let mut child = run_from_stdin_with(&[]);
    // A live source: frames keep coming until the run closes the pipe.
    let mut stdin = child.stdin.take().unwrap();
    let clip = common::synthetic_y4m(
        Size {
            width: 64,
            height: 48,
        },
        1,
    );
    let frame_at = clip.windows(5).position(|w| w == b"FRAME").unwrap();
    let writer = std::thread::spawn(move || {
        let mut sent = 0u64;
        let mut chunk = &clip[..];
        while stdin.write_all(chunk).is_ok() && sent < 1_000_000 {
            chunk = &clip[frame_at..];
            sent += 1;
        }
        sent
    });
    read_hello_and_leave(&mut child);
    // The next record (a status every 125 frames) meets the closed pipe.
    let status = wait_at_most(&mut child, std::time::Duration::from_secs(60))
        .expect("the run kept going after its only reader had left");
    let sent = writer.join().unwrap();
    assert!(sent < 1_000_000, "the run read every frame offered");
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(status.success(), "{status:?}: {err}");
    assert!(
        err.contains("standard output's reader has gone and there is no other sink")
            && err.contains("stopped by standard output's reader leaving"),
        "{err}"
    );
    // A run that ends by itself and finds its reader gone while it sends
    // its final records: still exit 0, and no signal in the log (the
    // report thread's wake-up was read as one: exit 3).
    for _ in 0..3 {
        let mut child = Command::new(stature_bin())
            .args(["run", "--source", "sim:plaza?seed=1", "--frames", "60"])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        read_hello_and_leave(&mut child);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{err}");
        assert!(!err.contains("signal"), "{err}");
    }
}

/// Reads `child`'s first record (its `hello`) and closes its standard
/// output, as `| head -1` does.
fn read_hello_and_leave(child: &mut std::process::Child) {
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut hello = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut hello).unwrap();
    assert!(hello.contains("\"hello\""), "{hello}");
}

/// A grey source runs, and the log says what it costs (without colour the
/// chroma foreground test and colour re-identification are blind: on the
/// plaza clip 18 final heights instead of 25, roll 2.96° against 1.57°).
#[test]
fn a_grey_source_is_warned_of() {
    let dir = common::fresh_dir("cli-a_grey_source_is_warned_of");
    let mut clip = b"YUV4MPEG2 W64 H48 F25:1 Cmono\n".to_vec();
    for i in 0..3u8 {
        clip.extend_from_slice(b"FRAME\n");
        clip.extend(std::iter::repeat_n(100 + i, 64 * 48));
    }
    let path = dir.join("grey.y4m");
    std::fs::write(&path, clip).unwrap();
    let out = run(&["run", "--source", &format!("y4m:{}", path.display())]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.lines()
            .any(|l| l.contains("WARN") && l.contains("grey source")),
        "{err}"
    );
    assert_eq!(records(&out.stdout).last().unwrap()["frames"], 3);
    // A colour clip says nothing of the kind.
    let colour = write_clip(&dir, "colour.y4m", 3);
    let out = run(&["run", "--source", &format!("y4m:{}", colour.display())]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("grey source"));
}

/// Postcard records to a terminal are binary noise on the screen: warned
/// of at start (`script` gives the run a terminal), and not when standard
/// output is a pipe, where binary is what a reader expects.
#[test]
fn postcard_records_to_a_terminal_are_warned_of() {
    let cmd = format!("{} run --frames 2 --format postcard", stature_bin());
    let out = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .stdin(Stdio::null())
        .output()
        .expect("script (util-linux) gives the run a terminal");
    let shown = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{shown}");
    assert!(
        shown.contains("postcard records are binary and standard output is a terminal"),
        "{shown}"
    );
    let out = run(&["run", "--frames", "2", "--format", "postcard"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.success() && !err.contains("is a terminal"),
        "{err}"
    );
}

/// `demo --frames` beyond the demo clip runs the clip and says so (it
/// stopped at 750 frames without a word).
#[test]
fn a_demo_asked_for_more_than_its_clip_says_so() {
    let out = run(&["demo", "--frames", "100000"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("the demo clip has 750 frames, not the 100000 asked for"),
        "{err}"
    );
    assert!(err.contains("(750 frames)"), "{err}");
}

/// Waits for `child` to exit, for at most `limit`.
fn wait_at_most(
    child: &mut std::process::Child,
    limit: std::time::Duration,
) -> Option<std::process::ExitStatus> {
    let start = std::time::Instant::now();
    while start.elapsed() < limit {
        if let Some(status) = child.try_wait().unwrap() {
            return Some(status);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let _ = child.kill();
    None
}

/// A signal while the source is still opening (a pipe, or a FIFO with no
/// writer yet, that has not sent its Y4M header) ends the run cleanly:
/// exit 0, a log line saying so, no records (there was no stream to
/// describe).
#[test]
fn signal_before_the_header_ends_cleanly() {
    let dir = common::fresh_dir("cli-signal_before_the_header_ends_cleanly");
    let fifo = dir.join("clip.fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let png = dir.join("s.png").display().to_string();
    let fifo_uri = format!("y4m:{}", fifo.display());
    let runs: [(&[&str], i32); 3] = [
        (&["run", "--source", "y4m:-"], 0),
        (&["run", "--source", &fifo_uri], 0),
        // A snapshot asked for and not made is an error (before: exit 0,
        // and `stature snapshot ... && upload` went on without a picture).
        (&["snapshot", "--source", &fifo_uri, "--out", &png], 3),
    ];
    for (args, code) in runs {
        let uri = args.join(" ");
        let mut child = Command::new(stature_bin())
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Signal handlers are in place before this line is logged.
        let mut stderr = std::io::BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        while !line.contains("opening source") {
            line.clear();
            let n = std::io::BufRead::read_line(&mut stderr, &mut line).unwrap();
            assert!(n > 0, "{uri}: stderr ended before the source was opened");
        }
        assert!(Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap()
            .success());
        let status = wait_at_most(&mut child, std::time::Duration::from_secs(60))
            .unwrap_or_else(|| panic!("{uri}: SIGTERM ignored while waiting for the header"));
        let mut rest = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
        assert_eq!(status.code(), Some(code), "{uri}: {rest}");
        assert!(rest.contains("stopped by a signal before"), "{uri}: {rest}");
        if code != 0 {
            assert!(rest.contains("no frame to draw"), "{uri}: {rest}");
            assert!(!std::path::Path::new(&png).exists());
        }
        let mut out = Vec::new();
        std::io::Read::read_to_end(&mut child.stdout.take().unwrap(), &mut out).unwrap();
        assert!(out.is_empty(), "{uri}: {}", String::from_utf8_lossy(&out));
    }
}

#[test]
fn sigterm_stops_cleanly_with_bye() {
    signal_stops_cleanly_with_bye("-TERM");
}

#[test]
fn sigint_stops_cleanly_with_bye() {
    signal_stops_cleanly_with_bye("-INT");
}

/// The terminal going away (an installer's SSH session dropping during
/// `stature snapshot`) is a stop like the others: it used to kill the run
/// with no final records, no `bye` and no snapshot.
#[test]
fn sighup_stops_cleanly_with_bye() {
    signal_stops_cleanly_with_bye("-HUP");
}

/// `nohup stature run ...` (SIGHUP ignored by the parent) asked for a run
/// that outlives its terminal: the hangup is not a stop, the frames after
/// it are measured, and the run ends at the end of its input.
#[test]
fn sighup_ignored_by_the_parent_stays_ignored() {
    let mut child = Command::new("sh")
        .args([
            "-c",
            "trap '' HUP; exec \"$0\" run --source y4m:- -q",
            stature_bin(),
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let size = Size {
        width: 64,
        height: 48,
    };
    let clip = common::synthetic_y4m(size, 8);
    // The header and the first four frames, then the hangup, then the rest.
    let frame_bytes = "FRAME\n".len() + 64 * 48 * 3 / 2;
    let split = clip.len() - 4 * frame_bytes;
    stdin.write_all(&clip[..split]).unwrap();
    stdin.flush().unwrap();
    let mut stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let mut hello = String::new();
    std::io::BufRead::read_line(&mut stdout, &mut hello).unwrap();
    assert!(hello.contains("\"hello\""), "{hello}");
    assert!(Command::new("kill")
        .args(["-HUP", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    // Time for a stop to take effect, were the hangup taken as one: the
    // frames written next would then find no reader.
    std::thread::sleep(std::time::Duration::from_millis(500));
    let _ = stdin.write_all(&clip[split..]);
    drop(stdin);
    let status = wait_at_most(&mut child, std::time::Duration::from_secs(120))
        .expect("the run did not end at the end of its input");
    let mut rest = hello.into_bytes();
    std::io::Read::read_to_end(&mut stdout, &mut rest).unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{status:?}: {err}");
    let recs = records(&rest);
    let bye = recs.last().unwrap();
    assert_eq!(bye["type"], "bye", "{err}");
    assert_eq!(
        bye["frames"], 8,
        "SIGHUP stopped a run started under nohup: {err}"
    );
}

#[test]
fn run_snapshot_flag_writes_the_final_calibration_over_the_last_frame() {
    let dir =
        common::fresh_dir("cli-run_snapshot_flag_writes_the_final_calibration_over_the_last_frame");
    let path = dir.join("run-snapshot.png");
    let out = run(&[
        "run",
        "--source",
        "sim:plaza?seed=1&frames=300",
        "--snapshot",
        &path.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("snapshot written to"), "{err}");
    let recs = records(&out.stdout);
    let cal = recs
        .iter()
        .find(|r| r["type"] == "calibration" && r["final"] == true)
        .expect("a final calibration within 300 frames of the plaza");
    let horizon: [f32; 3] = serde_json::from_value(cal["horizon"].clone()).unwrap();
    let ((w, h), rgb) = crate::snapshot::read_png(&path);
    assert_eq!((w, h), (640, 480));
    let pixel = |x: i64, y: i64| {
        ((0..w).contains(&x) && (0..h).contains(&y)).then(|| {
            let i = ((y * w + x) * 3) as usize;
            [rgb[i], rgb[i + 1], rgb[i + 2]]
        })
    };
    crate::snapshot::assert_horizon_drawn(&pixel, (w, h), horizon);
    assert!(!dir.join("run-snapshot.png.stature-tmp").exists());
}

#[test]
fn scale_options_exclude_each_other_and_replace_the_files_choice() {
    let dir = common::fresh_dir("cli-scale_options_exclude_each_other");
    let clip = write_clip(&dir, "s.y4m", 3);
    let src = format!("y4m:{}", clip.display());
    // Two ways of setting the scale at once: refused by the parser.
    let out = run(&[
        "run",
        "--source",
        &src,
        "--camera-height",
        "4",
        "--reference-height",
        "1.8",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("cannot be used with"), "{err}");
    for bad in ["-1", "0", "nan"] {
        let out = run(&["run", "--source", &src, "--camera-height", bad]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{bad}: {err}");
        assert!(err.contains("--camera-height"), "{bad}: {err}");
    }
    // The file sets a camera height; --reference-height on the command
    // line replaces it (before, the camera height silently won and the
    // combination even passed validation).
    let cfg = dir.join("ch.toml");
    std::fs::write(&cfg, "[calibrate]\ncamera_height_m = 3.0\n").unwrap();
    let out = run(&[
        "run",
        "--source",
        &src,
        "--config",
        cfg.to_str().unwrap(),
        "--reference-height",
        "1.75",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    // `config --check` also checks the source's URI, not only the keys.
    let uri = dir.join("uri.toml");
    std::fs::write(&uri, "[source]\nuri = \"sim:plaza?seed=abc\"\n").unwrap();
    let out = run(&["config", "--check", uri.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("seed=abc"), "{err}");
}

#[cfg(unix)]
#[test]
fn a_state_path_that_is_a_link_updates_the_linked_file() {
    let dir = common::fresh_dir("cli-a_state_path_that_is_a_link_updates_the_linked_file");
    let clip = write_clip(&dir, "l.y4m", 3);
    std::fs::create_dir_all(dir.join("persist")).unwrap();
    let link = dir.join("cam.state");
    std::os::unix::fs::symlink("persist/cam.state", &link).unwrap();
    let out = run(&[
        "run",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--state",
        link.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let meta = std::fs::symlink_metadata(&link).unwrap();
    assert!(meta.file_type().is_symlink(), "the link is still a link");
    let text = std::fs::read_to_string(dir.join("persist/cam.state")).unwrap();
    assert!(
        text.contains("\"version\""),
        "the linked file holds the state: {text}"
    );
    assert!(!dir.join("persist/cam.state.stature-tmp").exists());
}

/// A `--state` file that cannot be resumed from is renamed aside, never
/// overwritten: a mistyped path may name a config file, and a state of
/// another frame size is still good for that size.
#[test]
fn a_state_file_that_cannot_be_resumed_from_is_kept_aside() {
    let dir = common::fresh_dir("cli-a_state_file_that_cannot_be_resumed_from_is_kept_aside");
    let clip = write_clip(&dir, "s.y4m", 3);
    let state = dir.join("cam.toml");
    let config = "[report]\nsinks = [\"stdout\"]\n";
    std::fs::write(&state, config).unwrap();
    // Someone's file beside it with the common temporary suffix: the state
    // writes use a suffix of their own.
    let neighbour = dir.join("cam.toml.tmp");
    std::fs::write(&neighbour, "draft").unwrap();
    let state_arg = state.to_str().unwrap();
    let args = [
        "run",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--state",
        state_arg,
    ];
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let aside = dir.join("cam.toml.corrupt");
    assert!(
        err.contains("corrupt state file") && err.contains("kept as"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(&aside).unwrap(),
        config,
        "kept whole"
    );
    let written = std::fs::read_to_string(&state).unwrap();
    assert!(written.contains("\"width\":64"), "a new state: {written}");
    assert_eq!(std::fs::read_to_string(&neighbour).unwrap(), "draft");
    assert!(!dir.join("cam.toml.stature-tmp").exists());
    // Again: the first one set aside stays, the second gets a number.
    std::fs::write(&state, "not json").unwrap();
    let out = run(&args);
    assert_eq!(out.status.code(), Some(0));
    assert_eq!(std::fs::read_to_string(&aside).unwrap(), config);
    assert_eq!(
        std::fs::read_to_string(dir.join("cam.toml.corrupt.1")).unwrap(),
        "not json"
    );
    // A valid state of another frame size is kept under that size.
    let other = written.replace("\"width\":64", "\"width\":640");
    std::fs::write(&state, &other).unwrap();
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("it is for 640x48 frames, not 64x48"), "{err}");
    assert_eq!(
        std::fs::read_to_string(dir.join("cam.toml.640x48")).unwrap(),
        other
    );
}

#[test]
fn unwritable_snapshot_path_is_exit_3_before_the_run_starts() {
    let dir = common::fresh_dir("cli-unwritable_snapshot_path_is_exit_3_before_the_run_starts");
    let clip = write_clip(&dir, "snap.y4m", 3);
    for (path, want) in [
        (
            "/nonexistent-dir/x.png".to_string(),
            "directory /nonexistent-dir does not exist",
        ),
        (dir.display().to_string(), "it is a directory"),
    ] {
        let out = run(&[
            "run",
            "--source",
            &format!("y4m:{}", clip.display()),
            "--snapshot",
            &path,
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{path}: {err}");
        assert!(
            err.contains(&format!("cannot write snapshot {path}")) && err.contains(want),
            "{path}: {err}"
        );
        assert_eq!(
            err.lines().filter(|l| l.contains("ERROR")).count(),
            1,
            "{err}"
        );
        assert!(out.stdout.is_empty(), "the run never started: no hello");
    }
}

#[test]
fn a_snapshot_path_naming_another_format_is_exit_2_before_the_run_starts() {
    let dir = common::fresh_dir("cli-a_snapshot_path_naming_another_format");
    let clip = write_clip(&dir, "ext.y4m", 3);
    let src = format!("y4m:{}", clip.display());
    // Before, each of these ran and wrote a PNG under the other name.
    let jpg = dir.join("x.jpg").display().to_string();
    let jpeg = dir.join("x.JPEG").display().to_string();
    for (args, want) in [
        (
            vec!["run", "--source", &src, "--snapshot", &jpg],
            format!(
                "option `--snapshot` = {jpg}: only PNG is written: give a path ending in `.png`"
            ),
        ),
        (
            vec!["snapshot", "--source", &src, "--out", &jpeg],
            format!("option `--out` = {jpeg}: only PNG is written"),
        ),
        // `sim --png -` is stdout; here stdout has the records (a file
        // named `-` was written).
        (
            vec!["snapshot", "--source", &src, "--out", "-"],
            "option `--out` = -: `-` is not standard output here".to_string(),
        ),
    ] {
        let out = run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(&want), "{args:?}: {err}");
        assert_eq!(
            err.lines().filter(|l| l.contains("ERROR")).count(),
            1,
            "{err}"
        );
        assert!(out.stdout.is_empty(), "the run never started: no hello");
    }
    let cfg = dir.join("gif.toml");
    std::fs::write(&cfg, "[run]\nsnapshot = \"view.gif\"\n").unwrap();
    let out = run(&["config", "--check", &cfg.display().to_string()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("config key `run.snapshot` = view.gif: only PNG is written"),
        "{err}"
    );
    // `stature sim --png` writes the same format and is held to the same rule.
    let jpg = dir.join("frame.jpg");
    let out = run(&[
        "sim",
        "--scene",
        "plaza",
        "--png",
        &jpg.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("only PNG is written"), "{err}");
    assert!(!jpg.exists());
    // Any case of `.png`, and a name without an extension, are written.
    for name in ["upper.PNG", "no-extension"] {
        let path = dir.join(name);
        let out = run(&[
            "run",
            "--source",
            &src,
            "--snapshot",
            &path.display().to_string(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(0), "{name}: {err}");
        assert_eq!(crate::snapshot::read_png(&path).0, (64, 48), "{name}");
    }
    assert!(!dir.join("x.jpg").exists() && !dir.join("x.jpg.stature-tmp").exists());
}

#[test]
fn snapshot_command_stops_once_the_calibration_is_confident() {
    let dir = common::fresh_dir("cli-snapshot_command_stops_once_the_calibration_is_confident");
    // With a threshold of 0 the first estimate is confident enough.
    let cfg = dir.join("snap.toml");
    std::fs::write(&cfg, "[measure]\nmin_confidence = 0.0\n").unwrap();
    let path = dir.join("cmd-snapshot.png");
    let out = run(&[
        "snapshot",
        "--config",
        &cfg.display().to_string(),
        "--source",
        "sim:plaza?seed=1&frames=400",
        "--out",
        &path.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    let recs = records(&out.stdout);
    let first = recs
        .iter()
        .find(|r| r["type"] == "calibration")
        .expect("a calibration");
    let bye = recs.last().unwrap();
    assert_eq!(bye["type"], "bye");
    // Stopped right after the frame of the first estimate.
    assert_eq!(
        bye["frames"].as_u64(),
        first["frame"].as_u64().map(|f| f + 1),
        "{err}"
    );
    assert!(bye["frames"].as_u64().unwrap() < 400);
    assert_eq!(crate::snapshot::read_png(&path).0, (640, 480));
    // The output path is required.
    let out = run(&["snapshot", "--source", "sim:plaza?seed=1&frames=10"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--out"));
}

#[test]
fn verbosity_flags_add_debug_and_trace_lines() {
    let count = |args: &[&str], what: &str| {
        // The first calibration record comes at frame 95.
        let mut full = vec!["run", "--source", "sim:plaza?seed=1", "--frames", "120"];
        full.extend_from_slice(args);
        let out = run(&full);
        assert_eq!(out.status.code(), Some(0));
        String::from_utf8_lossy(&out.stderr)
            .lines()
            .filter(|l| l.contains(what))
            .count()
    };
    assert_eq!(count(&[], "DEBUG]"), 0);
    assert!(count(&["-v"], "DEBUG] calibration at frame") > 0);
    assert_eq!(count(&["-v"], "TRACE]"), 0);
    // One trace line per frame.
    assert_eq!(count(&["-vv"], "TRACE] frame "), 120);
    assert_eq!(count(&["-q"], "INFO ]"), 0);
    let out = run(&["run", "-v", "-q"]);
    assert_eq!(
        out.status.code(),
        Some(2),
        "-v and -q contradict each other"
    );
}

#[test]
fn a_short_quiet_demo_prints_its_table_and_nothing_else() {
    // Too short for a calibration: the table says why, truthfully (before:
    // "too few single-person observations (a stub classifier finds none)").
    let out = run(&["demo", "--frames", "20", "-q"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains(
            "calibration not estimated: too few single-person observations in 20 frames of 750; run more frames"
        ) && err.matches("too few single-person observations").count() == 1,
        "{err}"
    );
    assert!(!err.contains("stub"), "{err}");
    // `-q` leaves the banner and the progress out (before: both printed).
    assert!(!err.contains("stature demo:"), "{err}");
    assert!(!err.contains("frame 20/20"), "{err}");
    let out = run(&["demo", "--frames", "20"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("stature demo: running the pipeline") && err.contains("frame 20/20 (100%)"),
        "{err}"
    );
}

#[test]
fn config_check_names_its_option_and_a_camera_this_build_lacks() {
    let dir = common::fresh_dir("cli-config_check_names_its_option");
    // Before: "option `--config` = ...", an option not given.
    let out = run(&["config", "--check", "/nonexistent.toml"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("option `--check` = /nonexistent.toml: expected a readable TOML file"),
        "{err}"
    );
    // Before, a build without V4L2 passed this file and refused it only
    // once `run` tried to open the camera.
    let cfg = dir.join("camera.toml");
    std::fs::write(&cfg, "[source]\nuri = \"v4l2:/dev/video0\"\n").unwrap();
    let out = run(&["config", "--check", &cfg.display().to_string()]);
    let err = String::from_utf8_lossy(&out.stderr);
    if cfg!(feature = "v4l2") {
        assert_eq!(out.status.code(), Some(0), "{err}");
    } else {
        // Exit code 3, a feature not built in, as `run` gives.
        assert_eq!(out.status.code(), Some(3), "{err}");
        assert!(
            err.contains("source.uri: this build has no V4L2 support"),
            "{err}"
        );
        let out = run(&["run", "--config", &cfg.display().to_string()]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(3), "{err}");
        assert!(err.contains("this build has no V4L2 support"), "{err}");
    }
}

/// Under systemd (stderr is the journal's stream, named by
/// `JOURNAL_STREAM`) every log line carries its syslog priority, so that
/// `journalctl -p err` finds the errors; elsewhere lines are plain.
#[test]
fn log_lines_carry_syslog_priorities_when_stderr_is_the_journal() {
    use std::os::unix::fs::MetadataExt;
    let dir = common::fresh_dir("cli-log_lines_carry_syslog_priorities");
    let clip = write_clip(&dir, "j.y4m", 3);
    let log_path = dir.join("stderr.log");
    let run_with = |journal: bool, source: &str| {
        let log = std::fs::File::create(&log_path).unwrap();
        let meta = log.metadata().unwrap();
        let mut cmd = Command::new(stature_bin());
        // Records to a file: /dev/null there would add a warning line.
        let out = std::fs::File::create(dir.join("out.jsonl")).unwrap();
        cmd.args(["run", "--source", source])
            .stdout(out)
            .stderr(log);
        if journal {
            cmd.env("JOURNAL_STREAM", format!("{}:{}", meta.dev(), meta.ino()));
        } else {
            // Inherited from a service, but stderr is a file now.
            cmd.env(
                "JOURNAL_STREAM",
                format!("{}:{}", meta.dev(), meta.ino() + 1),
            );
        }
        let status = cmd.status().unwrap();
        (status.code(), std::fs::read_to_string(&log_path).unwrap())
    };
    let good = format!("y4m:{}", clip.display());
    let (code, text) = run_with(true, &good);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.lines().count() >= 2, "{text}");
    assert!(
        text.lines()
            .all(|l| l.starts_with("<6>[") && l.contains("INFO ]")),
        "{text}"
    );
    let missing = format!("y4m:{}", dir.join("missing.y4m").display());
    let (code, text) = run_with(true, &missing);
    assert_eq!(code, Some(3), "{text}");
    assert!(
        text.lines()
            .any(|l| l.starts_with("<3>[") && l.contains("ERROR]")),
        "{text}"
    );
    let (code, text) = run_with(false, &good);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.lines().all(|l| l.starts_with('[')), "{text}");
}

/// `stature ARGS` with `path` as its standard output.
fn run_to(path: &str, args: &[&str]) -> std::process::Output {
    Command::new(stature_bin())
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::from(std::fs::File::create(path).unwrap()))
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

/// Every refusal of `stature train` comes before it reads the data (a
/// training run takes minutes). Before: bad values trained a useless
/// classifier with exit 0, and a bad `--out` or `--report` was found
/// after training.
#[test]
fn train_refuses_bad_options_and_outputs_before_reading_data() {
    let dir = common::fresh_dir("cli-train_refuses_bad_options_and_outputs");
    // An empty data folder: training stops at its first file, so a
    // refusal that came after the data would say that instead.
    let data = dir.join("data");
    std::fs::create_dir(&data).unwrap();
    let out = dir.join("w.bin").display().to_string();
    let cases: &[(&[&str], i32, &str)] = &[
        (
            &["--c", "nan"],
            2,
            "--c NaN: expected a value in 0.0001..=1000",
        ),
        (&["--c", "0"], 2, "--c 0: expected a value in 0.0001..=1000"),
        (&["--c=-1"], 2, "--c -1: expected"),
        (
            &["--select", "0"],
            2,
            "--select 0: expected a value in 0.01..=1",
        ),
        (&["--select", "1.5"], 2, "--select 1.5: expected"),
        (
            &["--lbp-threshold", "200"],
            2,
            "--lbp-threshold 200: expected a value in 0..=64",
        ),
        (
            &["--pets-stride", "0"],
            2,
            "--pets-stride 0: expected a value in 1..=600",
        ),
        (
            &["--persons", "0"],
            2,
            "--persons 0: expected a value in 1..=8",
        ),
        (
            &["--mining-rounds", "11"],
            2,
            "--mining-rounds 11: expected a value in 0..=10",
        ),
        (
            &["--margin", "300"],
            2,
            "--margin 300: expected a value in 0..=256",
        ),
        (&["--sim-seeds", "101"], 2, "sim seed 101 is held out"),
        (
            &["--out", "/nonexistent-dir/w.bin"],
            3,
            "--out /nonexistent-dir/w.bin: cannot create /nonexistent-dir/w.bin.stature-tmp: directory /nonexistent-dir does not exist",
        ),
        (
            &["--out", "/dev/full"],
            3,
            "--out /dev/full: not a regular file",
        ),
        (
            &["--report", "/nonexistent-dir/r.md"],
            3,
            "--report /nonexistent-dir/r.md: cannot create",
        ),
        (&["--report", &out], 2, "is the weights file (--out)"),
        (
            &["--data", "/nonexistent-dir"],
            3,
            "data folder /nonexistent-dir: No such file",
        ),
        // Missing data is unavailable input, exit code 3 (before: 2).
        (&[], 3, "mit-cbcl-pedestrians"),
    ];
    for (args, code, want) in cases {
        let mut full = vec!["train"];
        for (option, default) in [("--data", data.to_str().unwrap()), ("--out", &out)] {
            if !args.contains(&option) {
                full.extend([option, default]);
            }
        }
        full.extend_from_slice(args);
        let o = run(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(*code), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        // Nothing written, no temporary file left beside the outputs.
        let left: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .filter(|n| n != "data")
            .collect();
        assert!(left.is_empty(), "{args:?}: {left:?}");
    }
}

/// A full disk or closed pipe on stdout was a panic (exit 101); `train`'s
/// panic came before its weights were written.
#[test]
fn an_unwritable_stdout_is_exit_3_with_the_reason() {
    let dir = common::fresh_dir("cli-an_unwritable_stdout_is_exit_3");
    let cfg = dir.join("ok.toml");
    std::fs::write(&cfg, "").unwrap();
    let cfg = cfg.display().to_string();
    for args in [
        &["config", "--print-defaults"][..],
        &["config", "--check", &cfg],
        &["sim", "--list"],
        &["sim", "--frames", "1", "--out", "-"],
    ] {
        let o = run_to("/dev/full", args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.contains("standard output: No space left on device"),
            "{args:?}: {err}"
        );
    }
}

/// Before: `--state x --report file:x` let the state loader set the
/// record stream aside as a corrupt state (every record went to
/// `x.corrupt`), and a state path that is not UTF-8 was written under
/// another name (U+FFFD for the bad bytes).
#[test]
fn run_outputs_are_refused_when_they_collide_or_cannot_be_named() {
    use std::os::unix::ffi::OsStrExt;
    let dir = common::fresh_dir("cli-run_outputs_collide");
    let x = dir.join("x.jsonl");
    let o = run(&[
        "run",
        "--source",
        "sim:plaza?seed=1&frames=3",
        "--state",
        x.to_str().unwrap(),
        "--report",
        &format!("file:{}", x.display()),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("the same file as run.state"), "{err}");
    let bad = dir.join(std::ffi::OsStr::from_bytes(b"st\xff.json"));
    let o = Command::new(stature_bin())
        .args(["run", "--source", "sim:plaza?seed=1&frames=3", "--state"])
        .arg(&bad)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("not UTF-8"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert!(left.is_empty(), "nothing written: {left:?}");
}

/// Before: `--state` naming the source video set the video aside as a
/// corrupt state and put the state in its place, a `file:` sink naming it
/// appended records to it, and outputs that were one file under two names
/// (a hard link; standard output redirected to a `file:` sink's file) got
/// every record twice. Each is now refused before anything is written.
#[test]
fn run_outputs_are_refused_when_they_are_its_inputs_or_one_file_twice() {
    let dir = common::fresh_dir("cli-run_outputs_are_inputs");
    let clip = write_clip(&dir, "src.y4m", 3);
    let video = std::fs::read(&clip).unwrap();
    let src = format!("y4m:{}", clip.display());
    let weights = dir.join("w.bin");
    std::fs::copy(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("weights/classifier.bin"),
        &weights,
    )
    .unwrap();
    let (a, b) = (dir.join("a.jsonl"), dir.join("b.jsonl"));
    std::fs::write(&a, b"").unwrap();
    std::fs::hard_link(&a, &b).unwrap();
    let file = |p: &std::path::Path| format!("file:{}", p.display());
    let cases: [(Vec<String>, &str); 4] = [
        (
            vec!["--state".into(), clip.display().to_string()],
            "--state",
        ),
        // The sink as written, scheme and all (before: the bare path).
        (
            vec!["--report".into(), file(&clip)],
            &format!(
                "= {}: the same file as the source.uri Y4M file",
                file(&clip)
            ),
        ),
        (
            vec![
                "--weights".into(),
                weights.display().to_string(),
                "--state".into(),
                weights.display().to_string(),
            ],
            "the classify.weights file",
        ),
        (
            vec!["--report".into(), file(&a), "--report".into(), file(&b)],
            &format!(
                "= {}: the same file as a report.sinks file `{}`",
                file(&b),
                file(&a)
            ),
        ),
    ];
    for (extra, want) in &cases {
        let mut args = vec!["run", "--source", &src];
        args.extend(extra.iter().map(String::as_str));
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(want), "{extra:?}: {err}");
    }
    // Standard output redirected to `path`, with a `stdout` sink: the
    // stderr of a run with `extra` arguments, which must refuse to start.
    let refused_on_stdout = |path: &std::path::Path, extra: &[&std::ffi::OsStr]| {
        let o = Command::new(stature_bin())
            .args(["run", "--source", &src, "--report", "stdout"])
            .args(extra)
            .stdin(Stdio::null())
            .stdout(std::fs::File::create(path).unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(2), "{err}");
        err
    };
    // The file a `file:` sink names.
    let out = dir.join("out.jsonl");
    let sink = file(&out);
    let err = refused_on_stdout(&out, &["--report".as_ref(), sink.as_ref()]);
    assert!(
        err.contains("the file standard output") && err.contains("written to it twice"),
        "{err}"
    );
    // A snapshot there would not double the records but mix an image in.
    let png = dir.join("out.png");
    let err = refused_on_stdout(&png, &["--snapshot".as_ref(), png.as_os_str()]);
    assert!(
        err.contains("the image and the records would be mixed"),
        "{err}"
    );
    std::fs::remove_file(dir.join("out.png")).unwrap();
    assert_eq!(std::fs::read(&clip).unwrap(), video, "the video is intact");
    assert_eq!(std::fs::read(&a).unwrap(), b"");
    assert_eq!(std::fs::read(dir.join("out.jsonl")).unwrap(), b"");
    let left = std::fs::read_dir(&*dir).unwrap().count();
    assert_eq!(left, 5, "nothing else written");
}

/// With stderr on a full disk (or a closed pipe) every command still ends
/// with its own exit code; `eprintln!` panicked (exit 101).
#[test]
fn an_unwritable_stderr_changes_no_exit_code() {
    for (args, code) in [
        (&["demo", "--frames", "5"][..], 0),
        (&["config", "--check", "/nonexistent.toml"], 2),
        (&["sim", "--scene", "nosuch", "--out", "-"], 2),
    ] {
        let o = Command::new(stature_bin())
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::from(std::fs::File::create("/dev/full").unwrap()))
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(code), "{args:?}");
    }
}

/// Before: `config --check /dev/zero` read until the OOM killer came.
#[test]
fn config_and_weights_files_are_read_up_to_a_size_cap() {
    let cases: &[(&[&str], &str)] = &[
        (&["config", "--check", "/dev/zero"], "option `--check` = /dev/zero: expected a readable TOML file (larger than 1 MiB, too large to be a config file)"),
        (&["run", "--config", "/dev/zero"], "larger than 1 MiB"),
        (&["run", "--weights", "/dev/zero", "--frames", "1"], "`/dev/zero`: larger than 256 KiB, too large to be a weight blob"),
    ];
    for (args, want) in cases {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn sim_opens_every_output_before_emptying_one() {
    let dir = common::fresh_dir("cli-sim_opens_every_output_before_emptying_one");
    let clip = dir.join("c.y4m");
    std::fs::write(&clip, b"an existing clip").unwrap();
    let clip_s = clip.display().to_string();
    let new = dir.join("new.y4m").display().to_string();
    let truth = dir.join("t.json").display().to_string();
    let png = dir.join("view.png");
    std::fs::write(&png, b"an existing picture").unwrap();
    let png_s = png.display().to_string();
    let cases: &[(&[&str], i32, &str)] = &[
        // Before: the picture was written, then the clip's directory
        // was found missing.
        (
            &["--png", &png_s, "--out", "/nonexistent-dir/c.y4m"],
            3,
            "--out /nonexistent-dir/c.y4m: directory /nonexistent-dir does not exist",
        ),
        // Before: a Y4M clip written into `x.png`.
        (&["--out", &png_s], 2, "a .png name for what is not a PNG"),
        (
            &["--truth", &clip_s],
            2,
            "a .y4m name for what is not a Y4M clip",
        ),
        // Before: the clip was emptied, then the truth failed.
        (
            &["--out", &clip_s, "--truth", "/nonexistent-dir/t.json"],
            3,
            "--truth /nonexistent-dir/t.json: directory /nonexistent-dir does not exist",
        ),
        (
            &["--out", &new, "--truth", "/nonexistent-dir/t.json"],
            3,
            "--truth /nonexistent-dir/t.json",
        ),
        // Before: both written into one file, interleaved.
        (
            &["--out", &clip_s, "--truth", &clip_s],
            2,
            "name the same output",
        ),
        (
            &["--out", "-", "--truth", "-"],
            2,
            "--out - and --truth - name the same output",
        ),
        // Before: ignored without a PNG to draw on.
        (&["--annotate", "--out", &new], 2, "--png"),
        (
            &["--out", "/dev/full", "--truth", &truth],
            3,
            "cannot write /dev/full: No space left on device",
        ),
    ];
    for (args, code, want) in cases {
        let mut full = vec!["sim", "--frames", "2"];
        full.extend_from_slice(args);
        let o = run(&full);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(*code), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert_eq!(
            std::fs::read(&clip).unwrap(),
            b"an existing clip",
            "{args:?}"
        );
        assert!(!std::path::Path::new(&new).exists(), "{args:?}");
        assert_eq!(std::fs::read(&png).unwrap(), b"an existing picture");
    }
    // `--png -` is standard output, as `--out -` is (before: a file
    // named `-`).
    let o = Command::new(stature_bin())
        .args(["sim", "--frames", "2", "--png", "-"])
        .current_dir(&*dir)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        o.stdout.starts_with(b"\x89PNG\r\n\x1a\n"),
        "a PNG on stdout"
    );
    assert!(!dir.join("-").exists());
}

/// `config --check` makes the checks `run` makes at start-up, with its
/// exit codes (before: these configs passed, then `run` stopped with 3).
#[test]
fn config_check_warns_of_a_run_with_no_sinks() {
    let dir = common::fresh_dir("cli-config_check_warns_of_a_run_with_no_sinks");
    let cfg = dir.join("quiet.toml");
    std::fs::write(&cfg, "[report]\nsinks = []\n").unwrap();
    let out = run(&["config", "--check", &cfg.display().to_string()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("report.sinks is empty"), "{err}");
    assert!(String::from_utf8_lossy(&out.stdout).ends_with(": ok\n"));
    // The default sinks draw no warning.
    std::fs::write(&cfg, "[report]\nsinks = [\"stdout\"]\n").unwrap();
    let out = run(&["config", "--check", &cfg.display().to_string()]);
    assert!(out.status.success());
    assert!(!String::from_utf8_lossy(&out.stderr).contains("report.sinks"));
}

#[test]
fn config_check_warns_of_a_state_file_a_run_would_set_aside() {
    let dir = common::fresh_dir("cli-config_check_warns_of_a_state_file");
    let state = dir.join("camera.state");
    let cfg = dir.join("camera.toml");
    std::fs::write(&cfg, format!("[run]\nstate = \"{}\"\n", state.display())).unwrap();
    let check = || {
        let out = run(&["config", "--check", &cfg.display().to_string()]);
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{err}");
        err
    };
    // No file yet: a new one, nothing to say.
    assert!(!check().contains("calibration state"));
    std::fs::write(&state, "{\"not\": \"a state\"}\n").unwrap();
    let err = check();
    assert!(
        err.contains("corrupt state file") && err.contains("set it aside"),
        "{err}"
    );
    // The check only looked: the file is where it was, as it was.
    assert_eq!(
        std::fs::read_to_string(&state).unwrap(),
        "{\"not\": \"a state\"}\n"
    );
}

#[test]
fn config_check_refuses_what_run_would_refuse_at_start() {
    let dir = common::fresh_dir("cli-config_check_refuses_what_run_would_refuse");
    let cases = [
        (
            "[report]\nsinks = [\"mqtt:127.0.0.1:1?tls=true&ca=/nonexistent-dir/ca.pem\"]\n",
            "MQTT CA file `/nonexistent-dir/ca.pem`",
        ),
        (
            "[run]\nstate = \"/nonexistent-dir/x.state\"\n",
            "calibration state /nonexistent-dir/x.state: cannot create /nonexistent-dir/x.state.stature-lock: directory /nonexistent-dir does not exist",
        ),
        (
            "[run]\nsnapshot = \"/nonexistent-dir/x.png\"\n",
            "cannot write snapshot /nonexistent-dir/x.png: cannot create /nonexistent-dir/x.png.stature-tmp: directory /nonexistent-dir does not exist",
        ),
        (
            "[report]\nsinks = [\"file:/nonexistent-dir/r.jsonl\"]\n",
            "report file `/nonexistent-dir/r.jsonl`: directory /nonexistent-dir does not exist",
        ),
        (
            "[report]\nsinks = [\"serial:/nonexistent-dir/ttyS9?baud=9600\"]\n",
            "serial port `/nonexistent-dir/ttyS9`: No such file or directory",
        ),
        (
            "[report]\nsinks = [\"serial:/dev/null?baud=9600\"]\n",
            "serial port `/dev/null`: not a serial device (a mem device)",
        ),
    ];
    // (`run` said "Not a typewriter" for /dev/null until 2026-12-07.)
    for (i, (toml, want)) in cases.iter().enumerate() {
        let cfg = dir.join(format!("{i}.toml"));
        std::fs::write(&cfg, toml).unwrap();
        let cfg = cfg.display().to_string();
        let check = run(&["config", "--check", &cfg]);
        let err = String::from_utf8_lossy(&check.stderr);
        assert_eq!(check.status.code(), Some(3), "{toml}: {err}");
        assert!(err.contains(want), "{toml}: {err}");
        let r = run(&["run", "--config", &cfg, "--frames", "1"]);
        let run_err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), check.status.code(), "{toml}: {run_err}");
        assert!(run_err.contains(want), "{toml}: {run_err}");
        // What board/install.sh asks, before the service's state
        // directory exists: the keys only.
        let keys = run(&["config", "--check", &cfg, "--keys-only"]);
        let err = String::from_utf8_lossy(&keys.stderr);
        assert_eq!(keys.status.code(), Some(0), "{toml}: {err}");
    }
    // Paths that can be written pass, and the check leaves nothing behind.
    let out = dir.join("out");
    std::fs::create_dir(&out).unwrap();
    // An existing report file is opened to append, and left as it was.
    let existing = dir.join("existing.jsonl");
    std::fs::write(&existing, b"{}\n").unwrap();
    let cfg = dir.join("ok.toml");
    std::fs::write(
        &cfg,
        format!(
            "[run]\nstate = \"{0}/x.state\"\nsnapshot = \"{0}/x.png\"\n\
             [report]\nsinks = [\"file:{0}/r.jsonl\", \"file:{1}\"]\n",
            out.display(),
            existing.display()
        ),
    )
    .unwrap();
    let o = run(&["config", "--check", &cfg.display().to_string()]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(std::fs::read_dir(&out).unwrap().count(), 0);
    assert_eq!(std::fs::read(&existing).unwrap(), b"{}\n");
}

/// `config --check` reads a Y4M source's header as `run` does (the frame
/// size is what its memory check needs), with `run`'s exit codes and
/// words; a FIFO at the path is not read (its frames are the feeder's).
/// Before: both configs passed the check, and `run` then stopped.
#[test]
fn config_check_reads_a_y4m_sources_header_as_run_does() {
    let dir = common::fresh_dir("cli-config_check_reads_a_y4m_sources_header");
    let bad = dir.join("bad.y4m");
    std::fs::write(&bad, b"YUV4MPEG W64 H48 F25:1\n").unwrap();
    let cases = [
        (dir.join("missing.y4m"), 3, "cannot open Y4M file"),
        (bad, 2, "missing YUV4MPEG2 signature"),
    ];
    for (i, (clip, code, want)) in cases.iter().enumerate() {
        let cfg = dir.join(format!("{i}.toml"));
        std::fs::write(
            &cfg,
            format!("[source]\nuri = \"y4m:{}\"\n", clip.display()),
        )
        .unwrap();
        let cfg = cfg.display().to_string();
        for args in [
            &["config", "--check", &cfg][..],
            &["run", "--config", &cfg, "--frames", "1"],
        ] {
            let o = run(args);
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(*code), "{args:?}: {err}");
            assert!(err.contains(want), "{args:?}: {err}");
        }
        let keys = run(&["config", "--check", &cfg, "--keys-only"]);
        assert_eq!(keys.status.code(), Some(0));
    }
    let good = write_clip(&dir, "good.y4m", 2);
    let fifo = dir.join("feed.y4m");
    common::mkfifo(&fifo);
    for clip in [good, fifo.clone()] {
        let cfg = dir.join("ok.toml");
        std::fs::write(
            &cfg,
            format!("[source]\nuri = \"y4m:{}\"\n", clip.display()),
        )
        .unwrap();
        // A writer stands by: a check that opened the FIFO would read
        // an empty stream (exit 2) instead of hanging.
        let o = common::with_fifo_writer(&fifo, || {
            run(&["config", "--check", &cfg.display().to_string()])
        });
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(0), "{}: {err}", clip.display());
    }
}

/// Under an address-space limit (`ulimit -v`, systemd's `LimitAS=`) a
/// frame size that does not fit is refused with exit 3, by `run` and by
/// `config --check`, as under a memory limit (before: the allocation
/// failed and the process aborted, exit 134 and a backtrace). Not under
/// qemu-user, which needs more address space of its own than the limit.
#[test]
fn an_address_space_limit_refuses_frames_that_do_not_fit() {
    if std::env::var_os("QEMU_LD_PREFIX").is_some() {
        eprintln!("skipped under qemu-user (the emulator's own mappings exceed the limit)");
        return;
    }
    let dir = common::fresh_dir("cli-an_address_space_limit");
    let clip = dir.join("huge.y4m");
    // 16384x16384 needs about 4 GiB; 1 GiB of address space is plenty
    // for everything else.
    std::fs::write(&clip, b"YUV4MPEG2 W16384 H16384 F25:1 C420\n").unwrap();
    let cfg = dir.join("c.toml");
    std::fs::write(
        &cfg,
        format!("[source]\nuri = \"y4m:{}\"\n", clip.display()),
    )
    .unwrap();
    for args in [
        format!("run --config {}", cfg.display()),
        format!("config --check {}", cfg.display()),
    ] {
        let o = Command::new("sh")
            .arg("-c")
            .arg(format!(
                "ulimit -v 1048576 && exec {} {args}",
                stature_bin()
            ))
            .stdin(Stdio::null())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args}: {err}");
        assert!(
            err.contains("16384x16384 frames need about"),
            "{args}: {err}"
        );
    }
    // A 4:4:4 stream's conversion buffer (768 MiB here) is allocated when
    // the source opens, before that check: refused the same way (before:
    // abort).
    let c444 = dir.join("huge444.y4m");
    std::fs::write(&c444, b"YUV4MPEG2 W16384 H16384 F25:1 C444\n").unwrap();
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 524288 && exec {} run --source y4m:{}",
            stature_bin(),
            c444.display()
        ))
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("frame buffer"), "{err}");
}

/// An MQTT `ca=` path naming a FIFO is refused at start-up, by `run` and
/// by `config --check` alike. Before, both blocked in open(2) waiting for
/// a writer, and only kill -9 ended them.
#[test]
fn an_mqtt_ca_fifo_is_refused_by_run_and_config_check() {
    let dir = common::fresh_dir("cli-an_mqtt_ca_fifo_is_refused");
    let fifo = dir.join("ca.fifo");
    common::mkfifo(&fifo);
    let sink = format!("mqtt:127.0.0.1:1?tls=true&ca={}", fifo.display());
    let cfg = dir.join("c.toml");
    std::fs::write(&cfg, format!("[report]\nsinks = [\"{sink}\"]\n")).unwrap();
    let cfg = cfg.display().to_string();
    let runs: [&[&str]; 2] = [
        &["config", "--check", &cfg],
        &[
            "run",
            "--source",
            "sim:plaza?seed=1&frames=5",
            "--report",
            &sink,
        ],
    ];
    for args in runs {
        // Fails instead of hanging if the open blocks again.
        let o = common::with_fifo_writer(&fifo, || run(args));
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains(&format!(
                "MQTT CA file `{}`: not a regular file (a FIFO)",
                fifo.display()
            )),
            "{args:?}: {err}"
        );
    }
}

/// Before: a blank PNG and exit 0 for a stream that had no frame.
#[test]
fn a_snapshot_of_a_stream_without_frames_is_an_error() {
    let dir = common::fresh_dir("cli-a_snapshot_of_a_stream_without_frames");
    let clip = dir.join("header-only.y4m");
    std::fs::write(&clip, b"YUV4MPEG2 W64 H48 F25:1 C420jpeg\n").unwrap();
    let png = dir.join("v.png");
    let o = run(&[
        "snapshot",
        "--source",
        &format!("y4m:{}", clip.display()),
        "--out",
        &png.display().to_string(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert!(err.contains("no frame to draw"), "{err}");
    assert!(!png.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        1,
        "no temporary file left"
    );
}
