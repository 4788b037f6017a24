//! The classifier allocates nothing per region once built.

use stature::alloc_count::thread_allocations;
use stature::classify::{Classifier, ClassifyConfig};
use stature::detect::{BBox, Region};
use stature::frame::Plane;

#[test]
fn no_allocation_per_region() {
    let cfg = ClassifyConfig {
        min_height: 8,
        ..Default::default()
    };
    let mut cls = Classifier::new(&cfg).unwrap();
    let (w, h) = (320usize, 240usize);
    let img: Vec<u8> = (0..w * h).map(|i| ((i * 31) % 253) as u8).collect();
    let plane = Plane::new(&img, w, h).unwrap();
    let regions: Vec<Region> = (0..40u16)
        .map(|k| Region {
            bbox: BBox {
                x0: k * 5,
                y0: k * 3,
                x1: k * 5 + 10 + k * 2,
                y1: k * 3 + 20 + k * 4,
            },
            ..Default::default()
        })
        .collect();
    // First call may initialise the shared orientation table.
    cls.classify(plane, &regions[0]);
    let before = thread_allocations();
    let mut scores = 0.0;
    for r in &regions {
        scores += cls.classify(plane, r).score;
    }
    assert_eq!(
        thread_allocations() - before,
        0,
        "allocations while classifying"
    );
    assert!(scores.is_finite());
    assert_eq!(cls.counters.classified, 41);
}
