//! Labelled boxes for training and evaluation (host side, never in the loop).
//!
//! * MIT CBCL crops: each 64×128 crop becomes one positive whose box is
//!   placed so that the window covers the whole crop ([`mit_person_box`]),
//!   plus its mirror image, plus one fragment negative (top or bottom part
//!   of the person).
//! * PETS 2009 S2.L1 frames, from the ground-truth boxes
//!   ([`pets_frame_samples`]): clean single people (inside the image, at
//!   most [`CLEAN_OCCLUSION`] of the box covered by other people) with box
//!   jitter as positives; background boxes away from people, union boxes of
//!   two nearby people, and fragments of clean people as negatives. People
//!   partly hidden by others are left out of both classes (ambiguous).
//!
//! Everything is drawn from a seeded [`Rng`], so a run is reproducible.

use crate::dataset::GtBox;
use crate::detect::morphology::BitMask;
use crate::detect::{BBox, DetectConfig, Detector, Region, RegionSet};
use crate::frame::{Frame, Plane, Size};
use std::path::Path;

/// SplitMix64: small, fast and good enough for sampling boxes.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9e37_79b9_7f4a_7c15)
    }
    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniform integer in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    /// Shuffles a slice (Fisher–Yates).
    pub fn shuffle<T>(&mut self, v: &mut [T]) {
        for i in (1..v.len()).rev() {
            v.swap(i, self.below(i + 1));
        }
    }
}

/// What a labelled box shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Kind {
    /// Exactly one upright person (the positive class).
    Person,
    /// No object.
    Background,
    /// Two or more people merged into one box.
    Group,
    /// Part of one person.
    Fragment,
    /// A car (simulated scenes).
    Car,
    /// A dog (simulated scenes).
    Dog,
}

impl Kind {
    /// True for the "single human" class.
    pub fn positive(self) -> bool {
        self == Kind::Person
    }
    /// Lower-case name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Person => "person",
            Kind::Background => "background",
            Kind::Group => "group",
            Kind::Fragment => "fragment",
            Kind::Car => "car",
            Kind::Dog => "dog",
        }
    }
    /// Every kind, in report order.
    pub const ALL: [Kind; 6] = [
        Kind::Person,
        Kind::Background,
        Kind::Group,
        Kind::Fragment,
        Kind::Car,
        Kind::Dog,
    ];
}

/// Where a sample came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Origin {
    /// MIT CBCL pedestrian crops.
    Mit,
    /// PETS 2009 S2.L1 video.
    Pets,
    /// The built-in simulated scene.
    Sim,
}

impl Origin {
    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Origin::Mit => "MIT CBCL",
            Origin::Pets => "PETS S2.L1",
            Origin::Sim => "sim",
        }
    }
}

/// Share of a person box that other people may cover for it to count as a
/// clean single person (more than that: ambiguous, left out).
pub const CLEAN_OCCLUSION: f64 = 0.15;

/// A float box `[x0, y0, x1, y1]`, inclusive pixel edges as in `gt.csv`.
pub type FBox = [f64; 4];

fn area(b: &FBox) -> f64 {
    (b[2] - b[0] + 1.0).max(0.0) * (b[3] - b[1] + 1.0).max(0.0)
}

fn inter(a: &FBox, b: &FBox) -> f64 {
    let w = a[2].min(b[2]) - a[0].max(b[0]) + 1.0;
    let h = a[3].min(b[3]) - a[1].max(b[1]) + 1.0;
    if w <= 0.0 || h <= 0.0 {
        0.0
    } else {
        w * h
    }
}

/// Share of `a` covered by `b`.
pub fn coverage(a: &FBox, b: &FBox) -> f64 {
    inter(a, b) / area(a).max(1.0)
}

/// Rounds a float box to a [`BBox`] inside a `w`×`h` image; `None` when
/// less than 8 px remain in either direction.
pub fn to_bbox(b: &FBox, w: usize, h: usize) -> Option<BBox> {
    let x0 = b[0].round().max(0.0);
    let y0 = b[1].round().max(0.0);
    let x1 = b[2].round().min(w as f64 - 1.0);
    let y1 = b[3].round().min(h as f64 - 1.0);
    (x1 - x0 >= 7.0 && y1 - y0 >= 7.0).then_some(BBox {
        x0: x0 as u16,
        y0: y0 as u16,
        x1: x1 as u16,
        y1: y1 as u16,
    })
}

