//! The installer snapshot (`stature run --snapshot PATH.png`, `stature
//! snapshot`): one frame with what the camera has worked out drawn over it,
//! so that whoever mounts the camera can see at a glance whether the
//! calibration makes sense.
//!
//! Drawn: the estimated horizon (or, when it lies outside the image, an
//! arrow toward it with its distance), dashed verticals converging toward
//! the estimated vertical vanishing point, every live track with its id,
//! box, head and foot points and its last reported height, and the
//! calibration values as text (focal length, tilt, roll, camera height and
//! how its scale was set, confidence against the measuring threshold).
//! Everything shown is the pipeline's own estimate, never a truth.
//!
//! When: at the end of the run ([`Snapshot`] is a [`run::Observer`]), with
//! the last processed frame, the final calibration, the tracks that were
//! live in that frame and their final heights. `stature snapshot` stops the
//! run as soon as the calibration confidence reaches
//! `measure.min_confidence`. The path is checked at start-up (a temporary
//! file is created beside it) and the PNG replaces it atomically at the end.
//!
//! Allocation: the RGB canvas is allocated when the snapshot is set up; in
//! the loop the observer only copies the live tracks into a fixed-capacity
//! table. Drawing and PNG encoding happen once, after the loop.

pub mod canvas;

use crate::calibrate::{Estimate, ScaleMode};
use crate::config::Config;
use crate::detect::BBox;
use crate::run::{self, Pipeline, StopReason};
use crate::source::SourceInfo;
use crate::track::{Track, MAX_TRACKS};
pub use canvas::Canvas;
use core::fmt::Write as _;
use embedded_graphics::mono_font::{iso_8859_1 as fonts, MonoFont, MonoTextStyle};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::{Point, Primitive, Size as EgSize};
use embedded_graphics::primitives::{
    Circle, PrimitiveStyle, PrimitiveStyleBuilder, Rectangle, StrokeAlignment, Triangle,
};
use embedded_graphics::text::{Baseline, Text};
use embedded_graphics::Drawable;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// The colours of the overlay (tests look for them).
pub mod colour {
    use embedded_graphics::pixelcolor::Rgb888;
    /// The estimated horizon.
    pub const HORIZON: Rgb888 = Rgb888::new(0, 230, 255);
    /// Verticals toward the vertical vanishing point.
    pub const VERTICAL: Rgb888 = Rgb888::new(255, 60, 255);
    /// Box of a person seen in this frame.
    pub const PERSON: Rgb888 = Rgb888::new(40, 255, 40);
    /// Box of a track that is coasting (not seen this frame) or merged.
    pub const COASTING: Rgb888 = Rgb888::new(255, 170, 0);
    /// Head point and the head–foot segment's top.
    pub const HEAD: Rgb888 = Rgb888::new(255, 40, 40);
    /// Foot point.
    pub const FOOT: Rgb888 = Rgb888::new(40, 110, 255);
    /// Head–foot segment.
    pub const SEGMENT: Rgb888 = Rgb888::new(255, 255, 0);
    /// Text.
    pub const TEXT: Rgb888 = Rgb888::new(255, 255, 255);
    /// Text on a coloured label.
    pub const INK: Rgb888 = Rgb888::new(0, 0, 0);
}

/// A track as the snapshot draws it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mark {
    /// Track id.
    pub id: u32,
    /// Box, pixels, inclusive.
    pub bbox: BBox,
    /// Head point, pixels.
    pub head: [f64; 2],
    /// Foot point, pixels.
    pub foot: [f64; 2],
    /// Head and foot are from this frame (else the track is coasting and
    /// they are not drawn).
    pub seen: bool,
    /// Merged with another region: coasting on its particles.
    pub merged: bool,
    /// Last reported height (metres) and its samples.
    pub height: Option<(f32, u32)>,
}

