//! Every board profile (`board/*.toml`) loads and validates with the real
//! configuration loader, and agrees with the systemd unit that runs it:
//! under `ProtectSystem=strict` only the `StateDirectory` is writable, and
//! the device nodes a profile names must be reachable by the unit's groups.

use crate::common;
use stature::config::Config;
use stature::report::sink::SinkSpec;
use std::path::{Path, PathBuf};

fn board_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("board")
}

fn profiles() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(board_dir())
        .expect("board/ exists")
        .map(|e| e.expect("readable board/ entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

fn unit() -> String {
    std::fs::read_to_string(board_dir().join("stature.service")).expect("board/stature.service")
}

/// `Key=value` lines of the unit (all of them, in order).
fn unit_values(unit: &str, key: &str) -> Vec<String> {
    unit.lines()
        .filter_map(|l| l.trim().strip_prefix(key)?.strip_prefix('='))
        .map(|v| v.trim().to_string())
        .collect()
}

#[test]
fn the_three_board_classes_have_profiles() {
    let names: Vec<String> = profiles()
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    for want in ["rpi4-aarch64", "rpi-zero2", "generic-armv7"] {
        assert!(
            names.iter().any(|n| n == want),
            "board/{want}.toml missing: {names:?}"
        );
    }
}

#[test]
fn every_profile_loads_and_validates() {
    let profiles = profiles();
    assert!(!profiles.is_empty());
    for path in &profiles {
        let cfg =
            Config::load(path, "--config").unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let stem = path.file_stem().unwrap().to_string_lossy();
        assert_eq!(
            cfg.board.name,
            stem,
            "{}: [board] name is the file name",
            path.display()
        );
        assert_ne!(cfg, Config::default(), "{}", path.display());
        // A board profile is for a camera: a V4L2 source with an explicit mode.
        let uri = &cfg.source.uri;
        assert!(
            uri.starts_with("v4l2:/dev/video"),
            "{}: source {uri}",
            path.display()
        );
        for key in ["width=", "height=", "fps=", "format="] {
            assert!(
                uri.contains(key),
                "{}: source {uri} lacks {key}",
                path.display()
            );
        }
        // Caps the service manager enforces.
        assert!(
            cfg.board.memory_max_mib >= 32,
            "{}: memory cap",
            path.display()
        );
        assert!(
            cfg.board.cpu_quota_percent > 0,
            "{}: cpu cap",
            path.display()
        );
        assert!(
            cfg.report.sinks.iter().any(|s| s.starts_with("udp:")),
            "{}: a UDP sink that install.sh --report can point at the workstation",
            path.display()
        );
        // The binary's own check agrees (what board/install.sh runs, with
        // a board build). A build without the `v4l2` feature accepts all
        // but the camera, which it says it cannot drive.
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_stature"))
            .args(["config", "--check"])
            .arg(path)
            .arg("--keys-only")
            .output()
            .expect("run stature config --check");
        let err = String::from_utf8_lossy(&out.stderr);
        if cfg!(feature = "v4l2") {
            assert!(out.status.success(), "{}: {err}", path.display());
        } else {
            assert_eq!(out.status.code(), Some(3), "{}: {err}", path.display());
            assert!(
                err.contains("source.uri: this build has no V4L2 support"),
                "{}: {err}",
                path.display()
            );
        }
    }
}

#[test]
fn profiles_write_only_where_the_hardened_unit_allows() {
    let unit = unit();
    assert_eq!(unit_values(&unit, "ProtectSystem"), ["strict"]);
    let state_dirs = unit_values(&unit, "StateDirectory");
    assert_eq!(state_dirs, ["stature"]);
    for path in profiles() {
        let cfg = Config::load(&path, "--config").unwrap();
        let state = &cfg.run.state;
        assert!(
            state.is_empty() || state.starts_with("/var/lib/stature/"),
            "{}: state file {state} is outside StateDirectory (read-only under ProtectSystem=strict)",
            path.display()
        );
        for sink in &cfg.report.sinks {
            match SinkSpec::parse(sink).unwrap() {
                SinkSpec::File(f) => assert!(
                    f.starts_with("/var/lib/stature/"),
                    "{}: file sink {f} is not writable by the service",
                    path.display()
                ),
                SinkSpec::Serial { path: dev, .. } => assert!(
                    unit_values(&unit, "SupplementaryGroups")
                        .iter()
                        .any(|g| g.split_whitespace().any(|g| g == "dialout")),
                    "{}: serial sink {dev} needs group dialout",
                    path.display()
                ),
                SinkSpec::Stdout | SinkSpec::Udp(_) | SinkSpec::Mqtt(_) => {}
            }
        }
    }
}

#[test]
fn unit_runs_the_installed_profile_as_an_unprivileged_user() {
    let unit = unit();
    assert_eq!(unit_values(&unit, "User"), ["stature"]);
    let groups = unit_values(&unit, "SupplementaryGroups").join(" ");
    for g in ["video", "dialout"] {
        assert!(
            groups.split_whitespace().any(|x| x == g),
            "SupplementaryGroups lacks {g}"
        );
    }
    assert_eq!(unit_values(&unit, "Restart"), ["on-failure"]);
    // A missing camera (exit 3) is retried until it appears: no start limit
    // (any limit would end the retries after a number of attempts), with a
    // pause between attempts.
    assert_eq!(unit_values(&unit, "StartLimitIntervalSec"), ["0"]);
    let pause: f64 = unit_values(&unit, "RestartSec")
        .first()
        .and_then(|s| s.parse().ok())
        .expect("RestartSec in seconds");
    assert!(pause >= 1.0, "RestartSec={pause}: a busy retry loop");
    assert_eq!(unit_values(&unit, "NoNewPrivileges"), ["yes"]);
    // Bad input (exit 2) is not retried; the exit codes are the binary's.
    assert_eq!(
        unit_values(&unit, "RestartPreventExitStatus"),
        [stature::exit::BAD_INPUT.to_string()]
    );
    // ExecStart names the path board/install.sh writes the profile to.
    let exec = unit_values(&unit, "ExecStart").join(" ");
    assert!(exec.starts_with("/usr/local/bin/stature run "), "{exec}");
    assert!(
        exec.contains("--config /etc/stature/stature.toml"),
        "{exec}"
    );
    let install = std::fs::read_to_string(board_dir().join("install.sh")).unwrap();
    assert!(install.contains("/etc/stature/stature.toml"));
    assert!(install.contains("/usr/local/bin/stature"));
    // Devices a profile may name are allowed by the device policy.
    let allowed = unit_values(&unit, "DeviceAllow").join(" ");
    assert!(allowed.contains("char-video4linux"), "{allowed}");
}

/// `sh board/install.sh ARGS` with `DESTDIR=root`: its exit code, and its
/// standard output and error together.
fn run_install(root: &Path, args: &[&str]) -> (Option<i32>, String) {
    let out = std::process::Command::new("sh")
        .arg(board_dir().join("install.sh"))
        .args(args)
        .env("DESTDIR", root)
        .output()
        .expect("run sh board/install.sh");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.code(), text)
}

/// `board/install.sh` into a scratch tree (`DESTDIR`), as an installer
/// runs it: the first time with a sink URI holding `&` (which sed once
/// turned into the matched text), then to upgrade after editing the config
/// (which the upgrade once replaced, credentials and sinks lost, and left
/// world-readable), with `--replace-config`, and with another board's
/// profile over a config nobody edited (replaced without being asked).
#[test]
fn install_sh_writes_the_sinks_as_given_and_an_upgrade_keeps_the_edited_config() {
    use std::os::unix::fs::PermissionsExt;
    let root = common::fresh_dir("board-install_sh_keeps_the_edited_config");
    std::fs::create_dir_all(root.join("etc")).unwrap();
    std::fs::write(root.join("etc/group"), "root:x:0:\n").unwrap();
    std::fs::write(root.join("etc/passwd"), "root:x:0:0:root:/root:/bin/sh\n").unwrap();
    // Not run under DESTDIR (it may be another architecture's binary).
    let binary = root.join("stature-arm");
    std::fs::write(&binary, "#!/bin/sh\nexit 9\n").unwrap();
    std::fs::set_permissions(&binary, std::fs::Permissions::from_mode(0o755)).unwrap();
    let install = |extra: &[&str]| {
        let binary = binary.to_str().unwrap();
        run_install(
            &root,
            &[&["--no-systemd", "--binary", binary][..], extra].concat(),
        )
    };
    let conf = root.join("etc/stature/stature.toml");
    let mqtt = "mqtt:broker.lan?topic=stature/entrance&qos=1";
    let rpi4 = ["--profile", "rpi4-aarch64.toml"];
    let (code, log) = install(
        &[
            &rpi4[..],
            &["--report", mqtt, "--report", "udp:10.0.0.5:9000"],
        ]
        .concat(),
    );
    assert_eq!(code, Some(0), "{log}");
    let cfg = Config::load(&conf, "--config").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cfg.report.sinks[..2], [mqtt, "udp:10.0.0.5:9000"]);
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(
        mode(&conf),
        0o640,
        "readable by root and the service's group only"
    );
    assert!(std::fs::read_to_string(root.join("etc/group"))
        .unwrap()
        .contains("stature:x:"));

    // The installer's edit: a broker password, the file made private.
    let mut edited = std::fs::read_to_string(&conf).unwrap();
    edited.push_str("\n[report.mqtt]\nusername = \"stature\"\npassword = \"change-me\"\n");
    std::fs::write(&conf, &edited).unwrap();
    std::fs::set_permissions(&conf, std::fs::Permissions::from_mode(0o600)).unwrap();
    let (code, log) = install(&rpi4);
    assert_eq!(code, Some(0), "{log}");
    assert_eq!(std::fs::read_to_string(&conf).unwrap(), edited, "kept");
    assert!(
        log.contains("kept your") && log.contains("stature.toml.dist"),
        "{log}"
    );
    assert_eq!(
        mode(&conf),
        0o640,
        "the service can read it, others still cannot"
    );
    let dist = root.join("etc/stature/stature.toml.dist");
    assert!(std::fs::read_to_string(&dist)
        .unwrap()
        .contains("\"udp:127.0.0.1:9000\""));
    // Asked for: the profile replaces it, the edited one is kept aside.
    let (code, log) = install(&[&rpi4[..], &["--replace-config"]].concat());
    assert_eq!(code, Some(0), "{log}");
    assert!(!std::fs::read_to_string(&conf).unwrap().contains("password"));
    let old = root.join("etc/stature/stature.toml.old");
    assert_eq!(std::fs::read_to_string(&old).unwrap(), edited, "{log}");
    assert_eq!(mode(&old), 0o640, "as private as the config was");

    // Left as installed, the config is the profile's to change: another
    // board's profile replaces it on the next run, with no option needed.
    let (code, log) = install(&["--profile", "rpi-zero2.toml"]);
    assert_eq!(code, Some(0), "{log}");
    assert!(log.contains("was as last installed"), "{log}");
    assert_eq!(
        std::fs::read_to_string(&conf).unwrap(),
        std::fs::read_to_string(board_dir().join("rpi-zero2.toml")).unwrap()
    );
    assert_eq!(mode(&conf), 0o640);

    // Values TOML cannot hold as written, and a missing value.
    for bad in ["udp:a\"b:1", "udp:a\\b:1", "udp:10.0.0.5:9000\nsinks = []"] {
        let (code, log) = install(&[&rpi4[..], &["--report", bad]].concat());
        assert_eq!(code, Some(2), "{bad:?}: {log}");
        assert!(
            log.contains("without quotes, backslashes or control characters"),
            "{bad:?}: {log}"
        );
    }
    let (code, log) = install(&[&rpi4[..], &["--report"]].concat());
    assert_eq!(code, Some(2), "{log}");
    assert!(log.contains("--report needs a value"), "{log}");
}

