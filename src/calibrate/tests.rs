//! Calibration from synthetic walks in front of random known cameras.

use super::geometry::*;
use super::synth::{random_camera, walk, SynthScene};
use super::*;
use crate::camera::Camera;

fn calibrate(
    cam: &Camera,
    scene: &SynthScene,
    cfg: &CalibrateConfig,
    seed: u64,
) -> (Calibrator, Vec<synth::SynthObs>) {
    let mut rng = Rng::new(seed);
    let obs = walk(cam, scene, &mut rng);
    let mut c = Calibrator::new(cfg, scene.width, scene.height);
    for o in &obs {
        c.observe(o.frame, o.id, o.hf);
        c.update(o.frame);
    }
    c.finish(obs.last().map_or(0, |o| o.frame));
    (c, obs)
}

struct Errors {
    focal_rel: f64,
    tilt_deg: f64,
    roll_deg: f64,
    height_rel: f64,
}

fn errors(e: &Estimate, cam: &Camera) -> Errors {
    Errors {
        focal_rel: (e.geom.focal() / cam.f - 1.0).abs(),
        tilt_deg: (e.geom.tilt() - cam.tilt).abs().to_degrees(),
        roll_deg: (e.geom.roll() - cam.roll).abs().to_degrees(),
        height_rel: (e.camera_height / cam.height - 1.0).abs(),
    }
}

#[test]
fn random_cameras_are_recovered_with_known_camera_height() {
    let mut rng = Rng::new(11);
    let mut worst = [0.0f64; 3];
    for k in 0..crate::scratch::runs_from_env("CALIBRATE_TEST_CAMERAS", 12) as u64 {
        let cam = random_camera(&mut rng, 640, 480);
        let cfg = CalibrateConfig {
            camera_height_m: cam.height,
            ..Default::default()
        };
        let (c, obs) = calibrate(&cam, &SynthScene::default(), &cfg, 100 + k);
        let e = c.estimate().expect("an estimate");
        let err = errors(e, &cam);
        worst[0] = worst[0].max(err.focal_rel);
        worst[1] = worst[1].max(err.tilt_deg);
        worst[2] = worst[2].max(err.roll_deg);
        assert!(
            err.focal_rel < 0.03 && err.tilt_deg < 1.0 && err.roll_deg < 1.0,
            "camera {k} {cam:?}: f {:.1} tilt {:.2} roll {:.2} ({} obs, conf {:.2}, {:?})",
            e.geom.focal(),
            e.geom.tilt().to_degrees(),
            e.geom.roll().to_degrees(),
            obs.len(),
            e.confidence,
            e.degeneracy
        );
        assert!(e.confidence > 0.5, "confidence {}", e.confidence);
        // Per-person heights through the estimate, median per person.
        let mut errs = Vec::new();
        for id in 1..=20u32 {
            let mut hs: Vec<f64> = obs
                .iter()
                .filter(|o| o.id == id)
                .filter_map(|o| e.height(&o.hf))
                .collect();
            let truth = obs.iter().find(|o| o.id == id).map(|o| o.height);
            if let (Some(m), Some(t)) = (median(&mut hs), truth) {
                errs.push((m - t).abs());
            }
        }
        let m = median(&mut errs).unwrap();
        eprintln!(
            "camera {k}: f {:.1}/{:.1} tilt {:.2}/{:.2} roll {:.2}/{:.2} h-err {m:.4} conf {:.2} obs {} hc {:.2} vvp-inl {} hor-inl {}",
            e.geom.focal(),
            cam.f,
            e.geom.tilt().to_degrees(),
            cam.tilt.to_degrees(),
            e.geom.roll().to_degrees(),
            cam.roll.to_degrees(),
            e.confidence,
            obs.len(),
            cam.height,
            e.inliers,
            e.horizon_inliers
        );
        assert!(m < 0.02, "camera {k}: median height error {m}");
    }
    eprintln!(
        "worst focal {:.4} tilt {:.3} roll {:.3}",
        worst[0], worst[1], worst[2]
    );
}

