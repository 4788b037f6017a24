//! Report sinks against real endpoints: a UDP socket on 127.0.0.1 and a
//! serial pseudo-terminal pair, both encodings, plus dead links.

use serialport::SerialPort;
use stature::config::{Config, Format};
use stature::frame::Size;
use stature::report::record::Record;
use stature::report::{self, encode, sink, Reporter};
use stature::run::{self, LoopOptions, Summary};
use stature::source::y4m::Y4mSource;
use std::io::{Read, Write};
use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

mod common;

/// Runs `frames` synthetic frames through the loop into `sinks`.
fn run_into(
    sinks: Vec<sink::Sink>,
    format: Format,
    frames: usize,
    status_interval_s: f64,
) -> (Summary, u64, u64) {
    let clip = common::synthetic_y4m(
        Size {
            width: 96,
            height: 64,
        },
        frames,
    );
    let mut src =
        Y4mSource::from_reader(Box::new(std::io::Cursor::new(clip)), "synthetic".into()).unwrap();
    let mut cfg = Config::default();
    cfg.report.format = format;
    cfg.report.status_interval_s = status_interval_s;
    cfg.report.queue = 16;
    let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let io = report::spawn_io(rx, sinks, format, counters.clone());
    let stop = AtomicBool::new(false);
    let opts = LoopOptions {
        max_frames: 0,
        status_interval_s,
        stop: &stop,
        allocations: || 0,
        state: None,
    };
    let summary = run::run(&cfg, &mut src, &mut reporter, opts);
    reporter.finish(Duration::from_secs(10));
    io.join().unwrap();
    (
        summary,
        counters.dropped_queue.load(Ordering::Relaxed),
        counters.dropped_sink.load(Ordering::Relaxed),
    )
}

/// A pseudo-terminal pair and the slave's path, with a guard that keeps the
/// serial tests from running at the same time: `TTYPort::pair` names the
/// slave with the non-reentrant `ptsname`, and two pairs made concurrently
/// were seen to cross.
fn pty_pair() -> (
    std::sync::MutexGuard<'static, ()>,
    serialport::TTYPort,
    serialport::TTYPort,
    String,
) {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let guard = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let (master, slave) = serialport::TTYPort::pair().expect("pseudo-terminal pair");
    let name = slave.name().expect("pty has a name");
    (guard, master, slave, name)
}

fn decode(format: Format, bytes: &[u8]) -> Record {
    match format {
        Format::Json => {
            let v: serde_json::Value = serde_json::from_slice(bytes).expect("valid JSON");
            // Rebuild the kind from the tag; the fields are checked by the kind-specific asserts.
            let kind = v["type"].as_str().unwrap().to_string();
            assert!(v["frame"].is_u64(), "every record carries frame: {v}");
            match kind.as_str() {
                "hello" => Record::Hello(serde_json::from_value(strip_type(v)).unwrap()),
                "status" => Record::Status(serde_json::from_value(strip_type(v)).unwrap()),
                "bye" => Record::Bye(serde_json::from_value(strip_type(v)).unwrap()),
                "calibration" => {
                    Record::Calibration(serde_json::from_value(strip_type(v)).unwrap())
                }
                "height" => Record::Height(serde_json::from_value(strip_type(v)).unwrap()),
                other => panic!("unknown record type {other}"),
            }
        }
        Format::Postcard => {
            let mut b = bytes.to_vec();
            encode::decode_postcard(&mut b).expect("valid postcard record")
        }
    }
}

fn strip_type(mut v: serde_json::Value) -> serde_json::Value {
    v.as_object_mut().unwrap().remove("type");
    v
}

#[test]
fn udp_sink_delivers_every_record_in_both_formats() {
    for format in [Format::Json, Format::Postcard] {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        let port = rx.local_addr().unwrap().port();
        let sink = sink::Sink::open(&sink::SinkSpec::Udp(format!("127.0.0.1:{port}"))).unwrap();
        let (summary, dq, ds) = run_into(vec![sink], format, 60, 0.4);
        assert_eq!((summary.frames, dq, ds), (60, 0, 0));
        let mut got = Vec::new();
        let mut buf = [0u8; 2048];
        loop {
            let n = rx.recv(&mut buf).expect("datagram before timeout");
            assert!(n <= 1200, "datagram of {n} bytes");
            let r = decode(format, &buf[..n]);
            let done = matches!(r, Record::Bye(_));
            got.push(r);
            if done {
                break;
            }
        }
        assert!(
            matches!(&got[0], Record::Hello(h) if h.width == 96 && h.height == 64 && h.schema == 1),
            "{format:?}: {:?}",
            got[0]
        );
        let statuses = got
            .iter()
            .filter(|r| matches!(r, Record::Status(_)))
            .count();
        // One status per 10 frames (0.4 s at 25 fps) and one at the end.
        assert_eq!(statuses, 7, "{format:?}");
        // The run ends on the interval: the closing status has no frames of
        // its own to time and repeats the last rate (it said 0 fps).
        let rates: Vec<f32> = got
            .iter()
            .filter_map(|r| match r {
                Record::Status(s) => Some(s.fps),
                _ => None,
            })
            .collect();
        assert!(rates.iter().all(|&r| r > 0.0), "{format:?}: {rates:?}");
        assert_eq!(rates[5], rates[6], "{format:?}");
        assert!(matches!(got.last(), Some(Record::Bye(b)) if b.frames == 60));
    }
}

// The two serial scenarios run in one test, one after the other: each uses
// its own pseudo-terminal pair, and the pair is created under a lock anyway.
#[test]
fn serial_sink_delivers_and_survives_a_stuck_reader() {
    serial_sink_over_a_pseudo_terminal_in_both_formats();
    serial_reader_that_stops_reading_drops_records_instead_of_stalling_the_loop();
}

