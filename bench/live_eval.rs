//! What the live pipeline feeds the calibrator, against the simulated truth.
//!
//! `cargo run --release --example live_eval -- [--scene NAME|all|pets] [--seeds 1,2] [--frames N]
//! [--query 'shadows=0'] [--toml '[detect]\nclose_radius_y = 2']`
//!
//! Runs the whole loop on a simulated scene and matches every head/foot
//! observation a track hands the calibrator to the true person under it
//! (largest box IoU), then prints: how many observations are of a person,
//! a dog, a car or nothing; head and foot errors against the truth; the
//! angle between each observed head–foot line and the true vertical through
//! its foot; track purity; and three calibrations from the same events —
//! live points (what the loop does), the true points of the same
//! (frame, track) events, and those true points with Gaussian noise of the
//! measured size — so that input noise, bias and event selection can be
//! told apart.
//!
//! Diagnostics by environment: `MISSES=1` sorts every eligible person who
//! got no final height (untracked, fragments, others, unmeasured);
//! `PERSON=id` prints that person's every frame: its truth box, visibility,
//! how many other boxes overlap it, the best region's IoU, box and SVM
//! score, and the tracks on it (`*`: gave a sample that frame); `TRACK=id`,
//! `FINALS=1`, `SWAP=1`, `KAPPA=1` follow one track, the final heights,
//! identity swaps and the lean fit; `DUMP=FILE` writes every observation
//! with its truth as CSV; `SWAP_TRUE=head,foot_y` calibrates the "live
//! points" line with those parts of every person observation replaced by
//! the truth's (parts: `head`, `foot`, `head_x`, `head_y`, `foot_x`,
//! `foot_y`).
//!
//! Many runs (`--scene all --seeds 1,2,...`) are summarised by
//! `python3 bench/live_summary.py OUTPUT...` (the figures bench/RESULTS.md
//! quotes: f, tilt, roll, camera height, heights, recall).
//!
//! Always printed besides: track-median heights from the live points under
//! the true geometry (so calibration error and point error can be told
//! apart), and the live foot's ground offset by walking direction.

use stature::calibrate::geometry::HeadFoot;
use stature::calibrate::live::{iou, run_sim};
use stature::calibrate::{CalibrateConfig, Calibrator};
use stature::config::Config;
use stature::rng::Rng;
use stature::source::sim::people::Kind;
use std::collections::BTreeMap;

struct Event {
    frame: u64,
    track: u32,
    live: HeadFoot,
    truth: Option<(Kind, u32, HeadFoot, f64)>,
}

fn stats(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt();
    (m, s)
}

fn calibrate(events: &[(u64, u32, HeadFoot)], cfg: &CalibrateConfig, w: usize, h: usize) -> String {
    let mut c = Calibrator::new(cfg, w, h);
    let mut last = 0;
    for (f, id, o) in events {
        c.observe(*f, *id, *o);
        c.update(*f);
        last = *f;
    }
    c.finish(last);
    match c.estimate() {
        Some(e) => format!(
            "f {:7.1} tilt {:5.2} roll {:5.2} hc {:5.2} vvp ({:7.1},{:7.1}) d {:6.1} inl {:3}/{:3} hinl {:4} conf {:.2}",
            e.geom.focal(),
            e.geom.tilt().to_degrees(),
            e.geom.roll().to_degrees(),
            e.camera_height,
            e.geom.v[0],
            e.geom.v[1],
            e.geom.d,
            e.inliers,
            c.anchor_count(),
            e.horizon_inliers,
            e.confidence
        ),
        None => "no estimate".into(),
    }
}