fn gt_fbox(g: &GtBox) -> FBox {
    [
        f64::from(g.x0),
        f64::from(g.y0),
        f64::from(g.x1),
        f64::from(g.y1),
    ]
}

/// A box of one frame with its label.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Labelled {
    /// What it shows.
    pub kind: Kind,
    /// The box.
    pub bbox: BBox,
    /// One of the detector's own regions ([`detected_labels`]), not a box
    /// drawn from the truth.
    pub detected: bool,
}

/// How many negatives of each kind to draw per frame.
#[derive(Clone, Copy, Debug)]
pub struct PerFrame {
    /// Jittered copies of each clean person.
    pub persons: usize,
    /// Background boxes.
    pub background: usize,
    /// Fragments (of randomly chosen clean people).
    pub fragments: usize,
    /// Take every qualifying pair of people as a group box (else none).
    pub groups: bool,
}

/// Jitter of a detected box around the true one: centre ±6 % of width and
/// ±4 % of height, height ×0.93..1.07, width ×0.85..1.2 (a detector's
/// silhouette box is looser at the sides than at head and feet).
pub fn jitter(b: &FBox, rng: &mut Rng) -> FBox {
    let (w, h) = (b[2] - b[0] + 1.0, b[3] - b[1] + 1.0);
    let cx = (b[0] + b[2]) / 2.0 + rng.range(-0.06, 0.06) * w;
    let cy = (b[1] + b[3]) / 2.0 + rng.range(-0.04, 0.04) * h;
    let nh = h * rng.range(0.93, 1.07);
    let nw = w * rng.range(0.85, 1.2);
    [
        cx - (nw - 1.0) / 2.0,
        cy - (nh - 1.0) / 2.0,
        cx + (nw - 1.0) / 2.0,
        cy + (nh - 1.0) / 2.0,
    ]
}

/// A random fragment of a person box: a top, bottom or middle band (how a
/// silhouette splits when clothing matches the background). Left or right
/// parts are not used: the window's width follows the box height, so such a
/// window still shows most of the person, only off-centre.
pub fn fragment(b: &FBox, rng: &mut Rng) -> FBox {
    let h = b[3] - b[1] + 1.0;
    match rng.below(3) {
        0 => [b[0], b[1], b[2], b[1] + h * rng.range(0.25, 0.6)],
        1 => [b[0], b[3] - h * rng.range(0.3, 0.6), b[2], b[3]],
        _ => {
            let t = b[1] + h * rng.range(0.15, 0.3);
            [b[0], t, b[2], t + h * rng.range(0.3, 0.45)]
        }
    }
}

/// [`detected_labels`] for one PETS frame's regions against its
/// ground-truth boxes (no props, no animals), `w`×`h` image.
pub fn pets_detected_labels(
    regions: &[Region],
    gt: &[GtBox],
    w: usize,
    h: usize,
    out: &mut Vec<Labelled>,
) {
    if regions.is_empty() {
        return;
    }
    let people: Vec<FBox> = gt.iter().map(gt_fbox).collect();
    let hidden = vec![false; people.len()];
    detected_labels(regions, &people, &hidden, &[], w, h, out);
}

/// Labelled boxes of one PETS frame (see the module doc), `w`×`h` image.
pub fn pets_frame_samples(
    gt: &[GtBox],
    w: usize,
    h: usize,
    per: PerFrame,
    rng: &mut Rng,
    out: &mut Vec<Labelled>,
) {
    let boxes: Vec<FBox> = gt.iter().map(gt_fbox).collect();
    let hidden = vec![false; boxes.len()];
    frame_samples(&boxes, &hidden, &[], w, h, per, rng, out);
}