fn serial_sink_over_a_pseudo_terminal_in_both_formats() {
    for format in [Format::Json, Format::Postcard] {
        let (_guard, mut master, slave, path) = pty_pair();
        // Raw mode on both ends is set by serialport; open the sink by path like a user would.
        let sink = sink::Sink::open(&sink::SinkSpec::Serial {
            path: path.clone(),
            baud: 115_200,
        })
        .unwrap();
        let reader = std::thread::spawn(move || {
            let mut all = Vec::new();
            let mut buf = [0u8; 4096];
            master.set_timeout(Duration::from_millis(200)).unwrap();
            let deadline = std::time::Instant::now() + Duration::from_secs(10);
            while std::time::Instant::now() < deadline {
                // A read that times out (nothing written yet) is retried.
                let n = match master.read(&mut buf) {
                    Ok(n) => n,
                    Err(_) => {
                        std::thread::sleep(Duration::from_millis(10));
                        continue;
                    }
                };
                all.extend_from_slice(&buf[..n]);
                let done = match format {
                    Format::Json => all
                        .windows(13)
                        .any(|w| w == b"\"type\":\"bye\"," || w.starts_with(b"\"type\":\"bye\"")),
                    Format::Postcard => decode_all_postcard(&all)
                        .iter()
                        .any(|r| matches!(r, Record::Bye(_))),
                };
                if done {
                    break;
                }
            }
            all
        });
        let (summary, _, ds) = run_into(vec![sink], format, 40, 0.4);
        assert_eq!((summary.frames, ds), (40, 0));
        // Keep a slave handle open until the reader is done: once the last
        // one closes, the master reports a hang-up before the unread data.
        let bytes = reader.join().unwrap();
        drop(slave);
        let records: Vec<Record> = match format {
            Format::Json => bytes
                .split(|&b| b == b'\n')
                .filter(|l| !l.is_empty())
                .map(|l| decode(format, l))
                .collect(),
            Format::Postcard => decode_all_postcard(&bytes),
        };
        assert!(
            matches!(records.first(), Some(Record::Hello(_))),
            "{format:?}: {:?}",
            String::from_utf8_lossy(&bytes[..bytes.len().min(300)])
        );
        assert!(
            matches!(records.last(), Some(Record::Bye(b)) if b.frames == 40),
            "{format:?}: {:?}",
            records.last()
        );
        assert_eq!(
            records
                .iter()
                .filter(|r| matches!(r, Record::Status(_)))
                .count(),
            5
        );
    }
}

fn decode_all_postcard(bytes: &[u8]) -> Vec<Record> {
    bytes
        .split_inclusive(|&b| b == 0)
        .filter(|f| f.last() == Some(&0))
        .map(|f| {
            let mut f = f.to_vec();
            encode::decode_postcard(&mut f).expect("COBS frame decodes")
        })
        .collect()
}

/// A broadcast destination (here the loopback network's, 127.255.255.255,
/// which needs SO_BROADCAST like a LAN's x.x.x.255): every datagram used to
/// fail with "Permission denied".
#[test]
fn udp_sink_sends_to_a_broadcast_address() {
    let rx = UdpSocket::bind("0.0.0.0:0").unwrap();
    rx.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let port = rx.local_addr().unwrap().port();
    let spec = sink::SinkSpec::Udp(format!("127.255.255.255:{port}"));
    let sink = sink::Sink::open(&spec).unwrap();
    let (summary, dq, ds) = run_into(vec![sink], Format::Json, 20, 0.4);
    assert_eq!((summary.frames, dq, ds), (20, 0, 0));
    let mut buf = [0u8; 2048];
    let n = rx.recv(&mut buf).expect("the hello datagram");
    assert!(matches!(decode(Format::Json, &buf[..n]), Record::Hello(_)));
}

#[test]
fn unreachable_udp_destination_neither_blocks_nor_crashes() {
    // A loopback port with nobody listening: the kernel answers with ICMP
    // port-unreachable, which a later send may report as an error.
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let sink = sink::Sink::open(&sink::SinkSpec::Udp(format!("127.0.0.1:{port}"))).unwrap();
    let (summary, _, _) = run_into(vec![sink], Format::Json, 200, 0.1);
    assert_eq!(summary.frames, 200);
    assert!(summary.error.is_none());
}

fn serial_reader_that_stops_reading_drops_records_instead_of_stalling_the_loop() {
    let (_guard, master, _slave, path) = pty_pair();
    // Nobody reads `master`: fill the terminal's buffer first, so that every
    // write of the run times out. A status every frame floods the 16-record queue.
    let mut filler = serialport::new(&path, 115_200)
        .timeout(Duration::from_millis(50))
        .open()
        .unwrap();
    let mut filled = 0;
    while let Ok(n) = filler.write(&[b'.'; 512]) {
        filled += n;
        assert!(filled < 1 << 24, "pseudo-terminal never filled");
    }
    drop(filler); // the port is opened exclusively
    let sink = sink::Sink::open(&sink::SinkSpec::Serial {
        path,
        baud: 115_200,
    })
    .unwrap();
    let (summary, dropped_queue, dropped_sink) = run_into(vec![sink], Format::Json, 3000, 0.04);
    assert_eq!(summary.frames, 3000);
    assert!(
        dropped_queue > 0,
        "the loop must drop, not wait, when the link is stuck"
    );
    assert!(
        dropped_sink > 0,
        "writes to the stuck port fail and are counted ({dropped_queue} dropped from the queue)"
    );
    drop(master);
}