/// `board/install.sh` into a new, empty tree. Before: it stopped at a
/// missing `etc/group`; `memory_max_mib = 1_024` (valid TOML) became
/// `MemoryMax=1M`; without systemd the state directory stayed root's and
/// the printed start command used a `setpriv` option busybox lacks; with
/// systemd under DESTDIR the unit was not enabled and the script said
/// "installed without systemd".
#[test]
fn install_sh_into_an_empty_tree_reads_the_caps_as_toml_and_gives_the_state_directory_away() {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let scratch = common::fresh_dir("board-install_sh_into_an_empty_tree");
    let binary = scratch.join("stature-arm");
    std::fs::write(&binary, "#!/bin/sh\nexit 9\n").unwrap();
    std::fs::set_permissions(&binary, std::fs::Permissions::from_mode(0o755)).unwrap();
    let profile = |name: &str, caps: &str| {
        let text = std::fs::read_to_string(board_dir().join("rpi4-aarch64.toml")).unwrap();
        let (before, after) = text
            .split_once("memory_max_mib = 128")
            .expect("the rpi4 cap");
        let p = scratch.join(name);
        std::fs::write(&p, format!("{before}{caps}{after}")).unwrap();
        p
    };
    let install = |root: &Path, profile: &Path, extra: &[&str]| {
        let (binary, profile) = (binary.to_str().unwrap(), profile.to_str().unwrap());
        run_install(
            root,
            &[&["--binary", binary, "--profile", profile][..], extra].concat(),
        )
    };
    let caps = |root: &Path| {
        std::fs::read_to_string(root.join("etc/systemd/system/stature.service.d/board.conf"))
            .unwrap()
    };

    // An indented key with digit separators and a comment.
    let root = scratch.join("no-systemd");
    let p = profile("sep.toml", "  memory_max_mib = 1_024 # a 2 GiB board");
    let (code, log) = install(&root, &p, &["--no-systemd"]);
    assert_eq!(code, Some(0), "{log}");
    assert!(caps(&root).contains("MemoryMax=1024M\n"), "{}", caps(&root));
    let conf = Config::load(&root.join("etc/stature/stature.toml"), "--config").unwrap();
    assert_eq!(conf.board.memory_max_mib, 1024, "the binary reads the same");
    // The state directory is the service user's (when the test runs as
    // root, which can give it away), and the start command is busybox's too.
    let uid_of = |file: &str| -> u32 {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        let line = text.lines().find(|l| l.starts_with("stature:")).unwrap();
        line.split(':').nth(2).unwrap().parse().unwrap()
    };
    let state = std::fs::metadata(root.join("var/lib/stature")).unwrap();
    // (A file this process creates is its user's: root's, or not.)
    let mine = scratch.join("mine");
    std::fs::write(&mine, b"").unwrap();
    if std::fs::metadata(&mine).unwrap().uid() == 0 {
        assert_eq!(state.uid(), uid_of("etc/passwd"));
        assert_eq!(state.gid(), uid_of("etc/group"));
    }
    assert_eq!(state.permissions().mode() & 0o777, 0o750);
    assert!(
        log.contains("run as: su -s /bin/sh -c 'exec /usr/local/bin/stature run --config /etc/stature/stature.toml' stature"),
        "{log}"
    );
    assert!(!log.contains("setpriv"), "{log}");

    // With systemd, into an image: enabled as `systemctl enable` would.
    let root = scratch.join("image");
    let (code, log) = install(&root, &board_dir().join("rpi4-aarch64.toml"), &[]);
    assert_eq!(code, Some(0), "{log}");
    let link = root.join("etc/systemd/system/multi-user.target.wants/stature.service");
    assert_eq!(
        std::fs::read_link(&link).unwrap(),
        Path::new("/etc/systemd/system/stature.service")
    );
    assert!(log.contains("enabled in"), "{log}");
    assert!(!log.contains("without systemd"), "{log}");
    assert!(caps(&root).contains("MemoryMax=128M\n"));

    // A value the script cannot read is refused before anything is
    // replaced: the installed config and binary stay.
    let before = std::fs::read(root.join("etc/stature/stature.toml")).unwrap();
    let p = profile("hex.toml", "memory_max_mib = 0x400");
    let (code, log) = install(&root, &p, &["--replace-config"]);
    assert_eq!(code, Some(2), "{log}");
    assert!(
        log.contains("memory_max_mib = 0x400") && log.contains("nothing was installed"),
        "{log}"
    );
    assert_eq!(
        std::fs::read(root.join("etc/stature/stature.toml")).unwrap(),
        before
    );
    assert!(!root.join("etc/stature/stature.toml.new").exists());
}
