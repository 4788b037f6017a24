//! Held-out accuracy of the built-in weights: PETS 2009 S2.L1 frames
//! 600–794 and simulated clips with seeds the trainer never uses. Floors
//! sit just under the measured values in `bench/RESULTS.md`
//! ("Classification"); the targets are there too (the sim accuracy
//! and the dog targets are missed, so the floors for them are lower than
//! the targets).

use stature::classify::eval::{evaluate_detected, evaluate_pets, evaluate_sim};
use stature::classify::samples::{Kind, Origin};
use stature::classify::svm::Model;
use stature::classify::BUILTIN_WEIGHTS;

#[test]
fn held_out_pets_regions() {
    let Some(dir) = stature::dataset::require_shared_data("classifier held-out evaluation") else {
        return;
    };
    let model = Model::from_bytes(BUILTIN_WEIGHTS).unwrap();
    let ev = evaluate_pets(&dir, &model, 1).unwrap();
    let all = ev.metrics(|r| r.origin == Origin::Pets);
    let of = |k: Kind| ev.metrics(|r| r.kind == k);
    eprintln!("{}", ev.table());
    assert!(all.n > 1500, "too few regions: {}", all.n);
    assert!(of(Kind::Person).n > 500 && of(Kind::Group).n > 50);
    // Measured: 95.02 %, 94.15 %, 96.02 %.
    assert!(all.accuracy() >= 0.94, "accuracy {:.4}", all.accuracy());
    assert!(all.precision() >= 0.93, "precision {:.4}", all.precision());
    assert!(all.recall() >= 0.95, "recall {:.4}", all.recall());
    // Measured: 99.66 %, 98.97 %, 64.41 % rejected.
    assert!(of(Kind::Background).accuracy() >= 0.99);
    assert!(of(Kind::Fragment).accuracy() >= 0.98);
    assert!(of(Kind::Group).accuracy() >= 0.60);
    assert!(ev.auc(|_| true) >= 0.98, "AUC {:.4}", ev.auc(|_| true));
}

#[test]
fn held_out_sim_regions() {
    let model = Model::from_bytes(BUILTIN_WEIGHTS).unwrap();
    let ev = evaluate_sim(&model, 1).unwrap();
    eprintln!("{}", ev.table());
    let all = ev.metrics(|_| true);
    let of = |k: Kind| ev.metrics(|r| r.kind == k);
    assert!(all.n > 2000 && of(Kind::Dog).n > 20, "{all:?}");
    // Measured: 95.56 %, 90.17 %, 94.70 %.
    assert!(all.accuracy() >= 0.95, "accuracy {:.4}", all.accuracy());
    assert!(all.precision() >= 0.89, "precision {:.4}", all.precision());
    assert!(all.recall() >= 0.93, "recall {:.4}", all.recall());
    // Measured: 98.65 %, 91.81 %, 98.27 % rejected.
    assert!(of(Kind::Background).accuracy() >= 0.98);
    assert!(of(Kind::Group).accuracy() >= 0.90);
    assert!(of(Kind::Fragment).accuracy() >= 0.97);
    assert!(ev.auc(|_| true) >= 0.985, "AUC {:.4}", ev.auc(|_| true));
    // Cars: none accepted. Dogs: the target is none; 7 of 32 regions (all
    // one dog trotting away from the camera) are accepted now.
    assert_eq!(of(Kind::Car).fp, 0, "cars accepted");
    let dogs = of(Kind::Dog);
    assert!(
        dogs.fp <= 8,
        "{} of {} dog regions accepted",
        dogs.fp,
        dogs.n
    );
}

/// The foreground-fill variant (`weights/classifier-mask.bin`, `stature
/// train --mask-fill true`; not the built-in weights, see RESULTS): its
/// features read the detector's mask, which the evaluation builds by
/// running the detector over every frame. Measured: PETS 95.62 %, sim
/// 96.49 %, 7 of 32 dog regions accepted.
#[test]
fn held_out_regions_with_foreground_fill() {
    let Some(dir) = stature::dataset::require_shared_data("classifier held-out evaluation") else {
        return;
    };
    let blob = std::fs::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/weights/classifier-mask.bin"
    ))
    .unwrap();
    let model = Model::from_bytes(&blob).unwrap();
    assert!(model.layout.mask_fill);
    let pets = evaluate_pets(&dir, &model, 1).unwrap();
    let sim = evaluate_sim(&model, 1).unwrap();
    eprintln!("{}\n{}", pets.table(), sim.table());
    let (p, s) = (pets.metrics(|_| true), sim.metrics(|_| true));
    assert!(p.accuracy() >= 0.95, "PETS accuracy {:.4}", p.accuracy());
    assert!(s.accuracy() >= 0.96, "sim accuracy {:.4}", s.accuracy());
    assert!(
        sim.auc(|_| true) >= 0.99,
        "sim AUC {:.4}",
        sim.auc(|_| true)
    );
    assert_eq!(sim.metrics(|r| r.kind == Kind::Car).fp, 0, "cars accepted");
    // Without its masks the same weights lose their silhouette cue: the
    // features are read, not ignored.
    let mut cls = stature::classify::eval::scorer(&model);
    let row = pets.rows.iter().find(|r| r.kind == Kind::Person).unwrap();
    let luma_w = 768;
    let grey = vec![128u8; luma_w * 576];
    let plane = stature::frame::Plane::new(&grey, luma_w, 576).unwrap();
    let bare = cls.classify_box(plane, &row.bbox).score;
    let mut mask = stature::detect::morphology::BitMask::new(luma_w, 576);
    for y in row.bbox.y0..=row.bbox.y1 {
        for x in row.bbox.x0..=row.bbox.x1 {
            mask.set(usize::from(x), usize::from(y), true);
        }
    }
    let filled = cls.classify_box_masked(plane, Some(&mask), &row.bbox).score;
    assert!(
        (bare - filled).abs() > 0.05,
        "mask ignored: {bare} vs {filled}"
    );
}

/// The built-in weights on what the loop classifies: the detector's own
/// regions of the held-out frames, labelled by the truth (ambiguous ones
/// left out). Far below the true-box figures, mostly because merged groups
/// pass as one person. Measured: PETS 87.67 % (people 99.11 %, groups
/// 20.61 % rejected), sim 79.21 % (people 91.69 %, groups 54.69 %).
#[test]
fn held_out_detected_regions() {
    let Some(dir) = stature::dataset::require_shared_data("classifier held-out evaluation") else {
        return;
    };
    let model = Model::from_bytes(BUILTIN_WEIGHTS).unwrap();
    let ev = evaluate_detected(&dir, &model, 1).unwrap();
    eprintln!("{}", ev.table());
    let pets = ev.metrics(|r| r.origin == Origin::Pets);
    let sim = ev.metrics(|r| r.origin == Origin::Sim);
    let of = |o: Origin, k: Kind| ev.metrics(|r| r.origin == o && r.kind == k);
    assert!(pets.n > 1000 && sim.n > 1500, "{pets:?} {sim:?}");
    assert!(
        of(Origin::Sim, Kind::Group).n > 300,
        "too few detected groups"
    );
    assert!(
        pets.accuracy() >= 0.86,
        "PETS accuracy {:.4}",
        pets.accuracy()
    );
    assert!(sim.accuracy() >= 0.77, "sim accuracy {:.4}", sim.accuracy());
    assert!(of(Origin::Pets, Kind::Person).accuracy() >= 0.98);
    assert!(of(Origin::Sim, Kind::Person).accuracy() >= 0.90);
    assert!(of(Origin::Sim, Kind::Group).accuracy() >= 0.50);
}
