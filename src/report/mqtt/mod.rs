//! The `mqtt:` report sink: schema v1 records published to an MQTT broker
//! (Mosquitto, EMQX, …) under one topic prefix per camera, with an optional
//! Home Assistant discovery announcement.
//!
//! Topics under the prefix `P` (default `stature/<hostname>`):
//!
//! | topic | payload | retained | QoS |
//! |---|---|---|---|
//! | `P/status` | `online` / `offline` (last will: `offline`) | yes | 1 |
//! | `P/hello` | `hello` record | yes | 1 |
//! | `P/calibration` | `calibration` record | yes | configured; final: 1 |
//! | `P/height` | `height` record | no | configured; final: 1 |
//! | `P/status/record` | periodic `status` record | no | configured |
//! | `P/bye` | `bye` record | no | 1 |
//!
//! `P/status` carries only the availability word so that Home Assistant (and
//! anything else that reads an availability topic) can use it as is; the
//! periodic health records go one level below it.
//!
//! This module is the part that needs no network: configuration, the
//! `mqtt:` URI, topic routing, discovery payloads and the [`Outbox`] that
//! holds records while the broker is away. The connection itself
//! (`link`, feature `mqtt`) runs in a thread of its own.

#[cfg(feature = "mqtt")]
pub mod link;
pub mod outbox;

pub use outbox::{Entry, Outbox, Pushed};

use crate::config::{check_range, ConfigError};
use crate::report::record::Record;
use serde::{Deserialize, Serialize};

/// `[report.mqtt]`: settings for every `mqtt:` sink. Keys given in the
/// sink's URI (`mqtt:HOST:PORT?topic=..&qos=..`) override these.
#[derive(Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MqttConfig {
    /// Topic prefix; empty means `stature/<hostname>`.
    pub topic: String,
    /// QoS (0 or 1) of non-final records; final records always use 1.
    pub qos: u8,
    /// MQTT client id; empty means `stature-<hostname>`.
    pub client_id: String,
    /// Connect with TLS (rustls).
    pub tls: bool,
    /// PEM file with the CA certificate(s) that sign the broker's
    /// certificate; empty means the system's CA store.
    pub ca: String,
    /// Announce the camera to Home Assistant (MQTT discovery).
    pub ha_discovery: bool,
    /// Home Assistant's discovery prefix.
    pub ha_prefix: String,
    /// User name; `STATURE_MQTT_USERNAME` overrides it. Never on the command line.
    pub username: String,
    /// Password; `STATURE_MQTT_PASSWORD` overrides it. Never on the command line.
    pub password: String,
    /// Seconds between keep-alive pings; the broker declares the camera
    /// dead (and publishes its last will) after 1.5 times this.
    pub keep_alive_s: u32,
    /// Records held while the broker is unreachable; when full, the oldest
    /// non-final record is dropped first (and counted in `status.dropped`).
    pub buffer: usize,
    /// First wait before reconnecting, seconds; doubles per failure.
    pub reconnect_min_s: f64,
    /// Longest wait between reconnection attempts, seconds.
    pub reconnect_max_s: f64,
    /// At the end of a run, how long to wait for held records to reach the
    /// broker before giving up on them, seconds.
    pub shutdown_timeout_s: f64,
}

// Hand-written so that the password never reaches a log line.
impl std::fmt::Debug for MqttConfig {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MqttConfig")
            .field("topic", &self.topic)
            .field("qos", &self.qos)
            .field("client_id", &self.client_id)
            .field("tls", &self.tls)
            .field("ca", &self.ca)
            .field("ha_discovery", &self.ha_discovery)
            .field("ha_prefix", &self.ha_prefix)
            .field("username", &self.username)
            .field(
                "password",
                &if self.password.is_empty() { "" } else { "***" },
            )
            .field("keep_alive_s", &self.keep_alive_s)
            .field("buffer", &self.buffer)
            .field("reconnect_min_s", &self.reconnect_min_s)
            .field("reconnect_max_s", &self.reconnect_max_s)
            .field("shutdown_timeout_s", &self.shutdown_timeout_s)
            .finish()
    }
}

impl Default for MqttConfig {
    fn default() -> Self {
        MqttConfig {
            topic: String::new(),
            qos: 0,
            client_id: String::new(),
            tls: false,
            ca: String::new(),
            ha_discovery: false,
            ha_prefix: "homeassistant".into(),
            username: String::new(),
            password: String::new(),
            keep_alive_s: 30,
            buffer: 256,
            reconnect_min_s: 0.5,
            reconnect_max_s: 30.0,
            shutdown_timeout_s: 5.0,
        }
    }
}