impl Mark {
    /// The mark of `t` in frame `frame`.
    pub fn of(t: &Track, frame: u64) -> Self {
        Mark {
            id: t.id,
            bbox: t.bbox,
            head: t.last.head,
            foot: t.last.foot,
            seen: t.last_seen == frame,
            merged: t.merged,
            height: t.reported,
        }
    }
}

/// Everything drawn over the frame.
#[derive(Clone, Copy, Debug)]
pub struct Overlay<'a> {
    /// Frame number shown.
    pub frame: u64,
    /// The calibration, if there is one yet.
    pub estimate: Option<&'a Estimate>,
    /// How the metric scale is set.
    pub scale: ScaleMode,
    /// Confidence from which heights are reported (`measure.min_confidence`).
    pub min_confidence: f64,
    /// The live tracks.
    pub tracks: &'a [Mark],
    /// A remark shown last (e.g. why the frame may be incomplete).
    pub note: Option<&'a str>,
}

/// Brightness (of 256) the scene keeps under text: dark enough for white
/// text over a white wall, light enough to see what is behind.
const PANEL_KEEP: u16 = 56;

/// Text sizes for an image of this width.
struct Fonts {
    panel: &'static MonoFont<'static>,
    label: &'static MonoFont<'static>,
}

fn fonts_for(width: usize) -> Fonts {
    if width >= 1200 {
        Fonts {
            panel: &fonts::FONT_10X20,
            label: &fonts::FONT_9X15,
        }
    } else if width >= 560 {
        Fonts {
            panel: &fonts::FONT_7X13,
            label: &fonts::FONT_7X13,
        }
    } else {
        Fonts {
            panel: &fonts::FONT_6X10,
            label: &fonts::FONT_5X8,
        }
    }
}

/// One line of text (longer ones are cut).
type Line = heapless::String<96>;

/// Lines of the calibration panel.
type Lines = heapless::Vec<Line, 12>;

/// Draws `o` over the image already in `c`.
pub fn draw(c: &mut Canvas, o: &Overlay<'_>) {
    let f = fonts_for(c.size().width);
    let lines = panel_lines(o, f.panel, c.size().width);
    let panel = panel_area(&lines, f.panel);
    // The panel's backdrop first, so that lines stay visible through it.
    c.dim(panel, PANEL_KEEP);
    if let Some(e) = o.estimate {
        verticals(c, e);
        horizon(c, e, f.label);
    }
    // Every box before any label, so that no box hides a label; labels
    // keep clear of the panel and of each other where they can.
    for m in o.tracks {
        track(c, m);
    }
    let mut taken = heapless::Vec::<Rectangle, { MAX_TRACKS + 1 }>::new();
    let _ = taken.push(panel);
    for m in o.tracks {
        label(c, m, f.label, &mut taken);
    }
    let style = MonoTextStyle::new(f.panel, colour::TEXT);
    let (pad, lh) = (4, f.panel.character_size.height as i32 + 2);
    for (i, l) in lines.iter().enumerate() {
        let at = Point::new(pad, pad + i as i32 * lh);
        let _ = Text::with_baseline(l, at, style, Baseline::Top).draw(c);
    }
    legend(c, f.label);
}

