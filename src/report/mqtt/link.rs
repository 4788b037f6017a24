//! The connection behind an `mqtt:` sink (feature `mqtt`).
//!
//! Two threads share one [`Outbox`] under a mutex, never held across
//! network I/O:
//! - the report I/O thread ([`MqttSink::write`]) adds each record and, while
//!   connected, hands the oldest waiting ones to the rumqttc client (a
//!   non-blocking channel push);
//! - the `stature-mqtt` thread drives rumqttc's event loop: it connects,
//!   pings, reads acknowledgements, and after a failure waits (backoff,
//!   doubling from `reconnect_min_s` to `reconnect_max_s`) and reconnects.
//!
//! So a broker that is down, slow or refusing costs the I/O thread a mutex
//! and a `Vec` copy per record, and the vision loop nothing. The outbox, not
//! rumqttc, is the source of truth for what was delivered: the client
//! forgets a clean session's unacknowledged messages when it reconnects, so
//! every message stays in the outbox until the broker confirmed it (QoS 1:
//! PUBACK; QoS 0: written to the socket), and a connection loss sends all
//! unconfirmed ones again, in order.

use super::{discovery, place, Entry, MqttSettings, Outbox, Placement, Pushed, Route, Topics};
use crate::config::Format;
use crate::report::encode;
use crate::report::record::Record;
use crate::report::Counters;
use rumqttc::{
    Client, ConnectReturnCode, Connection, ConnectionError, Event, LastWill, MqttOptions, Outgoing,
    Packet, QoS, StateError, TlsConfiguration, Transport,
};
use std::io;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Messages handed to the client or awaiting acknowledgement at once. It
/// bounds rumqttc's request channel and in-flight table: the client never
/// holds more than this, so its channel push never fails for lack of room.
const WINDOW: usize = 32;

/// State shared by the sink and its connection thread.
struct Link {
    outbox: Outbox,
    connected: bool,
    /// The run is ending: deliver what is left, then say `offline`.
    closing: bool,
    /// Stop now (shutdown timeout passed, or the sink was dropped).
    abandon: bool,
    /// The connection thread has ended.
    exited: bool,
    /// The last connection error as logged, to log each new one once.
    last_error: String,
    /// Records dropped here (also added to the shared counters when attached).
    dropped: u64,
    /// `dropped` when the broker was last reached (or at start).
    dropped_before: u64,
    /// The outbox overflowed since then, and the log said so.
    told_full: bool,
    counters: Option<Arc<Counters>>,
}

impl Link {
    fn drop_records(&mut self, n: u64) {
        self.dropped += n;
        if let Some(c) = &self.counters {
            c.dropped_sink.fetch_add(n, Ordering::Relaxed);
        }
    }
}