impl MqttConfig {
    /// Checks every value (called by [`crate::config::Config::validate`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !self.topic.is_empty() {
            check_topic(&self.topic)
                .map_err(|e| ConfigError::new("report.mqtt.topic", &self.topic, e))?;
        }
        check_range("report.mqtt.qos", self.qos, 0..=1)?;
        check_client_id(&self.client_id)
            .map_err(|e| ConfigError::new("report.mqtt.client_id", &self.client_id, e))?;
        check_topic(&self.ha_prefix)
            .map_err(|e| ConfigError::new("report.mqtt.ha_prefix", &self.ha_prefix, e))?;
        // A password without a user name is checked once the environment
        // is merged in (`MqttSettings::check_credentials`): its
        // STATURE_MQTT_USERNAME may supply the name.
        check_range("report.mqtt.keep_alive_s", self.keep_alive_s, 5..=3600)?;
        check_range("report.mqtt.buffer", self.buffer, 8..=65536)?;
        check_range(
            "report.mqtt.reconnect_min_s",
            self.reconnect_min_s,
            0.05..=60.0,
        )?;
        check_range(
            "report.mqtt.reconnect_max_s",
            self.reconnect_max_s,
            self.reconnect_min_s.max(0.05)..=3600.0,
        )?;
        check_range(
            "report.mqtt.shutdown_timeout_s",
            self.shutdown_timeout_s,
            0.0..=600.0,
        )?;
        Ok(())
    }
}

/// A topic prefix: no wildcards, no empty level, not a `$` system topic.
pub fn check_topic(t: &str) -> Result<(), String> {
    if t.is_empty() || t.len() > 200 {
        return Err("a topic of 1 to 200 bytes".into());
    }
    if t.contains(['+', '#', '\0']) || t.starts_with('$') {
        return Err("a topic without `+`, `#`, NUL or a leading `$`".into());
    }
    if t.split('/').any(str::is_empty) {
        return Err("a topic without empty levels (no leading, trailing or double `/`)".into());
    }
    Ok(())
}

/// A client id: empty (derived from the host name) or up to 64 printable ASCII characters.
pub fn check_client_id(id: &str) -> Result<(), String> {
    if id.len() > 64 || !id.bytes().all(|b| b.is_ascii_graphic()) {
        return Err("up to 64 printable ASCII characters without spaces".into());
    }
    Ok(())
}

/// The keys of an `mqtt:` URI's query; `None` leaves the config file's value.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MqttQuery {
    /// `topic=`
    pub topic: Option<String>,
    /// `qos=`
    pub qos: Option<u8>,
    /// `client_id=`
    pub client_id: Option<String>,
    /// `tls=`
    pub tls: Option<bool>,
    /// `ca=`
    pub ca: Option<String>,
    /// `ha_discovery=`
    pub ha_discovery: Option<bool>,
}

/// A parsed `mqtt:HOST[:PORT][?KEY=VALUE&..]`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MqttSpec {
    /// Broker host name or address (IPv6 without brackets).
    pub host: String,
    /// Broker port; `None` means 1883, or 8883 with TLS.
    pub port: Option<u16>,
    /// Options given in the URI.
    pub query: MqttQuery,
}

const MQTT_FORM: &str =
    "mqtt:HOST[:PORT][?topic=T&qos=0|1&client_id=ID&tls=true|false&ca=FILE&ha_discovery=true|false]";

/// The keys of an `mqtt:` URI's query, for the message about an unknown one.
const MQTT_KEYS: &str = "topic, qos, client_id, tls, ca or ha_discovery";

