use super::canvas::clip;
use super::*;
use crate::calibrate::geometry::ViewGeometry;
use crate::camera::Camera;
use crate::frame::{Frame, Size};
use embedded_graphics::prelude::RgbColor;

const SIZE: Size = Size {
    width: 640,
    height: 480,
};

fn rgb(c: Rgb888) -> [u8; 3] {
    [c.r(), c.g(), c.b()]
}

/// A mid-grey canvas.
fn grey() -> Canvas {
    let mut f = Frame::new(SIZE);
    f.y.fill(126);
    f.u.fill(128);
    f.v.fill(128);
    let mut c = Canvas::new(SIZE);
    c.load(&f);
    c
}

/// The exact estimate of a known camera.
fn estimate(tilt_deg: f64, roll_deg: f64) -> Estimate {
    let cam = Camera::centred(620.0, tilt_deg, roll_deg, 4.2, SIZE.width, SIZE.height);
    Estimate {
        geom: ViewGeometry::of_camera(&cam),
        camera_height: 4.2,
        inliers: 120,
        horizon_inliers: 40,
        focal_rel_sigma: 0.01,
        lean: 0.0,
        confidence: 0.8,
        degeneracy: None,
        version: 1,
    }
}

fn overlay<'a>(e: Option<&'a Estimate>, tracks: &'a [Mark]) -> Overlay<'a> {
    Overlay {
        frame: 99,
        estimate: e,
        scale: ScaleMode::PopulationPrior(1.7),
        min_confidence: 0.3,
        tracks,
        note: None,
    }
}

/// Whether `(x, y)` or a pixel above or below it has colour `c`.
fn near(canvas: &Canvas, x: i64, y: i64, c: Rgb888) -> bool {
    (-1..=1).any(|d| canvas.pixel(x, y + d) == Some(rgb(c)))
}

#[test]
fn clipping_keeps_the_part_inside_the_image() {
    // Toward a vanishing point far below: enters at the top, leaves at the bottom.
    let (a, b) = clip([100.0, -50.0], [400.0, 1e6], SIZE).unwrap();
    assert!(
        (a[1] - 0.0).abs() < 1e-9 && (b[1] - 479.0).abs() < 1e-9,
        "{a:?} {b:?}"
    );
    assert!(a[0] > 100.0 && b[0] < 101.0, "{a:?} {b:?}");
    // Inside stays as it is.
    assert_eq!(
        clip([10.0, 20.0], [30.0, 40.0], SIZE),
        Some(([10.0, 20.0], [30.0, 40.0]))
    );
    assert_eq!(clip([-10.0, -5.0], [-1.0, 900.0], SIZE), None);
    assert_eq!(clip([0.0, -20.0], [639.0, -1.0], SIZE), None);
    assert_eq!(clip([0.0, f64::NAN], [10.0, 10.0], SIZE), None);
    assert_eq!(clip([0.0, 0.0], [f64::INFINITY, 10.0], SIZE), None);
}

#[test]
fn horizon_is_drawn_where_the_estimate_puts_it() {
    let e = estimate(10.0, 4.0);
    let [a, b, k] = e.geom.horizon();
    let mut c = grey();
    draw(&mut c, &overlay(Some(&e), &[]));
    let on = (0..SIZE.width as i64)
        .filter(|&u| {
            let v = (-(a * u as f64 + k) / b).round() as i64;
            near(&c, u, v, colour::HORIZON)
        })
        .count();
    assert!(
        on * 100 >= SIZE.width * 95,
        "{on} of {} columns",
        SIZE.width
    );
    // Well away from it, nothing horizon-coloured in the middle column.
    let v_mid = -(a * 320.0 + k) / b;
    let stray = (0..SIZE.height as i64)
        .filter(|&y| (y as f64 - v_mid).abs() > 20.0 && y < 440)
        .filter(|&y| c.pixel(320, y) == Some(rgb(colour::HORIZON)))
        .count();
    assert_eq!(stray, 0);
}

