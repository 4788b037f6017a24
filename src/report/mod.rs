//! Reports: schema v1 records, their encodings, the sinks, and the bounded
//! queue that keeps slow links away from the vision loop.
//!
//! The loop hands records to a [`Reporter`] (never blocking). One I/O thread
//! ([`spawn_io`]) drains the queue, encodes each record once into a fixed
//! buffer and writes it to every sink. When the queue is full the oldest
//! non-final record is dropped and counted; final records (hello, bye, final
//! calibration, final heights) are held back by the loop and retried.

pub mod encode;
pub mod mqtt;
pub mod record;
pub mod sink;

use crate::config::Format;
use crossbeam_channel::{bounded, Receiver, Sender, TryRecvError, TrySendError};
use record::Record;
use sink::Sink;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;

/// Counters shared by the loop and the I/O thread.
#[derive(Debug, Default)]
pub struct Counters {
    /// Records dropped because the queue was full.
    pub dropped_queue: AtomicU64,
    /// Of those, final records (the held list was full too, or still held
    /// at the end's timeout): what a user misses most, named apart.
    pub dropped_finals: AtomicU64,
    /// Record deliveries that failed at a sink (one per sink per record).
    /// What each sink delivered in the end is its [`SinkTally`].
    pub dropped_sink: AtomicU64,
    /// The only sink is standard output and its reader has gone (`EPIPE`:
    /// `stature run | head -1`): no record can reach anyone any more, so
    /// the loop stops. (A `file:` FIFO whose reader quit may get a new one.)
    pub readers_gone: AtomicBool,
    /// Raised with [`Counters::readers_gone`]: the flag a blocked source
    /// read looks at (the signals raise it too; it is not their stop
    /// flag, so a reader leaving is never taken for a signal), so that a
    /// quiet pipe or camera does not keep the loop from seeing it.
    pub wake: std::sync::OnceLock<Arc<AtomicBool>>,
}

impl Counters {
    /// All drops so far.
    pub fn dropped(&self) -> u64 {
        self.dropped_queue.load(Ordering::Relaxed) + self.dropped_sink.load(Ordering::Relaxed)
    }
}

/// The loop's end of the report queue.
pub struct Reporter {
    tx: Sender<Record>,
    /// A receiver clone: lets the loop evict the oldest record when full.
    evict: Receiver<Record>,
    held: VecDeque<Record>,
    held_capacity: usize,
    counters: Arc<Counters>,
    /// Tracks whose final height was dropped with the queue full (the
    /// first [`DROPPED_FINALS_NAMED`]; all are counted in
    /// [`Counters::dropped_finals`]).
    dropped_final_tracks: heapless::Vec<u32, DROPPED_FINALS_NAMED>,
}

/// Dropped final heights a [`Reporter`] remembers by track, to name them.
pub const DROPPED_FINALS_NAMED: usize = 16;

impl Reporter {
    /// A queue of `capacity` records, holding up to `held_finals` final
    /// records while it is full. Returns the reporter and the I/O end.
    pub fn new(capacity: usize, held_finals: usize) -> (Reporter, Receiver<Record>, Arc<Counters>) {
        let (tx, rx) = bounded(capacity);
        let counters = Arc::new(Counters::default());
        let r = Reporter {
            tx,
            evict: rx.clone(),
            held: VecDeque::with_capacity(held_finals),
            held_capacity: held_finals,
            counters: counters.clone(),
            dropped_final_tracks: heapless::Vec::new(),
        };
        (r, rx, counters)
    }

    /// Shared counters.
    pub fn counters(&self) -> &Arc<Counters> {
        &self.counters
    }

    /// The tracks whose final height was dropped with the queue full, in
    /// order (the first [`DROPPED_FINALS_NAMED`]).
    pub fn dropped_final_tracks(&self) -> &[u32] {
        &self.dropped_final_tracks
    }

    /// Whether the only sink, standard output, lost its reader
    /// ([`Counters::readers_gone`]).
    pub fn readers_gone(&self) -> bool {
        self.counters.readers_gone.load(Ordering::Acquire)
    }

    /// Queues a record without blocking (held finals go first).
    pub fn send(&mut self, record: Record) {
        self.retry_held();
        if !self.held.is_empty() {
            self.enqueue_blocked(record);
            return;
        }
        if let Err(TrySendError::Full(record)) = self.tx.try_send(record) {
            self.enqueue_blocked(record);
        }
    }