/// The calibration values, one fact per short line (the panel must leave
/// the top centre free for the horizon arrow), long remarks wrapped.
fn panel_lines(o: &Overlay<'_>, font: &MonoFont<'_>, width: usize) -> Lines {
    let mut out = Lines::new();
    let cols = (width.saturating_sub(8) / font.character_size.width as usize).clamp(20, 44);
    let mut add = |s: core::fmt::Arguments<'_>| {
        let mut l = Line::new();
        let _ = l.write_fmt(s);
        let _ = out.push(l);
    };
    add(format_args!(
        "frame {}   {} tracks",
        o.frame,
        o.tracks.len()
    ));
    match o.estimate {
        Some(e) => {
            let g = &e.geom;
            add(format_args!(
                "f {:.0} px  tilt {:.1}°  roll {:.1}°",
                g.focal(),
                g.tilt().to_degrees(),
                g.roll().to_degrees()
            ));
            let h = e.camera_height;
            match o.scale {
                ScaleMode::PopulationPrior(m) => {
                    add(format_args!("camera height {h:.2} m (people avg {m:.2} m)"))
                }
                ScaleMode::CameraHeight(_) => add(format_args!("camera height {h:.2} m (given)")),
                ScaleMode::ReferencePerson(m) => {
                    add(format_args!("camera height {h:.2} m (reference {m:.2} m)"))
                }
            }
            if e.confidence >= o.min_confidence {
                add(format_args!(
                    "confidence {:.2}: measuring (>= {:.2})",
                    e.confidence, o.min_confidence
                ));
            } else {
                add(format_args!(
                    "confidence {:.2}: not measuring (< {:.2})",
                    e.confidence, o.min_confidence
                ));
            }
            add(format_args!(
                "vertical VP ({:.0}, {:.0}) px",
                g.v[0], g.v[1]
            ));
            add(format_args!(
                "from {} head-foot lines, {} tracked anchors",
                e.inliers, e.horizon_inliers
            ));
            if let Some(d) = e.degeneracy {
                wrap(d.describe(), cols, &mut out);
            }
        }
        None => {
            add(format_args!("no calibration yet:"));
            add(format_args!("needs people walking through"));
        }
    }
    if let Some(n) = o.note {
        wrap(n, cols, &mut out);
    }
    out
}

/// Splits `text` at spaces into lines of at most `cols` characters.
fn wrap(text: &str, cols: usize, out: &mut Lines) {
    let mut l = Line::new();
    let mut n = 0;
    for word in text.split(' ') {
        let w = word.chars().count();
        if n > 0 && n + 1 + w > cols {
            let _ = out.push(core::mem::take(&mut l));
            n = 0;
        }
        if n > 0 {
            let _ = l.push(' ');
            n += 1;
        }
        let _ = l.push_str(word);
        n += w;
    }
    if n > 0 {
        let _ = out.push(l);
    }
}

fn panel_area(lines: &Lines, font: &MonoFont<'_>) -> Rectangle {
    let cols = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0) as u32;
    let cs = font.character_size;
    Rectangle::new(
        Point::zero(),
        EgSize::new(
            cols * cs.width + 8,
            lines.len() as u32 * (cs.height + 2) + 6,
        ),
    )
}

/// Dashed lines through the vertical vanishing point, spread across the
/// image: world verticals (people, poles, walls) line up with them.
fn verticals(c: &mut Canvas, e: &Estimate) {
    let (w, h) = (c.size().width as f64, c.size().height as f64);
    let v = e.geom.v;
    let p = [(w - 1.0) / 2.0, (h - 1.0) / 2.0];
    let (dx, dy) = (p[0] - v[0], p[1] - v[1]);
    let n = (dx * dx + dy * dy).sqrt();
    if n.is_nan() || n <= 1e-6 {
        return;
    }
    // Base points on the line through the centre perpendicular to p→v.
    let perp = [-dy / n, dx / n];
    let half = 0.5 * (w * w + h * h).sqrt();
    const K: usize = 9;
    for k in 0..K {
        let t = -half + 2.0 * half * k as f64 / (K - 1) as f64;
        let base = [p[0] + perp[0] * t, p[1] + perp[1] * t];
        // Beyond the base, away from v, so the line crosses the whole image.
        let far = [base[0] + dx / n * 2.0 * half, base[1] + dy / n * 2.0 * half];
        c.segment(far, v, colour::VERTICAL, 1, Some((9.0, 6.0)));
    }
    let inside = v[0] >= 0.0 && v[1] >= 0.0 && v[0] <= w - 1.0 && v[1] <= h - 1.0;
    if inside {
        let style = PrimitiveStyle::with_stroke(colour::VERTICAL, 2);
        let _ = Circle::with_center(canvas::point(v), 15)
            .into_styled(style)
            .draw(c);
    }
}

