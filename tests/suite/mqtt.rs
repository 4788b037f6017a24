//! The `mqtt:` sink against a real Mosquitto broker on 127.0.0.1 (started
//! per test on a free port with a generated config) and a real subscriber
//! (`mosquitto_sub`): every record on its topic and decodable, retained
//! state for late subscribers and Home Assistant, the last will of a killed
//! camera, a broker outage mid-run, wrong credentials, and TLS.
//!
//! Needs the Debian packages `mosquitto` and `mosquitto-clients` (and
//! `openssl` for the TLS test). Without them the tests fail when `CI` is
//! set and skip with a message otherwise.
#![cfg(feature = "mqtt")]

use stature::config::{Format, ReportConfig};
use stature::frame::Size;
use stature::report::mqtt::MqttConfig;
use stature::report::record::{self, Bye, Calibration, Height, Hello, Record, Status};
use stature::report::{self, encode, sink, Reporter};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use crate::common;

/// Generous bound on waiting for something that should happen (the tests
/// never assert how long anything took; this only keeps a failure from hanging).
const PATIENCE: Duration = Duration::from_secs(20);

fn tool(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin".into(), "/usr/local/sbin".into()])
        .map(|d| d.join(name))
        .find(|p| p.is_file())
}

/// The broker and client programs, or `None` (skip) when not installed
/// locally; panics under CI.
/// A broker that lets anyone in, in a fresh directory named after the test;
/// `None` (the test is skipped, or fails under CI) without the Mosquitto tools.
fn anonymous_broker(name: &str) -> Option<(common::ScratchDir, Broker)> {
    tools(&["mosquitto", "mosquitto_sub", "mosquitto_pub"])?;
    let dir = temp_dir(name);
    let broker = Broker::start(&dir, "allow_anonymous true\n");
    Some((dir, broker))
}

fn tools(names: &[&str]) -> Option<Vec<PathBuf>> {
    let found: Vec<Option<PathBuf>> = names.iter().map(|n| tool(n)).collect();
    if found.iter().all(Option::is_some) {
        return Some(found.into_iter().flatten().collect());
    }
    let missing: Vec<&str> = names
        .iter()
        .zip(&found)
        .filter(|(_, f)| f.is_none())
        .map(|(n, _)| *n)
        .collect();
    let msg = format!(
        "{} not installed (apt-get install mosquitto mosquitto-clients openssl)",
        missing.join(", ")
    );
    if std::env::var_os("CI").is_some() {
        panic!("{msg}: the MQTT tests cannot run");
    }
    eprintln!("skipping: {msg}");
    None
}

/// A fresh directory the broker can write to and read from: started as
/// root, Mosquitto drops to its own user.
fn temp_dir(name: &str) -> common::ScratchDir {
    use std::os::unix::fs::PermissionsExt;
    let d = common::fresh_dir(&format!("mqtt-{name}"));
    std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o777)).unwrap();
    d
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A Mosquitto process on 127.0.0.1.
struct Broker {
    child: Option<Child>,
    port: u16,
    /// The second port [`Broker::start_free`] found (the config may use it).
    other_port: u16,
    conf: PathBuf,
    dir: PathBuf,
}

impl Broker {
    /// Starts a broker with `extra` config lines (the listener is added).
    fn start(dir: &Path, extra: &str) -> Broker {
        Broker::start_free(dir, |[port, _]| {
            format!("listener {port} 127.0.0.1\n{extra}")
        })
    }

    /// Starts a broker on two free ports (`[p, q]`; it must listen on `p`)
    /// with the config `conf` writes for them. A port found free can be
    /// taken before the broker binds it (by any socket of the parallel
    /// tests): then it tries again with fresh ports.
    fn start_free(dir: &Path, conf: impl Fn([u16; 2]) -> String) -> Broker {
        for attempt in 1.. {
            let ports = [free_port(), free_port()];
            let path = dir.join("mosquitto.conf");
            std::fs::write(&path, conf(ports)).unwrap();
            let mut b = Broker {
                child: None,
                port: ports[0],
                other_port: ports[1],
                conf: path,
                dir: dir.to_path_buf(),
            };
            match b.spawn() {
                Ok(()) => return b,
                Err(log) if attempt < 5 && log.contains("Address already in use") => continue,
                Err(log) => panic!("mosquitto exited on start: {log}"),
            }
        }
        unreachable!()
    }

    /// Starts the broker again on its port (after [`Broker::stop`]).
    fn restart(&mut self) {
        if let Err(log) = self.spawn() {
            panic!("mosquitto exited on restart: {log}");
        }
    }

    /// Spawns the broker and waits until it listens; its log if it exits
    /// first.
    fn spawn(&mut self) -> Result<(), String> {
        assert!(self.child.is_none());
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(self.dir.join("mosquitto.log"))
            .unwrap();
        let child = Command::new(tool("mosquitto").unwrap())
            .arg("-c")
            .arg(&self.conf)
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .expect("starting mosquitto");
        self.child = Some(child);
        let deadline = Instant::now() + PATIENCE;
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            if let Some(c) = self.child.as_mut() {
                if c.try_wait().ok().flatten().is_some() {
                    self.child = None;
                    return Err(self.log());
                }
            }
            assert!(
                Instant::now() < deadline,
                "mosquitto did not listen on {}: {}",
                self.port,
                self.log()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Ok(())
    }

    /// Stops the broker the way a service manager does (SIGTERM: it saves
    /// its persistent sessions and exits).
    fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = Command::new("kill")
                .arg("-TERM")
                .arg(c.id().to_string())
                .status();
            let _ = c.wait();
        }
    }

    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("mosquitto.log")).unwrap_or_default()
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// One message as a subscriber saw it.
#[derive(Clone, Debug)]
struct Msg {
    topic: String,
    retain: bool,
    qos: u8,
    payload: String,
}

/// A `mosquitto_sub` process collecting every message.
struct Sub {
    child: Child,
    msgs: Arc<Mutex<Vec<Msg>>>,
    port: u16,
    auth: Vec<String>,
}