/// Labelled boxes of one frame from its people (`boxes`, with `hidden[i]`
/// set for a person partly hidden by something other than people, e.g. a
/// prop) and other objects (`others`, kept clear of background boxes).
#[allow(clippy::too_many_arguments)]
pub fn frame_samples(
    boxes: &[FBox],
    hidden: &[bool],
    others: &[FBox],
    w: usize,
    h: usize,
    per: PerFrame,
    rng: &mut Rng,
    out: &mut Vec<Labelled>,
) {
    let inside =
        |b: &FBox| b[0] >= 2.0 && b[1] >= 2.0 && b[2] <= w as f64 - 3.0 && b[3] <= h as f64 - 3.0;
    let occlusion = |i: usize| -> f64 {
        boxes
            .iter()
            .enumerate()
            .filter(|&(j, _)| j != i)
            .map(|(_, o)| coverage(&boxes[i], o))
            .sum::<f64>()
            .min(1.0)
    };
    let clean: Vec<usize> = (0..boxes.len())
        .filter(|&i| inside(&boxes[i]) && !hidden[i] && occlusion(i) <= CLEAN_OCCLUSION)
        .collect();
    let mut push = |kind: Kind, b: &FBox| {
        if let Some(bbox) = to_bbox(b, w, h) {
            out.push(Labelled {
                kind,
                bbox,
                detected: false,
            });
        }
    };
    for &i in &clean {
        for _ in 0..per.persons {
            push(Kind::Person, &jitter(&boxes[i], rng));
        }
    }
    if !clean.is_empty() {
        for _ in 0..per.fragments {
            let i = clean[rng.below(clean.len())];
            push(Kind::Fragment, &fragment(&boxes[i], rng));
        }
    }
    if per.groups {
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                let (a, b) = (&boxes[i], &boxes[j]);
                if !inside(a) || !inside(b) {
                    continue;
                }
                let (wa, wb) = (a[2] - a[0] + 1.0, b[2] - b[0] + 1.0);
                let gap = a[0].max(b[0]) - a[2].min(b[2]) - 1.0;
                let v_overlap = a[3].min(b[3]) - a[1].max(b[1]) + 1.0;
                let hmin = (a[3] - a[1]).min(b[3] - b[1]) + 1.0;
                // Near enough to merge into one foreground region, and not
                // one hidden behind the other (that looks like one person).
                let near = gap < 0.5 * wa.min(wb) && v_overlap > 0.3 * hmin;
                let distinct = coverage(a, b) < 0.6 && coverage(b, a) < 0.6;
                if near && distinct {
                    let u = [
                        a[0].min(b[0]),
                        a[1].min(b[1]),
                        a[2].max(b[2]),
                        a[3].max(b[3]),
                    ];
                    // A little jitter, as for people.
                    let uj = jitter(&u, rng);
                    push(Kind::Group, &uj);
                }
            }
        }
    }
    if !boxes.is_empty() {
        let mut tries = 0;
        let mut made = 0;
        while made < per.background && tries < per.background * 20 {
            tries += 1;
            let r = &boxes[rng.below(boxes.len())];
            let bh = (r[3] - r[1] + 1.0) * rng.range(0.5, 1.5);
            let bw = bh * rng.range(0.25, 1.2);
            if bw >= w as f64 - 4.0 || bh >= h as f64 - 4.0 {
                continue;
            }
            let x0 = rng.range(0.0, w as f64 - bw);
            let y0 = rng.range(0.0, h as f64 - bh);
            let c = [x0, y0, x0 + bw - 1.0, y0 + bh - 1.0];
            // Away from people: little of the box is person, and no person
            // is substantially inside it.
            let clear = boxes
                .iter()
                .chain(others)
                .all(|p| coverage(&c, p) < 0.1 && coverage(p, &c) < 0.2);
            if clear {
                push(Kind::Background, &c);
                made += 1;
            }
        }
    }
}

/// The box in a 64×128 MIT crop whose window (for `margin_q8`, aspect 1:2)
/// is the whole crop: the person is taken as centred and `128 / (1 + 2m)`
/// rows tall, `0.36` of that wide (the median PETS aspect).
pub fn mit_person_box(margin_q8: u16) -> FBox {
    let h = 128.0 / (1.0 + 2.0 * f64::from(margin_q8) / 256.0);
    let w = (h * 0.36).round();
    [
        31.5 - (w - 1.0) / 2.0,
        63.5 - (h - 1.0) / 2.0,
        31.5 + (w - 1.0) / 2.0,
        63.5 + (h - 1.0) / 2.0,
    ]
}

