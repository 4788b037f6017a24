//! Report sinks: where encoded records go.
//!
//! Sinks live in the I/O thread. Each write is bounded in time (UDP never
//! blocks; serial writes time out), so one dead link delays the others by at
//! most its timeout, and the vision loop not at all.

use std::io::{self, Write};
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::Duration;

/// A parsed `--report` value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SinkSpec {
    /// Standard output.
    Stdout,
    /// Append to a file.
    File(String),
    /// One record per datagram to `HOST:PORT`.
    Udp(String),
    /// A serial port at a baud rate.
    Serial {
        /// Device path.
        path: String,
        /// Baud rate.
        baud: u32,
    },
}

impl SinkSpec {
    /// Parses `stdout`, `file:PATH`, `udp:HOST:PORT` or `serial:PATH?baud=N`.
    pub fn parse(s: &str) -> Result<Self, String> {
        if s == "stdout" {
            return Ok(SinkSpec::Stdout);
        }
        let (scheme, rest) = s.split_once(':').ok_or_else(|| {
            format!("`{s}`: expected stdout, file:PATH, udp:HOST:PORT or serial:PATH?baud=N")
        })?;
        match scheme {
            "file" if !rest.is_empty() => Ok(SinkSpec::File(rest.into())),
            "udp" => {
                let (host, port) = rest.rsplit_once(':').ok_or_else(|| format!("`{s}`: expected udp:HOST:PORT"))?;
                if host.is_empty() || port.parse::<u16>().map_or(true, |p| p == 0) {
                    return Err(format!("`{s}`: expected udp:HOST:PORT with a port in 1..=65535"));
                }
                Ok(SinkSpec::Udp(rest.into()))
            }
            "serial" => {
                let (path, query) = rest.split_once('?').unwrap_or((rest, ""));
                if !path.starts_with('/') {
                    return Err(format!("`{s}`: serial device must be an absolute path"));
                }
                let mut baud = 115_200;
                for (k, v) in crate::source::query_pairs(query) {
                    match (k, v.parse::<u32>()) {
                        ("baud", Ok(b)) if (300..=4_000_000).contains(&b) => baud = b,
                        _ => return Err(format!("`{s}`: serial option `{k}={v}` (expected baud=300..=4000000)")),
                    }
                }
                Ok(SinkSpec::Serial { path: path.into(), baud })
            }
            _ => Err(format!("`{s}`: unknown sink (expected stdout, file:PATH, udp:HOST:PORT or serial:PATH?baud=N)")),
        }
    }
}

/// An open sink.
pub enum Sink {
    /// Standard output.
    Stdout(io::Stdout),
    /// An appended file.
    File(io::BufWriter<std::fs::File>),
    /// A connected-less UDP socket and its destination.
    Udp(UdpSocket, SocketAddr),
    /// A serial port.
    Serial(Box<dyn serialport::SerialPort>),
}

/// How long a serial write may block before the record is dropped.
const SERIAL_TIMEOUT: Duration = Duration::from_millis(200);

impl Sink {
    /// Opens the sink (at start-up: resolving names and opening files may allocate).
    pub fn open(spec: &SinkSpec) -> io::Result<Sink> {
        Ok(match spec {
            SinkSpec::Stdout => Sink::Stdout(io::stdout()),
            SinkSpec::File(p) => Sink::File(io::BufWriter::with_capacity(
                1 << 14,
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(p)
                    .map_err(|e| io::Error::new(e.kind(), format!("report file `{p}`: {e}")))?,
            )),
            SinkSpec::Udp(addr) => {
                let dest = addr
                    .to_socket_addrs()
                    .map_err(|e| {
                        io::Error::new(e.kind(), format!("UDP destination `{addr}`: {e}"))
                    })?
                    .next()
                    .ok_or_else(|| {
                        io::Error::new(
                            io::ErrorKind::NotFound,
                            format!("UDP destination `{addr}` has no address"),
                        )
                    })?;
                let bind: SocketAddr = if dest.is_ipv4() {
                    "0.0.0.0:0".parse().unwrap()
                } else {
                    "[::]:0".parse().unwrap()
                };
                let sock = UdpSocket::bind(bind)?;
                sock.set_nonblocking(true)?;
                Sink::Udp(sock, dest)
            }
            SinkSpec::Serial { path, baud } => {
                let port = serialport::new(path, *baud)
                    .timeout(SERIAL_TIMEOUT)
                    .open()
                    .map_err(|e| {
                        io::Error::new(
                            io::ErrorKind::NotFound,
                            format!("serial port `{path}`: {e}"),
                        )
                    })?;
                Sink::Serial(port)
            }
        })
    }

    /// Writes one encoded record. An error means the record was not delivered.
    pub fn write_record(&mut self, bytes: &[u8]) -> io::Result<()> {
        match self {
            Sink::Stdout(s) => {
                let mut l = s.lock();
                l.write_all(bytes)?;
                l.flush()
            }
            Sink::File(f) => f.write_all(bytes),
            Sink::Udp(sock, dest) => sock.send_to(bytes, *dest).map(|_| ()),
            Sink::Serial(port) => port.write_all(bytes),
        }
    }

    /// Flushes buffered output (called when the queue runs empty).
    pub fn flush(&mut self) -> io::Result<()> {
        match self {
            Sink::File(f) => f.flush(),
            Sink::Serial(p) => p.flush(),
            _ => Ok(()),
        }
    }

    /// Short name for logs.
    pub fn name(&self) -> &'static str {
        match self {
            Sink::Stdout(_) => "stdout",
            Sink::File(_) => "file",
            Sink::Udp(..) => "udp",
            Sink::Serial(_) => "serial",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse() {
        assert_eq!(SinkSpec::parse("stdout"), Ok(SinkSpec::Stdout));
        assert_eq!(
            SinkSpec::parse("udp:127.0.0.1:9000"),
            Ok(SinkSpec::Udp("127.0.0.1:9000".into()))
        );
        assert_eq!(
            SinkSpec::parse("serial:/dev/ttyS0?baud=9600"),
            Ok(SinkSpec::Serial {
                path: "/dev/ttyS0".into(),
                baud: 9600
            })
        );
        assert_eq!(
            SinkSpec::parse("file:/tmp/x.jsonl"),
            Ok(SinkSpec::File("/tmp/x.jsonl".into()))
        );
        for bad in [
            "udp:host",
            "udp:host:0",
            "udp::9",
            "serial:ttyS0",
            "serial:/dev/ttyS0?baud=1",
            "tcp:x:1",
            "file:",
            "nope",
        ] {
            assert!(SinkSpec::parse(bad).is_err(), "{bad}");
        }
    }
}
