//! The simulated source renders without touching the heap.

use stature::frame::Frame;
use stature::source::sim::SimSource;
use stature::source::{FrameSource, Next};

#[test]
fn next_frame_allocates_nothing() {
    for name in ["plaza", "high", "busy"] {
        let mut sim = SimSource::open(name, "seed=1&frames=200").unwrap();
        let mut frame = Frame::new(sim.info().size);
        // Counted from the very first frame: nothing is allocated lazily.
        let before = stature::alloc_count::thread_allocations();
        let mut objects = 0;
        while sim.next_frame(&mut frame).unwrap() == Next::Frame {
            objects += sim.truth().len();
        }
        let after = stature::alloc_count::thread_allocations();
        assert_eq!(
            after - before,
            0,
            "{name}: {} allocations in 200 frames",
            after - before
        );
        assert!(
            objects > 100,
            "{name}: the frames had actors to draw ({objects})"
        );
    }
}