struct Shared {
    link: Mutex<Link>,
    /// Signalled when the outbox shrinks, the connection state changes or
    /// the thread exits.
    changed: Condvar,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Link> {
        // A panic elsewhere while holding the lock leaves plain data behind: keep going.
        self.link.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// An open `mqtt:` sink.
pub struct MqttSink {
    shared: Arc<Shared>,
    client: Client,
    topics: Arc<Topics>,
    settings: MqttSettings,
    /// JSON re-encoding when the run's format is postcard: MQTT payloads are
    /// always JSON, what Home Assistant and dashboards read.
    json: Box<[u8; encode::MAX_RECORD]>,
    closed: bool,
}

fn qos(q: u8) -> QoS {
    if q == 0 {
        QoS::AtMostOnce
    } else {
        QoS::AtLeastOnce
    }
}

/// Hands `e` to the client without blocking; false if its channel is full or closed.
fn publish(client: &Client, topics: &Topics, e: &Entry) -> bool {
    client
        .try_publish(
            topics.name(e.place.route),
            qos(e.place.qos),
            e.place.retain,
            e.payload.clone(),
        )
        .is_ok()
}

fn availability(online: bool) -> (Placement, Vec<u8>) {
    (
        Placement {
            route: Route::Availability,
            qos: 1,
            retain: true,
        },
        if online {
            b"online".to_vec()
        } else {
            b"offline".to_vec()
        },
    )
}

impl MqttSink {
    /// The broker, `HOST:PORT`, for logs.
    pub fn broker(&self) -> String {
        self.settings.broker()
    }

    /// Prepares the client and starts the connection thread. Does not wait
    /// for the broker: a camera may boot before it, and records are held
    /// until it answers. Fails only on local problems (an unreadable CA file).
    pub fn open(settings: MqttSettings) -> io::Result<MqttSink> {
        settings.check_credentials()?;
        let mut opts = MqttOptions::new(
            settings.client_id.clone(),
            settings.host.clone(),
            settings.port,
        );
        opts.set_keep_alive(Duration::from_secs(settings.keep_alive_s.into()));
        opts.set_clean_session(true);
        opts.set_inflight(WINDOW as u16 + 8);
        opts.set_request_channel_capacity(WINDOW + 8);
        let (will_place, will) = availability(false);
        let disc = if settings.ha_discovery {
            discovery(&settings)
        } else {
            Vec::new()
        };
        let topics = Arc::new(Topics::new(&settings.topic, &disc));
        opts.set_last_will(LastWill::new(
            topics.name(will_place.route),
            will,
            QoS::AtLeastOnce,
            true,
        ));
        if let Some((u, p)) = &settings.credentials {
            opts.set_credentials(u.clone(), p.clone());
        }
        if settings.tls {
            opts.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(
                Arc::new(tls_config(&settings.ca)?),
            )));
        }
        let (client, connection) = Client::new(opts, WINDOW + 8);
        let shared = Arc::new(Shared {
            link: Mutex::new(Link {
                outbox: Outbox::new(settings.buffer, WINDOW),
                connected: false,
                closing: false,
                abandon: false,
                exited: false,
                last_error: String::new(),
                dropped: 0,
                dropped_before: 0,
                told_full: false,
                counters: None,
            }),
            changed: Condvar::new(),
        });
        let thread = Connector {
            shared: shared.clone(),
            client: client.clone(),
            topics: topics.clone(),
            discovery: disc.into_iter().map(|d| d.payload).collect(),
            settings: settings.clone(),
        };
        // Said before the connector starts, so that its first error (an
        // absent broker) follows the line naming the broker, not precedes it.
        log::info!(
            "mqtt: publishing to {} under {}/ (client id {}{})",
            settings.broker(),
            settings.topic,
            settings.client_id,
            if settings.tls { ", TLS" } else { "" }
        );
        std::thread::Builder::new()
            .name("stature-mqtt".into())
            .spawn(move || thread.run(connection))?;
        Ok(MqttSink {
            shared,
            client,
            topics,
            settings,
            json: Box::new([0; encode::MAX_RECORD]),
            closed: false,
        })
    }

    /// Counts this sink's drops in `counters` too (and so in `status.dropped`).
    pub fn attach_counters(&mut self, counters: Arc<Counters>) {
        self.shared.lock().counters = Some(counters);
    }

