//! The tracker on synthetic frames: coloured people on a grey ground, with
//! regions built from their silhouettes as the detector would.

use super::*;
use crate::detect::Run;
use crate::frame::Size;

const W: usize = 320;
const H: usize = 240;

#[derive(Clone, Copy)]
struct Person {
    x0: i32,
    y0: i32,
    w: i32,
    h: i32,
    yuv: (u8, u8, u8),
}

fn paint(f: &mut Frame, people: &[Person]) {
    f.y.fill(110);
    f.u.fill(128);
    f.v.fill(128);
    for p in people {
        for y in p.y0.max(0)..(p.y0 + p.h).min(H as i32) {
            for x in p.x0.max(0)..(p.x0 + p.w).min(W as i32) {
                f.y[y as usize * W + x as usize] = p.yuv.0;
                let c = (y as usize / 2) * (W / 2) + x as usize / 2;
                f.u[c] = p.yuv.1;
                f.v[c] = p.yuv.2;
            }
        }
    }
}

/// One region covering the union of the given people's boxes (row spans).
fn region(set: &mut RegionSet, people: &[Person]) {
    let mut runs: Vec<Run> = Vec::new();
    let (mut area, mut bx) = (0u32, [i32::MAX, i32::MAX, i32::MIN, i32::MIN]);
    for y in 0..H as i32 {
        let mut lo = i32::MAX;
        let mut hi = i32::MIN;
        for p in people {
            if y >= p.y0 && y < p.y0 + p.h {
                lo = lo.min(p.x0.max(0));
                hi = hi.max((p.x0 + p.w - 1).min(W as i32 - 1));
            }
        }
        if lo <= hi {
            runs.push(Run {
                y: y as u16,
                x0: lo as u16,
                x1: hi as u16,
            });
            area += (hi - lo + 1) as u32;
            bx = [bx[0].min(lo), bx[1].min(y), bx[2].max(hi), bx[3].max(y)];
        }
    }
    if runs.is_empty() {
        return;
    }
    let cx = 0.5 * (bx[0] + bx[2]) as f32;
    let r = Region {
        area,
        bbox: BBox {
            x0: bx[0] as u16,
            y0: bx[1] as u16,
            x1: bx[2] as u16,
            y1: bx[3] as u16,
        },
        head: [cx, bx[1] as f32],
        foot: [cx, bx[3] as f32],
        touches_border: bx[0] == 0 || bx[1] == 0 || bx[2] == W as i32 - 1 || bx[3] == H as i32 - 1,
        split: false,
        loose_ends: false,
        core: 0..0,
        runs: 0..0,
    };
    set.push(r, &runs).unwrap();
}

/// A tracker with `cfg`, an empty frame and a region set for the tests.
fn setup(cfg: &TrackConfig) -> (Tracker, Frame, RegionSet) {
    (
        Tracker::new(cfg, 16),
        Frame::new(Size {
            width: W,
            height: H,
        }),
        RegionSet::with_capacity(16, 4096),
    )
}

fn single(n: usize, yes: bool) -> Vec<Verdict> {
    vec![
        Verdict {
            score: 1.0,
            single_human: yes
        };
        n
    ]
}

const RED: (u8, u8, u8) = (81, 90, 240);
const BLUE: (u8, u8, u8) = (41, 240, 110);

#[test]
fn crossing_people_keep_their_identities_and_withhold_merged_samples() {
    let cfg = TrackConfig::default();
    let (mut t, mut f, mut set) = setup(&cfg);
    let mut merged_fresh = 0;
    let mut merged_frames = 0;
    for k in 0..60i32 {
        let a = Person {
            x0: 40 + 3 * k,
            y0: 80,
            w: 20,
            h: 60,
            yuv: RED,
        };
        let b = Person {
            x0: 240 - 3 * k,
            y0: 84,
            w: 20,
            h: 60,
            yuv: BLUE,
        };
        paint(&mut f, &[a, b]);
        set.clear();
        let overlapping = (a.x0 - b.x0).abs() < 24;
        if overlapping {
            region(&mut set, &[a, b]);
        } else {
            region(&mut set, &[a]);
            region(&mut set, &[b]);
        }
        let v = single(set.regions().len(), !overlapping);
        t.step(k as u64, 10.0, &f, &set, &v);
        if overlapping {
            merged_frames += 1;
            merged_fresh += t.tracks().iter().filter(|t| t.fresh.is_some()).count();
            assert!(t.tracks().iter().all(|t| t.merged));
        }
    }
    assert!(merged_frames >= 5);
    assert_eq!(merged_fresh, 0, "samples must be withheld while merged");
    assert_eq!(t.tracks().len(), 2);
    // Red started left and walks right: after crossing it is on the right.
    let red = t.tracks().iter().find(|t| t.id == 1).unwrap();
    let blue = t.tracks().iter().find(|t| t.id == 2).unwrap();
    assert!(
        red.bbox.x0 > blue.bbox.x0,
        "identities swapped: {:?} {:?}",
        red.bbox,
        blue.bbox
    );
    assert!(red.samples.len() > 30);
}