#[test]
fn horizon_outside_the_image_gets_an_arrow_and_verticals_meet_at_the_vp() {
    let e = estimate(45.0, 0.0);
    // The whole image is below the horizon.
    assert!(e.geom.below_horizon([0.0, 0.0]) > 300.0);
    let mut c = grey();
    draw(&mut c, &overlay(Some(&e), &[]));
    // No row is a horizon line ...
    for y in 0..440 {
        let n = (0..SIZE.width as i64)
            .filter(|&x| c.pixel(x, y) == Some(rgb(colour::HORIZON)))
            .count();
        assert!(n < SIZE.width / 3, "row {y}: {n} horizon pixels");
    }
    // ... but an arrow at the top edge points up toward it.
    assert_eq!(c.pixel(320, 8), Some(rgb(colour::HORIZON)));
    // The VP is straight below the centre: the middle vertical is column 320, dashed.
    let v = e.geom.v;
    assert!((v[0] - 319.5).abs() < 1e-6 && v[1] > 800.0, "{v:?}");
    let dashes = (150..400)
        .filter(|&y| c.pixel(320, y) == Some(rgb(colour::VERTICAL)))
        .count();
    assert!((100..=200).contains(&dashes), "{dashes} of 250 rows");
    // The outer verticals lean toward it: left of centre they run down and right.
    let col_at = |y: i64| {
        (0..300)
            .filter(|&x| c.pixel(x, y) == Some(rgb(colour::VERTICAL)))
            .collect::<Vec<_>>()
    };
    let (top, bottom) = (col_at(150), col_at(400));
    assert!(!top.is_empty() && !bottom.is_empty());
    assert!(bottom[0] > top[0], "{top:?} -> {bottom:?}");
}

fn mark(seen: bool) -> Mark {
    Mark {
        id: 7,
        bbox: BBox {
            x0: 300,
            y0: 200,
            x1: 340,
            y1: 310,
        },
        head: [320.0, 200.0],
        foot: [320.0, 310.0],
        seen,
        merged: false,
        height: Some((1.74, 31)),
    }
}

#[test]
fn tracks_get_a_box_head_and_foot() {
    let m = mark(true);
    let mut c = grey();
    draw(&mut c, &overlay(None, &[m]));
    let b = m.bbox;
    let (x0, y0, x1, y1) = (
        i64::from(b.x0),
        i64::from(b.y0),
        i64::from(b.x1),
        i64::from(b.y1),
    );
    let is = |x, y, col| c.pixel(x, y) == Some(rgb(col));
    for y in y0..=y1 {
        assert!(
            is(x0 - 1, y, colour::PERSON) && is(x0 - 2, y, colour::PERSON),
            "left, row {y}"
        );
        assert!(
            is(x1 + 1, y, colour::PERSON) && is(x1 + 2, y, colour::PERSON),
            "right, row {y}"
        );
    }
    let top = (x0..=x1).filter(|&x| is(x, y0 - 1, colour::PERSON)).count();
    let bottom = (x0..=x1).filter(|&x| is(x, y1 + 1, colour::PERSON)).count();
    // The head and foot dots sit on the box's top and bottom edges.
    assert!(top >= 30 && bottom >= 30, "{top} {bottom}");
    assert!(is(320, 200, colour::HEAD) && is(320, 310, colour::FOOT));
    assert!(is(320, 255, colour::SEGMENT));
    // Inside the box, away from the segment, the frame shows through.
    assert_eq!(c.pixel(305, 255), grey().pixel(305, 255));
    // Its label sits above the box, on the box colour.
    let label = (x0..x0 + 60)
        .filter(|&x| (y0 - 16..y0 - 3).any(|y| is(x, y, colour::PERSON)))
        .count();
    assert!(label >= 50, "{label}");
}

#[test]
fn a_coasting_track_is_drawn_in_its_own_colour_without_points() {
    let m = mark(false);
    let mut c = grey();
    draw(&mut c, &overlay(None, &[m]));
    assert_eq!(c.pixel(299, 250), Some(rgb(colour::COASTING)));
    assert_ne!(c.pixel(320, 200), Some(rgb(colour::HEAD)));
    assert_ne!(c.pixel(320, 255), Some(rgb(colour::SEGMENT)));
}

#[test]
fn without_calibration_no_geometry_is_drawn() {
    let mut c = grey();
    draw(&mut c, &overlay(None, &[]));
    // Only the legend (bottom strip) carries the geometry colours.
    for y in 0..450 {
        for x in 0..SIZE.width as i64 {
            let p = c.pixel(x, y);
            assert!(
                p != Some(rgb(colour::HORIZON)) && p != Some(rgb(colour::VERTICAL)),
                "({x}, {y})"
            );
        }
    }
}