/// Reads one MIT crop as BT.601 limited-range luma (like the decoded video),
/// optionally mirrored left-right.
pub fn read_png_luma(path: &Path, mirror: bool) -> Result<(Vec<u8>, usize, usize), String> {
    let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut dec = png::Decoder::new(file);
    dec.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = dec
        .read_info()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let (w, h) = (info.width as usize, info.height as usize);
    let ch = match info.color_type {
        png::ColorType::Rgb => 3,
        png::ColorType::Rgba => 4,
        png::ColorType::Grayscale => 1,
        png::ColorType::GrayscaleAlpha => 2,
        png::ColorType::Indexed => return Err(format!("{}: indexed PNG", path.display())),
    };
    let mut y = vec![0u8; w * h];
    for row in 0..h {
        for col in 0..w {
            let p = &buf[(row * w + col) * ch..];
            let v = if ch >= 3 {
                // BT.601 limited range, Q8 coefficients.
                (16.0
                    + (65.738 * f64::from(p[0])
                        + 129.057 * f64::from(p[1])
                        + 25.064 * f64::from(p[2]))
                        / 256.0)
                    .round()
            } else {
                16.0 + f64::from(p[0]) * 219.0 / 255.0
            };
            let dst = if mirror { w - 1 - col } else { col };
            y[row * w + dst] = v.clamp(0.0, 255.0) as u8;
        }
    }
    Ok((y, w, h))
}

/// The MIT crop files, sorted, with the known pixel duplicates left out.
pub fn mit_files(data_dir: &Path) -> Result<Vec<std::path::PathBuf>, String> {
    let dir = data_dir.join("mit-cbcl-pedestrians");
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    v.sort();
    // per00002 = per00001, per00022 = per00021, per00026/27 = per00025.
    v.retain(|p| {
        let n = p.file_name().and_then(|s| s.to_str()).unwrap_or("");
        !matches!(
            n,
            "per00002.png" | "per00022.png" | "per00026.png" | "per00027.png"
        )
    });
    Ok(v)
}

