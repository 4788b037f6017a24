//! Golden features and weight-blob refusal.
//!
//! The features of fixed crops are compared with stored values in
//! `tests/golden/classify_features.txt`, so any silent change of the
//! feature arithmetic or layout fails here (and must come with a
//! `FEATURE_VERSION` bump and retrained weights). After an intended change,
//! regenerate with `STATURE_BLESS=1 cargo test --release --test suite classify_golden::`.

use stature::classify::layout::{fnv1a64, Layout};
use stature::classify::svm::{Model, WeightsError};
use stature::classify::{ClassifyConfig, Extractor, BUILTIN_WEIGHTS};
use stature::detect::BBox;
use stature::frame::Plane;
use std::fmt::Write as _;
use std::path::Path;

/// A deterministic 96x160 scene: shaded ground, a dark upright figure,
/// and LCG texture noise.
fn synthetic() -> Vec<u8> {
    let (w, h) = (96usize, 160usize);
    let mut s = 7u32;
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i32, (i / w) as i32);
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12_345);
            let noise = ((s >> 16) % 9) as i32 - 4;
            let ground = 120 + y / 4;
            let head = (x - 48).pow(2) + (y - 40).pow(2) < 81;
            let body = (40..=56).contains(&x) && (48..=100).contains(&y);
            let legs =
                ((40..=46).contains(&x) || (50..=56).contains(&x)) && (100..=132).contains(&y);
            let v = if head || body || legs { 50 } else { ground };
            (v + noise).clamp(0, 255) as u8
        })
        .collect()
}

fn crops() -> Vec<(&'static str, BBox)> {
    vec![
        (
            "figure",
            BBox {
                x0: 38,
                y0: 30,
                x1: 58,
                y1: 133,
            },
        ),
        (
            "figure-loose",
            BBox {
                x0: 30,
                y0: 25,
                x1: 66,
                y1: 140,
            },
        ),
        (
            "top-left-clamped",
            BBox {
                x0: 0,
                y0: 0,
                x1: 30,
                y1: 70,
            },
        ),
        (
            "wide",
            BBox {
                x0: 5,
                y0: 90,
                x1: 90,
                y1: 130,
            },
        ),
    ]
}

fn describe(name: &str, f: &[u8]) -> String {
    let sum: u64 = f.iter().map(|&v| u64::from(v)).sum();
    let head: Vec<String> = f.iter().take(24).map(|v| v.to_string()).collect();
    format!(
        "{name} dim={} sum={sum} fnv={:016x} head={}",
        f.len(),
        fnv1a64(f),
        head.join(",")
    )
}

fn current() -> String {
    let layout = Layout::default_layout();
    let mut ex = Extractor::new(&layout);
    let img = synthetic();
    let plane = Plane::new(&img, 96, 160).unwrap();
    let mut out = String::new();
    let _ = writeln!(out, "layout hash {:016x}", layout.hash());
    for (name, b) in crops() {
        let f = ex.extract(plane, &b).unwrap();
        let _ = writeln!(out, "{}", describe(name, f));
    }
    out
}

#[test]
fn features_of_fixed_crops_match_the_golden_values() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/classify_features.txt");
    let now = current();
    if std::env::var_os("STATURE_BLESS").is_some() {
        std::fs::write(&path, &now).unwrap();
    }
    let golden = std::fs::read_to_string(&path).expect("golden file (STATURE_BLESS=1 to create)");
    assert_eq!(now, golden, "feature vectors changed");
    // The golden figure crop is not trivial: both parts carry signal.
    let layout = Layout::default_layout();
    let mut ex = Extractor::new(&layout);
    let img = synthetic();
    let f = ex
        .extract(Plane::new(&img, 96, 160).unwrap(), &crops()[0].1)
        .unwrap()
        .to_vec();
    let (hd, cd) = (layout.hog_dim(), layout.hog_dim() + layout.coarse_dim());
    let ld = cd + layout.lbp_dim();
    assert!(f[..hd].iter().filter(|&&v| v > 100).count() > 50);
    assert!(f[hd..cd].iter().filter(|&&v| v > 100).count() > 20);
    assert!(f[cd..ld].iter().filter(|&&v| v > 100).count() > 32);
    // A tall narrow box: all of the shape vote in the narrowest two bins.
    assert_eq!(f[ld..].iter().map(|&v| u32::from(v)).sum::<u32>(), 255);
    assert_eq!(f[ld + 2..].iter().map(|&v| u32::from(v)).sum::<u32>(), 0);
}

#[test]
fn builtin_weights_match_this_build() {
    let m = Model::from_bytes(BUILTIN_WEIGHTS).expect("built-in weights load");
    assert_eq!(m.layout.win_w, 32);
    assert_eq!(m.weights.len(), m.layout.dim());
}