#[test]
fn matched_population_prior_gives_camera_height() {
    let mut rng = Rng::new(21);
    for k in 0..crate::scratch::runs_from_env("CALIBRATE_TEST_CAMERAS", 12).div_ceil(2) as u64 {
        let cam = random_camera(&mut rng, 640, 480);
        let scene = SynthScene::default();
        let obs = walk(&cam, &scene, &mut Rng::new(200 + k));
        // The prior matched to the people actually seen.
        let mut seen = std::collections::BTreeMap::new();
        for o in &obs {
            seen.insert(o.id, o.height);
        }
        let mean = seen.values().sum::<f64>() / seen.len() as f64;
        let cfg = CalibrateConfig {
            prior_height_m: mean,
            ..Default::default()
        };
        let (c, _) = calibrate(&cam, &scene, &cfg, 200 + k);
        let e = c.estimate().unwrap();
        let err = errors(e, &cam);
        assert!(
            err.height_rel < 0.03,
            "camera {k}: {} vs {}",
            e.camera_height,
            cam.height
        );
    }
}

#[test]
fn reference_person_sets_the_scale() {
    let mut rng = Rng::new(5);
    let cam = random_camera(&mut rng, 640, 480);
    let scene = SynthScene::default();
    let obs = walk(&cam, &scene, &mut Rng::new(77));
    // The first person with 8 anchors is the reference; with the default
    // step, person 1 qualifies first in this scene.
    let first = obs[0].id;
    let truth = obs[0].height;
    assert_eq!(first, 1);
    let cfg = CalibrateConfig {
        reference_height_m: truth,
        ..Default::default()
    };
    let (c, _) = calibrate(&cam, &scene, &cfg, 77);
    let e = c.estimate().unwrap();
    assert!(
        errors(e, &cam).height_rel < 0.03,
        "{} vs {}",
        e.camera_height,
        cam.height
    );
}

#[test]
fn loitering_person_is_bounded_and_does_not_bias() {
    let cam = Camera::centred(700.0, 25.0, 2.0, 4.0, 640, 480);
    let cfg = CalibrateConfig::default();
    let mut c = Calibrator::new(&cfg, 640, 480);
    let mut rng = Rng::new(9);
    // 20000 frames of one person shuffling around one spot.
    for f in 0..20_000u64 {
        let x = 0.3 * rng.normal();
        let y = 8.0 + 0.3 * rng.normal();
        let o = HeadFoot {
            head: cam.project([x, y, 1.75]).unwrap(),
            foot: cam.project([x, y, 0.0]).unwrap(),
        };
        c.observe(f, 1, o);
        c.update(f);
    }
    assert!(c.anchor_count() <= cfg.anchors_per_track);
    // One spot cannot give a horizon: no confident estimate.
    assert!(c.estimate().is_none_or(|e| e.confidence < 0.3));
}

/// A camera looking nearly straight down (82° tilt), 6 m up, and a
/// configuration that knows its height.
fn near_vertical_camera() -> (Camera, CalibrateConfig) {
    let cam = Camera::centred(500.0, 82.0, 0.0, 6.0, 640, 480);
    let cfg = CalibrateConfig {
        camera_height_m: 6.0,
        ..Default::default()
    };
    (cam, cfg)
}

#[test]
fn near_vertical_view_is_flagged() {
    let (cam, cfg) = near_vertical_camera();
    let (c, _) = calibrate(&cam, &SynthScene::default(), &cfg, 4);
    if let Some(e) = c.estimate() {
        assert_eq!(e.degeneracy, Some(Degeneracy::NearVertical), "{e:?}");
        assert!(e.confidence < 0.3);
    }
}