/// Borrow a tightly packed luma buffer as a plane.
pub fn plane(data: &[u8], w: usize, h: usize) -> Option<Plane<'_>> {
    Plane::new(data, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detected_regions_are_labelled_by_what_they_hold() {
        let region = |x0, y0, x1, y1| Region {
            bbox: BBox { x0, y0, x1, y1 },
            ..Default::default()
        };
        // Two people side by side, one apart, one hidden by a prop, a dog.
        let people = [
            [100.0, 100.0, 129.0, 189.0],
            [132.0, 102.0, 160.0, 190.0],
            [300.0, 100.0, 329.0, 189.0],
            [500.0, 100.0, 529.0, 189.0],
        ];
        let hidden = [false, false, false, true];
        let others = [(Kind::Dog, [400.0, 170.0, 440.0, 189.0])];
        let regions = [
            region(100, 100, 160, 190), // both neighbours: a group
            region(301, 98, 331, 190),  // the lone person, a loose box
            region(300, 100, 329, 130), // the lone person's head and chest
            region(402, 168, 439, 189), // the dog
            region(600, 300, 630, 350), // nothing there: a ghost
            region(500, 100, 529, 189), // the hidden person: ambiguous
            region(295, 95, 340, 240),  // the lone person and a long shadow: IoU < 0.5
            region(100, 100, 134, 189), // one neighbour and a sliver of the other
        ];
        let mut out = Vec::new();
        detected_labels(&regions, &people, &hidden, &others, 768, 576, &mut out);
        let kinds: Vec<(Kind, u16)> = out.iter().map(|l| (l.kind, l.bbox.x0)).collect();
        assert_eq!(
            kinds,
            [
                (Kind::Group, 100),
                (Kind::Person, 301),
                (Kind::Fragment, 300),
                (Kind::Dog, 402),
                (Kind::Background, 600),
                (Kind::Person, 100),
            ]
        );
    }

    fn gt(id: u32, x0: i32, y0: i32, x1: i32, y1: i32) -> GtBox {
        GtBox {
            frame: 0,
            id,
            x0,
            y0,
            x1,
            y1,
        }
    }

    #[test]
    fn frame_samples_respect_the_rules() {
        let boxes = [
            gt(1, 100, 100, 130, 180),
            gt(2, 135, 105, 165, 185), // near 1: a group
            gt(3, 400, 300, 430, 380),
            gt(4, 405, 305, 435, 385), // hides most of 3: both ambiguous, no group
        ];
        let mut rng = Rng::new(7);
        let mut out = Vec::new();
        let per = PerFrame {
            persons: 1,
            background: 20,
            fragments: 4,
            groups: true,
        };
        pets_frame_samples(&boxes, 768, 576, per, &mut rng, &mut out);
        let count = |k| out.iter().filter(|s| s.kind == k).count();
        assert_eq!(count(Kind::Person), 2, "{out:?}");
        assert_eq!(count(Kind::Group), 1);
        assert_eq!(count(Kind::Background), 20);
        assert_eq!(count(Kind::Fragment), 4);
        for s in out.iter().filter(|s| s.kind == Kind::Background) {
            let b = [
                f64::from(s.bbox.x0),
                f64::from(s.bbox.y0),
                f64::from(s.bbox.x1),
                f64::from(s.bbox.y1),
            ];
            for g in &boxes {
                assert!(coverage(&b, &gt_fbox(g)) < 0.12);
            }
        }
    }

    #[test]
    fn rng_is_reproducible() {
        let mut a = Rng::new(3);
        let mut b = Rng::new(3);
        assert!((0..100).all(|_| a.next_u64() == b.next_u64()));
        assert_ne!(Rng::new(4).next_u64(), Rng::new(3).next_u64());
    }
}

/// What the sample iterators do with the detector.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Detection {
    /// Run it and hand out its foreground mask (for foreground-fill
    /// features).
    pub mask: bool,
    /// Run it and also label its regions against the truth
    /// ([`detected_labels`]): training samples cut as the loop cuts them.
    pub label: bool,
}

impl Detection {
    /// Whether the detector runs at all.
    pub fn on(self) -> bool {
        self.mask || self.label
    }
}

/// The detector over every frame of a clip (default detection settings, as
/// the loop runs them): its cleaned foreground mask and its regions; does
/// nothing when off.
pub struct ClipDetector {
    detector: Option<(Detector, RegionSet)>,
    label: bool,
}

impl ClipDetector {
    /// A detector for frames of `size` when `use_.on()`.
    pub fn new(use_: Detection, size: Size) -> Self {
        let detector = use_.on().then(|| {
            let cfg = DetectConfig::default();
            let regions = RegionSet::with_capacity(cfg.region_capacity(), cfg.run_capacity(size));
            (Detector::new(&cfg, size), regions)
        });
        ClipDetector {
            detector,
            label: use_.label,
        }
    }
    /// Feeds the next frame of the clip (every frame, in order).
    pub fn update(&mut self, frame: &Frame) {
        if let Some((d, regions)) = self.detector.as_mut() {
            d.process(frame, regions);
        }
    }
    /// The last frame's foreground mask, or `None` when off.
    pub fn mask(&self) -> Option<&BitMask> {
        self.detector.as_ref().map(|(d, _)| d.mask())
    }
    /// The last frame's regions when labelling is on, else none.
    pub fn labelled_regions(&self) -> &[Region] {
        match &self.detector {
            Some((_, r)) if self.label => r.regions(),
            _ => &[],
        }
    }
}