    /// Queues one record for the broker. Never blocks on the network: when
    /// the broker is away the record waits in the outbox (making room by
    /// dropping the oldest non-final record, counted).
    pub fn write(&mut self, record: &Record, bytes: &[u8], format: Format) -> io::Result<()> {
        let payload = match format {
            // The newline ends a line on byte streams; a message needs none.
            Format::Json => bytes.strip_suffix(b"\n").unwrap_or(bytes),
            Format::Postcard => {
                let b = encode::encode(record, Format::Json, &mut self.json[..])
                    .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e))?;
                b.strip_suffix(b"\n").unwrap_or(b)
            }
        };
        let place = place(record, self.settings.qos);
        let mut link = self.shared.lock();
        let pushed = link.outbox.push(place, record.is_final(), payload.to_vec());
        if pushed != Pushed::Stored && !link.told_full {
            // Once per outage: a service never reaches the end-of-run count.
            link.told_full = true;
            log::warn!(
                "mqtt: {} records held for {} and it is not taking them: dropping records \
                 (the oldest non-final first) until it does (report.mqtt.buffer)",
                self.settings.buffer,
                self.settings.broker()
            );
        }
        match pushed {
            Pushed::Stored => {}
            Pushed::DroppedOldest => link.drop_records(1),
            Pushed::DroppedNew => link.drop_records(1),
            Pushed::DroppedOldestFinal => {
                link.drop_records(1);
                log::warn!(
                    "mqtt: {} records held for {} and all final: the oldest final one was dropped (raise report.mqtt.buffer)",
                    self.settings.buffer,
                    self.settings.broker()
                );
            }
        }
        if link.connected {
            let (client, topics) = (&self.client, &self.topics);
            link.outbox.pump(|e| publish(client, topics, e));
        }
        Ok(())
    }

    /// Records dropped by this sink so far.
    pub fn dropped(&self) -> u64 {
        self.shared.lock().dropped
    }

    /// Records not yet confirmed by the broker.
    pub fn pending(&self) -> usize {
        self.shared.lock().outbox.records()
    }

    /// True while connected to the broker.
    pub fn connected(&self) -> bool {
        self.shared.lock().connected
    }

    /// End of run: waits up to `shutdown_timeout_s` for held records to
    /// reach the broker, publishes `offline` (retained) and disconnects
    /// cleanly. Records still held then are dropped, counted and logged.
    pub fn close(&mut self) {
        if self.closed {
            return;
        }
        self.closed = true;
        let deadline = Instant::now() + Duration::from_secs_f64(self.settings.shutdown_timeout_s);
        let mut link = self.shared.lock();
        link.closing = true;
        link = self.wait(link, deadline, |l| l.outbox.is_empty());
        let lost = link.outbox.abandon() as u64;
        if lost > 0 {
            link.drop_records(lost);
            log::warn!(
                "mqtt: {lost} records not delivered to {} before shutdown ({})",
                self.settings.broker(),
                match (link.last_error.is_empty(), link.connected) {
                    (false, _) => link.last_error.clone(),
                    (true, true) => "broker too slow".to_string(),
                    // A listener that accepts and never answers (no CONNACK).
                    (true, false) => "no answer to the connection request".to_string(),
                }
            );
        }
        if link.connected {
            // A clean DISCONNECT cancels the last will: say `offline` ourselves.
            let (place, payload) = availability(false);
            link.outbox.push_control_back(place, payload);
            let (client, topics) = (&self.client, &self.topics);
            link.outbox.pump(|e| publish(client, topics, e));
            let grace = deadline.max(Instant::now() + Duration::from_secs(1));
            link = self.wait(link, grace, |l| l.outbox.is_empty() || !l.connected);
            let _ = self.client.try_disconnect();
        }
        link.abandon = true;
        self.shared.changed.notify_all();
        // The thread ends on the DISCONNECT (or at its next wake-up); do not
        // wait long for a thread stuck in a connection attempt.
        drop(self.wait(link, Instant::now() + Duration::from_secs(1), |l| l.exited));
    }

    fn wait<'a>(
        &'a self,
        mut link: MutexGuard<'a, Link>,
        deadline: Instant,
        done: impl Fn(&Link) -> bool,
    ) -> MutexGuard<'a, Link> {
        while !done(&link) {
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            link = match self.shared.changed.wait_timeout(link, deadline - now) {
                Ok((l, _)) => l,
                Err(e) => e.into_inner().0,
            };
        }
        link
    }
}

impl Drop for MqttSink {
    fn drop(&mut self) {
        self.close();
    }
}

/// The connection thread's state.
struct Connector {
    shared: Arc<Shared>,
    client: Client,
    topics: Arc<Topics>,
    discovery: Vec<Vec<u8>>,
    settings: MqttSettings,
}

