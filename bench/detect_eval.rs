//! Scores the detection stage on PETS 2009 S2.L1 against `gt.csv`, or on
//! a simulated scene against its exact truth (`--sim URI`, scored as in
//! `tests/suite/detect_sim.rs`: walking people ≥ 90 % visible), classifies
//! every miss (`detect_support::Miss`) and optionally dumps overlays
//! (frame, cleaned foreground in red, luma-only foreground dark red, truth
//! boxes green, regions blue) as PNG.
//!
//! ```text
//! cargo run --release --example detect_eval -- [--sim URI] [--frames N] [--warm-up N]
//!     [--set 'key = value']... [--dump 100,200 --out /tmp [--crop x0,y0,x1,y1 --zoom N]]
//! ```
//!
//! With `VERBOSE=1` every miss is printed with its frame, class, truth box
//! and best region.

#[path = "../tests/detect_support/mod.rs"]
mod detect_support;

use detect_support::{classify_miss, Miss, Score};
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
    let mut crop: Option<BBox> = None;
    let mut pixels_on = false;
    let mut zoom = 1usize;
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
            "--crop" => {
                let v: Vec<u16> = val().split(',').map(|s| s.parse().expect("crop")).collect();
                crop = Some(BBox {
                    x0: v[0],
                    y0: v[1],
                    x1: v[2],
                    y1: v[3],
                });
            }
            "--zoom" => zoom = val().parse().expect("zoom"),
            "--sim" => sim = Some(val()),
            "--pixels" => pixels_on = true,
            _ => panic!("unknown option {a}"),
        }
    }
    let cfg = Config::from_toml(&sets)
        .unwrap_or_else(|e| panic!("{e}"))
        .detect;
    // Pixel truth (sim only): the same clip without shadows and without
    // actors (same background, noise and drift).
    let mut px_truth = match (&sim, pixels_on) {
        (Some(u), true) => {
            let sep = if u.contains('?') { '&' } else { '?' };
            Some(Pixels::new(
                SimSource::open_uri(&format!("{u}{sep}shadows=0")).expect("sim scene"),
                SimSource::open_uri(&format!("{u}{sep}shadows=0&empty=1")).expect("sim scene"),
                SimSource::open_uri(&format!("{u}{sep}empty=1")).expect("sim scene"),
            ))
        }
        _ => None,
    };
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
    let mut people: Vec<bool> = Vec::new();
    let mut why = Why::default();
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
        people.clear();
        if let Some(s) = &sim_src {
            detect_support::truth_boxes(s, &mut truth);
            detect_support::scored_people(s, &mut people);
        } else {
            truth.extend(
                boxes_of_frame(&gt, i as u32)
                    .iter()
                    .filter_map(|b| b.clipped(size.width, size.height)),
            );
        }
        if let Some(p) = px_truth.as_mut() {
            p.add(&frame, &det, i >= warm, &truth, &people);
        }
        if i >= warm {
            why.add(i, &truth, &people, &det, out.regions());
            score.add_filtered(&truth, &people, out.regions());
            if i >= 300 {
                late.add_filtered(&truth, &people, out.regions());
            }
        }
        if dump.contains(&i) {
            write_overlay(
                &format!("{out_dir}/detect_{i:04}.png"),
                &frame,
                &det,
                &truth,
                &out,
                crop,
                zoom,
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
    if frames > 300 {
        println!(
        "frames 300..{frames}: isolated {} matched {} ({:.1} %) mean IoU {:.3} false/frame {:.2}",
        late.isolated,
        late.matched,
        100.0 * late.recall(),
        late.mean_iou(),
        late.false_per_frame()
    );
    }
    why.print();
    if let Some(p) = &px_truth {
        p.print();
    }
    println!(
        "slow-path pixels {:.2} %, foreground {:.2} %, shadow {:.2} %",
        100.0 * slow as f64 / px,
        100.0 * fg as f64 / px,
        100.0 * shadow as f64 / px
    );
}

/// Misses by class, with the mean fraction of the truth box that the
/// luma GMM, the chroma term and the cleaned mask marked foreground.
#[derive(Default)]
struct Why {
    n: [u32; 6],
    raw: [f64; 6],
    chroma: [f64; 6],
    clean: [f64; 6],
}

impl Why {
    fn add(
        &mut self,
        frame: u64,
        truth: &[BBox],
        people: &[bool],
        det: &Detector,
        regions: &[stature::detect::Region],
    ) {
        for (i, t) in truth.iter().enumerate() {
            let isolated = truth
                .iter()
                .enumerate()
                .all(|(j, o)| j == i || detect_support::overlap(t, o) == 0);
            if !isolated || !people.get(i).copied().unwrap_or(true) {
                continue;
            }
            let Some(m) = classify_miss(i, truth, regions) else {
                continue;
            };
            let c = Miss::ALL.iter().position(|&x| x == m).unwrap_or(0);
            self.n[c] += 1;
            self.raw[c] += coverage(det.raw_mask(), t);
            self.chroma[c] += coverage(det.chroma_mask(), t);
            self.clean[c] += coverage(det.mask(), t);
            if std::env::var_os("VERBOSE").is_some() {
                let best = regions
                    .iter()
                    .map(|r| (detect_support::iou(t, &r.bbox), r.bbox))
                    .max_by(|a, b| a.0.total_cmp(&b.0));
                println!(
                    "miss frame {frame} {m:?} truth {:?} best {:?} cover raw {:.2} chroma {:.2} clean {:.2}",
                    (t.x0, t.y0, t.x1, t.y1),
                    best.map(|(iou, b)| (b.x0, b.y0, b.x1, b.y1, (iou * 100.0).round() / 100.0)),
                    coverage(det.raw_mask(), t),
                    coverage(det.chroma_mask(), t),
                    coverage(det.mask(), t),
                );
            }
        }
    }

    fn print(&self) {
        let mut line = String::from("misses:");
        for (c, m) in Miss::ALL.iter().enumerate() {
            let n = f64::from(self.n[c].max(1));
            line.push_str(&format!(
                " {m:?} {} (cover raw/chroma/clean {:.2}/{:.2}/{:.2})",
                self.n[c],
                self.raw[c] / n,
                self.chroma[c] / n,
                self.clean[c] / n
            ));
        }
        println!("{line}");
    }
}

/// Pixel-level truth for a sim clip: actor pixels (the shadow-free render
/// differs from the empty one) and shadow-only pixels (the render with
/// shadows differs from the one without), against the detector's masks.
struct Pixels {
    noshadow: SimSource,
    empty: SimSource,
    /// Empty, with the scene's own shadow setting (static shadows of props).
    empty_sh: SimSource,
    f_ns: Frame,
    f_e: Frame,
    f_es: Frame,
    frames: u64,
    actor: u64,
    shadow: u64,
    /// Per mask (raw, chroma, raw|chroma, clean, GMM shadow): actor pixels hit,
    /// shadow pixels hit, other pixels hit.
    hits: [[u64; 3]; 5],
    /// Actor pixels by |ΔY| bin (≤3, ≤6, ≤9, ≤13, ≤20, more) × chroma L1
    /// bin (≤8, ≤16, more), and how many of each the raw|chroma mask had.
    contrast: [[[u64; 2]; 3]; 6],
}

impl Pixels {
    fn new(noshadow: SimSource, empty: SimSource, empty_sh: SimSource) -> Self {
        let size = noshadow.info().size;
        Pixels {
            noshadow,
            empty,
            empty_sh,
            f_ns: Frame::new(size),
            f_e: Frame::new(size),
            f_es: Frame::new(size),
            frames: 0,
            actor: 0,
            shadow: 0,
            hits: [[0; 3]; 5],
            contrast: [[[0; 2]; 3]; 6],
        }
    }

    /// Actor pixels count only inside the boxes of scored people.
    fn add(&mut self, frame: &Frame, det: &Detector, score: bool, truth: &[BBox], people: &[bool]) {
        self.noshadow.next_frame(&mut self.f_ns).expect("frame");
        self.empty.next_frame(&mut self.f_e).expect("frame");
        self.empty_sh.next_frame(&mut self.f_es).expect("frame");
        if !score {
            return;
        }
        self.frames += 1;
        let s = frame.size();
        let (ns, e, es) = (&self.f_ns, &self.f_e, &self.f_es);
        for y in 0..s.height {
            for x in 0..s.width {
                let (i, c) = (y * s.width + x, (y / 2) * s.chroma().width + x / 2);
                let scored = truth.iter().zip(people).any(|(b, &p)| {
                    p && (b.x0 as usize..=b.x1 as usize).contains(&x)
                        && (b.y0 as usize..=b.y1 as usize).contains(&y)
                });
                if ns.y[i] != e.y[i] && !scored {
                    continue;
                }
                let actor = ns.y[i] != e.y[i];
                let shadow = !actor && frame.y[i] != es.y[i];
                let raw = det.raw_mask().get(x, y);
                let chroma = det.chroma_mask().get(x, y);
                let m = [
                    raw,
                    chroma,
                    raw || chroma,
                    det.mask().get(x, y),
                    det.shadow_mask().get(x, y),
                ];
                let kind = if actor {
                    self.actor += 1;
                    0
                } else if shadow {
                    self.shadow += 1;
                    1
                } else {
                    2
                };
                for (h, &on) in self.hits.iter_mut().zip(&m) {
                    h[kind] += u64::from(on);
                }
                if actor {
                    let dy = frame.y[i].abs_diff(es.y[i]);
                    let dc = u32::from(frame.u[c].abs_diff(es.u[c]))
                        + u32::from(frame.v[c].abs_diff(es.v[c]));
                    let by = [3u8, 6, 9, 13, 20]
                        .iter()
                        .position(|&t| dy <= t)
                        .unwrap_or(5);
                    let bc = [8u32, 16].iter().position(|&t| dc <= t).unwrap_or(2);
                    self.contrast[by][bc][0] += 1;
                    self.contrast[by][bc][1] += u64::from(m[2]);
                }
            }
        }
    }

    fn print(&self) {
        let pct = |a: u64, b: u64| 100.0 * a as f64 / b.max(1) as f64;
        println!(
            "pixels: {:.0} actor px/frame (scored people), {:.0} shadow px/frame",
            self.actor as f64 / self.frames.max(1) as f64,
            self.shadow as f64 / self.frames.max(1) as f64
        );
        for (name, h) in ["raw", "chroma", "raw|chroma", "clean", "gmm shadow"]
            .iter()
            .zip(&self.hits)
        {
            println!(
                "  {name:10} actor px found {:5.1} %, shadow px marked {:5.1} %, other px marked {:.0}/frame",
                pct(h[0], self.actor),
                pct(h[1], self.shadow),
                h[2] as f64 / self.frames.max(1) as f64
            );
        }
        println!("  actor px by |dY| (rows) and chroma L1 <=8, <=16, >16 (share of actor px, found by raw|chroma):");
        for (b, row) in ["<=3", "<=6", "<=9", "<=13", "<=20", ">20"]
            .iter()
            .zip(&self.contrast)
        {
            let cells: Vec<String> = row
                .iter()
                .map(|c| {
                    format!(
                        "{:5.1} % ({:3.0} %)",
                        pct(c[0], self.actor),
                        pct(c[1], c[0])
                    )
                })
                .collect();
            println!("  dY {b:5} {}", cells.join("  "));
        }
    }
}

/// Fraction of the box's pixels set in `m`.
fn coverage(m: &stature::detect::morphology::BitMask, b: &BBox) -> f64 {
    let mut n = 0u32;
    for y in b.y0..=b.y1 {
        for x in b.x0..=b.x1 {
            n += u32::from(m.get(x as usize, y as usize));
        }
    }
    f64::from(n) / f64::from(b.width() * b.height())
}

/// Writes two panels side by side: the colour frame, and the overlay (cleaned
/// foreground red, luma-only foreground dark red, chroma-only foreground
/// blue tint, truth green, regions blue); cropped to `crop` and enlarged
/// `zoom` times when given.
fn write_overlay(
    path: &str,
    frame: &Frame,
    det: &Detector,
    truth: &[BBox],
    out: &RegionSet,
    crop: Option<BBox>,
    zoom: usize,
) {
    let (w, h) = (frame.size().width, frame.size().height);
    let mut over = vec![0u8; w * h * 3];
    let mut colour = vec![0u8; w * h * 3];
    let (cb, cr) = (frame.cb(), frame.cr());
    for y in 0..h {
        for x in 0..w {
            let l = frame.y[y * w + x];
            let (u, v) = (
                f64::from(cb.row(y / 2)[x / 2]) - 128.0,
                f64::from(cr.row(y / 2)[x / 2]) - 128.0,
            );
            let lf = f64::from(l);
            let c = |v: f64| v.round().clamp(0.0, 255.0) as u8;
            colour[(y * w + x) * 3..][..3].copy_from_slice(&[
                c(lf + 1.402 * v),
                c(lf - 0.344 * u - 0.714 * v),
                c(lf + 1.772 * u),
            ]);
            let p = &mut over[(y * w + x) * 3..][..3];
            p.copy_from_slice(&[l, l, l]);
            if det.mask().get(x, y) {
                p[0] = 255;
            } else if det.raw_mask().get(x, y) {
                p[0] = 160;
                p[1] = l / 2;
            }
            if det.chroma_mask().get(x, y) && !det.raw_mask().get(x, y) {
                p[2] = 255;
            }
        }
    }
    let mut rect = |b: &BBox, c: [u8; 3]| {
        for x in b.x0..=b.x1 {
            for y in [b.y0, b.y1] {
                over[(y as usize * w + x as usize) * 3..][..3].copy_from_slice(&c);
            }
        }
        for y in b.y0..=b.y1 {
            for x in [b.x0, b.x1] {
                over[(y as usize * w + x as usize) * 3..][..3].copy_from_slice(&c);
            }
        }
    };
    for t in truth {
        rect(t, [0, 255, 0]);
    }
    for r in out.regions() {
        rect(&r.bbox, [0, 128, 255]);
    }
    let c = crop.unwrap_or(BBox {
        x0: 0,
        y0: 0,
        x1: (w - 1) as u16,
        y1: (h - 1) as u16,
    });
    let (cw, ch) = (c.width() as usize * zoom, c.height() as usize * zoom);
    let mut rgb = vec![0u8; 2 * cw * ch * 3];
    for y in 0..ch {
        for x in 0..2 * cw {
            let (panel, px) = if x < cw {
                (&colour, x)
            } else {
                (&over, x - cw)
            };
            let sx = (c.x0 as usize + px / zoom).min(w - 1);
            let sy = (c.y0 as usize + y / zoom).min(h - 1);
            rgb[(y * 2 * cw + x) * 3..][..3].copy_from_slice(&panel[(sy * w + sx) * 3..][..3]);
        }
    }
    let file = std::fs::File::create(path).expect("create png");
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), 2 * cw as u32, ch as u32);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.write_header()
        .expect("png")
        .write_image_data(&rgb)
        .expect("png");
    println!("wrote {path}");
}