/// Labels the detector's regions of one frame against its true boxes:
/// `people` (with `hidden[i]` for a person partly hidden by a prop) and
/// `others` (cars, dogs). A region holding at least half of two people is
/// a group; one whose box matches one clean, unoccluded person (IoU ≥ 0.5,
/// under 0.2 of any other person inside) is a person; one lying at least
/// 0.7 inside a person's box but holding under half of anyone is a
/// fragment; one matching a car or dog (half of each inside the other) is
/// that; one touching nothing (under 0.1 of it on any true box) is
/// background. Everything else is ambiguous and left out. `w`×`h` image.
pub fn detected_labels(
    regions: &[Region],
    people: &[FBox],
    hidden: &[bool],
    others: &[(Kind, FBox)],
    w: usize,
    h: usize,
    out: &mut Vec<Labelled>,
) {
    let inside =
        |b: &FBox| b[0] >= 2.0 && b[1] >= 2.0 && b[2] <= w as f64 - 3.0 && b[3] <= h as f64 - 3.0;
    for r in regions {
        let b = r.bbox;
        let rb = [
            f64::from(b.x0),
            f64::from(b.y0),
            f64::from(b.x1),
            f64::from(b.y1),
        ];
        let held: Vec<f64> = people.iter().map(|p| coverage(p, &rb)).collect();
        let whole: Vec<usize> = (0..people.len()).filter(|&i| held[i] >= 0.5).collect();
        let kind = match whole.len() {
            0 => {
                let in_person = people.iter().map(|p| coverage(&rb, p)).fold(0.0, f64::max);
                let animal = others
                    .iter()
                    .find(|(_, o)| coverage(o, &rb) >= 0.5 && coverage(&rb, o) >= 0.5);
                let touched = people
                    .iter()
                    .chain(others.iter().map(|(_, o)| o))
                    .map(|o| coverage(&rb, o))
                    .fold(0.0, f64::max);
                if in_person >= 0.7 {
                    Some(Kind::Fragment)
                } else if let Some((k, _)) = animal {
                    Some(*k)
                } else if touched < 0.1 {
                    Some(Kind::Background)
                } else {
                    None
                }
            }
            1 => {
                let i = whole[0];
                let p = &people[i];
                let i_r = inter(p, &rb);
                let iou = i_r / (area(p) + area(&rb) - i_r).max(1.0);
                let others_in: f64 = (0..people.len()).filter(|&j| j != i).map(|j| held[j]).sum();
                (iou >= 0.5 && others_in < 0.2 && !hidden[i] && inside(p)).then_some(Kind::Person)
            }
            _ => Some(Kind::Group),
        };
        if let Some(kind) = kind {
            out.push(Labelled {
                kind,
                bbox: b,
                detected: true,
            });
        }
    }
}

/// Labelled boxes of simulated scenes: [`frame_samples`] on the people in
/// view (a person less than 85 % visible counts as hidden), plus every car
/// and dog at least half visible as a negative of its kind.
pub mod sim {
    use super::*;
    use crate::source::sim::people::Kind as SimKind;
    use crate::source::sim::{ObjectTruth, SimSource};

    fn truth_box(o: &ObjectTruth) -> FBox {
        o.bbox.map(f64::from)
    }

    /// The label kind of a car or dog; `None` for a person.
    fn animal_kind(o: &ObjectTruth) -> Option<Kind> {
        match o.kind {
            SimKind::Person => None,
            SimKind::Car => Some(Kind::Car),
            SimKind::Dog => Some(Kind::Dog),
        }
    }

    /// A car or dog at least half visible as a jittered negative of its
    /// kind; `None` for people and mostly hidden objects.
    fn animal_sample(o: &ObjectTruth, rng: &mut Rng, w: usize, h: usize) -> Option<Labelled> {
        let kind = animal_kind(o)?;
        if o.visible_fraction < 0.5 {
            return None;
        }
        let bbox = to_bbox(&jitter(&truth_box(o), rng), w, h)?;
        Some(Labelled {
            kind,
            bbox,
            detected: false,
        })
    }

