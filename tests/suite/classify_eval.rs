//! Held-out accuracy of the built-in weights: PETS 2009 S2.L1 frames
//! 600–794 and simulated clips with seeds the trainer never uses. Floors
//! sit a few points under the measured values in `bench/RESULTS.md`
//! ("Classification"); they are not the targets, which the current
//! weights miss (see there).

use stature::classify::samples::{Kind, Origin};
use stature::classify::svm::Model;
use stature::classify::train::{evaluate_pets, evaluate_sim};
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
    assert!(all.accuracy() >= 0.86, "accuracy {:.4}", all.accuracy());
    assert!(all.precision() >= 0.90, "precision {:.4}", all.precision());
    assert!(all.recall() >= 0.78, "recall {:.4}", all.recall());
    assert!(of(Kind::Background).accuracy() >= 0.97);
    assert!(of(Kind::Fragment).accuracy() >= 0.90);
}

#[test]
fn held_out_sim_regions() {
    let model = Model::from_bytes(BUILTIN_WEIGHTS).unwrap();
    let ev = evaluate_sim(&model, 1).unwrap();
    eprintln!("{}", ev.table());
    let all = ev.metrics(|_| true);
    let of = |k: Kind| ev.metrics(|r| r.kind == k);
    assert!(all.n > 2000 && of(Kind::Dog).n > 20, "{all:?}");
    assert!(
        all.accuracy() >= SIM_ACCURACY_FLOOR,
        "accuracy {:.4}",
        all.accuracy()
    );
    assert!(all.precision() >= 0.80, "precision {:.4}", all.precision());
    assert!(of(Kind::Background).accuracy() >= 0.97);
    // Cars and dogs: the target is none accepted; the floor allows what
    // the current weights do (see bench/RESULTS.md).
    let animals = ev.metrics(|r| matches!(r.kind, Kind::Dog | Kind::Car));
    assert!(
        animals.fp * 4 <= animals.n,
        "{} of {} cars/dogs accepted",
        animals.fp,
        animals.n
    );
}

const SIM_ACCURACY_FLOOR: f64 = 0.85;
