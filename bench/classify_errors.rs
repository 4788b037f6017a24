//! Error analysis of a classifier on the held-out regions: accuracy per
//! source, kind, box height and box aspect, and mosaics of the wrongly
//! classified windows (what the SVM saw) for looking at.
//!
//! ```text
//! cargo run --release --example classify_errors -- [WEIGHTS|-] [OUT_DIR]
//! ```
//!
//! Writes `OUT_DIR/errors-<source>-<kind>.png` (default `target/classify-errors`):
//! each tile is the bordered window, grey, with a bar under it as long as
//! the score is far from 0 (green: accepted as a single person, red:
//! rejected); and `OUT_DIR/scores.csv`, every held-out box with its score.

use stature::classify::eval;
use stature::classify::samples::{self, Kind, Origin};
use stature::classify::{Classifier, ClassifyConfig, Extractor};
use stature::detect::BBox;
use std::collections::BTreeMap;
use std::path::PathBuf;

struct Row {
    frame: u32,
    origin: Origin,
    scene: &'static str,
    kind: Kind,
    bbox: BBox,
    score: f32,
    win: Vec<u8>,
}

fn main() {
    let mut args = std::env::args().skip(1).filter(|a| !a.starts_with("--"));
    let weights = args.next().filter(|w| w != "-").unwrap_or_default();
    let out: PathBuf = args
        .next()
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target/classify-errors"));
    let cfg = ClassifyConfig {
        weights,
        min_height: 8,
        ..Default::default()
    };
    let model = Classifier::new(&cfg)
        .unwrap_or_else(|e| {
            eprintln!("{e}");
            std::process::exit(2)
        })
        .model()
        .clone();
    let mut cls = eval::scorer(&model);
    let mut ex = Extractor::new(&model.layout);
    let mut rows: Vec<Row> = Vec::new();
    let detection = samples::Detection {
        mask: model.layout.mask_fill,
        label: false,
    };
    let mut score = |origin,
                     scene,
                     frame,
                     luma: stature::frame::Plane<'_>,
                     mask: Option<&stature::detect::morphology::BitMask>,
                     boxes: &[samples::Labelled]| {
        for s in boxes {
            let v = cls.classify_box_masked(luma, mask, &s.bbox);
            let win = if ex.extract(luma, &s.bbox).is_some() {
                ex.window().to_vec()
            } else {
                Vec::new()
            };
            rows.push(Row {
                frame,
                origin,
                scene,
                kind: s.kind,
                bbox: s.bbox,
                score: v.score,
                win,
            });
        }
    };
    let data = stature::dataset::shared_data_dir().expect("../shared/data");
    eval::for_held_out_pets(&data, 1, detection, |f, luma, mask, boxes| {
        score(Origin::Pets, "pets", f, luma, mask, boxes)
    })
    .unwrap();
    eval::for_held_out_sim(1, detection, |scene, f, luma, mask, boxes| {
        score(Origin::Sim, scene, f as u32, luma, mask, boxes)
    })
    .unwrap();
    let right = |r: &Row| r.kind.positive() == (r.score > 0.0);
    // Every scored box, for analysis elsewhere.
    let mut csv = String::from("source,scene,kind,frame,x0,y0,x1,y1,score\n");
    for r in &rows {
        csv.push_str(&format!(
            "{},{},{},{},{},{},{},{},{:.3}\n",
            r.origin.name(),
            r.scene,
            r.kind.name(),
            r.frame,
            r.bbox.x0,
            r.bbox.y0,
            r.bbox.x1,
            r.bbox.y1,
            r.score
        ));
    }
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("scores.csv"), csv).unwrap();
    // Accuracy by (source, kind) and a bucket of the box.
    let report = |title: &str, bucket: &dyn Fn(&Row) -> String| {
        println!("\n## by {title}");
        let mut m: BTreeMap<(String, String, String), (usize, usize)> = BTreeMap::new();
        for r in &rows {
            let e = m
                .entry((r.origin.name().into(), r.kind.name().into(), bucket(r)))
                .or_default();
            e.0 += 1;
            e.1 += usize::from(right(r));
        }
        for ((o, k, b), (n, ok)) in m {
            println!(
                "{o:<10} {k:<10} {b:<14} {n:>5} {:>6.1} %",
                ok as f64 * 100.0 / n as f64
            );
        }
    };
    report("box height", &|r| {
        let h = r.bbox.height();
        match h {
            0..=23 => "h<24",
            24..=39 => "h24-39",
            40..=63 => "h40-63",
            64..=99 => "h64-99",
            _ => "h100+",
        }
        .into()
    });
    report("aspect w/h", &|r| {
        let a = f64::from(r.bbox.width()) / f64::from(r.bbox.height());
        format!("a{:.1}", (a * 5.0).floor() / 5.0)
    });
    report("sim scene", &|r| r.scene.into());
    // Mosaics of the errors.
    std::fs::create_dir_all(&out).unwrap();
    let layout = model.layout.clone();
    let (tw, th) = (usize::from(layout.win_w) + 2, usize::from(layout.win_h) + 2);
    for o in [Origin::Pets, Origin::Sim] {
        for k in Kind::ALL {
            let bad: Vec<&Row> = rows
                .iter()
                .filter(|r| r.origin == o && r.kind == k && !right(r) && !r.win.is_empty())
                .take(400)
                .collect();
            if bad.is_empty() {
                continue;
            }
            let cols = 20usize;
            let nrows = bad.len().div_ceil(cols);
            let (cw, ch) = (tw + 2, th + 6);
            let (w, h) = (cols * cw, nrows * ch);
            let mut rgb = vec![0u8; w * h * 3];
            for (i, r) in bad.iter().enumerate() {
                let (ox, oy) = ((i % cols) * cw, (i / cols) * ch);
                for y in 0..th {
                    for x in 0..tw {
                        let v = r.win[y * tw + x];
                        let p = ((oy + y) * w + ox + x) * 3;
                        rgb[p..p + 3].copy_from_slice(&[v, v, v]);
                    }
                }
                // Score bar: length ∝ |score|, green accepted, red rejected.
                let len = ((r.score.abs() * 10.0) as usize).min(tw);
                for y in th + 1..th + 4 {
                    for x in 0..len {
                        let p = ((oy + y) * w + ox + x) * 3;
                        let c = if r.score > 0.0 {
                            [0, 255, 0]
                        } else {
                            [255, 0, 0]
                        };
                        rgb[p..p + 3].copy_from_slice(&c);
                    }
                }
            }
            let path = out.join(format!(
                "errors-{}-{}.png",
                if o == Origin::Pets { "pets" } else { "sim" },
                k.name()
            ));
            let f = std::fs::File::create(&path).unwrap();
            stature::source::sim::export::write_png(std::io::BufWriter::new(f), &rgb, w, h)
                .unwrap();
            println!("{}: {} errors", path.display(), bad.len());
        }
    }
}