    /// Tries to move held final records into the queue.
    fn retry_held(&mut self) {
        while let Some(r) = self.held.pop_front() {
            match self.tx.try_send(r) {
                Ok(()) => {}
                Err(TrySendError::Full(r)) | Err(TrySendError::Disconnected(r)) => {
                    self.held.push_front(r);
                    break;
                }
            }
        }
    }

    /// The queue is full: make room by evicting the oldest non-final record.
    fn enqueue_blocked(&mut self, record: Record) {
        // Evict one queued record; a final one moves to the held list instead.
        match self.evict.try_recv() {
            Ok(old) if old.is_final() => self.hold(old),
            Ok(_) => {
                self.counters.dropped_queue.fetch_add(1, Ordering::Relaxed);
            }
            Err(TryRecvError::Empty) | Err(TryRecvError::Disconnected) => {}
        }
        if record.is_final() || !self.held.is_empty() {
            if record.is_final() {
                self.hold(record);
            } else {
                self.counters.dropped_queue.fetch_add(1, Ordering::Relaxed);
            }
            self.retry_held();
            return;
        }
        if self.tx.try_send(record).is_err() {
            self.counters.dropped_queue.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn hold(&mut self, record: Record) {
        if self.held.len() < self.held_capacity {
            self.held.push_back(record);
        } else {
            self.counters.dropped_queue.fetch_add(1, Ordering::Relaxed);
            self.counters.dropped_finals.fetch_add(1, Ordering::Relaxed);
            // Named now, and by track at the end of the run.
            match &record {
                Record::Height(h) => {
                    // Full: the rest are counted, not named.
                    let _ = self.dropped_final_tracks.push(h.track_id);
                    log::warn!(
                        "report: queue full, the final height of track {} ({:.2} m, frame {}) \
                         was dropped",
                        h.track_id,
                        h.height_m,
                        h.frame
                    )
                }
                r => log::warn!(
                    "report: queue full, the final {} record was dropped",
                    r.kind()
                ),
            }
        }
    }

    /// End of run: waits (bounded) until held records are queued, then closes the queue.
    pub fn finish(self, timeout: std::time::Duration) {
        let _ = self.finish_unless(timeout, || false);
    }

    /// [`Reporter::finish`], giving up the wait as soon as `give_up` says so
    /// (a signal: the user would rather lose the held records than wait).
    /// Returns the tracks whose final height was dropped, during the run or
    /// now (the first [`DROPPED_FINALS_NAMED`]).
    pub fn finish_unless(
        mut self,
        timeout: std::time::Duration,
        give_up: impl Fn() -> bool,
    ) -> heapless::Vec<u32, DROPPED_FINALS_NAMED> {
        let deadline = std::time::Instant::now() + timeout;
        while !self.held.is_empty() && std::time::Instant::now() < deadline && !give_up() {
            self.retry_held();
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        let left = self.held.len() as u64;
        self.counters
            .dropped_queue
            .fetch_add(left, Ordering::Relaxed);
        self.counters
            .dropped_finals
            .fetch_add(left, Ordering::Relaxed);
        for r in &self.held {
            if let Record::Height(h) = r {
                let _ = self.dropped_final_tracks.push(h.track_id);
            }
        }
        self.dropped_final_tracks
    }
}

/// What one sink did with the run's records, known when the I/O thread ends.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SinkTally {
    /// The sink as logs name it ([`Sink::label`]: `file:PATH`, ...).
    pub name: String,
    /// Records handed to it.
    pub records: u64,
    /// Of those, records it did not deliver (failed writes, and records
    /// it accepted and later dropped).
    pub lost: u64,
}

impl SinkTally {
    /// Whether the sink delivered nothing of a run that had records.
    pub fn lost_everything(&self) -> bool {
        self.records > 0 && self.lost >= self.records
    }
}

/// Starts the I/O thread writing every record from `rx` to every sink.
/// The thread ends when the queue is closed and drained, and returns what
/// each sink delivered.
///
/// Returns once the thread has made its one-time allocations, so that an
/// allocation count taken afterwards sees only the steady state: the first
/// time a thread blocks on a crossbeam channel it allocates (a cached
/// thread-local wait context, the channel's waiter list); left to happen
/// whenever the new thread first got scheduled, that raced with the loop's
/// baseline and showed up as a few allocations in every `status` record
/// (seen on an emulated aarch64 board reading vivid).
pub fn spawn_io(
    rx: Receiver<Record>,
    mut sinks: Vec<Sink>,
    format: Format,
    counters: Arc<Counters>,
) -> std::thread::JoinHandle<Vec<SinkTally>> {
    let (ready_tx, ready_rx) = bounded::<()>(1);
    let handle = std::thread::Builder::new()
        .name("stature-io".into())
        .spawn(move || {
            let mut buf = [0u8; encode::MAX_RECORD];
            let mut failures = vec![0u64; sinks.len()];
            // Sinks whose reader has gone: not written again.
            let mut gone = vec![false; sinks.len()];
            // Made once here, not per failing write (whose error text may
            // still allocate: the I/O thread's, never the vision loop's).
            let labels: Vec<String> = sinks.iter().map(Sink::label).collect();
            let mut records = 0u64;
            for s in sinks.iter_mut() {
                s.attach_counters(&counters);
            }
            let mut deliver = |record: Record, sinks: &mut Vec<Sink>| {
                records += 1;
                let bytes = match encode::encode(&record, format, &mut buf) {
                    Ok(b) => b,
                    Err(e) => {
                        log::error!("report: {} record not encoded: {e}", record.kind());
                        counters.dropped_sink.fetch_add(1, Ordering::Relaxed);
                        // Lost at every sink alike.
                        failures.iter_mut().for_each(|f| *f += 1);
                        return;
                    }
                };
                let it = sinks
                    .iter_mut()
                    .zip(failures.iter_mut())
                    .zip(gone.iter_mut());
                for (((sink, fails), gone), label) in it.zip(&labels) {
                    if *gone {
                        *fails += 1;
                        counters.dropped_sink.fetch_add(1, Ordering::Relaxed);
                        continue;
                    }
                    if let Err(e) = sink.write(&record, bytes, format) {
                        *fails += 1;
                        counters.dropped_sink.fetch_add(1, Ordering::Relaxed);
                        // Standard output's reader never comes back; a
                        // named FIFO takes a new reader (a restarted
                        // consumer), so a `file:` sink keeps trying.
                        *gone = e.kind() == std::io::ErrorKind::BrokenPipe
                            && matches!(sink, Sink::Stdout(_));
                        // Log the first failure and then every 100th, not each one.
                        if *fails == 1 || *fails % 100 == 0 || *gone {
                            let s = if *fails == 1 { "" } else { "s" };
                            log::warn!("report sink {label}: {e} ({fails} record{s} lost there)");
                        }
                    }
                }
                if !gone.is_empty()
                    && gone.iter().all(|&g| g)
                    && !counters.readers_gone.swap(true, Ordering::AcqRel)
                {
                    log::warn!(
                        "report: standard output's reader has gone and there is no other sink: \
                         stopping the run"
                    );
                    if let Some(wake) = counters.wake.get() {
                        wake.store(true, Ordering::Release);
                    }
                }
            };
            // Warm up: block on the (still empty) queue until one wait has
            // allocated and the next has not. crossbeam allocates the first
            // time a thread parks and the first time a channel's waiter list
            // grows; a timed-out wait does not always reach the blocking path
            // (the spin/yield phase runs before the deadline is looked at, and
            // under load can outlast it), so a single quiet wait proves
            // nothing. Nothing is sent before `ready`; deliver anything that
            // came anyway. Skipped when the counting allocator is not
            // installed (its count stays 0); bounded: at most 100 waits of 20 ms.
            if crate::alloc_count::allocations() > 0 {
                let mut allocated = false;
                for _ in 0..100 {
                    let before = crate::alloc_count::thread_allocations();
                    match rx.recv_timeout(std::time::Duration::from_millis(20)) {
                        Ok(record) => deliver(record, &mut sinks),
                        Err(crossbeam_channel::RecvTimeoutError::Disconnected) => break,
                        Err(crossbeam_channel::RecvTimeoutError::Timeout) => {
                            let quiet = crate::alloc_count::thread_allocations() == before;
                            if allocated && quiet {
                                break;
                            }
                            allocated |= !quiet;
                        }
                    }
                }
            }
            let _ = ready_tx.send(());
            while let Ok(record) = rx.recv() {
                deliver(record, &mut sinks);
                while let Ok(record) = rx.try_recv() {
                    deliver(record, &mut sinks);
                }
                for s in sinks.iter_mut() {
                    let _ = s.flush();
                }
            }
            for (s, label) in sinks.iter_mut().zip(&labels) {
                if let Err(e) = s.close() {
                    log::warn!("report sink {label}: final flush failed: {e}");
                }
            }
            sinks
                .iter()
                .zip(&failures)
                .zip(labels)
                .map(|((s, &failed), name)| SinkTally {
                    name,
                    records,
                    lost: (failed + s.lost_after_accepting()).min(records),
                })
                .collect()
        })
        .expect("spawning the I/O thread at start-up");
    // An error means the thread died before it was ready; `join` reports it.
    let _ = ready_rx.recv();
    handle
}

#[cfg(test)]
mod tests {
    use super::record::{bounded, Height, Status};
    use super::*;

    fn status(frame: u64) -> Record {
        Record::Status(Status {
            frame,
            frames: frame,
            fps: 0.0,
            dropped: 0,
            source: bounded("streaming"),
            allocations: 0,
            tracks: 0,
        })
    }
    fn final_height(frame: u64) -> Record {
        Record::Height(Height {
            frame,
            track_id: 1,
            height_m: 1.7,
            samples: 3,
            foot_px: [0.0; 2],
            head_px: [0.0; 2],
            bbox: [0; 4],
            is_final: true,
        })
    }

    #[test]
    fn full_queue_drops_oldest_non_final_and_keeps_finals() {
        let (mut rep, rx, counters) = Reporter::new(4, 8);
        rep.send(final_height(0));
        for f in 1..10 {
            rep.send(status(f));
        }
        rep.send(final_height(10));
        let mut got: Vec<Record> = rx.try_iter().collect();
        let frames: Vec<u64> = got
            .iter()
            .map(|r| match r {
                Record::Status(s) => s.frame,
                Record::Height(h) => h.frame,
                _ => 99,
            })
            .collect();
        // The newest statuses are kept over the oldest.
        assert!(frames.contains(&9), "{frames:?}");
        assert!(!frames.contains(&1), "{frames:?}");
        // Finals evicted or refused while full are held, then queued once room appears.
        rep.send(status(11));
        got.extend(rx.try_iter());
        assert!(got.contains(&final_height(0)), "first final lost");
        assert!(got.contains(&final_height(10)), "second final lost");
        assert!(counters.dropped_queue.load(Ordering::Relaxed) >= 6);
    }

    #[test]
    fn finish_holds_finals_until_the_timeout_or_a_signal() {
        // Queue of 2, nobody reading: the third final is held.
        let (mut rep, rx, counters) = Reporter::new(2, 8);
        for f in 0..3 {
            rep.send(final_height(f));
        }
        let t0 = std::time::Instant::now();
        let named = rep.finish_unless(std::time::Duration::from_secs(3600), || true);
        // (Not a speed check: it must not sit out the hour.)
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(60),
            "gave up at once"
        );
        assert_eq!(counters.dropped_queue.load(Ordering::Relaxed), 1);
        assert_eq!(counters.dropped_finals.load(Ordering::Relaxed), 1);
        assert_eq!(named, [1], "the final held to the end is named");
        assert_eq!(rx.try_iter().count(), 2);
        // More finals than the queue and the held list take: the rest are
        // dropped and counted as finals.
        let (mut rep, rx, counters) = Reporter::new(2, 1);
        for f in 0..5 {
            rep.send(final_height(f));
        }
        assert_eq!(counters.dropped_finals.load(Ordering::Relaxed), 3);
        assert_eq!(
            rep.dropped_final_tracks(),
            [1, 1, 1],
            "dropped with the queue full"
        );
        let named = rep.finish_unless(std::time::Duration::from_secs(3600), || true);
        assert_eq!(counters.dropped_finals.load(Ordering::Relaxed), 3);
        assert_eq!(named.len(), 3, "every dropped final height is named");
        assert_eq!(rx.try_iter().count(), 2);
        // Without a signal, the held final goes out once there is room.
        let (mut rep, rx, counters) = Reporter::new(2, 8);
        for f in 0..3 {
            rep.send(final_height(f));
        }
        let reader = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(50));
            rx.iter().count()
        });
        rep.finish(std::time::Duration::from_secs(30));
        assert_eq!(reader.join().unwrap(), 3);
        assert_eq!(counters.dropped_queue.load(Ordering::Relaxed), 0);
    }
}