/// Re-seals a blob after editing its body (new CRC), so the checks past
/// the checksum are reached.
fn reseal(mut b: Vec<u8>) -> Vec<u8> {
    let n = b.len() - 4;
    let crc = crc32fast::hash(&b[..n]);
    b[n..].copy_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn corrupt_blobs_are_refused_with_the_reason() {
    let good = BUILTIN_WEIGHTS.to_vec();
    let err = |b: &[u8]| Model::from_bytes(b).unwrap_err();

    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x01;
    assert!(matches!(err(&flipped), WeightsError::Checksum { .. }));

    assert!(matches!(
        err(&good[..good.len() - 1]),
        WeightsError::Truncated { .. }
    ));
    assert!(matches!(err(&good[..20]), WeightsError::Truncated { .. }));
    assert!(matches!(err(&[]), WeightsError::Truncated { .. }));

    let mut magic = good.clone();
    magic[0] = b'X';
    assert_eq!(err(&magic), WeightsError::BadMagic);

    let mut longer = good.clone();
    longer.push(0);
    assert!(matches!(err(&longer), WeightsError::TrailingBytes { .. }));

    let mut version = good.clone();
    version[8] = 9;
    assert_eq!(err(&version), WeightsError::UnsupportedVersion(9));

    // A header edited consistently (CRC fixed) but for another window:
    // the stored layout hash no longer matches.
    let mut window = good.clone();
    window[18] = 96;
    let e = err(&reseal(window));
    assert!(
        matches!(e, WeightsError::LayoutHash { .. } | WeightsError::Layout(_)),
        "{e:?}"
    );

    let mut hash = good.clone();
    hash[36] ^= 0xff;
    assert!(matches!(
        err(&reseal(hash)),
        WeightsError::LayoutHash { .. }
    ));

    let mut fv = good.clone();
    fv[32] = fv[32].wrapping_add(1);
    assert!(matches!(
        err(&reseal(fv)),
        WeightsError::FeatureVersion { .. }
    ));

    let mut scale = good.clone();
    scale[48..52].copy_from_slice(&f32::NAN.to_le_bytes());
    assert_eq!(err(&reseal(scale)), WeightsError::BadNumber("scale"));

    let mut wt = good.clone();
    wt[30] = 2;
    assert_eq!(err(&reseal(wt)), WeightsError::WeightType(2));

    // Fit code and layout flags this build does not know.
    let mut fit = good.clone();
    fit[27] = 7;
    assert!(matches!(err(&reseal(fit)), WeightsError::Layout(_)));
    let mut flags = good.clone();
    flags[29] |= 0x80;
    assert!(matches!(err(&reseal(flags)), WeightsError::Layout(_)));
    // A consistent header for features without the box-shape bins: the
    // layout hash still holds the truth.
    let mut aspect = good.clone();
    aspect[28] = 0;
    assert!(matches!(
        err(&reseal(aspect)),
        WeightsError::LayoutHash { .. } | WeightsError::Dimension { .. }
    ));
}

#[test]
fn a_blob_of_the_previous_format_is_refused_by_name() {
    // The weights shipped before feature code version 3 (format 1: no fit,
    // box-shape or coarse fields).
    let old = std::fs::read(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/golden/classifier-format1.bin"),
    )
    .unwrap();
    let e = Model::from_bytes(&old).unwrap_err();
    assert_eq!(e, WeightsError::UnsupportedVersion(1));
    let msg = e.to_string();
    assert!(
        msg.contains("version 1") && msg.contains("stature train"),
        "{msg}"
    );
}

#[test]
fn bad_weights_file_stops_the_binary_with_a_clear_message() {
    let dir = crate::common::fresh_dir("classify");
    let path = dir.join("bad.bin");
    let mut b = BUILTIN_WEIGHTS.to_vec();
    b[100] ^= 0x40;
    std::fs::write(&path, &b).unwrap();
    let cfg = ClassifyConfig {
        weights: path.display().to_string(),
        ..Default::default()
    };
    let e = cfg.validate().unwrap_err().to_string();
    assert!(
        e.contains("classify.weights") && e.contains("checksum"),
        "{e}"
    );

    let out = std::process::Command::new(env!("CARGO_BIN_EXE_stature"))
        .args(["run", "--source", "y4m:/nonexistent.y4m", "--weights"])
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(stature::exit::BAD_INPUT));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("checksum"), "{stderr}");

    // A good copy of the built-in blob is accepted from a file.
    std::fs::write(&path, BUILTIN_WEIGHTS).unwrap();
    assert!(cfg.validate().is_ok());
}