impl MqttSpec {
    /// Parses what follows `mqtt:`. Credentials are refused: a command line
    /// is visible to every user of the machine (`ps`).
    ///
    /// The error is the reason only, without the URI: the caller names it.
    pub fn parse(rest: &str) -> Result<Self, String> {
        let (addr, query) = rest.split_once('?').unwrap_or((rest, ""));
        let (host, port) = if let Some(v6) = addr.strip_prefix('[') {
            let (h, tail) = v6.split_once(']').ok_or("unclosed `[` in the host")?;
            match tail {
                "" => (h, None),
                p => (
                    h,
                    Some(
                        p.strip_prefix(':')
                            .ok_or_else(|| format!("expected {MQTT_FORM}"))?,
                    ),
                ),
            }
        } else {
            match addr.split_once(':') {
                Some((h, p)) => (h, Some(p)),
                None => (addr, None),
            }
        };
        if host.is_empty() || host.contains(['/', ' ']) || port == Some("") {
            return Err(format!("expected {MQTT_FORM}"));
        }
        let port = match port {
            None => None,
            Some(p) => match p.parse::<u16>() {
                Ok(n) if n > 0 => Some(n),
                _ => return Err(format!("port `{p}` is not in 1..=65535")),
            },
        };
        let mut q = MqttQuery::default();
        let bool_of = |k: &str, v: &str| match v {
            "true" | "1" | "yes" => Ok(true),
            "false" | "0" | "no" => Ok(false),
            _ => Err(format!(
                "`{k}={v}`: expected true or false (or 1/0, yes/no)"
            )),
        };
        let pairs = crate::source::query_pairs(query)
            .map_err(|k| format!("`{k}` given twice in `{query}`"))?;
        for (k, v) in pairs {
            match k {
                "topic" => {
                    check_topic(v).map_err(|e| format!("topic `{v}`: expected {e}"))?;
                    q.topic = Some(v.into());
                }
                "qos" => match v {
                    "0" => q.qos = Some(0),
                    "1" => q.qos = Some(1),
                    _ => return Err(format!("`qos={v}`: expected 0 or 1")),
                },
                "client_id" => {
                    check_client_id(v).map_err(|e| format!("client_id `{v}`: expected {e}"))?;
                    q.client_id = Some(v.into());
                }
                "tls" => q.tls = Some(bool_of(k, v)?),
                "ca" if v.is_empty() => return Err("`ca=`: expected the path of a PEM file".into()),
                "ca" => q.ca = Some(v.into()),
                "ha_discovery" => q.ha_discovery = Some(bool_of(k, v)?),
                "username" | "password" | "user" | "pass" => {
                    return Err(format!(
                        "`{k}` is not accepted in an mqtt: sink (a sink is shown in process lists and logs): \
                         {MQTT_CREDENTIALS}"
                    ))
                }
                _ => return Err(format!("unknown mqtt option `{k}` (expected {MQTT_KEYS})")),
            }
        }
        Ok(MqttSpec {
            host: host.into(),
            port,
            query: q,
        })
    }
}

impl MqttSpec {
    /// The client id this sink connects with: the URI's `client_id`, else
    /// `[report.mqtt] client_id`, else `stature-<hostname>`.
    pub fn client_id(&self, cfg: &MqttConfig) -> String {
        self.query
            .client_id
            .clone()
            .filter(|s| !s.is_empty())
            .or_else(|| Some(cfg.client_id.clone()).filter(|s| !s.is_empty()))
            .unwrap_or_else(|| format!("stature-{}", host_id()))
    }
}

