//! The installer snapshot of a real pipeline run on a simulated scene: the
//! estimated horizon and every live track's box are drawn where they are,
//! and the PNG on disk is that image.

use stature::config::{Config, Format};
use stature::report::{self, Reporter};
use stature::run::{self, LoopOptions};
use stature::snapshot::{colour, Snapshot};
use stature::source::sim::SimSource;
use stature::source::FrameSource;
use std::sync::atomic::AtomicBool;

use crate::common;

pub fn rgb(c: embedded_graphics::pixelcolor::Rgb888) -> Option<[u8; 3]> {
    use embedded_graphics::prelude::RgbColor;
    Some([c.r(), c.g(), c.b()])
}

/// Checks that `horizon` (`[a, b, c]` of a calibration record) is drawn on
/// a `w`×`h` image whose pixels `pixel` reads. Where it crosses the image:
/// a line in ≥ 60 % of those columns, and in ≥ 95 % either the line or
/// something the snapshot draws over it (a track's box or label, text).
/// Where it misses the image: an arrow on the edge toward it. A horizon
/// that cuts only a corner (≤ a quarter of the columns) is a line too, as
/// the snapshot draws one whenever the line meets the image, but its
/// fixed-width label may cover more than 40 % of it: there only the 95 %
/// rule applies.
pub fn assert_horizon_drawn(
    pixel: &dyn Fn(i64, i64) -> Option<[u8; 3]>,
    (w, h): (i64, i64),
    horizon: [f32; 3],
) {
    let [a, b, k] = horizon.map(f64::from);
    let any = |x: i64, y: i64, cols: &[embedded_graphics::pixelcolor::Rgb888]| {
        (-1..=1).any(|d| cols.iter().any(|&c| pixel(x, y + d) == rgb(c)))
    };
    let over = [
        colour::PERSON,
        colour::COASTING,
        colour::HEAD,
        colour::FOOT,
        colour::SEGMENT,
        colour::INK,
        colour::TEXT,
    ];
    if b.abs() > 1e-6 {
        // Columns where the line lies within the image (the drawing clips
        // it at rows 0 and h − 1, so a row that only rounds to 0 is out).
        let inside: Vec<(i64, i64)> = (0..w)
            .map(|u| (u, -(a * u as f64 + k) / b))
            .filter(|&(_, v)| (0.0..=(h - 1) as f64).contains(&v))
            .map(|(u, v)| (u, v.round() as i64))
            .collect();
        if !inside.is_empty() {
            let n = inside.len();
            let line = inside
                .iter()
                .filter(|&&(u, v)| any(u, v, &[colour::HORIZON]))
                .count();
            let hidden = inside
                .iter()
                .filter(|&&(u, v)| !any(u, v, &[colour::HORIZON]) && any(u, v, &over))
                .count();
            let short = n as i64 <= w / 4;
            assert!(
                (short || line * 10 >= n * 6) && (line + hidden) * 20 >= n * 19,
                "horizon {horizon:?}: drawn in {line} of {n} columns, covered in {hidden}"
            );
            return;
        }
    }
    // Off the image: the arrow sits where the line from the centre toward
    // the horizon's nearest point leaves the image.
    let p = [(w - 1) as f64 / 2.0, (h - 1) as f64 / 2.0];
    let s = a * p[0] + b * p[1] + k;
    let u = [-s.signum() * a, -s.signum() * b];
    let mut t = 0.0;
    while (0.0..w as f64 - 0.5).contains(&(p[0] + u[0] * t))
        && (0.0..h as f64 - 0.5).contains(&(p[1] + u[1] * t))
    {
        t += 0.5;
    }
    let at = [p[0] + u[0] * (t - 14.0), p[1] + u[1] * (t - 14.0)];
    assert_eq!(
        pixel(at[0].round() as i64, at[1].round() as i64),
        rgb(colour::HORIZON),
        "horizon {horizon:?} off the image: no arrow at {at:?}"
    );
}