fn run(scene: &str, seed: u64, frames: Option<u64>, extra: &str, toml: &str) {
    let mut q = match frames {
        Some(n) => format!("seed={seed}&frames={n}"),
        None => format!("seed={seed}"),
    };
    if !extra.is_empty() {
        q = format!("{q}&{extra}");
    }
    let cfg = Config::from_toml(toml).expect("--toml");
    // Where isolated, fully visible walkers are lost: [frames, with a
    // region of IoU >= 0.5, that region called single, a track snapped to
    // it this frame (sample given), a track on it but merged/coasting].
    let mut funnel = [0u64; 5];
    // PERSON=id: that person's frames, its best region and what became of it.
    let person: Option<u32> = std::env::var("PERSON")
        .ok()
        .map(|v| v.parse().expect("PERSON=id"));
    let mut frame_no = 0u64;
    // Region box edges minus the truth box's (x0, x1, y0, y1) for the
    // isolated walkers matched above.
    let mut box_edges: [Vec<f64>; 4] = Default::default();
    let run = run_sim(&format!("sim:{scene}?{q}"), &cfg, |p, sim| {
        let (w_px, h_px) = (p.frame.size().width as f64, p.frame.size().height as f64);
        let (set, verdicts) = p.regions();
        let truth = sim.truth();
        frame_no += 1;
        if let Some(o) = person.and_then(|id| truth.iter().find(|o| o.id == id && o.kind == Kind::Person)) {
            let ob = o.bbox.map(f64::from);
            let best = best_region(set, ob);
            let others = truth
                .iter()
                .filter(|q| q.id != o.id && q.visible_px >= 50 && iou(ob, q.bbox.map(f64::from)) > 0.0)
                .count();
            let tracks: Vec<String> = p
                .tracker()
                .tracks()
                .iter()
                .filter(|t| {
                    let tb = [t.bbox.x0, t.bbox.y0, t.bbox.x1, t.bbox.y1].map(f64::from);
                    iou(tb, ob) > 0.3
                })
                .map(|t| format!("t{}{}", t.id, if t.fresh.is_some() { "*" } else { "" }))
                .collect();
            println!(
                "  person {} frame {} box {:?} vis {:.2} overlapping {} | region iou {:.2} box {:?} score {:?} | tracks {:?}",
                o.id,
                frame_no - 1,
                ob.map(|v| v as i32),
                o.visible_fraction,
                others,
                best.map_or(0.0, |b| b.0),
                best.map(|b| b.2.map(|v| v as i32)),
                best.and_then(|b| verdicts.get(b.1)).map(|v| (v.score * 100.0).round() / 100.0),
                tracks
            );
        }
        for o in truth {
            if o.kind != Kind::Person || o.visible_fraction < 0.98 || !o.walking {
                continue;
            }
            let ob = o.bbox.map(f64::from);
            let alone = truth.iter().all(|q| {
                q.id == o.id || q.visible_px < 50 || iou(ob, q.bbox.map(f64::from)) <= 0.0
            });
            let inside = ob[0] > 2.0 && ob[1] > 2.0 && ob[2] < w_px - 3.0 && ob[3] < h_px - 3.0;
            if !alone || !inside {
                continue;
            }
            funnel[0] += 1;
            let best = best_region(set, ob).map(|(v, j, _)| (v, j));
            let Some((v, j)) = best else { continue };
            if v < 0.5 {
                continue;
            }
            funnel[1] += 1;
            let rb = set.regions()[j].bbox;
            for (acc, d) in box_edges.iter_mut().zip([
                f64::from(rb.x0) - ob[0],
                f64::from(rb.x1) - ob[2],
                f64::from(rb.y0) - ob[1],
                f64::from(rb.y1) - ob[3],
            ]) {
                acc.push(d);
            }
            if verdicts.get(j).is_some_and(|x| x.single_human) {
                funnel[2] += 1;
            }
            let r = &set.regions()[j];
            let on = p.tracker().tracks().iter().find(|t| {
                let tb = [t.bbox.x0, t.bbox.y0, t.bbox.x1, t.bbox.y1].map(f64::from);
                let rb = [r.bbox.x0, r.bbox.y0, r.bbox.x1, r.bbox.y1].map(f64::from);
                iou(tb, rb) > 0.5
            });
            match on {
                Some(t) if t.fresh.is_some() => funnel[3] += 1,
                Some(_) => funnel[4] += 1,
                None => {}
            }
        }
    })
    .expect("scene");
    let st = run.scene.clone();
    let cam = st.camera();
    let edge_means = box_edges.map(|v| v.iter().sum::<f64>() / v.len().max(1) as f64);
    let events: Vec<Event> = run
        .observations
        .iter()
        .map(|o| Event {
            frame: o.frame,
            track: o.track,
            live: o.live,
            truth: o.truth.map(|m| (m.kind, m.id, m.truth, m.visible)),
        })
        .collect();
    println!(
        "== {scene}:{seed} ({} observations): true f {:.1} tilt {:.2} roll {:.2} hc {:.2} vvp ({:.1},{:.1})",
        events.len(),
        cam.f,
        st.tilt_deg,
        st.roll_deg,
        st.camera_height_m,
        st.vertical_vp[0],
        st.vertical_vp[1]
    );
    println!(
        "  isolated walkers: {} person-frames, region IoU>=0.5 {}, called single {}, sampled by a track {}, track on it without a sample {}",
        funnel[0], funnel[1], funnel[2], funnel[3], funnel[4]
    );
    println!(
        "  their region box minus the truth box, mean px: x0 {:+.2} x1 {:+.2} y0 {:+.2} y1 {:+.2}",
        edge_means[0], edge_means[1], edge_means[2], edge_means[3]
    );
    if let Ok(path) = std::env::var("DUMP") {
        use std::io::Write;
        let mut out = std::fs::File::create(&path).expect("DUMP file");
        writeln!(out, "frame,track,hx,hy,fx,fy,kind,id,thx,thy,tfx,tfy").unwrap();
        for e in &events {
            let (k, id, t) = match e.truth {
                Some((k, id, t, _)) => (k as u8, id, t),
                None => (9, 0, HeadFoot::default()),
            };
            writeln!(
                out,
                "{},{},{:.2},{:.2},{:.2},{:.2},{k},{id},{:.2},{:.2},{:.2},{:.2}",
                e.frame,
                e.track,
                e.live.head[0],
                e.live.head[1],
                e.live.foot[0],
                e.live.foot[1],
                t.head[0],
                t.head[1],
                t.foot[0],
                t.foot[1]
            )
            .unwrap();
        }
    }
    let (w, h) = (st.width, st.height);
    let (mut person, mut dog, mut car, mut none) = (0, 0, 0, 0);
    let (mut hx, mut hy, mut fx, mut fy, mut ext, mut ang) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let vvp = st.vertical_vp;
    for e in &events {
        match &e.truth {
            None => none += 1,
            Some((Kind::Dog, ..)) => dog += 1,
            Some((Kind::Car, ..)) => car += 1,
            Some((Kind::Person, _, t, vis)) => {
                person += 1;
                if *vis < 0.95 {
                    continue;
                }
                hx.push(e.live.head[0] - t.head[0]);
                hy.push(e.live.head[1] - t.head[1]);
                fx.push(e.live.foot[0] - t.foot[0]);
                fy.push(e.live.foot[1] - t.foot[1]);
                ext.push(e.live.extent() / t.extent());
                // Signed angle between the observed foot→head direction and
                // the true foot→VVP-opposite direction (true vertical).
                let a_obs = libm::atan2(
                    e.live.head[0] - e.live.foot[0],
                    e.live.foot[1] - e.live.head[1],
                );
                let a_true = libm::atan2(e.live.foot[0] - vvp[0], vvp[1] - e.live.foot[1]);
                ang.push((a_obs - a_true).to_degrees());
            }
        }
    }
    println!(
        "observations {}: person {person}, dog {dog}, car {car}, nothing {none}",
        events.len()
    );
    let pr = |n: &str, v: &[f64]| {
        let (m, s) = stats(v);
        let mut sorted = v.to_vec();
        sorted.sort_by(f64::total_cmp);
        let med = stature::calibrate::eval::quantile(&sorted, 0.5);
        let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
        dev.sort_by(f64::total_cmp);
        let mad = 1.4826 * stature::calibrate::eval::quantile(&dev, 0.5);
        println!("  {n:<18} mean {m:+7.2} sd {s:6.2} median {med:+7.2} robust sd {mad:6.2}");
    };
    pr("head dx px", &hx);
    pr("head dy px", &hy);
    pr("foot dx px", &fx);
    pr("foot dy px", &fy);
    pr("extent ratio", &ext);
    pr("line angle deg", &ang);
    // Lean: the head's offset across the true vertical through the foot,
    // as a fraction of the extent, against the sine of the angle between
    // the foot's motion (over the last 8 observations of the track) and
    // that vertical.
    let (mut xs, mut ys) = (vec![], vec![]);
    let mut hist: BTreeMap<u32, Vec<(u64, HeadFoot)>> = BTreeMap::new();
    for e in &events {
        let h = hist.entry(e.track).or_default();
        h.push((e.frame, e.live));
        if h.len() < 9 {
            continue;
        }
        let Some((Kind::Person, _, _, vis)) = e.truth else {
            continue;
        };
        if vis < 0.95 {
            continue;
        }
        let (_, old) = h[h.len() - 9];
        let o = e.live;
        let mv = [o.foot[0] - old.foot[0], o.foot[1] - old.foot[1]];
        let ml = (mv[0] * mv[0] + mv[1] * mv[1]).sqrt();
        if ml < 4.0 {
            continue;
        }
        // Unit vertical (foot toward head, away from the VVP below).
        let up = [o.foot[0] - vvp[0], o.foot[1] - vvp[1]];
        let ul = (up[0] * up[0] + up[1] * up[1]).sqrt();
        let up = [up[0] / ul, up[1] / ul];
        let across = [-up[1], up[0]];
        let hv = [o.head[0] - o.foot[0], o.head[1] - o.foot[1]];
        let off = (hv[0] * across[0] + hv[1] * across[1]) / o.extent();
        let sin_a = (mv[0] * across[0] + mv[1] * across[1]) / ml;
        xs.push(sin_a);
        ys.push(off);
    }
    // Vertical biases of head and foot against the true extent:
    // dy = a + k·g by least squares.
    {
        let fit = |sel: &dyn Fn(&HeadFoot, &HeadFoot) -> f64| {
            let (mut n, mut sg, mut sgg, mut sy, mut sgy) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for e in &events {
                let Some((Kind::Person, _, t, vis)) = e.truth else {
                    continue;
                };
                if vis < 0.95 {
                    continue;
                }
                let (g, y) = (t.extent(), sel(&e.live, &t));
                if y.abs() > 30.0 {
                    continue;
                }
                n += 1.0;
                sg += g;
                sgg += g * g;
                sy += y;
                sgy += g * y;
            }
            let k = (n * sgy - sg * sy) / (n * sgg - sg * sg);
            let a = (sy - k * sg) / n;
            (a, k, sg / n)
        };
        let (a, k, gm) = fit(&|l, t| l.foot[1] - t.foot[1]);
        let (ah, kh, _) = fit(&|l, t| l.head[1] - t.head[1]);
        println!("  foot dy = {a:+.2} px {k:+.4}*extent; head dy = {ah:+.2} px {kh:+.4}*extent (mean extent {gm:.0} px)");
        let mut bins: BTreeMap<i64, (Vec<f64>, Vec<f64>)> = BTreeMap::new();
        for e in &events {
            let Some((Kind::Person, _, t, vis)) = e.truth else {
                continue;
            };
            if vis < 0.95 {
                continue;
            }
            let b = bins.entry((t.extent() / 20.0) as i64).or_default();
            b.0.push(e.live.foot[1] - t.foot[1]);
            b.1.push(e.live.head[1] - t.head[1]);
        }
        // The live foot's ground point against the true one, toward the
        // camera along the radial line, in units of the person's height.
        let mut gb: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
        for e in &events {
            let Some((Kind::Person, id, t, vis)) = e.truth else {
                continue;
            };
            if vis < 0.95 {
                continue;
            }
            let _ = id;
            let (Some(gl), Some(gt)) = (cam.ground_point(e.live.foot), cam.ground_point(t.foot))
            else {
                continue;
            };
            let rho = |g: [f64; 2]| (g[0] * g[0] + g[1] * g[1]).sqrt();
            // height from truth: head is projection of H above t.foot; use 1.7 nominal
            gb.entry((t.extent() / 20.0) as i64)
                .or_default()
                .push((rho(gt) - rho(gl)) / 1.7);
        }
        print!("  ground offset toward camera / H by extent (median):");
        for (k, v) in gb.iter_mut() {
            v.sort_by(f64::total_cmp);
            print!(
                "  {}-{}: {:+.3}/{}",
                k * 20,
                k * 20 + 20,
                v[v.len() / 2],
                v.len()
            );
        }
        println!();
        print!("  by extent (median foot dy / head dy / n):");
        for (k, (f, hh)) in bins.iter_mut() {
            f.sort_by(f64::total_cmp);
            hh.sort_by(f64::total_cmp);
            print!(
                "  {}-{}: {:+.1}/{:+.1}/{}",
                k * 20,
                k * 20 + 20,
                f[f.len() / 2],
                hh[hh.len() / 2],
                f.len()
            );
        }
        println!();
    }
    // Line angle error by foot column: lines too parallel show as an error
    // that falls from left to right.
    let mut bins = [(0.0f64, 0.0f64, 0usize); 5];
    for e in &events {
        let Some((Kind::Person, _, t, vis)) = e.truth else {
            continue;
        };
        if vis < 0.95 {
            continue;
        }
        let o = e.live;
        let a_obs = libm::atan2(o.head[0] - o.foot[0], o.foot[1] - o.head[1]);
        let a_true = libm::atan2(t.foot[0] - vvp[0], vvp[1] - t.foot[1]);
        let b = ((o.foot[0] / w as f64 * 5.0) as usize).min(4);
        bins[b].0 += (a_obs - a_true).to_degrees();
        bins[b].1 += a_true.to_degrees();
        bins[b].2 += 1;
    }
    print!("  angle error by column (err / true angle / n):");
    for b in &bins {
        let n = b.2.max(1) as f64;
        print!("  {:+.2}/{:+.1}/{}", b.0 / n, b.1 / n, b.2);
    }
    println!();
    let n = xs.len() as f64;
    let sxx: f64 = xs.iter().map(|x| x * x).sum();
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| x * y).sum();
    let lam = sxy / sxx;
    let (m0, s0) = stats(&ys);
    let res: Vec<f64> = xs.iter().zip(&ys).map(|(x, y)| y - lam * x).collect();
    let (m1, s1) = stats(&res);
    println!(
        "  lean: {} moving obs, offset/extent mean {m0:+.4} sd {s0:.4}; lambda {lam:+.4}; after removing lambda*sin: mean {m1:+.4} sd {s1:.4} (n {n})",
        xs.len()
    );
    // Track purity: share of a track's person observations on its majority id.
    let mut by_track: BTreeMap<u32, BTreeMap<u32, usize>> = BTreeMap::new();
    for e in &events {
        if let Some((Kind::Person, id, ..)) = e.truth {
            *by_track.entry(e.track).or_default().entry(id).or_default() += 1;
        }
    }
    let (mut maj, mut tot) = (0, 0);
    for m in by_track.values() {
        maj += m.values().max().copied().unwrap_or(0);
        tot += m.values().sum::<usize>();
    }
    let people: std::collections::BTreeSet<u32> = events
        .iter()
        .filter_map(|e| match e.truth {
            Some((Kind::Person, id, ..)) => Some(id),
            _ => None,
        })
        .collect();
    println!(
        "tracks {} covering {} people, purity {:.1} %, ended on re-identification {}",
        by_track.len(),
        people.len(),
        100.0 * maj as f64 / tot.max(1) as f64,
        run.reid_splits
    );
    if let Some(e) = &run.estimate {
        println!(
            "  pipeline estimate: f {:.1} tilt {:.2} roll {:.2} hc {:.2} focal sigma {:.2} % lean {:.3} inliers {} horizon anchors {} confidence {:.2}",
            e.geom.focal(), e.geom.tilt().to_degrees(), e.geom.roll().to_degrees(), e.camera_height,
            100.0 * e.focal_rel_sigma, e.lean, e.inliers, e.horizon_inliers, e.confidence
        );
    }
    let hs = run.heights();
    oracle_heights(&run, &events, &cam, &cfg.calibrate);
    offset_by_walk_direction(&run, &events, &cam);
    {
        let maj = run.majority();
        for h in &run.final_heights {
            if let Some((k, id)) = maj.get(&h.track_id) {
                if std::env::var("FINALS").is_ok() {
                    println!(
                        "  final: frame {} track {} -> {:?} {id} (true {:.2}): {:.2} m from {} samples",
                        h.frame, h.track_id, k, run.true_heights.get(id).copied().unwrap_or(f64::NAN),
                        h.height_m, h.samples
                    );
                }
                if *k != Kind::Person {
                    println!("  NON-PERSON height: track {} -> {:?} {id}: {:.2} m from {} samples, bbox {:?}", h.track_id, k, h.height_m, h.samples, h.bbox);
                }
            }
        }
    }
    println!(
        "  pipeline final heights: {} records of {} people; |err| median {:.3} p90 {:.3} m, mean signed {:+.3} m; scale-free median {:.4} p90 {:.4}; recall (seen >= 3 s) {}/{}; dog/car heights {} (scale: {})",
        hs.records,
        hs.people,
        hs.abs_median,
        hs.abs_p90,
        hs.signed_mean,
        hs.scale_free_median,
        hs.scale_free_p90,
        hs.measured,
        hs.eligible,
        hs.non_person,
        if cfg.calibrate.camera_height_m > 0.0 { "camera height" } else { "prior" }
    );
    println!(
        "  recall of people seen >= 3 s alone (no other person's box touching theirs): {}/{}",
        hs.measured_alone, hs.eligible_alone
    );
    println!(
        "  recall of people seen >= 3 s walking (not standing still): {}/{}",
        hs.measured_walking, hs.eligible_walking
    );
    if std::env::var("MISSES").is_ok() {
        recall_misses(&run);
    }
    let swap = std::env::var("SWAP_TRUE").unwrap_or_default();
    let ccfg = CalibrateConfig {
        camera_height_m: st.camera_height_m,
        ..cfg.calibrate.clone()
    };
    // A true head row is the crown itself: no back of the head to undo.
    let swap_cfg = CalibrateConfig {
        head_radius: if swap.split(',').any(|p| p == "head" || p == "head_y") {
            0.0
        } else {
            ccfg.head_radius
        },
        ..ccfg.clone()
    };
    let live: Vec<(u64, u32, HeadFoot)> = events
        .iter()
        .map(|e| (e.frame, e.track, with_true_parts(e, &swap)))
        .collect();
    let label = if swap.is_empty() {
        "live points       ".to_string()
    } else {
        format!("live, true {swap:<6}")
    };
    println!("  {label} {}", calibrate(&live, &swap_cfg, w, h));
    let truth: Vec<(u64, u32, HeadFoot)> = events
        .iter()
        .filter_map(|e| match e.truth {
            Some((Kind::Person, _, t, _)) => Some((e.frame, e.track, t)),
            _ => None,
        })
        .collect();
    // True foot points are under the head: no foot offset to undo.
    let tcfg = CalibrateConfig {
        foot_offset: 0.0,
        head_radius: 0.0,
        ..ccfg.clone()
    };
    println!("  true points, same  {}", calibrate(&truth, &tcfg, w, h));
    let (_, shx) = stats(&hx);
    let (_, shy) = stats(&hy);
    let (_, sfx) = stats(&fx);
    let (_, sfy) = stats(&fy);
    let mut rng = Rng::new(7);
    let noisy: Vec<(u64, u32, HeadFoot)> = truth
        .iter()
        .map(|(f, id, t)| {
            let mut o = *t;
            o.head[0] += shx * rng.normal();
            o.head[1] += shy * rng.normal();
            o.foot[0] += sfx * rng.normal();
            o.foot[1] += sfy * rng.normal();
            (*f, *id, o)
        })
        .collect();
    println!("  true + live noise  {}", calibrate(&noisy, &tcfg, w, h));
    if std::env::var("KAPPA").is_ok() {
        let tg = stature::calibrate::geometry::ViewGeometry::of_camera(&cam);
        for kappa in [0.0, 0.03, 0.06, 0.09, 0.12] {
            let v: Vec<(u64, u32, HeadFoot)> = live
                .iter()
                .map(|(f, id, o)| {
                    let mut o = *o;
                    if let (Some(r), Some(g)) = (tg.height_ratio(&o), cam.ground_point(o.foot)) {
                        let rho = (g[0] * g[0] + g[1] * g[1]).sqrt();
                        let k = 1.0 + kappa * r * cam.height / rho;
                        if let Some(p) = cam.project([g[0] * k, g[1] * k, 0.0]) {
                            o.foot = p;
                        }
                    }
                    (*f, *id, o)
                })
                .collect();
            println!(
                "  oracle foot kappa {kappa:.2} {}",
                calibrate(&v, &ccfg, w, h)
            );
        }
    }
    if std::env::var("SWAP").is_ok() {
        let swap = |f: &dyn Fn(&HeadFoot, &HeadFoot) -> HeadFoot| -> Vec<(u64, u32, HeadFoot)> {
            events
                .iter()
                .filter_map(|e| match e.truth {
                    Some((Kind::Person, _, t, _)) => Some((e.frame, e.track, f(&e.live, &t))),
                    _ => None,
                })
                .collect()
        };
        let v = swap(&|l, t| HeadFoot {
            head: l.head,
            foot: t.foot,
        });
        println!("  live head, true foot {}", calibrate(&v, &ccfg, w, h));
        let v = swap(&|l, t| HeadFoot {
            head: t.head,
            foot: l.foot,
        });
        println!("  true head, live foot {}", calibrate(&v, &ccfg, w, h));
        let v = swap(&|l, t| HeadFoot {
            head: [t.head[0], l.head[1]],
            foot: [t.foot[0], l.foot[1]],
        });
        println!("  true x, live y       {}", calibrate(&v, &ccfg, w, h));
        let v = swap(&|l, t| HeadFoot {
            head: [l.head[0], t.head[1]],
            foot: [l.foot[0], t.foot[1]],
        });
        println!("  live x, true y       {}", calibrate(&v, &ccfg, w, h));
        for cut in [50.0, 65.0, 80.0] {
            let v = swap(&|l, t| {
                let mut o = *l;
                if l.extent() < cut {
                    o.foot[1] = t.foot[1];
                }
                o
            });
            println!("  true foot y < {cut:3}  {}", calibrate(&v, &ccfg, w, h));
        }
    }
}