/// Refuses two `mqtt:` sinks (each as written and parsed) that would
/// connect with the same client id: a broker keeps one session per id and
/// drops the older connection whenever the other one connects, so the two
/// would take turns, each losing records. Two different brokers are held
/// to it too, since two addresses (`localhost` and `127.0.0.1`, ports 1883
/// and 8883) may well reach the same broker. Ids are not made distinct
/// behind the user's back: broker ACLs and the Home Assistant device (named
/// after the id) depend on them.
///
/// The error is the second sink as written and the reason.
pub fn check_client_ids<'a>(
    sinks: &[(&'a str, MqttSpec)],
    cfg: &MqttConfig,
) -> Result<(), (&'a str, String)> {
    let ids: Vec<String> = sinks.iter().map(|(_, m)| m.client_id(cfg)).collect();
    for (i, (uri, m)) in sinks.iter().enumerate() {
        let Some(first) = (0..i).find(|&j| ids[j] == ids[i]) else {
            continue;
        };
        let id = &ids[i];
        // Cut so that the suggestion itself passes `check_client_id`.
        let suffix = format!("-{}", i + 1);
        let stem: String = id.chars().take(64 - suffix.len()).collect();
        let new_id = format!("{stem}{suffix}");
        let fix = if m.query.client_id.is_some() {
            format!("`client_id={new_id}`")
        } else if uri.contains('?') {
            format!("`{uri}&client_id={new_id}`")
        } else {
            format!("`{uri}?client_id={new_id}`")
        };
        return Err((
            uri,
            format!(
                "same MQTT client id `{id}` as `{}` (a broker disconnects one whenever the other \
                 connects): give each mqtt: sink its own with `client_id=`, e.g. {fix}",
                sinks[first].0
            ),
        ));
    }
    Ok(())
}

/// Where to point users who put credentials in a sink (its query or its
/// host).
pub(crate) const MQTT_CREDENTIALS: &str = "set [report.mqtt] username/password in the config file \
     or the environment variables STATURE_MQTT_USERNAME/STATURE_MQTT_PASSWORD";

/// Refuses a CA file for a connection without TLS: a plain connection
/// would ignore it, and whoever gave one meant the link to be encrypted.
pub fn check_tls(m: &MqttSpec, cfg: &MqttConfig) -> Result<(), String> {
    let tls = m.query.tls.unwrap_or(cfg.tls);
    let ca = m.query.ca.as_deref().unwrap_or(&cfg.ca);
    if ca.is_empty() || tls {
        return Ok(());
    }
    Err(format!(
        "a CA file (`{ca}`) but TLS is off: add `tls=true` to the sink \
         (or `tls = true` in [report.mqtt]), or drop the CA"
    ))
}

/// Everything a connection needs: the config file, the URI and the
/// environment merged, defaults filled in.
#[derive(Clone, PartialEq)]
pub struct MqttSettings {
    /// Broker host.
    pub host: String,
    /// Broker port.
    pub port: u16,
    /// Topic prefix.
    pub topic: String,
    /// QoS of non-final records.
    pub qos: u8,
    /// Client id.
    pub client_id: String,
    /// TLS on.
    pub tls: bool,
    /// CA file (empty: system store).
    pub ca: String,
    /// Home Assistant discovery on.
    pub ha_discovery: bool,
    /// Discovery prefix.
    pub ha_prefix: String,
    /// User name and password, if any.
    pub credentials: Option<(String, String)>,
    /// A password was given (the file's or `STATURE_MQTT_PASSWORD`) with
    /// no user name from either place: MQTT cannot send it, and connecting
    /// without it would hide the mistake ([`MqttSettings::check_credentials`]).
    pub password_without_user: bool,
    /// Keep-alive, seconds.
    pub keep_alive_s: u32,
    /// Held records.
    pub buffer: usize,
    /// Reconnection backoff bounds, seconds.
    pub reconnect_s: (f64, f64),
    /// Shutdown wait, seconds.
    pub shutdown_timeout_s: f64,
}

impl std::fmt::Debug for MqttSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mqtt{}://{}@{}:{} topic {} client {}",
            if self.tls { "s" } else { "" },
            self.credentials.as_ref().map_or("", |c| c.0.as_str()),
            self.host,
            self.port,
            self.topic,
            self.client_id
        )
    }
}

impl MqttSettings {
    /// Merges `spec` over `cfg`; `env` reads an environment variable
    /// (injected so tests need not touch the process environment).
    pub fn resolve(
        spec: &MqttSpec,
        cfg: &MqttConfig,
        env: impl Fn(&str) -> Option<String>,
    ) -> Self {
        let q = &spec.query;
        let tls = q.tls.unwrap_or(cfg.tls);
        let host_id = host_id();
        let client_id = spec.client_id(cfg);
        let topic = q
            .topic
            .clone()
            .or_else(|| Some(cfg.topic.clone()).filter(|s| !s.is_empty()))
            .unwrap_or_else(|| format!("stature/{host_id}"));
        let nonempty = |v: Option<String>| v.filter(|s| !s.is_empty());
        let user = nonempty(env("STATURE_MQTT_USERNAME")).unwrap_or_else(|| cfg.username.clone());
        let pass = nonempty(env("STATURE_MQTT_PASSWORD")).unwrap_or_else(|| cfg.password.clone());
        MqttSettings {
            host: spec.host.clone(),
            port: spec.port.unwrap_or(if tls { 8883 } else { 1883 }),
            topic,
            qos: q.qos.unwrap_or(cfg.qos),
            client_id,
            tls,
            ca: q.ca.clone().unwrap_or_else(|| cfg.ca.clone()),
            ha_discovery: q.ha_discovery.unwrap_or(cfg.ha_discovery),
            ha_prefix: cfg.ha_prefix.clone(),
            password_without_user: user.is_empty() && !pass.is_empty(),
            credentials: (!user.is_empty()).then_some((user, pass)),
            keep_alive_s: cfg.keep_alive_s,
            buffer: cfg.buffer,
            reconnect_s: (cfg.reconnect_min_s, cfg.reconnect_max_s),
            shutdown_timeout_s: cfg.shutdown_timeout_s,
        }
    }