#[test]
fn panel_states_the_estimate() {
    let e = estimate(20.0, -2.0);
    let o = overlay(Some(&e), &[]);
    let lines = panel_lines(&o, &fonts::FONT_7X13, SIZE.width);
    let text: Vec<&str> = lines.iter().map(|l| l.as_str()).collect();
    let all = text.join("\n");
    for want in [
        "frame 99",
        "f 620 px",
        "tilt 20.0°",
        "roll -2.0°",
        "camera height 4.20 m (people avg 1.70 m)",
        "confidence 0.80: measuring (>= 0.30)",
        "from 120 head-foot lines, 40 tracked anchors",
    ] {
        assert!(all.contains(want), "{want:?} missing from\n{all}");
    }
    let low = Estimate {
        confidence: 0.1,
        degeneracy: Some(crate::calibrate::geometry::Degeneracy::NearLevel),
        ..e
    };
    let o = Overlay {
        scale: ScaleMode::CameraHeight(4.2),
        note: Some("a note"),
        ..overlay(Some(&low), &[])
    };
    let lines = panel_lines(&o, &fonts::FONT_7X13, SIZE.width);
    let all: Vec<&str> = lines.iter().map(|l| l.as_str()).collect();
    let all = all.join("\n");
    assert!(all.contains("camera height 4.20 m (given)"), "{all}");
    assert!(
        all.contains("confidence 0.10: not measuring (< 0.30)"),
        "{all}"
    );
    assert!(all.contains("camera nearly level"), "{all}");
    assert!(all.ends_with("a note"), "{all}");
    // Short lines (the top centre stays free for the horizon arrow).
    assert!(lines.iter().all(|l| l.chars().count() <= 44), "{all}");
}

#[test]
fn wrap_splits_at_spaces() {
    let mut out = Lines::new();
    wrap("aaa bbb ccc dddd e", 8, &mut out);
    let got: Vec<&str> = out.iter().map(|l| l.as_str()).collect();
    assert_eq!(got, ["aaa bbb", "ccc dddd", "e"]);
}

fn scratch(name: &str) -> crate::scratch::ScratchDir {
    crate::scratch::fresh_dir(&format!("snapshot-{name}"))
}

#[test]
fn snapshot_file_is_checked_at_creation_and_replaced_whole() {
    let dir = scratch("file");
    let e = SnapshotFile::create(&dir.join("missing/x.png")).unwrap_err();
    assert_eq!(e.error.kind(), io::ErrorKind::NotFound);
    assert!(e.to_string().starts_with("cannot write snapshot "), "{e}");
    assert!(e.to_string().contains("missing/x.png"), "{e}");
    let e = SnapshotFile::create(&dir).unwrap_err();
    assert!(e.to_string().contains("it is a directory"), "{e}");

    let path = dir.join("s.png");
    std::fs::write(&path, b"old").unwrap();
    let mut f = SnapshotFile::create(&path).unwrap();
    let tmp = dir.join("s.png.stature-tmp");
    assert!(tmp.exists());
    assert_eq!(
        std::fs::read(&path).unwrap(),
        b"old",
        "untouched until written"
    );
    let c = grey();
    f.write(&c).unwrap();
    assert!(!tmp.exists());
    let dec = png::Decoder::new(File::open(&path).unwrap());
    let mut r = dec.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size()];
    let info = r.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (640, 480));
    assert_eq!(&buf[..info.buffer_size()], c.rgb());
    assert!(f.write(&c).is_err(), "written once");

    // Dropped unwritten (a run that never got to its end): no stray file.
    let f = SnapshotFile::create(&dir.join("t.png")).unwrap();
    drop(f);
    assert!(std::fs::read_dir(&dir).unwrap().count() == 1, "only s.png");
}

