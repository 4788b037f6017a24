//! Record encodings into a caller-owned buffer (no allocation).

use super::record::Record;
use crate::config::Format;

/// Largest encoded record in bytes (fits a UDP datagram under 1200 bytes).
pub const MAX_RECORD: usize = 1024;

/// Why a record could not be encoded or decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CodecError {
    /// The record does not fit the buffer.
    TooLong,
    /// The bytes are not a valid record.
    Malformed,
}

impl core::fmt::Display for CodecError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CodecError::TooLong => "record too long",
            CodecError::Malformed => "malformed record",
        })
    }
}
impl std::error::Error for CodecError {}

/// Encodes `record` into `buf`; returns the used part. JSON ends with `\n`,
/// postcard with the COBS frame delimiter `0`.
pub fn encode<'b>(
    record: &Record,
    format: Format,
    buf: &'b mut [u8],
) -> Result<&'b [u8], CodecError> {
    match format {
        Format::Json => {
            let n = serde_json_core::to_slice(record, buf).map_err(|_| CodecError::TooLong)?;
            let nl = buf.get_mut(n).ok_or(CodecError::TooLong)?;
            *nl = b'\n';
            Ok(&buf[..=n])
        }
        Format::Postcard => postcard::to_slice_cobs(record, buf)
            .map(|b| &*b)
            .map_err(|_| CodecError::TooLong),
    }
}

/// Decodes one COBS-framed postcard record (the frame may include its trailing `0`).
/// The buffer is decoded in place.
pub fn decode_postcard(frame: &mut [u8]) -> Result<Record, CodecError> {
    postcard::from_bytes_cobs(frame).map_err(|_| CodecError::Malformed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::record::*;

    fn height() -> Record {
        Record::Height(Height {
            frame: 42,
            track_id: 7,
            height_m: 1.734,
            samples: 31,
            foot_px: [320.5, 400.25],
            head_px: [318.0, 250.0],
            bbox: [300, 250, 340, 401],
            is_final: true,
        })
    }

    #[test]
    fn json_is_tagged_and_parses() {
        let mut buf = [0u8; MAX_RECORD];
        let out = encode(&height(), Format::Json, &mut buf).unwrap();
        assert_eq!(*out.last().unwrap(), b'\n');
        let v: serde_json::Value = serde_json::from_slice(out).unwrap();
        assert_eq!(v["type"], "height");
        assert_eq!(v["frame"], 42);
        assert_eq!(v["final"], true);
        assert!((v["height_m"].as_f64().unwrap() - 1.734).abs() < 1e-6);
        assert_eq!(v["bbox"][3], 401);
    }

    #[test]
    fn postcard_round_trips_every_kind() {
        let records = [
            Record::Hello(Hello {
                frame: 0,
                version: bounded("0.1.0"),
                schema: SCHEMA,
                source: bounded("sim:plaza"),
                width: 640,
                height: 480,
                fps: 25.0,
            }),
            Record::Calibration(Calibration {
                frame: 9,
                f_px: 800.0,
                tilt_deg: 20.0,
                roll_deg: -2.0,
                camera_height_m: 4.0,
                horizon: [0.0, 1.0, -10.0],
                vertical_vp: [300.0, 2500.0],
                inliers: 50,
                confidence: 0.8,
                is_final: false,
            }),
            height(),
            Record::Status(Status {
                frame: 5,
                frames: 5,
                fps: 30.0,
                dropped: 1,
                source: bounded("streaming"),
                allocations: 0,
                tracks: 2,
            }),
            Record::Bye(Bye {
                frame: 100,
                frames: 100,
                dropped: 0,
            }),
        ];
        for r in records {
            let mut buf = [0u8; MAX_RECORD];
            let out = encode(&r, Format::Postcard, &mut buf).unwrap();
            assert_eq!(*out.last().unwrap(), 0);
            assert!(
                !out[..out.len() - 1].contains(&0),
                "COBS frames hold no zero"
            );
            let mut frame = out.to_vec();
            assert_eq!(decode_postcard(&mut frame).unwrap(), r);
        }
    }

    #[test]
    fn garbage_does_not_decode() {
        let mut junk = [0xffu8, 0x13, 0x00];
        assert_eq!(decode_postcard(&mut junk), Err(CodecError::Malformed));
    }
}