fn main() {
    let mut scene = "plaza".to_string();
    let mut seeds = vec![1u64];
    let mut frames = None;
    let mut extra = String::new();
    let mut toml = String::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--scene" => scene = args.next().expect("--scene NAME"),
            "--seeds" => {
                seeds = args
                    .next()
                    .expect("--seeds 1,2")
                    .split(',')
                    .map(|s| s.parse().expect("seed"))
                    .collect()
            }
            "--toml" => {
                toml.push_str(&args.next().expect("--toml 'section.key = value'"));
                toml.push('\n');
            }
            "--query" => extra = args.next().expect("--query K=V&..."),
            "--frames" => frames = Some(args.next().expect("N").parse().expect("N")),
            other => panic!("unknown option {other}"),
        }
    }
    if scene == "pets" {
        pets(&toml);
        return;
    }
    for s in seeds {
        if scene == "all" {
            for spec in stature::source::sim::scene::scenes() {
                run(spec.name, s, frames, &extra, &toml);
            }
        } else {
            run(&scene, s, frames, &extra, &toml);
        }
    }
}

/// `--scene pets`: the whole PETS 2009 S2.L1 clip (`../shared/data`)
/// against its real calibration, as `live_accuracy::pets_*` scores it, with
/// the `--toml` config.
fn pets(toml: &str) {
    let cfg = Config::from_toml(toml).expect("--toml");
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    let r = stature::calibrate::live::run_pets(&dir, &cfg).expect("PETS run");
    let t = &r.truth;
    let e = r.abs_errors(); // sorted
    match &r.calibration {
        Some(c) => println!(
            "== pets: f {:.0} / {:.0} px, tilt {:.2} / {:.2}, roll {:.2} / {:.2}, camera {:.2} / {:.2} m; {} heights matched ({} people, {} repeats), {} of people without a true height, {} of no one; |err| median {:.3} p90 {:.3} m",
            c.f_px, t.focal_px, c.tilt_deg, t.tilt_deg, c.roll_deg, t.roll_deg,
            c.camera_height_m, t.camera_height_m, r.heights.len(),
            r.heights.len() - r.repeated(), r.repeated(), r.no_truth, r.unmatched,
            e.get(e.len() / 2).copied().unwrap_or(f64::NAN),
            e.get(e.len() * 9 / 10).copied().unwrap_or(f64::NAN),
        ),
        None => println!("== pets: no calibration"),
    }
}

