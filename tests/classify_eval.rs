//! Held-out accuracy of the built-in weights on PETS 2009 S2.L1 frames
//! 600–794, which the trainer never sees. Floors are conservative: the
//! measured values are in `bench/RESULTS.md` ("Classification").

use stature::classify::samples::{Kind, Origin};
use stature::classify::svm::Model;
use stature::classify::train::evaluate_pets;
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
    assert!(
        all.accuracy() >= ACCURACY_FLOOR,
        "accuracy {:.4}",
        all.accuracy()
    );
    assert!(all.precision() >= 0.90, "precision {:.4}", all.precision());
    assert!(all.recall() >= RECALL_FLOOR, "recall {:.4}", all.recall());
    assert!(of(Kind::Background).accuracy() >= 0.98);
    assert!(of(Kind::Fragment).accuracy() >= 0.90);
}

/// Floors a few points under the measured values.
const ACCURACY_FLOOR: f64 = 0.88;
const RECALL_FLOOR: f64 = 0.82;
