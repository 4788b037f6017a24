//! Fault injection with real resources: a report file on a full disk, and
//! the process killed (SIGKILL) while it writes its calibration state.

use crate::common::stature_bin;
use stature::calibrate::state::parse_state;
use std::process::{Command, Stdio};
use std::time::Duration;

/// `/dev/full` accepts the open and fails every write with ENOSPC: a full
/// filesystem without needing root to mount a small one.
#[test]
fn report_file_on_a_full_disk_drops_with_counts_and_the_run_goes_on() {
    assert!(
        std::path::Path::new("/dev/full").exists(),
        "/dev/full is a standard Linux device; this test needs it"
    );
    let out = Command::new(stature_bin())
        .args([
            "run",
            "--source",
            "sim:plaza?seed=3&frames=300",
            "--report",
            "file:/dev/full",
            "--report",
            "stdout",
        ])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    // The run goes on to the end (below), then says that a sink delivered
    // nothing: exit 3, the sink named.
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains("report sink file:/dev/full: none of the run's"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains("report sink file:/dev/full: No space left on device"),
        "the full disk is reported: {stderr}"
    );
    let records: Vec<serde_json::Value> = out
        .stdout
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .map(|l| serde_json::from_slice(l).unwrap())
        .collect();
    let bye = records.last().expect("records on stdout");
    assert_eq!(bye["type"], "bye");
    // The vision loop is unaffected: every frame was processed.
    assert_eq!(bye["frames"], 300);
    // Every record reached stdout and none reached the file: the file
    // sink's line counts each lost one (the bye record cannot count its
    // own loss), and the closing line says what each sink delivered.
    let n = records.len();
    let lost = format!("report sink file:/dev/full: none of the run's {n} records was delivered");
    assert!(stderr.contains(&lost), "{stderr} (expected {lost})");
    let summary = stderr
        .lines()
        .find(|l| l.contains("records delivered"))
        .unwrap_or_else(|| panic!("no summary line: {stderr}"));
    let expected =
        format!("records delivered: file:/dev/full 0 of {n}, stdout {n} of {n}; 0 dropped with the queue full");
    assert!(
        summary.contains(&expected),
        "{summary} (expected {expected})"
    );
    // bye counts what was lost before it was made: everything but the
    // final burst (final calibration and heights, the last status, bye
    // itself), which the I/O thread may not have reached yet.
    let burst = records
        .iter()
        .filter(|r| r["final"] == true || r["type"] == "status" || r["type"] == "bye")
        .count() as u64;
    let dropped = bye["dropped"].as_u64().unwrap();
    assert!(
        dropped + burst >= records.len() as u64,
        "bye counted {dropped} of {} lost records",
        records.len()
    );
}

/// A tiny deterministic sequence for kill delays.
fn delays(n: usize) -> impl Iterator<Item = Duration> {
    let mut x = 0x9e37_79b9_u32;
    (0..n).map(move |_| {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        Duration::from_millis(u64::from(x % 400))
    })
}

/// The state file is replaced atomically: whenever the process dies, the
/// file on disk is a complete old or new version, and the next run resumes
/// from it.
#[test]
fn sigkill_during_state_writes_leaves_a_complete_state_file() {
    let dir = crate::common::fresh_dir("faults-state");
    let state = dir.join("calibration.json");
    let config = dir.join("stature.toml");
    // A write at every calibration record (every few frames while it
    // settles), so the kills land among a stream of writes.
    std::fs::write(
        &config,
        format!(
            "[run]\nstate = \"{}\"\n[calibrate]\nstate_interval_s = 0.0\n",
            state.display()
        ),
    )
    .unwrap();
    let mut versions = std::collections::HashSet::new();
    let mut resumed = 0;
    // Each run waits for its first state write (seconds under emulation).
    let runs = crate::common::runs_from_env("FAULT_KILL_RUNS", 20);
    assert!(runs >= 2, "FAULT_KILL_RUNS: a later run must resume");
    for (i, delay) in delays(runs).enumerate() {
        let before = std::fs::read(&state).ok();
        let mut child = Command::new(stature_bin())
            .args(["run", "--report", "file:/dev/null", "--config"])
            .arg(&config)
            .args([
                "--source",
                &format!("sim:plaza?seed={}&frames=100000", i % 3),
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Wait until this run has written something new (start-up time
        // varies with load and under emulation), then kill at a random
        // point after it.
        let deadline = std::time::Instant::now() + Duration::from_secs(120);
        while std::fs::read(&state).ok() == before && std::time::Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(
            std::fs::read(&state).ok() != before,
            "run {i} wrote no new state in 120 s"
        );
        std::thread::sleep(delay);
        child.kill().unwrap(); // SIGKILL
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("starting afresh"), "run {i}: {stderr}");
        resumed += usize::from(stderr.contains("resumed"));
        let bytes = std::fs::read(&state).expect("the state file survives the kill");
        let saved = parse_state(&bytes)
            .unwrap_or_else(|e| panic!("run {i}: torn state file after SIGKILL: {e}"));
        assert_eq!((saved.width, saved.height), (640, 480));
        versions.insert(bytes);
    }
    // Every run left a different file, and each run after the first
    // resumed from what the killed one before it had left.
    assert_eq!(versions.len(), runs, "distinct versions left by the kills");
    assert_eq!(resumed, runs - 1, "later runs resumed from the file");

    // A kill rarely lands inside a write (microseconds among tens of
    // milliseconds), so crash the process exactly there: with a file-size
    // limit below the state's size, the kernel kills it with SIGXFSZ in the
    // middle of writing the next version. The old version must survive.
    let complete = std::fs::read(&state).unwrap();
    let limit = complete.len() / 2;
    let out = Command::new("prlimit")
        .arg(format!("--fsize={limit}"))
        .args(["--core=0", "--"])
        .arg(stature_bin())
        .args(["run", "--report", "stdout", "--config"])
        .arg(&config)
        .args(["--source", "sim:plaza?seed=4&frames=100000"])
        .stdin(Stdio::null())
        .output()
        .expect("prlimit (util-linux) runs");
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(
        out.status.signal(),
        Some(25), // SIGXFSZ on Linux (x86, ARM)
        "killed mid-write: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let after = std::fs::read(&state).unwrap();
    assert!(
        after == complete,
        "a write cut short left {} bytes in place of the last complete version ({} bytes)",
        after.len(),
        complete.len()
    );
}