/// The horizon across the image, or an arrow toward it when it is outside.
fn horizon(c: &mut Canvas, e: &Estimate, font: &MonoFont<'_>) {
    let [a, b, k] = e.geom.horizon();
    let (w, h) = (c.size().width as f64, c.size().height as f64);
    // The horizon's point nearest the image centre, and its direction.
    let p = [(w - 1.0) / 2.0, (h - 1.0) / 2.0];
    let s = a * p[0] + b * p[1] + k;
    let q = [p[0] - s * a, p[1] - s * b];
    let dir = [-b, a];
    let span = 4.0 * (w + h);
    let ends = (
        [q[0] - dir[0] * span, q[1] - dir[1] * span],
        [q[0] + dir[0] * span, q[1] + dir[1] * span],
    );
    let style = embedded_graphics::mono_font::MonoTextStyleBuilder::new()
        .font(font)
        .text_color(colour::HORIZON)
        .background_color(colour::INK)
        .build();
    let cs = font.character_size;
    let (cw, ch) = (f64::from(cs.width), f64::from(cs.height));
    if let Some((l, r)) = canvas::clip(ends.0, ends.1, c.size()) {
        c.segment(l, r, colour::HORIZON, 2, None);
        // Labelled at its right end, away from the panel at the top left.
        let right = if l[0] >= r[0] { l } else { r };
        let x = right[0] - 8.0 * cw - 4.0;
        let y = (right[1] - ch - 4.0).max(2.0);
        let _ = Text::with_baseline("horizon", canvas::point([x, y]), style, Baseline::Top).draw(c);
        return;
    }
    // Outside: the gap is the distance of the nearest image corner.
    let gap = [
        [0.0, 0.0],
        [w - 1.0, 0.0],
        [0.0, h - 1.0],
        [w - 1.0, h - 1.0],
    ]
    .iter()
    .map(|x| (a * x[0] + b * x[1] + k).abs())
    .fold(f64::INFINITY, f64::min);
    // Arrow on the image edge where p→q leaves the image.
    let Some((_, edge)) = canvas::clip(p, q, c.size()) else {
        return;
    };
    let (ux, uy) = (-s.signum() * a, -s.signum() * b);
    let tip = [edge[0] - ux * 2.0, edge[1] - uy * 2.0];
    let back = [tip[0] - ux * 18.0, tip[1] - uy * 18.0];
    let wing = [-uy * 9.0, ux * 9.0];
    let _ = Triangle::new(
        canvas::point(tip),
        canvas::point([back[0] + wing[0], back[1] + wing[1]]),
        canvas::point([back[0] - wing[0], back[1] - wing[1]]),
    )
    .into_styled(PrimitiveStyle::with_fill(colour::HORIZON))
    .draw(c);
    let side = match (uy.abs() >= ux.abs(), uy < 0.0, ux < 0.0) {
        (true, true, _) => "above",
        (true, false, _) => "below",
        (false, _, true) => "left of",
        (false, _, false) => "right of",
    };
    let mut t = Line::new();
    let _ = write!(t, "horizon {gap:.0} px {side} the image");
    let tw = t.chars().count() as f64 * cw;
    let mid = [0.5 * (tip[0] + back[0]), 0.5 * (tip[1] + back[1])];
    let (x, y) = if uy.abs() >= ux.abs() {
        // Beside an up or down arrow, on the side with room.
        let x = if mid[0] + 14.0 + tw <= w - 2.0 {
            mid[0] + 14.0
        } else {
            mid[0] - 14.0 - tw
        };
        (x, mid[1] - ch / 2.0)
    } else {
        (mid[0] - tw / 2.0, mid[1] + 14.0)
    };
    let x = x.clamp(2.0, (w - tw - 2.0).max(2.0));
    let y = y.clamp(2.0, h - ch - 2.0);
    let _ = Text::with_baseline(&t, canvas::point([x, y]), style, Baseline::Top).draw(c);
}

/// A track's colour: seen in this frame, or coasting/merged.
fn track_colour(m: &Mark) -> Rgb888 {
    if m.seen && !m.merged {
        colour::PERSON
    } else {
        colour::COASTING
    }
}

