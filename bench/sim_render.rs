//! Simulated-scene rendering speed: frames per second on one core.
//!
//! `cargo bench --bench sim_render [-- --frames=N --scene=NAME]` (release
//! profile). Prints, per scene, the
//! time to open it (cast, ray-traced background, tables) and the steady
//! rendering rate over the clip.

use stature::frame::Frame;
use stature::source::sim::{scene, SimSource};
use stature::source::{FrameSource, Next};
use std::time::Instant;

fn main() {
    let frames: u64 = std::env::args()
        .skip(1)
        .find_map(|a| a.strip_prefix("--frames=").and_then(|n| n.parse().ok()))
        .unwrap_or(600);
    let only: Option<String> = std::env::args()
        .skip(1)
        .find_map(|a| a.strip_prefix("--scene=").map(str::to_string));
    println!(
        "{:<6} {:>9} {:>9} {:>8} {:>10} {:>9}",
        "scene", "size", "open ms", "frames", "ms/frame", "fps"
    );
    for spec in scene::scenes() {
        if only.as_deref().is_some_and(|n| n != spec.name) {
            continue;
        }
        let t0 = Instant::now();
        let mut sim = SimSource::open(spec.name, &format!("seed=1&frames={frames}")).unwrap();
        let open_ms = t0.elapsed().as_secs_f64() * 1e3;
        let mut frame = Frame::new(sim.info().size);
        let mut objects = 0usize;
        let t1 = Instant::now();
        let mut n = 0u64;
        while sim.next_frame(&mut frame).unwrap() == Next::Frame {
            objects += sim.truth().len();
            n += 1;
        }
        let secs = t1.elapsed().as_secs_f64();
        println!(
            "{:<6} {:>9} {:>9.0} {:>8} {:>10.3} {:>9.0}   ({:.1} objects/frame)",
            spec.name,
            format!("{}x{}", spec.width, spec.height),
            open_ms,
            n,
            secs * 1e3 / n as f64,
            n as f64 / secs,
            objects as f64 / n as f64
        );
    }
}