/// The camera the state-file tests walk people past (640x480), and a
/// configuration that knows its height.
fn state_test_camera() -> (Camera, CalibrateConfig) {
    let cam = random_camera(&mut Rng::new(2), 640, 480);
    let cfg = CalibrateConfig {
        camera_height_m: cam.height,
        ..Default::default()
    };
    (cam, cfg)
}

#[test]
fn state_file_round_trip_and_corrupt_file() {
    let dir = crate::scratch::fresh_dir("state");
    let path = dir.join("cal.json");
    let (cam, cfg) = state_test_camera();
    let obs = walk(&cam, &SynthScene::default(), &mut Rng::new(8));
    let mut c = Calibrator::new(&cfg, 640, 480);
    c.state = Some(state::StateFile::new(&path, 1 << 20));
    assert!(c.state.as_ref().unwrap().load().unwrap().is_none());
    for o in &obs {
        c.observe(o.frame, o.id, o.hf);
        c.update(o.frame);
    }
    let fin = c.finish(obs.last().unwrap().frame).unwrap();
    assert!(!path.with_extension("json.stature-tmp").exists());
    let saved = state::StateFile::new(&path, 0).load().unwrap().unwrap();
    let mut d = Calibrator::new(&cfg, 640, 480);
    let n = d.resume(&saved).unwrap().restored;
    assert_eq!(n, c.anchor_count());
    // Every saved anchor is restored as it was (not re-smoothed as if it
    // were a new frame's observation).
    assert_eq!(d.anchor_count(), c.anchor_count());
    let e = d.estimate().unwrap();
    assert!((e.geom.focal() / f64::from(fin.f_px) - 1.0).abs() < 0.01);
    // A different frame size is refused.
    let mut other = Calibrator::new(&cfg, 800, 600);
    assert_eq!(other.resume(&saved), Err([640, 480, 800, 600]));
    assert_eq!(other.anchor_count(), 0);
    // A crash part-way through a write leaves a torn temporary file behind
    // (tests/suite/faults.rs crashes the real process mid-write): readers
    // never look at it, and the next write replaces it.
    let complete = std::fs::read(&path).unwrap();
    let tmp = path.with_extension("json.stature-tmp");
    for cut in [0, 1, complete.len() / 2, complete.len() - 1] {
        std::fs::write(&tmp, &complete[..cut]).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), complete, "cut at {cut}");
        assert!(state::StateFile::new(&path, 0).load().unwrap().is_some());
    }
    // A new track, seen for long enough to give an anchor.
    let next = obs.last().unwrap().frame + 1;
    for f in 0..super::ANCHOR_SMOOTHING as u64 {
        c.observe(next + f, 999, obs[0].hf);
    }
    c.finish(next + super::ANCHOR_SMOOTHING as u64).unwrap();
    assert!(!tmp.exists(), "the leftover was replaced and renamed");
    assert_ne!(std::fs::read(&path).unwrap(), complete, "a new version");
    // A write that fails (here the rename: a non-empty directory now
    // stands at the path; on a board, more often a full disk) leaves no
    // temporary file holding on to the space.
    let blocked = dir.join("blocked");
    std::fs::create_dir_all(blocked.join("inside")).unwrap();
    c.state = Some(state::StateFile::new(&blocked, 1 << 20));
    c.observe(next + 100, 998, obs[0].hf);
    c.finish(next + 101).unwrap();
    assert!(
        blocked.join("inside").is_dir(),
        "the directory is untouched"
    );
    assert!(!dir.join("blocked.stature-tmp").exists());
    // Corrupt content is an error, not a panic.
    std::fs::write(&path, b"{\"version\":1,\"width\":640,").unwrap();
    assert!(matches!(
        state::StateFile::new(&path, 0).load(),
        Err(state::StateError::Corrupt(_))
    ));
}