/// A track's box, and its head and foot when seen in this frame.
fn track(c: &mut Canvas, m: &Mark) {
    let col = track_colour(m);
    let b = m.bbox;
    let style = PrimitiveStyleBuilder::new()
        .stroke_color(col)
        .stroke_width(2)
        .stroke_alignment(StrokeAlignment::Outside)
        .build();
    let _ = Rectangle::with_corners(
        Point::new(i32::from(b.x0), i32::from(b.y0)),
        Point::new(i32::from(b.x1), i32::from(b.y1)),
    )
    .into_styled(style)
    .draw(c);
    if m.seen {
        c.segment(m.head, m.foot, colour::SEGMENT, 1, None);
        for (p, col) in [(m.head, colour::HEAD), (m.foot, colour::FOOT)] {
            if p.iter().all(|v| v.is_finite()) {
                let _ = Circle::with_center(canvas::point(p), 7)
                    .into_styled(
                        PrimitiveStyleBuilder::new()
                            .fill_color(col)
                            .stroke_color(colour::INK)
                            .stroke_width(1)
                            .build(),
                    )
                    .draw(c);
            }
        }
    }
}

/// A track's label (id, height, state) on its colour, above its box, else
/// below it, else inside its top, whichever first overlaps nothing `taken`.
fn label<const N: usize>(
    c: &mut Canvas,
    m: &Mark,
    font: &MonoFont<'_>,
    taken: &mut heapless::Vec<Rectangle, N>,
) {
    let b = m.bbox;
    let col = track_colour(m);
    let mut t = Line::new();
    let _ = write!(t, "#{}", m.id);
    let _ = match m.height {
        Some((hm, _)) => write!(t, " {hm:.2} m"),
        None => write!(t, " --"),
    };
    if m.merged {
        let _ = write!(t, " merged");
    } else if !m.seen {
        let _ = write!(t, " coasting");
    }
    let cs = font.character_size;
    let size = EgSize::new(t.chars().count() as u32 * cs.width, cs.height);
    let (w, h) = (c.size().width as i32, c.size().height as i32);
    let x = (i32::from(b.x0) - 2).clamp(0, (w - size.width as i32).max(0));
    let ch = cs.height as i32;
    let candidates = [
        i32::from(b.y0) - 3 - ch,
        i32::from(b.y1) + 3,
        i32::from(b.y0) + 2,
    ];
    let fits = |y: i32| y >= 0 && y + ch <= h;
    let free = |r: &Rectangle| {
        taken
            .iter()
            .all(|o| o.intersection(r).size.width == 0 || o.intersection(r).size.height == 0)
    };
    let rect = |y| Rectangle::new(Point::new(x, y), size);
    let y = candidates
        .into_iter()
        .find(|&y| fits(y) && free(&rect(y)))
        .or_else(|| candidates.into_iter().find(|&y| fits(y)))
        .unwrap_or(0);
    let _ = taken.push(rect(y));
    let style = embedded_graphics::mono_font::MonoTextStyleBuilder::new()
        .font(font)
        .text_color(colour::INK)
        .background_color(col)
        .build();
    let _ = Text::with_baseline(&t, Point::new(x, y), style, Baseline::Top).draw(c);
}

