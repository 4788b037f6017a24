//! Scores the detection stage on PETS 2009 S2.L1 against `gt.csv` and
//! optionally dumps overlays (frame, foreground in red, truth boxes green,
//! regions blue) as PNG.
//!
//! ```text
//! cargo run --release --example detect_eval -- [--frames N] [--warm-up N]
//!     [--set 'key = value']... [--dump 100,200 --out /tmp]
//! ```

#[path = "../tests/detect_support/mod.rs"]
mod detect_support;

use detect_support::Score;
use stature::config::Config;
use stature::dataset::{boxes_of_frame, load_pets_gt, pets_video, shared_data_dir};
use stature::detect::{BBox, Detector, RegionSet};
use stature::frame::Frame;
use stature::source::sim::SimSource;
use stature::source::{FrameSource, Next};

fn main() {
    let mut frames = 795u64;
    let mut warm = 50u64;
    let mut sets = String::from("[detect]\n");
    let mut dump: Vec<u64> = Vec::new();
    let mut out_dir = String::from("/tmp");
    let mut sim: Option<String> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut val = || args.next().expect("option value");
        match a.as_str() {
            "--frames" => frames = val().parse().expect("frames"),
            "--warm-up" => warm = val().parse().expect("warm-up"),
            "--set" => {
                sets.push_str(&val());
                sets.push('\n');
            }
            "--dump" => {
                dump = val()
                    .split(',')
                    .map(|s| s.parse().expect("frame"))
                    .collect()
            }
            "--out" => out_dir = val(),
            "--sim" => sim = Some(val()),
            _ => panic!("unknown option {a}"),
        }
    }
    let cfg = Config::from_toml(&sets)
        .unwrap_or_else(|e| panic!("{e}"))
        .detect;
    let mut sim_src = sim.map(|u| SimSource::open_uri(&u).expect("sim scene"));
    let (gt, mut pets) = if sim_src.is_some() {
        (Vec::new(), None)
    } else {
        let dir = shared_data_dir().expect("../shared/data");
        (
            load_pets_gt(&dir).expect("gt"),
            Some(pets_video(&dir).expect("video")),
        )
    };
    fn pick<'a>(
        sim: &'a mut Option<SimSource>,
        pets: &'a mut Option<stature::source::y4m::Y4mSource>,
    ) -> &'a mut dyn FrameSource {
        match (sim, pets) {
            (Some(s), _) => s,
            (None, Some(p)) => p,
            _ => unreachable!("one source is open"),
        }
    }
    let size = pick(&mut sim_src, &mut pets).info().size;
    let mut frame = Frame::new(size);
    let mut det = Detector::new(&cfg, size);
    let mut out = RegionSet::with_capacity(cfg.region_capacity(), cfg.run_capacity(size));
    let mut score = Score::default();
    let mut late = Score::default();
    let (mut slow, mut fg, mut shadow) = (0u64, 0u64, 0u64);
    let mut truth: Vec<BBox> = Vec::new();
    let mut why = [0u32; 6];
    for i in 0..frames {
        if pick(&mut sim_src, &mut pets)
            .next_frame(&mut frame)
            .expect("frame")
            != Next::Frame
        {
            break;
        }
        det.process(&frame, &mut out);
        let st = det.stats();
        slow += u64::from(st.slow_pixels);
        fg += u64::from(st.foreground);
        shadow += u64::from(st.shadow);
        truth.clear();
        if let Some(s) = &sim_src {
            detect_support::truth_boxes(s, &mut truth);
        } else {
            truth.extend(
                boxes_of_frame(&gt, i as u32)
                    .iter()
                    .filter_map(|b| b.clipped(size.width, size.height)),
            );
        }
        if i >= warm {
            diagnose(&truth, out.regions(), &mut why);
            score.add(&truth, out.regions());
            if i >= 300 {
                late.add(&truth, out.regions());
            }
        }
        if dump.contains(&i) {
            write_overlay(
                &format!("{out_dir}/detect_{i:04}.png"),
                &frame,
                &det,
                &truth,
                &out,
            );
        }
    }
    let px = (size.pixels() as u64 * frames) as f64;
    println!(
        "frames {warm}..{frames}: isolated {} matched {} ({:.1} %) mean IoU {:.3} false/frame {:.2} regions/frame {:.2}",
        score.isolated,
        score.matched,
        100.0 * score.recall(),
        score.mean_iou(),
        score.false_per_frame(),
        f64::from(score.regions) / f64::from(score.frames.max(1))
    );
    println!(
        "frames 300..{frames}: isolated {} matched {} ({:.1} %) mean IoU {:.3} false/frame {:.2}",
        late.isolated,
        late.matched,
        100.0 * late.recall(),
        late.mean_iou(),
        late.false_per_frame()
    );
    println!(
        "misses: none {} | too small (split/partial) {} | too tall {} | too wide {} | offset {} | other {}",
        why[0], why[1], why[2], why[3], why[4], why[5]
    );
    println!(
        "slow-path pixels {:.2} %, foreground {:.2} %, shadow {:.2} %",
        100.0 * slow as f64 / px,
        100.0 * fg as f64 / px,
        100.0 * shadow as f64 / px
    );
}

