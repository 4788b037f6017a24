//! Tracks that ended before the calibration could measure them.
//!
//! Heights need a confident calibration, which takes the first few hundred
//! frames of people walking. Every person who walks through in that time
//! would otherwise leave without a height, although their samples were
//! taken: over the 42 simulated runs of `bench/live_eval.rs` that was 49 of
//! the 171 people the pipeline missed. So an ended track with enough
//! samples is parked here, in a fixed pool, and measured later (below);
//! its final height is then dated to the frame the person was last seen,
//! which is earlier than the records around it.
//!
//! They wait for `measure.pending_confidence`, not just the
//! `min_confidence` that lets live tracks report: a calibration that has
//! only just become usable measures worse (over the 42 runs, measuring
//! them at the first usable calibration gave a height error median of
//! 5.7 cm, waiting as below 5.5 cm), and these people are gone, so there
//! is no hurry. They do not wait for ever: once the calibration has been
//! usable for `measure.pending_wait_s`, or at the end of the stream,
//! `min_confidence` is enough.
//!
//! Capacity: `measure.pending_tracks` slots of one track's sample ring
//! each, taken at start-up. Tracks are parked only while the calibration
//! is not usable, so the oldest track a full pool hands back cannot be
//! measured: the caller counts it as lost.

use crate::calibrate::geometry::HeadFoot;
use crate::detect::BBox;
use crate::track::{Track, RING};
use heapless::HistoryBuffer;

/// An ended track waiting for a calibration.
#[derive(Clone, Debug)]
pub struct PendingTrack {
    /// Track id.
    pub id: u32,
    /// Its samples, oldest first when read with `oldest_ordered`.
    pub samples: HistoryBuffer<HeadFoot, RING>,
    /// The head/foot of the frame it was last seen.
    pub last: HeadFoot,
    /// That frame.
    pub last_seen: u64,
    /// Box of the region it was last seen in.
    pub seen_box: BBox,
}

/// The pool: at most its capacity of [`PendingTrack`]s, oldest first.
#[derive(Debug)]
pub struct PendingPool {
    slots: Vec<PendingTrack>,
    capacity: usize,
}

impl PendingPool {
    /// Room for `capacity` tracks (0: tracks that end early are not kept).
    pub fn new(capacity: usize) -> Self {
        PendingPool {
            slots: Vec::with_capacity(capacity),
            capacity,
        }
    }

    /// Tracks waiting.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether none is waiting.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Parks `track` (ended). With a full pool the oldest track waiting
    /// is handed back to make room (with capacity 0, `track` itself).
    /// Nothing allocates: the slots were reserved at start.
    pub fn park(&mut self, track: &Track) -> Option<PendingTrack> {
        let parked = PendingTrack {
            id: track.id,
            samples: track.samples.clone(),
            last: track.last,
            last_seen: track.last_seen,
            seen_box: track.seen_box,
        };
        if self.capacity == 0 {
            return Some(parked);
        }
        let evicted = (self.slots.len() == self.capacity).then(|| self.slots.remove(0));
        self.slots.push(parked);
        evicted
    }

    /// Hands every waiting track to `f`, oldest first, and empties the pool.
    pub fn drain(&mut self, mut f: impl FnMut(&PendingTrack)) {
        for p in &self.slots {
            f(p);
        }
        self.slots.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn track_with(id: u32, n: usize) -> Track {
        let mut t = Track::born(id, BBox::default(), 0);
        for k in 0..n {
            t.samples.write(HeadFoot {
                head: [10.0, k as f64],
                foot: [10.0, 100.0 + k as f64],
            });
        }
        t.last_seen = 40 + u64::from(id);
        t
    }

    #[test]
    fn keeps_samples_in_order_and_gives_up_the_oldest_when_full() {
        let mut pool = PendingPool::new(2);
        assert!(pool.park(&track_with(1, 6)).is_none());
        assert!(pool.park(&track_with(2, 7)).is_none());
        let evicted = pool
            .park(&track_with(3, 8))
            .expect("the oldest handed back");
        assert_eq!(evicted.id, 1);
        assert_eq!(evicted.samples.len(), 6);
        assert_eq!(pool.len(), 2);
        let mut seen = Vec::new();
        pool.drain(|p| {
            let rows: Vec<f64> = p.samples.oldest_ordered().map(|s| s.head[1]).collect();
            seen.push((p.id, p.last_seen, rows));
        });
        assert_eq!(seen[0].0, 2);
        assert_eq!(seen[0].1, 42);
        assert_eq!(seen[0].2, (0..7).map(f64::from).collect::<Vec<_>>());
        assert_eq!(seen[1].0, 3);
        assert_eq!(seen[1].2.len(), 8);
        assert!(pool.is_empty());
    }

    #[test]
    fn capacity_zero_keeps_nothing() {
        let mut pool = PendingPool::new(0);
        let back = pool.park(&track_with(1, 10)).expect("handed back");
        assert_eq!(back.id, 1);
        assert!(pool.is_empty());
    }
}