    /// Calls `each(frame_index, luma, samples)` for every `stride`-th frame
    /// of scene `name` with `seed` in which a car or a dog is in view, with
    /// only the cars and dogs (at least half visible) as samples: more
    /// animals and vehicles for training, without rendering the frames
    /// that have none (the cast's frame ranges come from the geometry).
    /// With `masks`, every frame is rendered for the detector and `each`
    /// gets its mask (these frames have no people to label regions by).
    pub fn for_animal_frames(
        name: &str,
        seed: u64,
        stride: u64,
        rng: &mut Rng,
        masks: bool,
        mut each: impl FnMut(u64, Plane<'_>, Option<&BitMask>, &[Labelled]),
    ) -> Result<(), String> {
        let mut src = SimSource::open(name, &format!("seed={seed}")).map_err(|e| e.to_string())?;
        let spans: Vec<(u64, u64)> = src
            .cast()
            .iter()
            .filter(|m| m.kind != SimKind::Person && m.frames_in_view > 0)
            .map(|m| (m.first_frame, m.last_frame))
            .collect();
        let size = crate::source::FrameSource::info(&src).size;
        let mut frame = Frame::new(size);
        let only_mask = Detection {
            mask: masks,
            label: false,
        };
        let mut detector = ClipDetector::new(only_mask, size);
        let mut out = Vec::new();
        let (mut k, mut next) = (0, 0);
        while k < src.frames() {
            let wanted = k >= next && spans.iter().any(|&(a, b)| (a..=b).contains(&k));
            if !wanted && !masks {
                k += 1;
                continue;
            }
            src.render(k, &mut frame);
            detector.update(&frame);
            if wanted {
                out.clear();
                for o in src.truth() {
                    out.extend(animal_sample(o, rng, size.width, size.height));
                }
                each(k, frame.luma(), detector.mask(), &out);
                next = k + stride;
            }
            k += 1;
        }
        Ok(())
    }

    /// Calls `each(frame_index, luma, samples)` for every `stride`-th frame
    /// of scene `name` with `seed`.
    pub fn for_sim_frames(
        name: &str,
        seed: u64,
        stride: u64,
        per: PerFrame,
        rng: &mut Rng,
        detection: Detection,
        mut each: impl FnMut(u64, Plane<'_>, Option<&BitMask>, &[Labelled]),
    ) -> Result<(), String> {
        let mut src = SimSource::open(name, &format!("seed={seed}")).map_err(|e| e.to_string())?;
        let size = crate::source::FrameSource::info(&src).size;
        let mut frame = Frame::new(size);
        // The detector needs every frame; without it only sampled ones render.
        let step = if detection.on() { 1 } else { stride };
        let mut detector = ClipDetector::new(detection, size);
        let mut out = Vec::new();
        for k in (0..src.frames()).step_by(step as usize) {
            src.render(k, &mut frame);
            detector.update(&frame);
            if k % stride != 0 {
                continue;
            }
            let mut people = Vec::new();
            let mut hidden = Vec::new();
            let mut others = Vec::new();
            let mut animals = Vec::new();
            out.clear();
            for o in src.truth() {
                if o.kind == SimKind::Person {
                    people.push(truth_box(o));
                    hidden.push(o.visible_fraction < 0.85);
                } else {
                    others.push(truth_box(o));
                    animals.extend(animal_kind(o).map(|k| (k, truth_box(o))));
                    out.extend(animal_sample(o, rng, size.width, size.height));
                }
            }
            frame_samples(
                &people,
                &hidden,
                &others,
                size.width,
                size.height,
                per,
                rng,
                &mut out,
            );
            let (w, h) = (size.width, size.height);
            let regions = detector.labelled_regions();
            detected_labels(regions, &people, &hidden, &animals, w, h, &mut out);
            each(k, frame.luma(), detector.mask(), &out);
        }
        Ok(())
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[test]
        fn animal_frames_give_only_cars_and_dogs() {
            let (mut frames, mut dogs) = (0, 0);
            for_animal_frames(
                "plaza",
                1,
                5,
                &mut Rng::new(1),
                false,
                |_, luma, _, boxes| {
                    frames += 1;
                    assert_eq!((luma.width, luma.height), (640, 480));
                    for b in boxes {
                        assert!(matches!(b.kind, Kind::Dog | Kind::Car), "{b:?}");
                        dogs += usize::from(b.kind == Kind::Dog);
                    }
                },
            )
            .unwrap();
            // The plaza has a dog; only frames with it in view are rendered.
            assert!(frames > 5 && frames < 150, "{frames}");
            assert!(dogs > 5, "{dogs}");
        }
    }
}