/// The state is written every `state_interval_s` while new anchors come
/// in, also once the estimate has settled and sends no more records.
/// Before, it was written only with a calibration record: a settled
/// camera could go hours unsaved, and a power cut lost what it learnt.
#[test]
fn state_is_saved_on_the_interval_after_the_records_stop() {
    let dir = crate::scratch::fresh_dir("state-interval");
    let path = dir.join("cal.json");
    let (cam, mut cfg) = state_test_camera();
    // Records only when the confidence moves: the geometry never counts
    // as material.
    cfg.emit_focal_change = 1.0;
    cfg.emit_angle_deg = 45.0;
    cfg.state_interval_s = 2.0;
    let obs = walk(&cam, &SynthScene::default(), &mut Rng::new(8));
    let mut c = Calibrator::new(&cfg, 640, 480);
    c.set_fps(25.0);
    c.state = Some(state::StateFile::new(&path, 1 << 20));
    let (first, last) = (obs[0].frame, obs.last().unwrap().frame);
    let span_s = (last - first) as f64 / 25.0;
    assert!(span_s > 20.0, "{span_s} s of walkers");
    // The same people walk by again and again: the estimate settles and
    // its records stop, while new anchors keep coming.
    let mut saved = None;
    let mut pass = |k: u64| {
        let (mut records, mut writes) = (0, 0);
        for o in &obs {
            let frame = o.frame + k * (last - first + 1);
            c.observe(frame, o.id + 1000 * k as u32, o.hf);
            records += usize::from(c.update(frame).is_some());
            let now = std::fs::read(&path).ok();
            if now.is_some() && now != saved {
                writes += 1;
                saved = now;
            }
        }
        (records, writes)
    };
    let _ = pass(0);
    let (records, writes) = (1..3).map(&mut pass).last().unwrap();
    eprintln!("{records} records, {writes} writes over {span_s:.0} s");
    assert!(
        records <= 1,
        "{records} records: the estimate has not settled"
    );
    // About one write per interval (before: only with a record).
    assert!(
        writes as f64 >= 0.5 * span_s / cfg.state_interval_s,
        "{writes} writes over {span_s:.0} s"
    );
}

/// Two processes on one state file (an installer's `stature snapshot` with
/// the service's config while the service runs): the first to open it
/// writes it, the second resumes from it but never writes or moves it.
/// Before, both wrote through the one temporary file and readers saw torn
/// files. `flock` locks belong to an open file, so two opens in one
/// process conflict as two processes do.
#[test]
fn only_the_first_to_open_a_state_file_writes_it() {
    let dir = crate::scratch::fresh_dir("state-lock");
    let path = dir.join("shared.json");
    let lock = dir.join("shared.json.stature-lock");
    let tmp = dir.join("shared.json.stature-tmp");
    let (cam, cfg) = state_test_camera();
    let obs = walk(&cam, &SynthScene::default(), &mut Rng::new(8));
    let (early, late) = obs.split_at(obs.len() / 2);
    let feed = |c: &mut Calibrator, obs: &[synth::SynthObs]| {
        for o in obs {
            c.observe(o.frame, o.id, o.hf);
            c.update(o.frame);
        }
        c.finish(obs.last().unwrap().frame);
    };
    let mut first = Calibrator::new(&cfg, 640, 480);
    first.state = Some(state::StateFile::open(&path, 1 << 20).unwrap());
    assert!(!first.state.as_ref().unwrap().in_use_elsewhere());
    assert!(lock.exists());
    feed(&mut first, early);
    let written = std::fs::read(&path).unwrap();
    // The first one's write in progress: the second's start-up check must
    // neither truncate nor remove its temporary file.
    std::fs::write(&tmp, b"partial").unwrap();
    let file = state::StateFile::open(&path, 1 << 20).unwrap();
    assert!(file.in_use_elsewhere());
    assert_eq!(std::fs::read(&tmp).unwrap(), b"partial");
    std::fs::remove_file(&tmp).unwrap();
    // It resumes from the state...
    let mut second = Calibrator::new(&cfg, 640, 480);
    let n = second
        .resume(&file.load().unwrap().unwrap())
        .unwrap()
        .restored;
    assert_eq!(n, first.anchor_count());
    // ...but its writes leave the file as the first wrote it.
    second.state = Some(file);
    feed(&mut second, late);
    assert!(second.anchor_count() > n);
    assert_eq!(std::fs::read(&path).unwrap(), written);
    assert!(!tmp.exists());
    // Nor does it move the file aside (its resume failed, say).
    let e = second.state.as_ref().unwrap().set_aside("corrupt");
    assert!(e.unwrap_err().to_string().contains(state::IN_USE));
    assert_eq!(std::fs::read(&path).unwrap(), written);
    // The first one goes on writing.
    feed(&mut first, late);
    assert_ne!(std::fs::read(&path).unwrap(), written);
    // Once it is done, the next one to open the state writes it, although
    // the second still holds the removed lock file open.
    drop(first);
    assert!(!lock.exists(), "the holder removes its lock file");
    let third = state::StateFile::open(&path, 0).unwrap();
    assert!(!third.in_use_elsewhere());
    assert!(state::StateFile::open(&path, 0).unwrap().in_use_elsewhere());
    drop(third);
    // The second, a reader since its start, takes the state over at its
    // next write now that nobody holds it (before: never, to its end).
    std::fs::remove_file(&path).unwrap();
    second.finish(late.last().unwrap().frame);
    assert!(!second.state.as_ref().unwrap().in_use_elsewhere());
    assert!(state::StateFile::new(&path, 0).load().unwrap().is_some());
    assert!(lock.exists());
    drop(second);
    assert!(!lock.exists());
    // A FIFO at the lock's path does not block the open.
    crate::scratch::mkfifo(&lock);
    let _ = state::StateFile::open(&path, 0);
}