/// What the colours mean, along the bottom edge.
fn legend(c: &mut Canvas, font: &MonoFont<'_>) {
    let cs = font.character_size;
    let (cw, ch) = (cs.width as i32, cs.height as i32);
    let y = c.size().height as i32 - ch - 4;
    let items: [(&str, Rgb888); 6] = [
        ("horizon", colour::HORIZON),
        ("to vertical VP", colour::VERTICAL),
        ("person #id height", colour::PERSON),
        ("coasting/merged", colour::COASTING),
        ("head", colour::HEAD),
        ("foot", colour::FOOT),
    ];
    let total: i32 = items
        .iter()
        .map(|(s, _)| 3 * cw + s.len() as i32 * cw + 2 * cw)
        .sum();
    c.dim(
        Rectangle::new(
            Point::new(0, y - 3),
            EgSize::new(total.max(0) as u32 + 6, ch as u32 + 7),
        ),
        PANEL_KEEP,
    );
    let mut x = 4;
    for (s, col) in items {
        let mid = f64::from(y + ch / 2);
        c.segment(
            [f64::from(x), mid],
            [f64::from(x + 2 * cw), mid],
            col,
            3,
            None,
        );
        x += 3 * cw;
        let style = MonoTextStyle::new(font, colour::TEXT);
        let _ = Text::with_baseline(s, Point::new(x, y), style, Baseline::Top).draw(c);
        x += (s.len() as i32 + 2) * cw;
    }
}

/// Refuses a path whose extension names another format: the snapshot is
/// always PNG, and a `.jpg` name would mislead every viewer and upload
/// that trusts it. A path without an extension makes no such claim and
/// is accepted. Checked with the other settings, before anything opens.
pub fn check_path(path: &Path) -> Result<(), &'static str> {
    match path.extension() {
        Some(e) if !e.eq_ignore_ascii_case("png") => {
            Err("only PNG is written: give a path ending in `.png`")
        }
        _ => Ok(()),
    }
}

/// A snapshot path that cannot be used.
#[derive(Debug)]
pub struct SnapshotError {
    /// The path given.
    pub path: PathBuf,
    /// What failed.
    pub error: io::Error,
}

impl core::fmt::Display for SnapshotError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "cannot write snapshot {}: {}",
            self.path.display(),
            self.error
        )
    }
}

impl std::error::Error for SnapshotError {}

/// The snapshot's file: a temporary file beside it, created (and so
/// checked) at start-up, renamed over the path once the PNG is in it
/// ([`crate::replace::create_own_tmp`]: this process's alone).
#[derive(Debug)]
pub struct SnapshotFile {
    path: PathBuf,
    tmp: PathBuf,
    file: Option<File>,
}

impl SnapshotFile {
    /// Checks that `path` can be written by creating `PATH.stature-tmp` now (beside
    /// the file a symbolic link at `path` points to).
    pub fn create(path: &Path) -> Result<Self, SnapshotError> {
        let err = |error| SnapshotError {
            path: path.to_path_buf(),
            error,
        };
        // A link is followed (its file is replaced); a directory, device
        // or FIFO is refused.
        let target = crate::replace::target(path).map_err(err)?;
        if target.file_name().is_none() {
            return Err(err(io::Error::other("not a file name")));
        }
        // Its own temporary file, locked: another process writing this
        // snapshot path uses another.
        let (tmp, file) = crate::replace::create_own_tmp(&target).map_err(err)?;
        Ok(SnapshotFile {
            path: target,
            tmp,
            file: Some(file),
        })
    }

    /// The path the snapshot goes to.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes `c` as PNG and moves it into place (once; later calls fail).
    pub fn write(&mut self, c: &Canvas) -> Result<(), SnapshotError> {
        let err = |error| SnapshotError {
            path: self.path.clone(),
            error,
        };
        let file = self
            .file
            .take()
            .ok_or_else(|| err(io::Error::other("already written")))?;
        let mut out = BufWriter::new(file);
        let done = c
            .write_png(&mut out)
            .and_then(|_| out.flush())
            .and_then(|_| out.get_ref().sync_all())
            .and_then(|_| std::fs::rename(&self.tmp, &self.path));
        if done.is_err() {
            let _ = std::fs::remove_file(&self.tmp);
        }
        done.map_err(err)
    }
}

impl Drop for SnapshotFile {
    fn drop(&mut self) {
        // Never written (the run did not get to its end): no stray file.
        // Removed before the file is closed, while its lock still keeps
        // another process from taking that name up in between.
        if let Some(file) = self.file.take() {
            let _ = std::fs::remove_file(&self.tmp);
            drop(file);
        }
    }
}