/// The region with the largest IoU with box `ob`: (IoU, index, its box).
fn best_region(set: &stature::detect::RegionSet, ob: [f64; 4]) -> Option<(f64, usize, [f64; 4])> {
    set.regions()
        .iter()
        .enumerate()
        .map(|(j, r)| {
            let rb = [r.bbox.x0, r.bbox.y0, r.bbox.x1, r.bbox.y1].map(f64::from);
            (iou(ob, rb), j, rb)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// Why eligible people got no final height: each one's tracks, with the
/// samples they gave and whether the track ended with a height.
fn recall_misses(run: &stature::calibrate::live::LiveRun) {
    if let Ok(t) = std::env::var("TRACK") {
        let t: u32 = t.parse().expect("TRACK=id");
        for o in run.observations.iter().filter(|o| o.track == t) {
            println!(
                "  track {t} frame {} truth {:?} extent {:.1} head ({:.1},{:.1})",
                o.frame,
                o.truth.map(|m| (m.kind, m.id)),
                o.live.extent(),
                o.live.head[0],
                o.live.head[1]
            );
        }
    }
    let majority = run.majority();
    let min_frames = 3 * u64::from(run.scene.fps);
    let finals: BTreeMap<u32, (f32, u32)> = run
        .final_heights
        .iter()
        .map(|h| (h.track_id, (h.height_m, h.samples)))
        .collect();
    for (&id, &seen) in &run.seen_frames {
        if seen < min_frames {
            continue;
        }
        let measured = finals.keys().any(|t| {
            majority
                .get(t)
                .is_some_and(|m| m.0 == Kind::Person && m.1 == id)
        });
        if measured {
            continue;
        }
        // Samples per track on this person.
        let mut per_track: BTreeMap<u32, (u64, u64, u64)> = BTreeMap::new();
        for o in &run.observations {
            let e = per_track.entry(o.track).or_insert((0, 0, u64::MAX));
            if o.truth
                .is_some_and(|m| m.kind == Kind::Person && m.id == id)
            {
                e.0 += 1;
                e.2 = e.2.min(o.frame);
            }
            e.1 += 1;
        }
        let tracks: Vec<String> = per_track
            .iter()
            .filter(|(_, v)| v.0 > 0)
            .map(|(t, v)| {
                format!(
                    "t{t} {}/{} from f{} maj {:?} final {:?}",
                    v.0,
                    v.1,
                    v.2,
                    majority.get(t).map(|m| m.1),
                    finals.get(t)
                )
            })
            .collect();
        let own = per_track
            .iter()
            .filter(|(t, v)| v.0 > 0 && majority.get(t).is_some_and(|m| m.1 == id))
            .map(|(_, v)| v.0)
            .max()
            .unwrap_or(0);
        let why = if tracks.is_empty() {
            "untracked"
        } else if own >= 8 {
            "unmeasured"
        } else if own > 0 {
            "fragments"
        } else {
            "others"
        };
        println!(
            "  miss: {why} person {id} h {:.2} seen {seen} frames; tracks: {}",
            run.true_heights.get(&id).copied().unwrap_or(f64::NAN),
            if tracks.is_empty() {
                "none".into()
            } else {
                tracks.join("; ")
            }
        );
    }
}

/// The live points of `e` with the parts named in `swap` (comma-separated:
/// `head`, `foot` or one coordinate of them: `head_x`, `head_y`, `foot_x`,
/// `foot_y`) replaced by the truth's, to tell
/// which end of the head–foot line a calibration bias comes from.
fn with_true_parts(e: &Event, swap: &str) -> HeadFoot {
    let mut l = e.live;
    if let Some((Kind::Person, _, t, _)) = e.truth {
        for part in swap.split(',') {
            match part {
                "head" => l.head = t.head,
                "foot" => l.foot = t.foot,
                "head_x" => l.head[0] = t.head[0],
                "foot_x" => l.foot[0] = t.foot[0],
                "head_y" => l.head[1] = t.head[1],
                "foot_y" => l.foot[1] = t.foot[1],
                "" => {}
                other => panic!("SWAP_TRUE: unknown part {other:?}"),
            }
        }
    }
    l
}

/// Where a person's height error comes from. Each track's median
/// per-observation height (observations at least 95 % visible, of the
/// track's first person) from three sources: the live points under the
/// *true* geometry and camera height (the configured foot offset applied), the
/// true points under the true geometry (0 by construction: a check), and
/// the live points under the pipeline's final geometry and camera height.
/// Printed: median |error| over tracks, the mean signed error, and the
/// median |error| once that mean is removed (what a perfect global scale
/// would leave).
fn oracle_heights(
    run: &stature::calibrate::live::LiveRun,
    events: &[Event],
    cam: &stature::camera::Camera,
    ccfg: &CalibrateConfig,
) {
    use stature::calibrate::geometry::ViewGeometry;
    let hc = run.scene.camera_height_m;
    let mut truth_geom = ViewGeometry::of_camera(cam);
    let exact = truth_geom.ratio_frame();
    truth_geom.foot_offset = ccfg.foot_offset;
    truth_geom.head_radius = ccfg.head_radius;
    let live_true = truth_geom.ratio_frame();
    let est = run
        .estimate
        .as_ref()
        .map(|e| (e.geom.ratio_frame(), e.camera_height));
    let mut per: BTreeMap<u32, (u32, [Vec<f64>; 3])> = BTreeMap::new();
    for e in events {
        let Some((Kind::Person, id, t, vis)) = e.truth else {
            continue;
        };
        let slot = per.entry(e.track).or_insert((id, Default::default()));
        if slot.0 != id || vis < 0.95 {
            continue;
        }
        let sources = [
            live_true.height_ratio(&e.live).map(|r| r * hc),
            exact.height_ratio(&t).map(|r| r * hc),
            est.as_ref()
                .and_then(|(g, h)| g.height_ratio(&e.live).map(|r| r * h)),
        ];
        for (v, x) in slot.1.iter_mut().zip(sources) {
            v.extend(x);
        }
    }
    let mut errs: [Vec<f64>; 3] = Default::default();
    for (id, v) in per.values_mut() {
        let Some(th) = run.true_heights.get(id) else {
            continue;
        };
        for (out, v) in errs.iter_mut().zip(v.iter_mut()) {
            if v.len() >= 8 {
                v.sort_by(f64::total_cmp);
                out.push(v[v.len() / 2] - th);
            }
        }
    }
    let median_abs = |v: &[f64], minus: f64| {
        let mut a: Vec<f64> = v.iter().map(|e| (e - minus).abs()).collect();
        a.sort_by(f64::total_cmp);
        a.get(a.len() / 2).copied().unwrap_or(f64::NAN)
    };
    print!("  track-median heights (m), |err| median / mean signed / |err| median without the mean, tracks:");
    for (name, v) in [
        "true geometry + live points",
        "true geometry + true points",
        "estimated geometry + live points",
    ]
    .iter()
    .zip(&errs)
    {
        let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
        print!(
            "  {name} {:.3} / {m:+.3} / {:.3}, {}",
            median_abs(v, 0.0),
            median_abs(v, m),
            v.len()
        );
    }
    println!();
}

/// The live foot's ground offset toward the camera (in units of the
/// person's height, against the true ground point between the feet) by the
/// angle between the walk (the true foot's motion over 8 observations of
/// the track) and the camera's ray: `|cos| = 1` walks toward or away from
/// the camera, 0 across. `calibrate.foot_offset` assumes one value.
fn offset_by_walk_direction(
    run: &stature::calibrate::live::LiveRun,
    events: &[Event],
    cam: &stature::camera::Camera,
) {
    let mut by_track: BTreeMap<u32, Vec<&Event>> = BTreeMap::new();
    for e in events {
        by_track.entry(e.track).or_default().push(e);
    }
    let mut bins: BTreeMap<i64, Vec<f64>> = BTreeMap::new();
    for v in by_track.values() {
        for w in v.windows(9) {
            let (a, b) = (w[0], w[8]);
            let (Some((Kind::Person, ia, ta, _)), Some((Kind::Person, ib, tb, vis))) =
                (a.truth, b.truth)
            else {
                continue;
            };
            let Some(th) = run.true_heights.get(&ib) else {
                continue;
            };
            let (Some(g0), Some(g1), Some(gl)) = (
                cam.ground_point(ta.foot),
                cam.ground_point(tb.foot),
                cam.ground_point(b.live.foot),
            ) else {
                continue;
            };
            let walk = [g1[0] - g0[0], g1[1] - g0[1]];
            let (wl, rl) = (libm::hypot(walk[0], walk[1]), libm::hypot(g1[0], g1[1]));
            if ia != ib || vis < 0.95 || wl < 0.3 || rl < 1e-6 {
                continue;
            }
            let cos = ((walk[0] * g1[0] + walk[1] * g1[1]) / (wl * rl)).abs();
            bins.entry((cos * 5.0).min(4.0) as i64)
                .or_default()
                .push((rl - libm::hypot(gl[0], gl[1])) / th);
        }
    }
    print!("  foot ground offset toward camera / H by |cos(walk, camera ray)| (median/n):");
    for (k, v) in bins.iter_mut() {
        v.sort_by(f64::total_cmp);
        print!(
            "  {:.1}-{:.1}: {:+.3}/{}",
            *k as f64 / 5.0,
            (*k + 1) as f64 / 5.0,
            v[v.len() / 2],
            v.len()
        );
    }
    println!();
}