#[test]
fn tracks_end_after_coasting_and_overflow_is_counted() {
    let cfg = TrackConfig {
        capacity: 4,
        ..Default::default()
    };
    let (mut t, mut f, mut set) = setup(&cfg);
    let people: Vec<Person> = (0..6)
        .map(|i| Person {
            x0: 10 + 50 * i,
            y0: 60,
            w: 16,
            h: 50,
            yuv: RED,
        })
        .collect();
    paint(&mut f, &people);
    for p in &people {
        region(&mut set, &[*p]);
    }
    t.step(0, 10.0, &f, &set, &single(6, true));
    assert_eq!(t.tracks().len(), 4);
    assert_eq!(t.overflow, 2);
    // Everyone leaves: tracks coast for max_coast_s (10 frames), then end.
    paint(&mut f, &[]);
    set.clear();
    let mut ended_at = None;
    for k in 1..30u64 {
        t.step(k, 10.0, &f, &set, &[]);
        if ended_at.is_none() && t.tracks().iter().all(|t| t.ended) {
            ended_at = Some(k);
        }
    }
    assert_eq!(ended_at, Some(11));
    assert_eq!(t.live(), 0);
}

#[test]
fn non_person_regions_start_no_tracks() {
    let (mut t, mut f, mut set) = setup(&TrackConfig::default());
    let car = Person {
        x0: 100,
        y0: 100,
        w: 60,
        h: 30,
        yuv: BLUE,
    };
    for k in 0..10 {
        paint(&mut f, &[car]);
        set.clear();
        region(&mut set, &[car]);
        t.step(k, 10.0, &f, &set, &single(1, false));
    }
    assert!(t.tracks().is_empty());
}

#[test]
fn cut_and_border_samples_are_rejected() {
    let (mut t, mut f, mut set) = setup(&TrackConfig::default());
    let mut accepted = Vec::new();
    for k in 0..30i32 {
        let mut p = Person {
            x0: 60 + 2 * k,
            y0: 70,
            w: 20,
            h: 60,
            yuv: RED,
        };
        if (10..13).contains(&k) {
            p.h = 40; // a bench hides the legs
        }
        if k >= 25 {
            p.y0 = 0; // walks into the top border (head cut by the image edge)
        }
        paint(&mut f, &[p]);
        set.clear();
        region(&mut set, &[p]);
        t.step(k as u64, 10.0, &f, &set, &single(1, true));
        accepted.push(t.tracks()[0].fresh.is_some());
    }
    assert!(accepted[1..10].iter().all(|&a| a));
    assert!(
        accepted[10..13].iter().all(|&a| !a),
        "cut samples accepted: {accepted:?}"
    );
    assert!(accepted[13..25].iter().all(|&a| a));
    assert!(accepted[25..].iter().all(|&a| !a));
}

#[test]
fn a_flickering_verdict_on_a_lone_walker_does_not_break_the_track() {
    // Every third frame the classifier scores the walker just below its
    // threshold: the track keeps sampling (keep_score), but a region of a
    // very different size with the same low score does not snap it.
    let (mut t, mut f, mut set) = setup(&TrackConfig::default());
    let mut sampled = 0;
    for k in 0..30i32 {
        let p = Person {
            x0: 60 + 2 * k,
            y0: 70,
            w: 20,
            h: 60,
            yuv: RED,
        };
        paint(&mut f, &[p]);
        set.clear();
        region(&mut set, &[p]);
        let low = k % 3 == 2;
        let v = [Verdict {
            score: if low { -0.3 } else { 1.0 },
            single_human: !low,
        }];
        t.step(k as u64, 10.0, &f, &set, &v);
        let tr = &t.tracks()[0];
        if low && k > 3 {
            assert!(!tr.merged && tr.fresh.is_some(), "frame {k}");
        }
        sampled += usize::from(tr.fresh.is_some());
    }
    assert!(sampled >= 28, "{sampled}");
    // A twice-as-wide region (a neighbour joined) scored just as low is a merge.
    let p = Person {
        x0: 120,
        y0: 70,
        w: 44,
        h: 60,
        yuv: RED,
    };
    paint(&mut f, &[p]);
    set.clear();
    region(&mut set, &[p]);
    let v = [Verdict {
        score: -0.3,
        single_human: false,
    }];
    t.step(30, 10.0, &f, &set, &v);
    assert!(t.tracks()[0].merged && t.tracks()[0].fresh.is_none());
}