impl Sub {
    /// Subscribes (QoS 1) to `filters` plus a probe topic, and returns once
    /// the subscription is live (a probe published afterwards came back).
    fn start(port: u16, filters: &[&str], extra: &[&str]) -> Sub {
        Sub::start_auth(port, filters, extra, &[])
    }

    /// [`Sub::start`] with `auth` (`-u`, `-P`) given to the subscriber and the prober.
    fn start_auth(port: u16, filters: &[&str], extra: &[&str], auth: &[&str]) -> Sub {
        let mut cmd = Command::new(tool("mosquitto_sub").unwrap());
        cmd.args(["-h", "127.0.0.1", "-p", &port.to_string(), "-q", "1"])
            .args(["-F", "%t\t%r\t%q\t%p"])
            .args(extra)
            .args(auth)
            .args(["-t", "probe/#"]);
        for f in filters {
            cmd.args(["-t", f]);
        }
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("starting mosquitto_sub");
        let msgs = Arc::new(Mutex::new(Vec::new()));
        let out = child.stdout.take().unwrap();
        let store = msgs.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(out).lines() {
                let Ok(line) = line else { break };
                let mut f = line.splitn(4, '\t');
                let (Some(t), Some(r), Some(q), Some(p)) = (f.next(), f.next(), f.next(), f.next())
                else {
                    continue;
                };
                store.lock().unwrap().push(Msg {
                    topic: t.into(),
                    retain: r == "1",
                    qos: q.parse().unwrap_or(9),
                    payload: p.into(),
                });
            }
        });
        let sub = Sub {
            child,
            msgs,
            port,
            auth: auth.iter().map(|a| a.to_string()).collect(),
        };
        let deadline = Instant::now() + PATIENCE;
        for n in 0.. {
            assert!(Instant::now() < deadline, "mosquitto_sub never subscribed");
            let probe = format!("probe/{n}");
            sub.publish(&probe, "p");
            if sub.wait(Duration::from_millis(300), |m| {
                m.iter().any(|m| m.topic == probe)
            }) {
                break;
            }
        }
        sub
    }

    fn publish(&self, topic: &str, payload: &str) {
        let _ = Command::new(tool("mosquitto_pub").unwrap())
            .args(["-h", "127.0.0.1", "-p", &self.port.to_string()])
            .args(&self.auth)
            .args(["-t", topic, "-m", payload])
            .status();
    }

    /// Waits until `done` holds for the messages so far (false on timeout).
    fn wait(&self, timeout: Duration, done: impl Fn(&[Msg]) -> bool) -> bool {
        let deadline = Instant::now() + timeout;
        loop {
            if done(&self.msgs.lock().unwrap()) {
                return true;
            }
            if Instant::now() >= deadline {
                return false;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Messages on topics under `prefix`.
    fn under(&self, prefix: &str) -> Vec<Msg> {
        self.msgs
            .lock()
            .unwrap()
            .iter()
            .filter(|m| m.topic.starts_with(prefix))
            .cloned()
            .collect()
    }
}

impl Drop for Sub {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Subscribes, waits `settle` for retained messages, and returns them.
fn retained_now(port: u16, filter: &str, settle: Duration) -> Vec<Msg> {
    let sub = Sub::start(port, &[filter], &[]);
    std::thread::sleep(settle);
    let prefix = filter.trim_end_matches('#');
    sub.under(prefix)
}

// ---------------------------------------------------------------- records

fn hello() -> Record {
    Record::Hello(Hello {
        frame: 0,
        version: record::bounded(env!("CARGO_PKG_VERSION")),
        schema: record::SCHEMA,
        source: record::bounded("synthetic walkers"),
        width: 640,
        height: 480,
        fps: 25.0,
    })
}

fn calibration(frame: u64, confidence: f32, is_final: bool) -> Record {
    Record::Calibration(Calibration {
        frame,
        f_px: 812.5,
        tilt_deg: 18.25,
        roll_deg: -1.5,
        camera_height_m: 4.125,
        horizon: [0.0125, 0.99992, -60.5],
        vertical_vp: [322.0, 2890.0],
        inliers: (confidence * 100.0) as u32,
        confidence,
        is_final,
    })
}

/// Person `track` seen at `frame`: a height that settles as samples grow.
fn height(frame: u64, track: u32, samples: u32, is_final: bool) -> Record {
    let x = (frame % 600) as f32;
    Record::Height(Height {
        frame,
        track_id: track,
        height_m: 1.55 + (track % 7) as f32 * 0.05 + 0.2 / (samples as f32 + 1.0),
        samples,
        foot_px: [40.0 + x, 400.5],
        head_px: [41.0 + x, 250.25],
        bbox: [30 + x as u16, 248, 55 + x as u16, 401],
        is_final,
    })
}

fn status(frame: u64, tracks: u32) -> Record {
    Record::Status(Status {
        frame,
        frames: frame,
        fps: 25.0,
        dropped: 0,
        source: record::bounded("streaming"),
        allocations: 0,
        tracks,
    })
}

/// What a camera watching people walk by reports: each person is in view
/// for `stay` frames (a height every frame, the final one as they leave),
/// a status every 25 frames.
fn walkers(frames: u64, stay: u64) -> Vec<Record> {
    let mut out = vec![hello()];
    for f in 1..=frames {
        let track = (f / stay) as u32 + 1;
        let seen = (f % stay) as u32 + 1;
        let leaving = seen as u64 == stay;
        out.push(height(f, track, seen, leaving));
        if f % 25 == 0 {
            out.push(status(f, 1));
        }
        if f == frames / 2 {
            out.push(calibration(f, 0.55, false));
        }
    }
    out.push(calibration(frames, 0.8, true));
    out.push(status(frames, 0));
    out.push(Record::Bye(Bye {
        frame: frames,
        frames,
        dropped: 0,
    }));
    out
}

/// The JSON payload every other sink writes for `r` (without its newline).
fn json(r: &Record) -> String {
    let mut buf = [0u8; encode::MAX_RECORD];
    let b = encode::encode(r, Format::Json, &mut buf).unwrap();
    String::from_utf8(b[..b.len() - 1].to_vec()).unwrap()
}

fn topic_of(prefix: &str, r: &Record) -> String {
    match r {
        Record::Hello(_) => format!("{prefix}/hello"),
        Record::Calibration(_) => format!("{prefix}/calibration"),
        Record::Height(_) => format!("{prefix}/height"),
        Record::Status(_) => format!("{prefix}/status/record"),
        Record::Bye(_) => format!("{prefix}/bye"),
    }
}

/// Decodes a payload back into a record, as a consumer would.
fn decode(payload: &str) -> Record {
    let mut v: serde_json::Value = serde_json::from_str(payload).expect("payload is JSON");
    let kind = v["type"].as_str().expect("payload has a type").to_string();
    v.as_object_mut().unwrap().remove("type");
    match kind.as_str() {
        "hello" => Record::Hello(serde_json::from_value(v).unwrap()),
        "calibration" => Record::Calibration(serde_json::from_value(v).unwrap()),
        "height" => Record::Height(serde_json::from_value(v).unwrap()),
        "status" => Record::Status(serde_json::from_value(v).unwrap()),
        "bye" => Record::Bye(serde_json::from_value(v).unwrap()),
        k => panic!("unknown record type {k}"),
    }
}

fn mqtt_sink(spec: &str, cfg: &MqttConfig) -> sink::Sink {
    let spec = sink::SinkSpec::parse(spec).expect("valid mqtt spec");
    sink::Sink::open_with(&spec, cfg).expect("mqtt sink opens")
}

/// Runs `records` through the report queue and I/O thread into `sinks`,
/// one every `pace` (zero: as fast as they come), calling `at(i)` before
/// record `i`. Returns the run's counters once the I/O thread has ended
/// (which includes the MQTT sink's shutdown).
fn drive(
    records: &[Record],
    sinks: Vec<sink::Sink>,
    format: Format,
    pace: Duration,
    mut at: impl FnMut(usize),
) -> Arc<report::Counters> {
    let cfg = ReportConfig::default();
    let (mut rep, rx, counters) = Reporter::new(cfg.queue, cfg.held_finals);
    let io = report::spawn_io(rx, sinks, format, counters.clone());
    let start = Instant::now();
    for (i, r) in records.iter().enumerate() {
        at(i);
        rep.send(r.clone());
        if !pace.is_zero() {
            // Keep to a fixed schedule, like a camera's frame clock.
            let due = start + pace * (i as u32 + 1);
            if let Some(d) = due.checked_duration_since(Instant::now()) {
                std::thread::sleep(d);
            }
        }
    }
    rep.finish(PATIENCE);
    io.join().expect("the I/O thread ends cleanly");
    counters
}

// ------------------------------------------------------------------ tests

#[test]
fn every_record_arrives_on_its_topic_as_schema_v1_json() {
    let Some((_dir, broker)) = anonymous_broker("every") else {
        return;
    };
    // JSON and postcard runs: MQTT payloads are JSON either way.
    for (n, format) in [Format::Json, Format::Postcard].into_iter().enumerate() {
        let prefix = format!("stature/every{n}");
        let sub = Sub::start(broker.port, &[&format!("{prefix}/#")], &[]);
        let records = walkers(300, 40);
        // Room for the whole run, should the first connection take a while.
        let cfg = MqttConfig {
            buffer: 1024,
            ..Default::default()
        };
        let sink = mqtt_sink(
            &format!(
                "mqtt:127.0.0.1:{}?topic={prefix}&qos=0&client_id=every{n}",
                broker.port
            ),
            &cfg,
        );
        let counters = drive(
            &records,
            vec![sink],
            format,
            Duration::from_millis(1),
            |_| {},
        );
        assert_eq!(counters.dropped(), 0);
        assert!(
            sub.wait(PATIENCE, |m| m.iter().any(|m| m.payload == "offline")),
            "{format:?}: no offline after the run: {:?}",
            sub.under(&prefix).last()
        );
        let got = sub.under(&prefix);
        // Availability first and last.
        let avail: Vec<&str> = got
            .iter()
            .filter(|m| m.topic == format!("{prefix}/status"))
            .map(|m| m.payload.as_str())
            .collect();
        assert_eq!(avail, ["online", "offline"], "{format:?}");
        // Every record exactly once, in order, on its topic, byte-identical
        // to the other sinks' JSON, and decodable into the same record.
        let recs: Vec<&Msg> = got
            .iter()
            .filter(|m| m.topic != format!("{prefix}/status"))
            .collect();
        assert_eq!(recs.len(), records.len(), "{format:?}");
        for (m, r) in recs.iter().zip(&records) {
            assert_eq!(m.topic, topic_of(&prefix, r), "{format:?}");
            assert_eq!(m.payload, json(r), "{format:?}");
            let back = decode(&m.payload);
            assert_eq!(back.kind(), r.kind());
            assert_eq!(back.is_final(), r.is_final());
            // Final records go with QoS 1 even though qos=0 was asked for.
            assert_eq!(
                m.qos,
                if r.is_final() { 1 } else { 0 },
                "{format:?} {}",
                m.payload
            );
        }
        let finals = recs
            .iter()
            .filter(|m| m.topic.ends_with("/height") && decode(&m.payload).is_final())
            .count();
        assert_eq!(finals, 7);
    }
    drop(broker);
}

#[test]
fn late_subscribers_see_retained_state_and_home_assistant_discovery() {
    let Some((_dir, broker)) = anonymous_broker("retained") else {
        return;
    };
    let prefix = "stature/lobby";
    let records = vec![
        hello(),
        calibration(100, 0.4, false),
        height(120, 3, 20, false),
        calibration(200, 0.65, false),
        height(230, 3, 40, true),
        status(250, 2),
    ];
    let sink = mqtt_sink(
        &format!(
            "mqtt:127.0.0.1:{}?topic={prefix}&client_id=lobby-cam&ha_discovery=true",
            broker.port
        ),
        &MqttConfig::default(),
    );
    // The run stays up while the late subscribers look, as a camera would.
    let watch = Sub::start(broker.port, &[&format!("{prefix}/#")], &[]);
    let (mut rep, rx, counters) = Reporter::new(64, 16);
    let io = report::spawn_io(rx, vec![sink], Format::Json, counters.clone());
    for r in &records {
        rep.send(r.clone());
    }
    let cal = json(&records[3]);
    // Once the last record went through the broker, everything before it did.
    let last = json(records.last().unwrap());
    assert!(watch.wait(PATIENCE, |m| m.iter().any(|m| m.payload == last)));
    let live = retained_now(
        broker.port,
        &format!("{prefix}/#"),
        Duration::from_millis(300),
    );
    let by_topic = |t: &str| -> Vec<&Msg> {
        live.iter()
            .filter(|m| m.topic == format!("{prefix}/{t}"))
            .collect()
    };
    // The newest calibration only, retained; hello retained; online.
    let c = by_topic("calibration");
    assert_eq!(c.len(), 1, "{live:?}");
    assert!(c[0].retain);
    assert_eq!(c[0].payload, cal);
    match decode(&c[0].payload) {
        Record::Calibration(c) => assert_eq!(c.confidence, 0.65),
        other => panic!("{other:?}"),
    }
    let h = by_topic("hello");
    assert!(
        h.len() == 1 && h[0].retain && h[0].payload == json(&records[0]),
        "{h:?}"
    );
    let s = by_topic("status");
    assert!(
        s.len() == 1 && s[0].retain && s[0].payload == "online",
        "{s:?}"
    );
    // Heights and status records are events, not state: not retained.
    assert!(
        by_topic("height").is_empty() && by_topic("status/record").is_empty(),
        "{live:?}"
    );

    // Home Assistant: three sensors of one device, retained, pointing at our topics.
    let ha = retained_now(broker.port, "homeassistant/#", Duration::from_millis(500));
    assert_eq!(ha.len(), 3, "{ha:?}");
    let mut states = Vec::new();
    for m in &ha {
        assert!(
            m.retain && m.topic.starts_with("homeassistant/sensor/lobby-cam/"),
            "{m:?}"
        );
        assert!(m.topic.ends_with("/config"));
        let v: serde_json::Value = serde_json::from_str(&m.payload).unwrap();
        assert_eq!(v["availability_topic"], format!("{prefix}/status"));
        assert_eq!(v["device"]["identifiers"][0], "stature_lobby-cam");
        states.push((
            v["state_topic"].as_str().unwrap().to_string(),
            v["value_template"].as_str().unwrap().to_string(),
        ));
    }
    states.sort();
    assert_eq!(
        states,
        [
            (
                format!("{prefix}/calibration"),
                "{{ (value_json.confidence * 100) | round(0) }}".to_string()
            ),
            (
                format!("{prefix}/height"),
                "{{ value_json.height_m | round(2) }}".to_string()
            ),
            (
                format!("{prefix}/status/record"),
                "{{ value_json.tracks }}".to_string()
            ),
        ]
    );

    // End of run: `offline` replaces `online`, the calibration stays.
    rep.send(Record::Bye(Bye {
        frame: 300,
        frames: 300,
        dropped: 0,
    }));
    rep.finish(PATIENCE);
    io.join().unwrap();
    assert_eq!(counters.dropped(), 0);
    let after = retained_now(
        broker.port,
        &format!("{prefix}/#"),
        Duration::from_millis(500),
    );
    let s: Vec<&str> = after
        .iter()
        .filter(|m| m.topic == format!("{prefix}/status"))
        .map(|m| m.payload.as_str())
        .collect();
    assert_eq!(s, ["offline"]);
    assert!(after.iter().any(|m| m.payload == cal && m.retain));
}

#[test]
fn a_killed_camera_is_marked_offline_by_its_last_will() {
    let Some((_dir, broker)) = anonymous_broker("will") else {
        return;
    };
    let prefix = "stature/gate";
    let sub = Sub::start(broker.port, &[&format!("{prefix}/#")], &[]);
    // A live camera: frames arrive on stdin as they are captured; stdin stays open.
    let mut cam = Command::new(common::stature_bin())
        .args(["run", "--source", "y4m:-", "--report"])
        .arg(format!(
            "mqtt:127.0.0.1:{}?topic={prefix}&client_id=gate",
            broker.port
        ))
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let clip = common::synthetic_y4m(
        Size {
            width: 64,
            height: 48,
        },
        10,
    );
    let mut stdin = cam.stdin.take().unwrap();
    stdin.write_all(&clip).unwrap();
    stdin.flush().unwrap();
    assert!(
        sub.wait(PATIENCE, |m| m
            .iter()
            .any(|m| m.topic == format!("{prefix}/hello"))),
        "camera never said hello: {:?}",
        sub.under(prefix)
    );
    assert!(sub
        .under(&format!("{prefix}/status"))
        .iter()
        .any(|m| m.payload == "online"));
    cam.kill().unwrap(); // SIGKILL: no chance to say goodbye
    cam.wait().unwrap();
    drop(stdin);
    assert!(
        sub.wait(PATIENCE, |m| m.iter().any(|m| m.topic
            == format!("{prefix}/status")
            && m.payload == "offline")),
        "no last will: {:?}\nbroker log:\n{}",
        sub.under(prefix),
        broker.log()
    );
    // Nothing else came from the camera after the kill (no bye: it died).
    assert!(!sub.under(prefix).iter().any(|m| m.topic.ends_with("/bye")));
    // A dashboard connecting later sees the camera offline.
    let later = retained_now(
        broker.port,
        &format!("{prefix}/status"),
        Duration::from_millis(300),
    );
    assert_eq!(
        later
            .iter()
            .map(|m| (m.payload.as_str(), m.retain))
            .collect::<Vec<_>>(),
        [("offline", true)]
    );
}

#[test]
fn broker_outage_mid_run_loses_no_final_height() {
    let Some(_) = tools(&["mosquitto", "mosquitto_sub", "mosquitto_pub"]) else {
        return;
    };
    let dir = temp_dir("outage");
    // Persistence keeps the subscriber's session (and the messages queued
    // for it) across the restart, as a production broker would.
    let mut broker = Broker::start_free(&dir, |[port, _]| {
        format!(
            "listener {port} 127.0.0.1\nallow_anonymous true\npersistence true\npersistence_location {}/\n",
            dir.display()
        )
    });
    let port = broker.port;
    let prefix = "stature/outage";
    let sub = Sub::start(
        port,
        &[&format!("{prefix}/#")],
        &["-c", "-i", "outage-watcher"],
    );
    // 25 records a second for 10 s: heights every frame, a person leaving
    // every 20 frames; the broker is down from 2 s to 6 s.
    let frames = 250;
    let records = walkers(frames, 20);
    let cfg = MqttConfig {
        buffer: 48,
        reconnect_min_s: 0.1,
        reconnect_max_s: 0.5,
        shutdown_timeout_s: 10.0,
        ..Default::default()
    };
    let sink = mqtt_sink(
        &format!("mqtt:127.0.0.1:{port}?topic={prefix}&qos=1&client_id=outage"),
        &cfg,
    );
    let frame_of = |i: usize| match &records[i] {
        Record::Height(h) => h.frame,
        Record::Status(s) => s.frame,
        _ => 0,
    };
    let (mut stopped, mut restarted) = (None, None);
    let counters = drive(
        &records,
        vec![sink],
        Format::Json,
        Duration::from_millis(40),
        |i| {
            let f = frame_of(i);
            if f == 50 && stopped.is_none() {
                broker.stop();
                stopped = Some(i);
            }
            if f == 150 && restarted.is_none() {
                broker.restart();
                restarted = Some(i);
            }
        },
    );
    let (stopped, restarted) = (stopped.unwrap(), restarted.unwrap());
    // `offline` is the camera's last message, after `bye`. The broker's
    // restart can publish an earlier `offline` (the lost session's will),
    // so wait for the whole ending: `bye` arrived, the camera came back
    // online, and the last status is `offline`.
    let bye = json(records.last().unwrap());
    let status_topic = format!("{prefix}/status");
    assert!(
        sub.wait(PATIENCE, |m| {
            let st: Vec<&str> = m
                .iter()
                .filter(|m| m.topic == status_topic)
                .map(|m| m.payload.as_str())
                .collect();
            m.iter().any(|m| m.payload == bye)
                && st.iter().filter(|p| **p == "online").count() >= 2
                && st.last() == Some(&"offline")
        }),
        "bye never arrived: {:?}",
        sub.under(prefix).last()
    );
    let got: Vec<String> = sub
        .under(prefix)
        .iter()
        .filter(|m| m.topic != format!("{prefix}/status"))
        .map(|m| m.payload.clone())
        .collect();
    let sent: Vec<String> = records.iter().map(json).collect();
    // The loop's queue never overflowed: the I/O thread kept draining it
    // while the broker was away.
    assert_eq!(counters.dropped_queue.load(Ordering::Relaxed), 0);
    // Every final record arrived, including the 5 heights of people who
    // left while the broker was down.
    let during: Vec<&Record> = records[stopped..restarted]
        .iter()
        .filter(|r| r.is_final())
        .collect();
    assert_eq!(during.len(), 5);
    for r in records.iter().filter(|r| r.is_final()) {
        assert!(got.contains(&json(r)), "final record lost: {}", json(r));
    }
    // Nothing arrived that was not sent; each record at most once or twice
    // (QoS 1 may repeat one whose acknowledgement the outage cut).
    let mut unique: Vec<&String> = got.iter().collect();
    unique.sort();
    unique.dedup();
    for p in &unique {
        assert!(sent.contains(p), "unknown payload {p}");
    }
    assert!(
        got.len() - unique.len() <= 2 * 48,
        "{} duplicates",
        got.len() - unique.len()
    );
    // What did not arrive is exactly what the sink counted as dropped: the
    // outage held more than `buffer` records, so the oldest non-final ones went.
    let dropped = counters.dropped_sink.load(Ordering::Relaxed) as usize;
    assert!(
        dropped > 0,
        "the outage should have overflowed the 48-record buffer"
    );
    assert_eq!(
        unique.len() + dropped,
        sent.len(),
        "lost records must all be counted"
    );
    eprintln!(
        "outage: {} records sent over 10 s, broker down for 4 s; {} arrived ({} repeats), \
         {dropped} oldest non-final dropped and counted, {} finals (5 during the outage) all arrived",
        sent.len(),
        unique.len(),
        got.len() - unique.len(),
        records.iter().filter(|r| r.is_final()).count()
    );
    // The newest records of the outage were kept: the last height before the restart arrived.
    let last_before = records[..restarted]
        .iter()
        .rev()
        .find(|r| matches!(r, Record::Height(_)))
        .unwrap();
    assert!(got.contains(&json(last_before)));
    // Records arrived in the order they were sent (first arrivals; repeats
    // of unacknowledged ones may follow a reconnection).
    let mut seen = std::collections::HashSet::new();
    let order: Vec<usize> = got
        .iter()
        .filter(|p| seen.insert(p.as_str()))
        .map(|p| sent.iter().position(|s| s == p).unwrap())
        .collect();
    assert!(
        order.windows(2).all(|w| w[0] < w[1]),
        "out of order: {order:?}"
    );
    // Everything sent after the reconnection arrived.
    for p in &sent[restarted..] {
        assert!(got.contains(p), "lost after reconnection: {p}");
    }
    // Retained availability came back with the broker.
    let avail: Vec<String> = sub
        .under(&format!("{prefix}/status"))
        .iter()
        .filter(|m| m.topic == format!("{prefix}/status"))
        .map(|m| m.payload.clone())
        .collect();
    assert_eq!(avail.first().map(String::as_str), Some("online"));
    assert_eq!(avail.last().map(String::as_str), Some("offline"));
    assert!(
        avail.iter().filter(|p| *p == "online").count() >= 2,
        "{avail:?}"
    );
}

/// Writes a stature config file with `[report.mqtt]` lines.
fn config_file(dir: &Path, mqtt: &str) -> PathBuf {
    let p = dir.join("stature.toml");
    std::fs::write(
        &p,
        format!("[report]\nstatus_interval_s = 0.2\n\n[report.mqtt]\n{mqtt}"),
    )
    .unwrap();
    p
}

/// A password with no user name is a configuration mistake: exit code 2
/// from `run` and `config --check`, as the README says (it was 3, the code
/// of a broker that cannot be reached). No broker is needed: it is refused
/// before any connection.
#[test]
fn a_password_without_a_user_name_is_bad_input() {
    let dir = temp_dir("password-alone");
    let conf = dir.join("stature.toml");
    std::fs::write(
        &conf,
        "[report]\nsinks = [\"mqtt:127.0.0.1:9\"]\n\n[report.mqtt]\npassword = \"s3cret\"\n",
    )
    .unwrap();
    let go = |args: &[&str], user: Option<&str>| {
        let mut cmd = Command::new(common::stature_bin());
        cmd.args(args)
            .env_remove("STATURE_MQTT_USERNAME")
            .env_remove("STATURE_MQTT_PASSWORD")
            .stdin(Stdio::null())
            .stdout(Stdio::null());
        if let Some(u) = user {
            cmd.env("STATURE_MQTT_USERNAME", u);
        }
        cmd.output().unwrap()
    };
    let conf = conf.to_str().unwrap();
    let run = ["run", "--config", conf, "--source", "sim:low?frames=1"];
    for args in [&run[..], &["config", "--check", conf][..]] {
        let out = go(args, None);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("without a user name"), "{args:?}: {err}");
        assert!(
            !err.contains("s3cret"),
            "the password is never shown: {err}"
        );
    }
    // The installer's check of the keys alone passes, as the user name may
    // come from the service's environment, and says so.
    let out = go(&["config", "--check", conf, "--keys-only"], None);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(
        err.contains("password without a username") && err.contains("STATURE_MQTT_USERNAME"),
        "{err}"
    );
    // The environment's user name makes it legal (the check connects to
    // nothing, so no broker is needed).
    let out = go(&["config", "--check", conf], Some("camera"));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
}

#[test]
fn wrong_credentials_are_reported_and_the_run_goes_on() {
    let Some(t) = tools(&[
        "mosquitto",
        "mosquitto_sub",
        "mosquitto_pub",
        "mosquitto_passwd",
    ]) else {
        return;
    };
    let dir = temp_dir("auth");
    let pw = dir.join("passwords");
    let ok = Command::new(&t[3])
        .args(["-c", "-b"])
        .arg(&pw)
        .args(["camera", "s3cret"])
        .status()
        .unwrap();
    assert!(ok.success());
    let broker = Broker::start(
        &dir,
        &format!("allow_anonymous false\npassword_file {}\n", pw.display()),
    );
    let clip = common::synthetic_y4m(
        Size {
            width: 64,
            height: 48,
        },
        150,
    );
    let prefix = "stature/door";
    let conf = config_file(
        &dir,
        "username = \"camera\"\npassword = \"not-the-Pa55word\"\nbuffer = 8\nshutdown_timeout_s = 1.0\nreconnect_max_s = 0.5\n",
    );
    let run = |env_password: Option<&str>| {
        let out_file = dir.join("records.jsonl");
        let _ = std::fs::remove_file(&out_file);
        let mut cmd = Command::new(common::stature_bin());
        cmd.arg("run")
            .arg("--config")
            .arg(&conf)
            .args(["--source", "y4m:-", "--report"])
            .arg(format!(
                "mqtt:127.0.0.1:{}?topic={prefix}&client_id=door",
                broker.port
            ))
            .arg("--report")
            .arg(format!("file:{}", out_file.display()))
            .env_remove("STATURE_MQTT_USERNAME")
            .env_remove("STATURE_MQTT_PASSWORD")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        if let Some(p) = env_password {
            cmd.env("STATURE_MQTT_PASSWORD", p);
        }
        let mut child = cmd.spawn().unwrap();
        // Frames come in as a camera delivers them, not all at once.
        let mut stdin = child.stdin.take().unwrap();
        let header = clip.iter().position(|&b| b == b'\n').unwrap() + 1;
        stdin.write_all(&clip[..header]).unwrap();
        for frame in clip[header..].chunks(6 + 64 * 48 * 3 / 2) {
            stdin.write_all(frame).unwrap();
            std::thread::sleep(Duration::from_millis(10));
        }
        drop(stdin);
        let out = child.wait_with_output().unwrap();
        let records: Vec<serde_json::Value> = std::fs::read_to_string(&out_file)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        (out, records)
    };

    let (out, records) = run(None);
    let log = String::from_utf8_lossy(&out.stderr);
    // The run goes on (below: the file got it all), but it ends with exit
    // 3 and an error naming the sink that delivered nothing.
    assert_eq!(out.status.code(), Some(3), "{log}");
    let named = format!(
        "report sink mqtt:127.0.0.1:{}: none of the run's",
        broker.port
    );
    assert!(log.contains(&named), "{log}");
    // The closing line says what each sink delivered (the MQTT sink had
    // accepted every record into its outbox; that is not delivery).
    assert!(
        log.contains(&format!("mqtt:127.0.0.1:{} 0 of ", broker.port)),
        "{log}"
    );
    assert!(
        log.contains("refused the connection")
            && (log.contains("not authorised") || log.contains("bad user name or password"))
            && log.contains("STATURE_MQTT_PASSWORD"),
        "no clear error in the log:\n{log}"
    );
    assert!(
        !log.contains("Pa55word"),
        "the password must not be logged:\n{log}"
    );
    // The other sink got the whole run; status counts the records the broker never got.
    let bye = records.last().unwrap();
    assert_eq!(bye["type"], "bye", "{records:?}");
    assert_eq!(bye["frames"], 150);
    let statuses: Vec<&serde_json::Value> =
        records.iter().filter(|r| r["type"] == "status").collect();
    assert!(statuses.len() >= 10, "{}", statuses.len());
    let last_dropped = statuses.last().unwrap()["dropped"].as_u64().unwrap();
    assert!(
        last_dropped > 0,
        "status.dropped should count undelivered MQTT records"
    );
    assert!(bye["dropped"].as_u64().unwrap() >= last_dropped);
    assert!(log.contains("not delivered"), "{log}");

    // The environment overrides the file's password: now everything arrives.
    let sub = Sub::start_auth(
        broker.port,
        &[&format!("{prefix}/#")],
        &[],
        &["-u", "camera", "-P", "s3cret"],
    );
    let (out, records) = run(Some("s3cret"));
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{log}");
    assert!(!log.contains("refused"), "{log}");
    assert!(
        sub.wait(PATIENCE, |m| m.iter().any(|m| m.topic.ends_with("/bye"))),
        "{:?}",
        sub.under(prefix)
    );
    let got: Vec<String> = sub
        .under(prefix)
        .iter()
        .filter(|m| m.topic != format!("{prefix}/status"))
        .map(|m| m.payload.clone())
        .collect();
    assert_eq!(got.len(), records.len());
    for (m, r) in got.iter().zip(&records) {
        let v: serde_json::Value = serde_json::from_str(m).unwrap();
        assert_eq!(&v, r);
    }
}

#[test]
fn tls_with_a_private_ca() {
    let Some(t) = tools(&["mosquitto", "mosquitto_sub", "mosquitto_pub", "openssl"]) else {
        return;
    };
    let dir = temp_dir("tls");
    let ssl = |args: &[&str]| {
        let out = Command::new(&t[3])
            .current_dir(&dir)
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "openssl {args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    // A CA, and a broker certificate it signs for 127.0.0.1; a second,
    // unrelated CA to check that the wrong one is refused.
    for ca in ["ca", "other"] {
        ssl(&[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "2",
            "-subj",
            &format!("/CN=test {ca}"),
            "-keyout",
            &format!("{ca}.key"),
            "-out",
            &format!("{ca}.pem"),
        ]);
    }
    ssl(&[
        "req",
        "-newkey",
        "rsa:2048",
        "-nodes",
        "-subj",
        "/CN=127.0.0.1",
        "-keyout",
        "server.key",
        "-out",
        "server.csr",
    ]);
    std::fs::write(dir.join("san.ext"), "subjectAltName=IP:127.0.0.1\nbasicConstraints=CA:FALSE\nkeyUsage=digitalSignature,keyEncipherment\nextendedKeyUsage=serverAuth\n").unwrap();
    for key in ["server.key", "ca.key"] {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(dir.join(key), std::fs::Permissions::from_mode(0o644)).unwrap();
    }
    ssl(&[
        "x509",
        "-req",
        "-in",
        "server.csr",
        "-CA",
        "ca.pem",
        "-CAkey",
        "ca.key",
        "-CAcreateserial",
        "-days",
        "2",
        "-extfile",
        "san.ext",
        "-out",
        "server.pem",
    ]);
    let d = dir.display();
    let broker = Broker::start_free(&dir, |[plain_port, tls_port]| {
        format!(
            "per_listener_settings false\nallow_anonymous true\nlistener {plain_port} 127.0.0.1\nlistener {tls_port} 127.0.0.1\ncafile {d}/ca.pem\ncertfile {d}/server.pem\nkeyfile {d}/server.key\n"
        )
    });
    let tls_port = broker.other_port;
    let prefix = "stature/secure";
    // The subscriber watches on the plain listener; the camera publishes over TLS.
    let sub = Sub::start(broker.port, &[&format!("{prefix}/#")], &[]);
    let records = walkers(60, 20);
    let sink = mqtt_sink(
        &format!(
            "mqtt:127.0.0.1:{tls_port}?topic={prefix}&tls=true&ca={d}/ca.pem&client_id=secure"
        ),
        &MqttConfig {
            buffer: 1024,
            ..Default::default()
        },
    );
    let counters = drive(
        &records,
        vec![sink],
        Format::Json,
        Duration::from_millis(1),
        |_| {},
    );
    assert_eq!(counters.dropped(), 0);
    assert!(sub.wait(PATIENCE, |m| m.iter().any(|m| m.topic.ends_with("/bye"))));
    let got: Vec<String> = sub
        .under(prefix)
        .iter()
        .filter(|m| m.topic != format!("{prefix}/status"))
        .map(|m| m.payload.clone())
        .collect();
    assert_eq!(got, records.iter().map(json).collect::<Vec<_>>());

    // A CA that did not sign the broker's certificate: nothing is sent,
    // everything is counted, nothing crashes.
    let cfg = MqttConfig {
        shutdown_timeout_s: 1.0,
        ..Default::default()
    };
    let sink = mqtt_sink(
        &format!("mqtt:127.0.0.1:{tls_port}?topic=stature/impostor&tls=true&ca={d}/other.pem&client_id=impostor"),
        &cfg,
    );
    let counters = drive(
        &records[..10],
        vec![sink],
        Format::Json,
        Duration::ZERO,
        |_| {},
    );
    assert_eq!(counters.dropped_sink.load(Ordering::Relaxed), 10);
    // A missing CA file is a start-up error naming the file.
    let e = match sink::Sink::open_with(
        &sink::SinkSpec::parse(&format!(
            "mqtt:127.0.0.1:{tls_port}?tls=true&ca={d}/nope.pem"
        ))
        .unwrap(),
        &MqttConfig::default(),
    ) {
        Err(e) => e,
        Ok(_) => panic!("a missing CA file must be refused"),
    };
    assert!(e.to_string().contains("nope.pem"), "{e}");
}

#[test]
fn the_real_pipeline_publishes_what_the_file_sink_writes() {
    let Some((dir, broker)) = anonymous_broker("pipeline") else {
        return;
    };
    let prefix = "stature/plaza";
    let sub = Sub::start(broker.port, &[&format!("{prefix}/#")], &[]);
    let file = dir.join("records.jsonl");
    // The simulated scene: the full pipeline, with calibration records
    // (and heights, once people are measured) from real stages.
    let out = Command::new(common::stature_bin())
        .args(["run", "--source", "sim:plaza?seed=1&frames=600", "--report"])
        .arg(format!(
            "mqtt:127.0.0.1:{}?topic={prefix}&qos=1&client_id=plaza",
            broker.port
        ))
        .arg("--report")
        .arg(format!("file:{}", file.display()))
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{log}");
    assert!(
        sub.wait(PATIENCE, |m| m.iter().any(|m| m.topic
            == format!("{prefix}/status")
            && m.payload == "offline")),
        "{log}"
    );
    let written: Vec<String> = std::fs::read_to_string(&file)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let published: Vec<Msg> = sub
        .under(prefix)
        .into_iter()
        .filter(|m| m.topic != format!("{prefix}/status"))
        .collect();
    assert_eq!(published.len(), written.len());
    for (m, line) in published.iter().zip(&written) {
        assert_eq!(&m.payload, line);
        assert_eq!(m.topic, topic_of(prefix, &decode(line)));
    }
    assert!(
        written
            .iter()
            .any(|l| l.contains("\"type\":\"calibration\"")),
        "the scene should calibrate within 600 frames"
    );
    // The final calibration is what a dashboard arriving now sees.
    let last_cal = written
        .iter()
        .rfind(|l| l.contains("\"type\":\"calibration\""))
        .unwrap();
    let retained = retained_now(
        broker.port,
        &format!("{prefix}/calibration"),
        Duration::from_millis(300),
    );
    assert_eq!(retained.len(), 1);
    assert!(retained[0].retain && &retained[0].payload == last_cal);
}

/// A signal while the run waits for an absent broker to take what its
/// sink holds ends the wait at once (exit 3) and still says what the run
/// did: frames and why it stopped (before, only that records were lost).
#[test]
fn a_signal_during_the_wait_for_an_absent_broker_still_sums_up_the_run() {
    let dir = temp_dir("mqtt-signal-during-sink-wait");
    let (status, log, rest) =
        signal_during_the_wait(&dir, &["--source", "sim:plaza?seed=1", "--frames", "20"]);
    assert_eq!(status.code(), Some(3), "{log}{rest}");
    assert!(
        rest.contains("20 frames, stopped by frame limit") && rest.contains("were not delivered"),
        "{log}{rest}"
    );
    // The line naming the broker comes before the first failure to reach it.
    let (named, refused) = (
        log.find("mqtt: publishing to"),
        log.find("mqtt: cannot connect"),
    );
    assert!(
        named.is_some() && refused.is_some() && named < refused,
        "{log}"
    );
    // A malformed stream stays the run's first problem: exit 2 with its
    // error line (the signal's early return had hidden both behind exit 3).
    let clip = common::synthetic_y4m(
        stature::frame::Size {
            width: 64,
            height: 48,
        },
        5,
    );
    let cut = dir.join("cut.y4m");
    std::fs::write(&cut, &clip[..clip.len() - 100]).unwrap();
    let source = format!("y4m:{}", cut.display());
    let (status, log, rest) = signal_during_the_wait(&dir, &["--source", &source]);
    assert_eq!(status.code(), Some(2), "{log}{rest}");
    assert!(
        rest.contains("stopped by a source error") && rest.contains("truncated"),
        "{log}{rest}"
    );
}

/// Runs `stature run ARGS` into an MQTT sink nobody listens for, sends
/// SIGTERM once it waits for that sink at the end; returns the exit status,
/// the log up to the wait and the log after it.
fn signal_during_the_wait(dir: &Path, args: &[&str]) -> (std::process::ExitStatus, String, String) {
    let conf = config_file(dir, "shutdown_timeout_s = 120.0\nreconnect_max_s = 0.5\n");
    let mut child = Command::new(common::stature_bin())
        .arg("run")
        .arg("--config")
        .arg(&conf)
        .args(args)
        .arg("--report")
        // Nothing listens there: every record stays in the sink.
        .arg(format!("mqtt:127.0.0.1:{}?client_id=away", free_port()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let (mut line, mut log) = (String::new(), String::new());
    while !line.contains("waiting for the report sinks") {
        line.clear();
        let n = stderr.read_line(&mut line).unwrap();
        assert!(n > 0, "stderr ended before the wait: {log}");
        log.push_str(&line);
    }
    assert!(Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "SIGTERM did not end the wait: {log}"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stderr, &mut rest).unwrap();
    (status, log, rest)
}

/// A broker that stays away makes the sink's buffer overflow: the log says
/// so when it starts (once per outage), not only in the end-of-run count,
/// which a service that runs for weeks never reaches.
#[test]
fn an_overflowing_buffer_is_logged_when_it_starts() {
    let dir = temp_dir("mqtt-overflow-told");
    let conf = config_file(
        &dir,
        "buffer = 8\nshutdown_timeout_s = 0.5\nreconnect_max_s = 0.5\n",
    );
    let out = Command::new(common::stature_bin())
        .arg("run")
        .arg("--config")
        .arg(&conf)
        .args(["--source", "sim:plaza?seed=1", "--frames", "60", "--report"])
        .arg(format!("mqtt:127.0.0.1:{}?client_id=full", free_port()))
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    let told: Vec<&str> = err
        .lines()
        .filter(|l| l.contains("WARN") && l.contains("it is not taking them"))
        .collect();
    assert_eq!(told.len(), 1, "{err}");
    assert!(told[0].contains("8 records held"), "{err}");
}

/// A listener that accepts the connection and never answers it (no
/// CONNACK) is named for what it did: it was called "broker too slow".
#[test]
fn a_broker_that_never_answers_is_named_so() {
    let dir = temp_dir("mqtt-never-answers");
    let conf = config_file(&dir, "shutdown_timeout_s = 0.5\nreconnect_max_s = 0.5\n");
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = listener.local_addr().unwrap().port();
    // Accepts and holds every connection, says nothing.
    std::thread::spawn(move || {
        let mut held = Vec::new();
        for s in listener.incoming().take(64) {
            held.push(s);
        }
    });
    let out = Command::new(common::stature_bin())
        .arg("run")
        .arg("--config")
        .arg(&conf)
        .args(["--source", "sim:plaza?seed=1", "--frames", "20", "--report"])
        .arg(format!("mqtt:127.0.0.1:{port}?client_id=silent"))
        .stdout(Stdio::null())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "nothing was delivered: {err}");
    assert!(
        err.contains("before shutdown (no answer to the connection request)"),
        "{err}"
    );
}