/// Decodes a PNG written by stature: size and RGB bytes.
pub fn read_png(path: &std::path::Path) -> ((i64, i64), Vec<u8>) {
    let dec = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    ((i64::from(info.width), i64::from(info.height)), buf)
}

#[test]
fn sim_run_snapshot_shows_the_estimated_horizon_and_every_live_track() {
    let frames = 300;
    let uri = format!("sim:plaza?seed=1&frames={frames}");
    let mut sim = SimSource::open_uri(&uri).unwrap();
    let mut cfg = Config::default();
    cfg.source.uri = uri;
    let dir = common::fresh_dir("snapshot-sim");
    let path = dir.join("plaza.png");
    let mut snap = Snapshot::new(&cfg, sim.info(), &path, false).unwrap();
    let (mut reporter, rx, counters) = Reporter::new(cfg.report.queue, cfg.report.held_finals);
    let io = report::spawn_io(rx, Vec::new(), Format::Json, counters);
    let stop = AtomicBool::new(false);
    let opts = LoopOptions {
        max_frames: 0,
        status_interval_s: 5.0,
        stop: &stop,
        allocations: || 0,
        state: None,
    };
    let summary = run::run_observed(&cfg, &mut sim, &mut reporter, opts, &mut snap);
    reporter.finish(std::time::Duration::from_secs(5));
    io.join().unwrap();
    assert_eq!(summary.frames, frames);
    assert!(
        matches!(snap.result, Some(Ok(()))),
        "written: {:?}",
        snap.result
    );
    let c = snap.canvas();
    let cal = summary
        .calibration
        .expect("a calibration within 300 frames of the plaza");
    assert_horizon_drawn(&|x, y| c.pixel(x, y), (640, 480), cal.horizon);

    // Every track live in the last frame has its box drawn just outside it.
    let marks = snap.marks();
    assert!(!marks.is_empty(), "people are in view at frame {frames}");
    for m in marks {
        let b = m.bbox;
        let boxed = |x, y| {
            let p = c.pixel(x, y);
            p == rgb(colour::PERSON) || p == rgb(colour::COASTING)
        };
        let rows = i64::from(b.y0)..=i64::from(b.y1);
        let n = rows.clone().count();
        for x in [i64::from(b.x0) - 1, i64::from(b.x1) + 1] {
            if !(0..c.size().width as i64).contains(&x) {
                continue;
            }
            let drawn = rows.clone().filter(|&y| boxed(x, y)).count();
            // Other tracks' labels may cross it.
            assert!(
                drawn * 10 >= n * 8,
                "track {}: column {x}: {drawn} of {n}",
                m.id
            );
        }
        // Its colour says whether it was seen in this frame.
        let own = rgb(if m.seen && !m.merged {
            colour::PERSON
        } else {
            colour::COASTING
        });
        // (Either side: a neighbour's box of the other colour may lie over
        // one of them.)
        let w = c.size().width as i64;
        let mine = [i64::from(b.x0) - 2, i64::from(b.x1) + 2]
            .into_iter()
            .filter(|x| (0..w).contains(x))
            .map(|x| rows.clone().filter(|&y| c.pixel(x, y) == own).count())
            .max()
            .unwrap_or(n);
        assert!(mine * 2 >= n, "track {}: {mine} of {n} in its colour", m.id);
    }
    // The tracks drawn as seen are people of the scene: each foot point
    // lies near a true person's foot.
    let last = frames - 1;
    let seen: Vec<_> = marks.iter().filter(|m| m.seen).collect();
    let real = seen
        .iter()
        .filter(|m| sim.person_at(last, m.foot, 25.0).is_some())
        .count();
    assert!(
        real >= 1 && real * 2 >= seen.len(),
        "{real} of {} seen tracks are people",
        seen.len()
    );

    // The file is that image.
    let (size, bytes) = read_png(&path);
    assert_eq!(size, (640, 480));
    assert!(bytes == c.rgb());
}