impl Connector {
    fn run(self, mut connection: Connection) {
        let (min, max) = self.settings.reconnect_s;
        let mut backoff = min;
        let mut failures = 0u32;
        let mut connected_once = false;
        loop {
            let event = match connection.recv() {
                Ok(e) => e,
                // Every client handle is gone: nothing more can be published.
                Err(_) => break,
            };
            let mut link = self.shared.lock();
            match event {
                Ok(Event::Incoming(Packet::ConnAck(_))) => {
                    link.connected = true;
                    backoff = min;
                    let waiting = link.outbox.records();
                    let lost = link.dropped - link.dropped_before;
                    (link.dropped_before, link.told_full) = (link.dropped, false);
                    if connected_once || failures > 0 {
                        log::info!(
                            "mqtt: connected to {} after {failures} failed attempt(s); {waiting} records waiting, {} of them final; {lost} dropped since the last connection",
                            self.settings.broker(),
                            link.outbox.finals()
                        );
                    } else {
                        log::info!("mqtt: connected to {}", self.settings.broker());
                    }
                    connected_once = true;
                    failures = 0;
                    link.last_error.clear();
                    // Availability and discovery first, then the retained
                    // state (the broker may have restarted without it).
                    let mut control = vec![availability(true)];
                    control.extend(self.discovery.iter().enumerate().map(|(i, p)| {
                        (
                            Placement {
                                route: Route::Discovery(i as u8),
                                qos: 1,
                                retain: true,
                            },
                            p.clone(),
                        )
                    }));
                    control.extend(link.outbox.retained_state(self.settings.qos));
                    link.outbox.push_control_front(control);
                    self.pump(&mut link);
                    self.shared.changed.notify_all();
                }
                Ok(Event::Outgoing(Outgoing::Publish(pkid))) => {
                    if link.outbox.written(pkid) {
                        self.pump(&mut link);
                        self.shared.changed.notify_all();
                    }
                }
                Ok(Event::Incoming(Packet::PubAck(ack))) => {
                    if link.outbox.acked(ack.pkid) {
                        self.pump(&mut link);
                        self.shared.changed.notify_all();
                    }
                }
                Ok(Event::Outgoing(Outgoing::Disconnect)) if link.closing => {
                    link.connected = false;
                    break;
                }
                Ok(_) => {}
                Err(e) => {
                    // Whatever rumqttc still holds from this connection is
                    // also in the outbox: drop its copies so that nothing is
                    // sent twice after reconnecting, and its stale events.
                    connection.eventloop.clean();
                    connection.eventloop.pending.clear();
                    connection.eventloop.state.events.clear();
                    link.outbox.requeue();
                    let was_connected = std::mem::replace(&mut link.connected, false);
                    self.shared.changed.notify_all();
                    if link.abandon || (link.closing && !was_connected) {
                        break;
                    }
                    failures += 1;
                    let msg = describe(&e);
                    if was_connected {
                        log::warn!(
                            "mqtt: connection to {} lost: {msg}; reconnecting (records are held meanwhile)",
                            self.settings.broker()
                        );
                    } else if msg != link.last_error {
                        let hint = hint(&e);
                        log::error!(
                            "mqtt: cannot connect to {}: {msg}{hint}; retrying (backoff up to {:.1} s), records are held meanwhile",
                            self.settings.broker(),
                            max
                        );
                    } else if failures % 20 == 0 {
                        log::warn!(
                            "mqtt: still cannot connect to {} ({failures} attempts): {msg}; {} records held",
                            self.settings.broker(),
                            link.outbox.records()
                        );
                    }
                    link.last_error = msg;
                    // Refusals will not fix themselves quickly: wait the longest.
                    let wait = if matches!(e, ConnectionError::ConnectionRefused(_)) {
                        max
                    } else {
                        backoff
                    };
                    backoff = (backoff * 2.0).min(max);
                    let until = Instant::now() + Duration::from_secs_f64(wait);
                    while !link.abandon {
                        let now = Instant::now();
                        if now >= until {
                            break;
                        }
                        link = match self.shared.changed.wait_timeout(link, until - now) {
                            Ok((l, _)) => l,
                            Err(e) => e.into_inner().0,
                        };
                    }
                    if link.abandon {
                        break;
                    }
                }
            }
        }
        let mut link = self.shared.lock();
        link.connected = false;
        link.exited = true;
        self.shared.changed.notify_all();
    }

    fn pump(&self, link: &mut Link) {
        let (client, topics) = (&self.client, &self.topics);
        link.outbox.pump(|e| publish(client, topics, e));
    }
}