/// Why isolated truth boxes were missed: no region, best region much
/// smaller, taller, wider, shifted, or else.
fn diagnose(truth: &[BBox], regions: &[stature::detect::Region], why: &mut [u32; 6]) {
    for (i, t) in truth.iter().enumerate() {
        if truth
            .iter()
            .enumerate()
            .any(|(j, o)| j != i && detect_support::overlap(t, o) > 0)
        {
            continue;
        }
        let best = regions.iter().max_by(|a, b| {
            detect_support::iou(t, &a.bbox).total_cmp(&detect_support::iou(t, &b.bbox))
        });
        let Some(r) = best else {
            why[0] += 1;
            continue;
        };
        let iou = detect_support::iou(t, &r.bbox);
        if iou >= 0.5 {
            continue;
        }
        let b = r.bbox;
        let (th, tw, rh, rw) = (
            t.height() as f64,
            t.width() as f64,
            b.height() as f64,
            b.width() as f64,
        );
        if iou == 0.0 {
            why[0] += 1;
        } else if rh < 0.75 * th || rw < 0.6 * tw {
            why[1] += 1;
        } else if rh > 1.25 * th {
            why[2] += 1;
        } else if rw > 1.4 * tw {
            why[3] += 1;
        } else if iou > 0.2 {
            why[4] += 1;
        } else {
            why[5] += 1;
        }
        if std::env::var_os("VERBOSE").is_some() {
            println!("miss truth {t:?} region {b:?} iou {iou:.2}");
        }
    }
}

fn write_overlay(path: &str, frame: &Frame, det: &Detector, truth: &[BBox], out: &RegionSet) {
    let (w, h) = (frame.size().width, frame.size().height);
    let mut rgb = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            let l = frame.y[y * w + x];
            let p = &mut rgb[(y * w + x) * 3..][..3];
            p.copy_from_slice(&[l, l, l]);
            if det.mask().get(x, y) {
                p[0] = 255;
            } else if det.raw_mask().get(x, y) {
                p[0] = 160;
                p[1] = l / 2;
            }
        }
    }
    let mut rect = |b: &BBox, c: [u8; 3]| {
        for x in b.x0..=b.x1 {
            for y in [b.y0, b.y1] {
                rgb[(y as usize * w + x as usize) * 3..][..3].copy_from_slice(&c);
            }
        }
        for y in b.y0..=b.y1 {
            for x in [b.x0, b.x1] {
                rgb[(y as usize * w + x as usize) * 3..][..3].copy_from_slice(&c);
            }
        }
    };
    for t in truth {
        rect(t, [0, 255, 0]);
    }
    for r in out.regions() {
        rect(&r.bbox, [0, 128, 255]);
    }
    let file = std::fs::File::create(path).expect("create png");
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w as u32, h as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .expect("png")
        .write_image_data(&rgb)
        .expect("png");
    println!("wrote {path}");
}