/// The snapshot as a loop [`run::Observer`]: keeps the live tracks of the
/// latest frame, draws and writes at the end.
pub struct Snapshot {
    canvas: Canvas,
    file: SnapshotFile,
    scale: ScaleMode,
    min_confidence: f64,
    until_confident: bool,
    marks: heapless::Vec<Mark, MAX_TRACKS>,
    /// The outcome of the write at the end (`None` before the end).
    pub result: Option<Result<(), SnapshotError>>,
}

impl Snapshot {
    /// Sets up a snapshot of `info`'s frames to `path` (checked now).
    /// With `until_confident` the run stops once the calibration confidence
    /// reaches `measure.min_confidence`.
    pub fn new(
        cfg: &Config,
        info: &SourceInfo,
        path: &Path,
        until_confident: bool,
    ) -> Result<Self, SnapshotError> {
        Ok(Snapshot::with_file(
            cfg,
            info,
            SnapshotFile::create(path)?,
            until_confident,
        ))
    }

    /// [`Snapshot::new`] with the file already created (checked at
    /// start-up, after the source opened, before its first frame is read).
    pub fn with_file(
        cfg: &Config,
        info: &SourceInfo,
        file: SnapshotFile,
        until_confident: bool,
    ) -> Self {
        Snapshot {
            canvas: Canvas::new(info.size),
            file,
            scale: cfg.calibrate.scale_mode(),
            min_confidence: cfg.measure.min_confidence,
            until_confident,
            marks: heapless::Vec::new(),
            result: None,
        }
    }

    /// The image (drawn at the end).
    pub fn canvas(&self) -> &Canvas {
        &self.canvas
    }

    /// The tracks drawn: those live in the last processed frame.
    pub fn marks(&self) -> &[Mark] {
        &self.marks
    }

    /// Draws the pipeline's last frame, calibration and the tracks kept by
    /// [`run::Observer::frame`] (with their heights as `p` has them now).
    pub fn render(&mut self, p: &Pipeline, note: Option<&str>) {
        if p.frames > 0 {
            self.canvas.load(&p.frame);
        }
        for m in self.marks.iter_mut() {
            if let Some(t) = p.tracker().tracks().iter().find(|t| t.id == m.id) {
                m.height = t.reported;
            }
        }
        let note = match (p.frames, note) {
            (0, _) => Some("no frame was processed"),
            (_, n) => n,
        };
        draw(
            &mut self.canvas,
            &Overlay {
                frame: p.frames.saturating_sub(1),
                estimate: p.estimate(),
                scale: self.scale,
                min_confidence: self.min_confidence,
                tracks: &self.marks,
                note,
            },
        );
    }
}

impl run::Observer for Snapshot {
    fn frame(&mut self, p: &Pipeline) -> bool {
        let now = p.frames.saturating_sub(1);
        self.marks.clear();
        for t in p.tracker().tracks().iter().filter(|t| !t.ended) {
            // The table holds at most MAX_TRACKS tracks: this always fits.
            let _ = self.marks.push(Mark::of(t, now));
        }
        self.until_confident
            && p.estimate()
                .is_some_and(|e| e.confidence >= self.min_confidence)
    }

    fn end(&mut self, p: &Pipeline, stopped_by: StopReason) {
        if p.frames == 0 {
            // A blank picture would pass for a camera that saw nothing.
            let e = SnapshotError {
                path: self.file.path().to_path_buf(),
                error: io::Error::other("no frame to draw (the run ended before its first frame)"),
            };
            log::error!("{e}");
            self.result = Some(Err(e));
            return;
        }
        let note = (stopped_by == StopReason::SourceError)
            .then_some("the source failed: this frame may be partly the one that failed");
        self.render(p, note);
        let written = self.file.write(&self.canvas);
        match &written {
            Ok(()) => log::info!("snapshot written to {}", self.file.path().display()),
            Err(e) => log::error!("{e}"),
        }
        self.result = Some(written);
    }
}

#[cfg(test)]
mod tests;