    /// Refuses a password without a user name, each from the config file
    /// or the environment (a user name without a password is legal MQTT;
    /// the reverse is not).
    pub fn check_credentials(&self) -> std::io::Result<()> {
        if self.password_without_user {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                "MQTT password set ([report.mqtt] password or STATURE_MQTT_PASSWORD) without a \
                 user name (STATURE_MQTT_USERNAME or [report.mqtt] username): MQTT sends no \
                 password without one",
            ));
        }
        Ok(())
    }

    /// `HOST:PORT` for log lines.
    pub fn broker(&self) -> String {
        if self.host.contains(':') {
            format!("[{}]:{}", self.host, self.port)
        } else {
            format!("{}:{}", self.host, self.port)
        }
    }
}

/// The machine's host name reduced to `[A-Za-z0-9_-]`, for default topic
/// and client id (`camera` when it cannot be read).
pub fn host_id() -> String {
    let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .or_else(|_| std::fs::read_to_string("/etc/hostname"))
        .unwrap_or_default();
    let id: String = raw
        .trim()
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .take(40)
        .collect();
    if id.is_empty() {
        "camera".into()
    } else {
        id
    }
}

/// Where each kind of message goes: an index into [`Topics::names`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// `P/status`: availability word.
    Availability,
    /// `P/hello`
    Hello,
    /// `P/calibration`
    Calibration,
    /// `P/height`
    Height,
    /// `P/status/record`
    Status,
    /// `P/bye`
    Bye,
    /// Home Assistant discovery config number `n`.
    Discovery(u8),
}

/// The topic names of one sink, built once at start-up.
#[derive(Clone, Debug)]
pub struct Topics {
    /// Availability, hello, calibration, height, status record, bye, then discovery configs.
    pub names: Vec<String>,
}

impl Topics {
    /// Topics under `prefix`; discovery topics when `discovery` is given.
    pub fn new(prefix: &str, discovery: &[Discovery]) -> Self {
        let mut names: Vec<String> = [
            "status",
            "hello",
            "calibration",
            "height",
            "status/record",
            "bye",
        ]
        .iter()
        .map(|s| format!("{prefix}/{s}"))
        .collect();
        names.extend(discovery.iter().map(|d| d.topic.clone()));
        Topics { names }
    }

    /// The topic of `route`.
    pub fn name(&self, route: Route) -> &str {
        let i = match route {
            Route::Availability => 0,
            Route::Hello => 1,
            Route::Calibration => 2,
            Route::Height => 3,
            Route::Status => 4,
            Route::Bye => 5,
            Route::Discovery(n) => 6 + n as usize,
        };
        &self.names[i]
    }
}

/// How a record is published: topic, QoS, retain flag.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    /// Topic.
    pub route: Route,
    /// QoS 0 or 1.
    pub qos: u8,
    /// Retained by the broker for later subscribers.
    pub retain: bool,
}

/// Where `record` goes, given the configured QoS of non-final records.
pub fn place(record: &Record, qos: u8) -> Placement {
    let q = if record.is_final() { 1 } else { qos };
    let (route, retain) = match record {
        Record::Hello(_) => (Route::Hello, true),
        Record::Calibration(_) => (Route::Calibration, true),
        Record::Height(_) => (Route::Height, false),
        Record::Status(_) => (Route::Status, false),
        Record::Bye(_) => (Route::Bye, false),
    };
    Placement {
        route,
        qos: q,
        retain,
    }
}

/// One Home Assistant discovery message.
#[derive(Clone, Debug, PartialEq)]
pub struct Discovery {
    /// `<prefix>/sensor/<node>/<object>/config`
    pub topic: String,
    /// The JSON config.
    pub payload: Vec<u8>,
}