#[test]
fn two_writers_of_one_snapshot_path_each_put_a_whole_png_in_place() {
    // A service and an installer's `stature snapshot` with its config:
    // both hold the path's temporary file from their start. (Two opens in
    // one process lock each other out as two processes do.)
    let dir = scratch("two-writers");
    let path = dir.join("view.png");
    let mut first = SnapshotFile::create(&path).unwrap();
    let mut second = SnapshotFile::create(&path).unwrap();
    let shared = dir.join("view.png.stature-tmp");
    let own = dir.join(format!("view.png.stature-tmp.{}", std::process::id()));
    assert!(shared.exists() && own.exists());
    let decode = || {
        let mut r = png::Decoder::new(File::open(&path).unwrap())
            .read_info()
            .unwrap();
        let mut buf = vec![0; r.output_buffer_size()];
        let info = r.next_frame(&mut buf).unwrap();
        buf.truncate(info.buffer_size());
        buf
    };
    let a = grey();
    let mut b = grey();
    b.dim(
        embedded_graphics::primitives::Rectangle::new(
            embedded_graphics::prelude::Point::new(10, 10),
            embedded_graphics::prelude::Size::new(200, 100),
        ),
        64,
    );
    assert_ne!(a.rgb(), b.rgb());
    first.write(&a).unwrap();
    assert_eq!(decode(), a.rgb());
    // Before: the second wrote into the file the first had just put in
    // place (a torn PNG) and then failed to rename.
    second.write(&b).unwrap();
    assert_eq!(decode(), b.rgb());
    assert!(!shared.exists() && !own.exists());
    // The shared name is free again for the next one.
    let third = SnapshotFile::create(&path).unwrap();
    assert!(shared.exists());
    drop(third);
    assert!(!shared.exists());
}

#[test]
fn something_left_at_the_temporary_name_is_stepped_around() {
    // A FIFO at `PATH.stature-tmp` failed the run at start (ENXIO); so
    // would another user's file there. A name of the process's own does.
    let dir = scratch("left-behind");
    let path = dir.join("view.png");
    let shared = dir.join("view.png.stature-tmp");
    crate::scratch::mkfifo(&shared);
    let mut f = SnapshotFile::create(&path).unwrap();
    f.write(&grey()).unwrap();
    assert!(png::Decoder::new(File::open(&path).unwrap())
        .read_info()
        .is_ok());
    // What was there is not this process's to remove.
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 2, "{left:?}");
    assert!(shared.exists());
}

#[test]
fn a_killed_writers_temporary_file_is_removed_by_the_next_one() {
    let dir = scratch("abandoned");
    let path = dir.join("view.png");
    let tmp = |pid: &str| dir.join(format!("view.png.stature-tmp.{pid}"));
    // Left by a second writer killed mid-run, and one a live writer holds.
    std::fs::write(tmp("999999"), b"half a png").unwrap();
    let live = crate::replace::lock_at(&tmp("424242"), rustix::fs::OFlags::WRONLY).unwrap();
    assert!(matches!(live, crate::replace::Locked::Held(_)));
    // Not of this kind: left alone.
    std::fs::write(tmp("notes"), b"x").unwrap();
    let f = SnapshotFile::create(&path).unwrap();
    assert!(!tmp("999999").exists(), "abandoned: removed");
    assert!(tmp("424242").exists(), "held: kept");
    assert!(tmp("notes").exists());
    drop(f);
    drop(live);
}

#[test]
fn only_png_names_or_no_extension_are_accepted() {
    for ok in [
        "s.png",
        "S.PNG",
        "dir.d/s.Png",
        "snapshot",
        "/srv/www/view",
        "",
    ] {
        assert_eq!(check_path(Path::new(ok)), Ok(()), "{ok}");
    }
    for bad in ["s.jpg", "s.JPEG", "s.png.bak", "s.gif", "dir.png/s.webp"] {
        let e = check_path(Path::new(bad)).unwrap_err();
        assert!(e.contains("only PNG is written"), "{bad}: {e}");
    }
}

#[test]
fn labels_keep_clear_of_each_other() {
    let a = mark(true);
    let b = Mark {
        id: 8,
        bbox: BBox {
            x0: 320,
            x1: 360,
            ..a.bbox
        },
        head: [340.0, 200.0],
        foot: [340.0, 310.0],
        ..a
    };
    let mut c = grey();
    draw(&mut c, &overlay(None, &[a, b]));
    let label_px = |x0: i64, y0: i64| {
        (x0..x0 + 60)
            .filter(|&x| (y0..y0 + 13).any(|y| c.pixel(x, y) == Some(rgb(colour::PERSON))))
            .count()
    };
    // The first sits above the boxes, the second (it would overlap) below.
    assert!(label_px(298, 184) >= 50);
    assert!(label_px(318, 313) >= 50, "{}", label_px(318, 313));
}
