//! Two stature processes on one calibration state file (the installer's
//! `stature snapshot` with the service's config while the service runs):
//! the first to open the state writes it; another resumes from it, says
//! that it will not update it (and, at its end, that it did not), and
//! leaves it as it was. Before, both wrote through one temporary file and
//! readers saw torn state files.

use stature::calibrate::state::{StateFile, IN_USE};

use crate::common;

use crate::common::run_stature as run;

#[test]
fn a_second_process_resumes_from_the_state_but_never_writes_it() {
    let dir = common::fresh_dir("state_lock-second_process");
    let state = dir.join("shared.json");
    let state_arg = state.to_str().unwrap();
    let args = [
        "run",
        "--source",
        "sim:plaza?seed=1&frames=300",
        "--state",
        state_arg,
    ];
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains(IN_USE), "{err}");
    let written = std::fs::read(&state).unwrap();
    assert!(
        !dir.join("shared.json.stature-lock").exists(),
        "a run removes its lock file"
    );

    // "The service": this test process holds the state.
    let held = StateFile::open(&state, 0).unwrap();
    assert!(!held.in_use_elsewhere());
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(err.contains("resumed"), "{err}");
    assert_eq!(
        err.matches(IN_USE).count(),
        2,
        "one warning that the state is in use, one at the end: {err}"
    );
    assert!(err.contains("will not update it"), "{err}");
    assert!(err.contains("not saved"), "{err}");
    assert!(!err.contains("No such file"), "{err}");
    assert_eq!(std::fs::read(&state).unwrap(), written, "left as it was");
    // A config check while the service runs still passes.
    let cfg = dir.join("c.toml");
    std::fs::write(&cfg, format!("[run]\nstate = \"{state_arg}\"\n")).unwrap();
    let check = run(&["config", "--check", cfg.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&check.stderr);
    assert_eq!(check.status.code(), Some(0), "{err}");
    assert_eq!(std::fs::read(&state).unwrap(), written);

    // Once it is done, the next run writes again.
    drop(held);
    let out = run(&args);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(!err.contains(IN_USE), "{err}");
    assert_ne!(std::fs::read(&state).unwrap(), written, "updated");
}