/// Home Assistant MQTT discovery for one camera: sensors for the last
/// height, the people count and the calibration confidence, all tied to one
/// device and to the availability topic.
pub fn discovery(s: &MqttSettings) -> Vec<Discovery> {
    // Node and object ids allow only [a-zA-Z0-9_-].
    let node: String = s
        .client_id
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let t = Topics::new(&s.topic, &[]);
    let device = serde_json::json!({
        "identifiers": [format!("stature_{node}")],
        // A client id such as `stature-entrance` names itself already.
        "name": if node.starts_with("stature") { node.clone() } else { format!("stature {node}") },
        "manufacturer": "stature",
        "model": "stature camera",
        "sw_version": env!("CARGO_PKG_VERSION"),
    });
    let sensors = [
        (
            "height",
            "Last height",
            t.name(Route::Height),
            "{{ value_json.height_m | round(2) }}",
            Some("m"),
            Some("distance"),
            Some("mdi:human-male-height"),
        ),
        (
            "people",
            "People in view",
            t.name(Route::Status),
            "{{ value_json.tracks }}",
            None,
            None,
            Some("mdi:account-group"),
        ),
        (
            "calibration_confidence",
            "Calibration confidence",
            t.name(Route::Calibration),
            "{{ (value_json.confidence * 100) | round(0) }}",
            Some("%"),
            None,
            Some("mdi:camera-metering-center"),
        ),
    ];
    sensors
        .iter()
        .map(|(object, name, state_topic, template, unit, class, icon)| {
            let mut v = serde_json::json!({
                "name": name,
                "unique_id": format!("stature_{node}_{object}"),
                "state_topic": state_topic,
                "value_template": template,
                "state_class": "measurement",
                "availability_topic": t.name(Route::Availability),
                "payload_available": "online",
                "payload_not_available": "offline",
                "device": device,
            });
            let o = v.as_object_mut().expect("a JSON object literal");
            // Height and calibration records carry more than the state
            // (track, samples, final; focal length, tilt, camera height):
            // Home Assistant shows them as the sensor's attributes.
            if *object != "people" {
                o.insert("json_attributes_topic".into(), (*state_topic).into());
            }
            if let Some(u) = unit {
                o.insert("unit_of_measurement".into(), (*u).into());
            }
            if let Some(c) = class {
                o.insert("device_class".into(), (*c).into());
            }
            if let Some(i) = icon {
                o.insert("icon".into(), (*i).into());
            }
            Discovery {
                topic: format!("{}/sensor/{node}/{object}/config", s.ha_prefix),
                payload: serde_json::to_vec(&v).expect("serialising a JSON value"),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::record::{bounded, Calibration, Height, Status};

    fn place_h(q: u8) -> Placement {
        Placement {
            route: Route::Height,
            qos: q,
            retain: false,
        }
    }

    #[test]
    fn uri_parses_and_refuses_credentials() {
        let s = MqttSpec::parse("broker.lan:1884?topic=stature/cam1&qos=1&client_id=cam1&tls=true&ca=/etc/ca.pem&ha_discovery=true").unwrap();
        assert_eq!(s.host, "broker.lan");
        assert_eq!(s.port, Some(1884));
        assert_eq!(s.query.topic.as_deref(), Some("stature/cam1"));
        assert_eq!(s.query.qos, Some(1));
        assert_eq!(s.query.tls, Some(true));
        assert_eq!(s.query.ca.as_deref(), Some("/etc/ca.pem"));
        assert_eq!(s.query.ha_discovery, Some(true));
        let v6 = MqttSpec::parse("[::1]:1883").unwrap();
        assert_eq!((v6.host.as_str(), v6.port), ("::1", Some(1883)));
        assert_eq!(MqttSpec::parse("h").unwrap().port, None);
        let e = MqttSpec::parse("h:1883?password=hunter2").unwrap_err();
        assert!(
            e.contains("STATURE_MQTT_PASSWORD") && !e.contains("hunter2"),
            "{e}"
        );
        for bad in [
            "",
            ":1883",
            "h:0",
            "h:99999",
            "h:1?qos=2",
            "h:1?topic=a/+/b",
            "h:1?topic=a//b",
            "h:1?tls=maybe",
            "h:1?x=1",
            "[::1",
        ] {
            assert!(MqttSpec::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn settings_merge_uri_over_file_and_environment_over_file() {
        let cfg = MqttConfig {
            topic: "site/cam9".into(),
            qos: 1,
            username: "file-user".into(),
            password: "file-pass".into(),
            ..Default::default()
        };
        let spec = MqttSpec::parse("b:1?qos=0&tls=true").unwrap();
        let s = MqttSettings::resolve(&spec, &cfg, |k| {
            (k == "STATURE_MQTT_PASSWORD").then(|| "env-pass".to_string())
        });
        assert_eq!((s.topic.as_str(), s.qos, s.tls), ("site/cam9", 0, true));
        assert_eq!(s.credentials, Some(("file-user".into(), "env-pass".into())));
        assert!(!format!("{s:?}").contains("pass"), "{s:?}");
        let d = MqttSettings::resolve(
            &MqttSpec::parse("b?tls=true").unwrap(),
            &MqttConfig::default(),
            |_| None,
        );
        assert_eq!(d.port, 8883);
        assert!(d.topic.starts_with("stature/") && d.client_id.starts_with("stature-"));
        assert_eq!(d.credentials, None);
        assert!(d.check_credentials().is_ok());
        // A password from the environment with no user name anywhere is
        // refused (before: dropped, and the client connected anonymously).
        let e = MqttSettings::resolve(
            &MqttSpec::parse("b").unwrap(),
            &MqttConfig::default(),
            |k| (k == "STATURE_MQTT_PASSWORD").then(|| "hunter2".to_string()),
        );
        let err = e.check_credentials().unwrap_err().to_string();
        assert!(
            err.contains("without a user name") && !err.contains("hunter2"),
            "{err}"
        );
        assert!(crate::report::mqtt::link::check_local(&e).is_err());
        assert!(s.check_credentials().is_ok());
        // The file's password with the environment's user name is a pair
        // (before: refused while validating the file, before the
        // environment was read); alone it is refused the same way.
        let file_pass = MqttConfig {
            password: "file-pass".into(),
            ..MqttConfig::default()
        };
        assert!(file_pass.validate().is_ok());
        let paired = MqttSettings::resolve(&MqttSpec::parse("b").unwrap(), &file_pass, |k| {
            (k == "STATURE_MQTT_USERNAME").then(|| "env-user".to_string())
        });
        assert_eq!(
            paired.credentials,
            Some(("env-user".into(), "file-pass".into()))
        );
        assert!(paired.check_credentials().is_ok());
        let alone = MqttSettings::resolve(&MqttSpec::parse("b").unwrap(), &file_pass, |_| None);
        let err = alone.check_credentials().unwrap_err().to_string();
        assert!(
            err.contains("without a") && !err.contains("file-pass"),
            "{err}"
        );
    }

    #[test]
    fn two_sinks_with_one_client_id_are_refused_naming_the_id() {
        let sinks = |uris: &[&'static str]| -> Vec<(&'static str, MqttSpec)> {
            uris.iter()
                .map(|u| (*u, MqttSpec::parse(&u["mqtt:".len()..]).unwrap()))
                .collect()
        };
        let file = MqttConfig::default();
        // Both default to stature-<hostname>, whatever their brokers.
        let (uri, e) =
            check_client_ids(&sinks(&["mqtt:a", "mqtt:b:1884?qos=1"]), &file).unwrap_err();
        assert_eq!(uri, "mqtt:b:1884?qos=1");
        let id = format!("stature-{}", host_id());
        assert_eq!(
            e,
            format!(
                "same MQTT client id `{id}` as `mqtt:a` (a broker disconnects one whenever the \
                 other connects): give each mqtt: sink its own with `client_id=`, e.g. \
                 `mqtt:b:1884?qos=1&client_id={id}-2`"
            )
        );
        // The same id given twice: the suggestion is the key alone.
        let (_, e) = check_client_ids(
            &sinks(&["mqtt:a?client_id=cam", "mqtt:b", "mqtt:c?client_id=cam"]),
            &file,
        )
        .unwrap_err();
        assert!(e.contains("`cam` as `mqtt:a?client_id=cam`"), "{e}");
        assert!(e.ends_with("e.g. `client_id=cam-3`"), "{e}");
        // [report.mqtt] client_id applies to every sink without its own.
        let named = MqttConfig {
            client_id: "gate".into(),
            ..Default::default()
        };
        let (_, e) = check_client_ids(&sinks(&["mqtt:a", "mqtt:b"]), &named).unwrap_err();
        assert!(
            e.contains("`gate` as `mqtt:a`") && e.contains("`mqtt:b?client_id=gate-2`"),
            "{e}"
        );
        check_client_ids(&sinks(&["mqtt:a", "mqtt:b?client_id=gate-2"]), &named).unwrap();
        // The suggested id is itself valid when the first is at the limit.
        let long = "x".repeat(64);
        let uris: Vec<&'static str> = ["a", "b"]
            .map(|h| &*format!("mqtt:{h}?client_id={long}").leak())
            .to_vec();
        let (_, e) = check_client_ids(&sinks(&uris), &named).unwrap_err();
        let suggested = e.rsplit("client_id=").next().unwrap().trim_end_matches('`');
        assert_eq!(suggested, format!("{}-2", "x".repeat(62)), "{e}");
        check_client_id(suggested).unwrap();
        check_client_ids(&sinks(&["mqtt:a?client_id=x", "mqtt:b"]), &file).unwrap();
        check_client_ids(&sinks(&["mqtt:a"]), &file).unwrap();
        // The id checked is the one the sink connects with.
        let spec = MqttSpec::parse("b?client_id=").unwrap();
        assert_eq!(
            MqttSettings::resolve(&spec, &named, |_| None).client_id,
            "gate"
        );
    }

    #[test]
    fn config_validation_names_the_key() {
        let mut c = MqttConfig::default();
        c.validate().unwrap();
        c.qos = 2;
        assert_eq!(c.validate().unwrap_err().key, "report.mqtt.qos");
        c = MqttConfig {
            topic: "a/#".into(),
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().key, "report.mqtt.topic");
        c = MqttConfig {
            reconnect_min_s: 10.0,
            reconnect_max_s: 5.0,
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().key, "report.mqtt.reconnect_max_s");
    }

    #[test]
    fn finals_use_qos_1_and_state_is_retained() {
        let h = |is_final| {
            Record::Height(Height {
                frame: 1,
                track_id: 1,
                height_m: 1.7,
                samples: 1,
                foot_px: [0.0; 2],
                head_px: [0.0; 2],
                bbox: [0; 4],
                is_final,
            })
        };
        assert_eq!(place(&h(false), 0), place_h(0));
        assert_eq!(place(&h(true), 0), place_h(1));
        let c = Record::Calibration(Calibration {
            frame: 1,
            f_px: 1.0,
            tilt_deg: 0.0,
            roll_deg: 0.0,
            camera_height_m: 3.0,
            horizon: [0.0, 1.0, 0.0],
            vertical_vp: [0.0; 2],
            inliers: 0,
            confidence: 0.5,
            is_final: false,
        });
        assert_eq!(
            place(&c, 0),
            Placement {
                route: Route::Calibration,
                qos: 0,
                retain: true
            }
        );
        let s = Record::Status(Status {
            frame: 1,
            frames: 1,
            fps: 1.0,
            dropped: 0,
            source: bounded("streaming"),
            allocations: 0,
            tracks: 2,
        });
        assert_eq!(place(&s, 1).route, Route::Status);
        let t = Topics::new("stature/cam1", &[]);
        assert_eq!(t.name(Route::Status), "stature/cam1/status/record");
        assert_eq!(t.name(Route::Availability), "stature/cam1/status");
    }

    #[test]
    fn discovery_names_the_state_topics() {
        let s = MqttSettings::resolve(
            &MqttSpec::parse("b?topic=stature/cam1&client_id=cam1&ha_discovery=true").unwrap(),
            &MqttConfig::default(),
            |_| None,
        );
        let d = discovery(&s);
        assert_eq!(d.len(), 3);
        let v: Vec<serde_json::Value> = d
            .iter()
            .map(|d| serde_json::from_slice(&d.payload).unwrap())
            .collect();
        assert_eq!(d[0].topic, "homeassistant/sensor/cam1/height/config");
        assert_eq!(v[0]["state_topic"], "stature/cam1/height");
        assert_eq!(v[0]["unit_of_measurement"], "m");
        assert_eq!(v[1]["state_topic"], "stature/cam1/status/record");
        assert_eq!(v[1]["value_template"], "{{ value_json.tracks }}");
        assert_eq!(v[0]["json_attributes_topic"], "stature/cam1/height");
        assert!(v[1].get("json_attributes_topic").is_none());
        assert_eq!(v[0]["device"]["name"], "stature cam1");
        assert_eq!(v[2]["state_topic"], "stature/cam1/calibration");
        for x in &v {
            assert_eq!(x["availability_topic"], "stature/cam1/status");
            assert_eq!(x["device"]["identifiers"][0], "stature_cam1");
        }
    }
}