/// A one-line reason for a connection error.
fn describe(e: &ConnectionError) -> String {
    match e {
        ConnectionError::ConnectionRefused(code) => format!(
            "the broker refused the connection: {}",
            match code {
                ConnectReturnCode::BadUserNamePassword => "bad user name or password",
                ConnectReturnCode::NotAuthorized =>
                    "not authorised (user name or password wrong or missing)",
                ConnectReturnCode::BadClientId => "client id rejected",
                ConnectReturnCode::RefusedProtocolVersion => "MQTT 3.1.1 not supported",
                ConnectReturnCode::ServiceUnavailable => "service unavailable",
                ConnectReturnCode::Success => "success (?)",
            }
        ),
        ConnectionError::MqttState(StateError::ConnectionAborted) => {
            "the broker closed the connection".into()
        }
        ConnectionError::MqttState(StateError::AwaitPingResp) => {
            "the broker stopped answering pings".into()
        }
        ConnectionError::MqttState(StateError::Io(e)) | ConnectionError::Io(e) => format!("{e}"),
        ConnectionError::NetworkTimeout => "no answer within the connection timeout".into(),
        other => other.to_string(),
    }
}

/// What the user can do about `e`.
fn hint(e: &ConnectionError) -> &'static str {
    match e {
        ConnectionError::ConnectionRefused(
            ConnectReturnCode::BadUserNamePassword | ConnectReturnCode::NotAuthorized,
        ) => " (check [report.mqtt] username/password or STATURE_MQTT_USERNAME/STATURE_MQTT_PASSWORD)",
        ConnectionError::Tls(_) => " (check tls/ca and the broker's certificate)",
        _ => "",
    }
}

/// The local part of [`MqttSink::open`], which cannot wait for the
/// broker: the TLS roots (the `ca=` file, or the system's). What `stature
/// config --check` asks of an `mqtt:` sink without connecting.
pub fn check_local(settings: &MqttSettings) -> io::Result<()> {
    settings.check_credentials()?;
    if settings.tls {
        tls_config(&settings.ca)?;
    }
    Ok(())
}

/// The most a `ca=` file may hold. Mozilla's whole bundle (about 150
/// roots, what a system store holds) is about 220 KiB of PEM; a broker's CA
/// is one or two certificates of 1–2 KiB each. 1 MiB leaves room for any
/// real bundle and stops a mistyped path (a video, `/dev/zero`) from taking
/// all the memory there is.
pub const MAX_CA_BYTES: u64 = 1 << 20;

/// The certificates of the `ca=` file `ca`. Only a regular file (after
/// symbolic links) is read: opening a FIFO blocks until something writes
/// to it, where no signal ends the wait, and a device such as `/dev/zero`
/// never ends; both are refused before the open, and again after it (on
/// the file opened, without waiting: a FIFO swapped in between is
/// refused, not waited on).
fn ca_certificates(ca: &str) -> io::Result<Vec<rustls::pki_types::CertificateDer<'static>>> {
    use rustls::pki_types::{pem::PemObject, CertificateDer};
    use std::os::unix::fs::OpenOptionsExt;
    let bad = |msg: &dyn std::fmt::Display| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("MQTT CA file `{ca}`: {msg}"),
        )
    };
    let regular = |kind: std::fs::FileType| {
        if kind.is_file() {
            return Ok(());
        }
        Err(bad(&format!(
            "not a regular file ({}): give a PEM file with the broker's CA certificate(s)",
            kind_name(kind)
        )))
    };
    regular(std::fs::metadata(ca).map_err(|e| bad(&e))?.file_type())?;
    let f = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(rustix::fs::OFlags::NONBLOCK.bits() as i32)
        .open(ca)
        .map_err(|e| bad(&e))?;
    regular(f.metadata().map_err(|e| bad(&e))?.file_type())?;
    let bytes = crate::replace::read_capped_from(f, MAX_CA_BYTES).map_err(|e| bad(&e))?;
    CertificateDer::pem_slice_iter(&bytes)
        .map(|c| c.map(CertificateDer::into_owned).map_err(|e| bad(&e)))
        .collect()
}