#[test]
fn a_duplicate_track_on_one_person_ends() {
    // A person whose region was split for two frames gets a second track;
    // once the region is whole again (one person, both tracks pick it) the
    // track overlapping it most keeps it and the duplicate coasts out.
    let cfg = TrackConfig::default();
    let (mut t, mut f, mut set) = setup(&cfg);
    for k in 0..40i32 {
        let p = Person {
            x0: 80 + k,
            y0: 60,
            w: 24,
            h: 70,
            yuv: BLUE,
        };
        paint(&mut f, &[p]);
        set.clear();
        if (5..7).contains(&k) {
            // Split into upper and lower halves, both called a person.
            let top = Person { h: 34, ..p };
            let bottom = Person {
                y0: p.y0 + 36,
                h: 34,
                ..p
            };
            region(&mut set, &[top]);
            region(&mut set, &[bottom]);
        } else {
            region(&mut set, &[p]);
        }
        let n = set.regions().len();
        t.step(k as u64, 10.0, &f, &set, &single(n, true));
    }
    let live: Vec<_> = t.tracks().iter().filter(|t| !t.ended).collect();
    assert_eq!(
        live.len(),
        1,
        "{:?}",
        t.tracks().iter().map(|t| t.id).collect::<Vec<_>>()
    );
    assert!(live[0].fresh.is_some() && !live[0].merged);
}

/// A walker coming toward the camera whose region is joined at the top by
/// something that stays (a standing person behind): the region's top row
/// stays while its bottom walks on. Those samples are refused; the same
/// walk alone (head moving with the feet, as under a 4 m camera) is not.
#[test]
fn a_region_top_that_stays_while_the_feet_walk_is_refused() {
    let walk = |pinned: bool| {
        let (mut t, mut f, mut set) = setup(&TrackConfig::default());
        let mut accepted = Vec::new();
        for k in 0..30i32 {
            // Feet move down 1 px a frame, the head 0.6 px (ratio (H-h)/H).
            let foot = 140 + k;
            let head = if pinned { 60 } else { 60 + (3 * k) / 5 };
            let p = Person {
                x0: 100,
                y0: head,
                w: 20,
                h: foot - head,
                yuv: RED,
            };
            paint(&mut f, &[p]);
            set.clear();
            region(&mut set, &[p]);
            t.step(k as u64, 10.0, &f, &set, &single(1, true));
            accepted.push(t.tracks()[0].fresh.is_some());
        }
        accepted
    };
    let alone = walk(false);
    assert!(alone[1..].iter().all(|&a| a), "walker alone: {alone:?}");
    let pinned = walk(true);
    // Accepted until the feet have moved 8 px with the head still, then refused.
    assert!(pinned[1..8].iter().all(|&a| a), "{pinned:?}");
    assert!(
        pinned[9..].iter().all(|&a| !a),
        "pinned top accepted: {pinned:?}"
    );
}

/// A red walker vanishes for a second (behind something the detector
/// cannot see through) and someone comes out where its track coasts:
/// `who` in the colours of the walker or another person's.
fn reappear(cfg: &TrackConfig, who: (u8, u8, u8)) -> Tracker {
    let (mut t, mut f, mut set) = setup(cfg);
    for k in 0..40i32 {
        let p = Person {
            x0: 40 + 3 * k,
            y0: 80,
            w: 20,
            h: 60,
            yuv: if k < 20 { RED } else { who },
        };
        let hidden = (20..30).contains(&k);
        paint(
            &mut f,
            if hidden {
                &[]
            } else {
                std::slice::from_ref(&p)
            },
        );
        set.clear();
        if !hidden {
            region(&mut set, &[p]);
        }
        t.step(k as u64, 10.0, &f, &set, &single(set.regions().len(), true));
    }
    t
}

#[test]
fn a_coasting_track_that_reacquires_someone_else_ends_and_a_new_one_starts() {
    let cfg = TrackConfig::default();
    // The same person comes back: one track throughout.
    let t = reappear(&cfg, RED);
    assert_eq!(t.reid_splits, 0);
    assert_eq!(t.tracks().len(), 1);
    assert_eq!(t.tracks()[0].id, 1);
    assert!(t.tracks()[0].samples.len() >= 28);
    // Someone else: the red track ended (its samples are its own) and the
    // blue walker has a track of its own.
    let t = reappear(&cfg, BLUE);
    assert_eq!(t.reid_splits, 1);
    let ids: Vec<u32> = t
        .tracks()
        .iter()
        .filter(|t| !t.ended)
        .map(|t| t.id)
        .collect();
    assert_eq!(ids, [2]);
    assert!(t.tracks().iter().find(|t| t.id == 2).unwrap().samples.len() >= 9);
    // Without the check the red track takes the blue walker over.
    let off = TrackConfig {
        reid_min_similarity: 0.0,
        ..Default::default()
    };
    let t = reappear(&off, BLUE);
    assert_eq!(t.reid_splits, 0);
    assert_eq!(t.tracks().len(), 1);
    assert_eq!(t.tracks()[0].id, 1);
}