/// `tracks × anchors_per_track` is bounded: each key in its range, the
/// product could be 262,144 anchors, a state file over the 16 MiB read cap
/// (the run's own state called corrupt at the next start) and a loop at a
/// few frames per second.
#[test]
fn the_store_size_is_bounded_by_tracks_times_anchors_per_track() {
    let cfg = |tracks, anchors_per_track| CalibrateConfig {
        tracks,
        anchors_per_track,
        ..Default::default()
    };
    assert!(cfg(1024, 8).validate().is_ok());
    assert!(cfg(32, 256).validate().is_ok());
    assert_eq!(32 * 256, MAX_ANCHORS);
    for (t, k) in [(1024, 256), (33, 256), (1024, 9)] {
        let e = cfg(t, k).validate().unwrap_err().to_string();
        assert!(
            e.contains("calibrate.tracks")
                && e.contains("calibrate.anchors_per_track")
                && e.contains(&MAX_ANCHORS.to_string())
                && e.contains(&(t * k).to_string()),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
    // Through the config file too.
    let e =
        crate::config::Config::from_toml("[calibrate]\ntracks = 1024\nanchors_per_track = 256\n")
            .unwrap_err();
    assert!(e.to_string().contains("262144"), "{e}");

    // The largest store allowed, every number at its longest, writes a
    // file well under the read cap.
    let long = -1.234_567_890_123_456_7e-300;
    let a = Anchor {
        head: [long; 2],
        foot: [long; 2],
        motion: [long; 2],
    };
    let tracks = MAX_ANCHORS / 256;
    let slots = vec![
        Slot {
            used: true,
            len: 256,
            ..Slot::default()
        };
        tracks
    ];
    let anchors = vec![a; MAX_ANCHORS];
    let view = state::StateView {
        width: 640,
        height: 480,
        tracks: &slots,
        anchors: &anchors,
        per_track: 256,
    };
    let bytes = serde_json::to_vec(&view).unwrap();
    let saved = state::parse_state(&bytes).unwrap();
    assert_eq!(
        saved.tracks.iter().map(Vec::len).sum::<usize>(),
        MAX_ANCHORS
    );
    let per_anchor = bytes.len() / MAX_ANCHORS;
    assert!(per_anchor < 200, "{per_anchor} bytes per anchor");
    assert!(
        (bytes.len() as u64) < state::MAX_STATE_BYTES / 8,
        "{} bytes",
        bytes.len()
    );
}

/// A state whose anchors no run can have stored (an edited or damaged
/// file): they are dropped and counted, the rest resumed. Before, heads
/// scaled by 1e300 (finite) were resumed, silenced the calibration and
/// were written back.
#[test]
fn impossible_anchors_in_a_state_are_dropped_and_counted() {
    let (cam, cfg) = state_test_camera();
    let (c, _) = calibrate(&cam, &SynthScene::default(), &cfg, 8);
    let good: Vec<Vec<Anchor>> = c
        .slots
        .iter()
        .enumerate()
        .filter(|(_, s)| s.used && s.len > 0)
        .map(|(i, s)| c.anchors[i * cfg.anchors_per_track..][..s.len].to_vec())
        .collect();
    let n_good: usize = good.iter().map(Vec::len).sum();
    let clean = state::Saved {
        version: state::STATE_VERSION,
        width: 640,
        height: 480,
        tracks: good.clone(),
    };
    let mut reference = Calibrator::new(&cfg, 640, 480);
    let r = reference.resume(&clean).unwrap();
    assert_eq!(r.restored, n_good);
    assert_eq!((r.outside, r.impossible), (0, 0));
    let want = reference.estimate().unwrap().geom.focal();

    let a = good[0][0];
    let with = |f: &dyn Fn(&mut Anchor)| {
        let mut b = a;
        f(&mut b);
        b
    };
    // Within a tenth of the frame beyond its edges: kept (slack).
    let near = [
        with(&|b| b.foot[0] = -60.0),
        with(&|b| b.head[1] = -40.0),
        with(&|b| b.foot[1] = 520.0),
    ];
    let outside = [
        with(&|b| b.head = [b.head[0] * 1e300, b.head[1] * 1e300]),
        with(&|b| b.head[1] = -1e300),
        with(&|b| b.foot[0] = -70.0),
        with(&|b| b.foot[0] = 710.0),
        with(&|b| b.foot[1] = 1e6),
    ];
    let impossible = [
        with(&|b| b.motion = [f64::NAN, 0.0]),
        with(&|b| b.foot[0] = f64::INFINITY),
        with(&|b| b.head[1] = b.foot[1] + 10.0),
        with(&|b| b.head[1] = b.foot[1] - 0.5),
        with(&|b| b.motion = [5.0, 0.0]),
    ];
    let mut tracks = good.clone();
    // A whole track of heads scaled by 1e300, as in the review.
    tracks.push(
        good[1]
            .iter()
            .map(|b| Anchor {
                head: [b.head[0] * 1e300, b.head[1] * 1e300],
                ..*b
            })
            .collect(),
    );
    tracks.push(outside.to_vec());
    tracks.push(impossible.to_vec());
    tracks.push(near.to_vec());
    let damaged = state::Saved { tracks, ..clean };
    let mut d = Calibrator::new(&cfg, 640, 480);
    let r = d.resume(&damaged).unwrap();
    assert_eq!(r.outside, good[1].len() + outside.len(), "{r:?}");
    assert_eq!(r.impossible, impossible.len(), "{r:?}");
    assert_eq!(r.restored, n_good + near.len(), "{r:?}");
    // The calibration is the clean state's (three near anchors aside).
    let f = d.estimate().expect("still calibrated").geom.focal();
    assert!((f / want - 1.0).abs() < 0.02, "{f} vs {want}");
    // Nothing dropped is written back.
    let dir = crate::scratch::fresh_dir("state-impossible");
    let path = dir.join("s.json");
    d.state = Some(state::StateFile::new(&path, 1 << 20));
    d.finish(1);
    let saved = state::StateFile::new(&path, 0).load().unwrap().unwrap();
    let mut again = Calibrator::new(&cfg, 640, 480);
    let r = again.resume(&saved).unwrap();
    assert_eq!((r.outside, r.impossible), (0, 0), "{r:?}");
}

/// A file too large to be a state file is refused unread (a mistyped
/// `--state` may name a video) and renamed aside, never over an existing
/// name.
#[test]
fn an_oversized_state_file_is_refused_unread_and_set_aside() {
    let dir = crate::scratch::fresh_dir("state-big");
    let path = dir.join("clip.y4m");
    // Sparse: no 17 MiB written.
    let f = std::fs::File::create(&path).unwrap();
    f.set_len(state::MAX_STATE_BYTES + 1).unwrap();
    drop(f);
    let file = state::StateFile::new(&path, 0);
    let e = file.load().unwrap_err();
    assert!(
        e.to_string().contains("too large to be a state file"),
        "{e}"
    );
    std::fs::write(dir.join("clip.y4m.corrupt"), "kept").unwrap();
    let aside = file.set_aside("corrupt").unwrap();
    assert_eq!(aside, dir.join("clip.y4m.corrupt.1"));
    assert_eq!(
        std::fs::read_to_string(dir.join("clip.y4m.corrupt")).unwrap(),
        "kept"
    );
    assert_eq!(
        std::fs::metadata(&aside).unwrap().len(),
        state::MAX_STATE_BYTES + 1
    );
    assert!(!path.exists());
}

/// A degenerate view is warned of only once it has held for a few refits
/// (PETS passed through "nearly level" for one early refit), a warning is
/// withdrawn only after as many clean ones, and a failed refit (the same
/// estimate again) counts for nothing.
#[test]
fn a_passing_degeneracy_is_not_warned_of_and_a_warning_is_withdrawn() {
    let (cam, cfg) = near_vertical_camera();
    let (c, _) = calibrate(&cam, &SynthScene::default(), &cfg, 4);
    let flagged = *c.estimate().expect("an estimate");
    assert_eq!(flagged.degeneracy, Some(Degeneracy::NearVertical));
    let mut version = 0;
    let mut refit = |degeneracy: Option<Degeneracy>| {
        version += 1;
        Estimate {
            degeneracy,
            version,
            ..flagged
        }
    };
    let (bad, good) = (Some(Degeneracy::NearVertical), None);
    let mut c = Calibrator::new(&cfg, 640, 480);
    // One degenerate refit between good ones: nothing said.
    assert_eq!(c.tell_degeneracy(&refit(good)), None);
    assert_eq!(c.tell_degeneracy(&refit(bad)), None);
    assert_eq!(c.tell_degeneracy(&refit(good)), None);
    // Failed refits leave the same estimate: they do not add up.
    let same = refit(bad);
    for _ in 0..2 * DEGENERACY_REFITS {
        assert_eq!(c.tell_degeneracy(&same), None);
    }
    for _ in 2..DEGENERACY_REFITS {
        assert_eq!(c.tell_degeneracy(&refit(bad)), None);
    }
    // Held for DEGENERACY_REFITS refits: warned of, once.
    assert_eq!(c.tell_degeneracy(&refit(bad)), Some(bad));
    assert_eq!(c.tell_degeneracy(&refit(bad)), None);
    // One clean refit is not enough to withdraw it (no flapping)...
    assert_eq!(c.tell_degeneracy(&refit(good)), None);
    assert_eq!(c.tell_degeneracy(&refit(bad)), None);
    for _ in 1..DEGENERACY_REFITS {
        assert_eq!(c.tell_degeneracy(&refit(good)), None);
    }
    // ...as many as it took to give it: the all-clear, once.
    assert_eq!(c.tell_degeneracy(&refit(good)), Some(None));
    assert_eq!(c.tell_degeneracy(&refit(good)), None);
}