/// What a file that is not a regular one is, in words.
fn kind_name(kind: std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_dir() {
        "a directory"
    } else if kind.is_fifo() {
        "a FIFO"
    } else if kind.is_char_device() {
        "a character device"
    } else if kind.is_block_device() {
        "a block device"
    } else if kind.is_socket() {
        "a socket"
    } else {
        "something else"
    }
}

/// A rustls client configuration with the ring provider, trusting `ca`
/// (a PEM file) or, when empty, the system's CA certificates.
fn tls_config(ca: &str) -> io::Result<rustls::ClientConfig> {
    let bad = |msg: String| io::Error::new(io::ErrorKind::InvalidInput, msg);
    let mut roots = rustls::RootCertStore::empty();
    if ca.is_empty() {
        let found = rustls_native_certs::load_native_certs();
        for cert in found.certs {
            let _ = roots.add(cert);
        }
        if roots.is_empty() {
            return Err(bad(
                "MQTT over TLS: no system CA certificates found; give the broker's CA with ca=FILE"
                    .into(),
            ));
        }
    } else {
        for cert in ca_certificates(ca)? {
            roots
                .add(cert)
                .map_err(|e| bad(format!("MQTT CA file `{ca}`: {e}")))?;
        }
        if roots.is_empty() {
            return Err(bad(format!("MQTT CA file `{ca}` holds no PEM certificate")));
        }
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    Ok(rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| bad(format!("MQTT TLS: {e}")))?
        .with_root_certificates(roots)
        .with_no_client_auth())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(ca: &std::path::Path) -> String {
        match tls_config(ca.to_str().unwrap()) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("`{}` must be refused as a CA file", ca.display()),
        }
    }

    #[test]
    fn a_ca_fifo_is_refused_without_opening_it() {
        let dir = crate::scratch::fresh_dir("mqtt-ca-fifo");
        let ca = dir.join("ca.fifo");
        crate::scratch::mkfifo(&ca);
        // Before: open(2) waited for a writer, and no signal ended it.
        let e = crate::scratch::with_fifo_writer(&ca, || refusal(&ca));
        assert!(
            e.contains(&format!("MQTT CA file `{}`", ca.display())),
            "{e}"
        );
        assert!(e.contains("not a regular file (a FIFO)"), "{e}");
        // The same through a symbolic link: it is followed.
        let link = dir.join("ca.pem");
        std::os::unix::fs::symlink(&ca, &link).unwrap();
        let e = crate::scratch::with_fifo_writer(&ca, || refusal(&link));
        assert!(e.contains("not a regular file (a FIFO)"), "{e}");
    }

    #[test]
    fn a_ca_device_is_refused_without_reading_it() {
        // Before: /dev/zero was read until the OOM killer came (~24 GB).
        let e = refusal(std::path::Path::new("/dev/zero"));
        assert!(e.contains("MQTT CA file `/dev/zero`"), "{e}");
        assert!(e.contains("not a regular file (a character device)"), "{e}");
        let e = refusal(std::path::Path::new("/"));
        assert!(e.contains("not a regular file (a directory)"), "{e}");
    }

    #[test]
    fn a_ca_file_over_the_cap_is_refused_naming_the_cap() {
        let dir = crate::scratch::fresh_dir("mqtt-ca-large");
        let ca = dir.join("ca.pem");
        // Past the cap by one byte; the cap itself still gets parsed.
        std::fs::write(&ca, vec![b'A'; MAX_CA_BYTES as usize + 1]).unwrap();
        let e = refusal(&ca);
        assert!(
            e.contains(&format!("MQTT CA file `{}`", ca.display())),
            "{e}"
        );
        assert!(e.contains("larger than 1 MiB"), "{e}");
        std::fs::write(&ca, vec![b'A'; MAX_CA_BYTES as usize]).unwrap();
        let e = refusal(&ca);
        assert!(e.contains("holds no PEM certificate"), "{e}");
        // A link to a regular file is followed and the file read.
        let link = dir.join("link.pem");
        std::os::unix::fs::symlink(&ca, &link).unwrap();
        let e = refusal(&link);
        assert!(e.contains("holds no PEM certificate"), "{e}");
    }
}
