//! The outbox of an `mqtt:` sink: records held until the broker confirms
//! them, bounded, with an explicit drop policy. Pure bookkeeping (no
//! network), shared by the I/O thread and the connection thread under one mutex.

use super::{Placement, Route};
use std::collections::VecDeque;

/// One message waiting for, or on its way to, the broker.
#[derive(Clone, Debug, PartialEq)]
pub struct Entry {
    /// Arrival order; requeued entries go back in this order.
    pub seq: u64,
    /// Topic, QoS, retain.
    pub place: Placement,
    /// Never dropped while a non-final entry could be dropped instead.
    pub is_final: bool,
    /// Sent by the sink itself (availability, discovery, retained state
    /// republished after a reconnection), not a record from the queue: it
    /// does not count against the buffer and is rebuilt on each connection.
    pub control: bool,
    /// The message body.
    pub payload: Vec<u8>,
}

/// What [`Outbox::push`] had to give up to make room.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pushed {
    /// Nothing: there was room.
    Stored,
    /// The oldest waiting non-final record was dropped.
    DroppedOldest,
    /// Only final records were waiting: the oldest of them was dropped.
    DroppedOldestFinal,
    /// The new (non-final) record was dropped: only finals were waiting.
    DroppedNew,
}

/// Messages not yet confirmed by the broker, in three stages: waiting,
/// handed to the MQTT client (until it reports writing them), and — QoS 1 —
/// written but not yet acknowledged. A connection loss puts everything
/// unconfirmed back into the waiting list in arrival order, because the
/// client forgets a clean session's unacknowledged messages on reconnection.
///
/// Bounded: records (not control messages) never exceed `capacity`; when
/// full, the oldest waiting non-final record goes first.
#[derive(Debug)]
pub struct Outbox {
    waiting: VecDeque<Entry>,
    handed: VecDeque<Entry>,
    unacked: VecDeque<(u16, Entry)>,
    capacity: usize,
    window: usize,
    next_seq: u64,
    /// Last confirmed hello and calibration payloads, republished (retained)
    /// after each reconnection in case the broker lost its retained store.
    retained: [Option<Vec<u8>>; 2],
}

impl Outbox {
    /// Holds up to `capacity` records, with at most `window` handed to the
    /// client or awaiting acknowledgement at once.
    pub fn new(capacity: usize, window: usize) -> Self {
        Outbox {
            waiting: VecDeque::with_capacity(capacity + 8),
            handed: VecDeque::with_capacity(window + 8),
            unacked: VecDeque::with_capacity(window + 8),
            capacity,
            window: window.max(1),
            next_seq: 1,
            retained: [None, None],
        }
    }

    /// Records (not control messages) not yet confirmed.
    pub fn records(&self) -> usize {
        self.all().filter(|e| !e.control).count()
    }

    /// Final records not yet confirmed.
    pub fn finals(&self) -> usize {
        self.all().filter(|e| e.is_final && !e.control).count()
    }

    /// True when nothing at all is unconfirmed.
    pub fn is_empty(&self) -> bool {
        self.waiting.is_empty() && self.handed.is_empty() && self.unacked.is_empty()
    }

    fn all(&self) -> impl Iterator<Item = &Entry> {
        self.waiting
            .iter()
            .chain(self.handed.iter())
            .chain(self.unacked.iter().map(|(_, e)| e))
    }

    /// Adds a record, first making room if the outbox is full.
    pub fn push(&mut self, place: Placement, is_final: bool, payload: Vec<u8>) -> Pushed {
        let mut outcome = Pushed::Stored;
        if self.records() >= self.capacity {
            let victim = self.waiting.iter().position(|e| !e.is_final && !e.control);
            match victim {
                Some(i) => {
                    self.waiting.remove(i);
                    outcome = Pushed::DroppedOldest;
                }
                None if !is_final => return Pushed::DroppedNew,
                None => match self.waiting.iter().position(|e| !e.control) {
                    Some(i) => {
                        self.waiting.remove(i);
                        outcome = Pushed::DroppedOldestFinal;
                    }
                    // Everything is in flight: nothing to trade.
                    None => return Pushed::DroppedNew,
                },
            }
        }
        let seq = self.next_seq;
        self.next_seq += 1;
        self.waiting.push_back(Entry {
            seq,
            place,
            is_final,
            control: false,
            payload,
        });
        outcome
    }

    /// Puts control messages ahead of everything waiting (in the given order).
    pub fn push_control_front(&mut self, msgs: Vec<(Placement, Vec<u8>)>) {
        for (place, payload) in msgs.into_iter().rev() {
            self.waiting.push_front(Entry {
                seq: 0,
                place,
                is_final: true,
                control: true,
                payload,
            });
        }
    }

    /// Appends a control message after everything waiting.
    pub fn push_control_back(&mut self, place: Placement, payload: Vec<u8>) {
        self.waiting.push_back(Entry {
            seq: 0,
            place,
            is_final: true,
            control: true,
            payload,
        });
    }

    /// Hands waiting entries to `publish` (oldest first) while the window
    /// allows; stops at the first refusal, which stays first in line.
    /// Returns how many were handed.
    pub fn pump(&mut self, mut publish: impl FnMut(&Entry) -> bool) -> usize {
        let mut n = 0;
        while self.handed.len() + self.unacked.len() < self.window {
            let Some(e) = self.waiting.pop_front() else {
                break;
            };
            if publish(&e) {
                self.handed.push_back(e);
                n += 1;
            } else {
                self.waiting.push_front(e);
                break;
            }
        }
        n
    }

    /// The client wrote the oldest handed message with packet id `pkid`
    /// (0 for QoS 0). Returns true if that completed it.
    pub fn written(&mut self, pkid: u16) -> bool {
        let Some(e) = self.handed.pop_front() else {
            return false;
        };
        if e.place.qos == 0 {
            self.confirmed(e);
            true
        } else {
            self.unacked.push_back((pkid, e));
            false
        }
    }

    /// The broker acknowledged packet `pkid`.
    pub fn acked(&mut self, pkid: u16) -> bool {
        match self.unacked.iter().position(|(p, _)| *p == pkid) {
            Some(i) => {
                if let Some((_, e)) = self.unacked.remove(i) {
                    self.confirmed(e);
                }
                true
            }
            None => false,
        }
    }

    fn confirmed(&mut self, e: Entry) {
        if e.control {
            return;
        }
        match e.place.route {
            Route::Hello => self.retained[0] = Some(e.payload),
            Route::Calibration => self.retained[1] = Some(e.payload),
            _ => {}
        }
    }

    /// The connection dropped: everything handed or unacknowledged waits
    /// again, in arrival order; control messages are discarded (rebuilt on
    /// the next connection).
    pub fn requeue(&mut self) {
        let mut back: Vec<Entry> = self
            .unacked
            .drain(..)
            .map(|(_, e)| e)
            .chain(self.handed.drain(..))
            .chain(self.waiting.drain(..))
            .filter(|e| !e.control)
            .collect();
        back.sort_by_key(|e| e.seq);
        self.waiting.extend(back);
    }

    /// The retained state to republish after connecting: the last confirmed
    /// hello and calibration, unless a newer one is already waiting.
    pub fn retained_state(&self, qos_calibration: u8) -> Vec<(Placement, Vec<u8>)> {
        let waiting = |r: Route| self.waiting.iter().any(|e| e.place.route == r);
        let mut out = Vec::new();
        if let (Some(p), false) = (&self.retained[0], waiting(Route::Hello)) {
            out.push((
                Placement {
                    route: Route::Hello,
                    qos: 1,
                    retain: true,
                },
                p.clone(),
            ));
        }
        if let (Some(p), false) = (&self.retained[1], waiting(Route::Calibration)) {
            out.push((
                Placement {
                    route: Route::Calibration,
                    qos: qos_calibration,
                    retain: true,
                },
                p.clone(),
            ));
        }
        out
    }

    /// Drops every unconfirmed record (end of run); returns how many.
    pub fn abandon(&mut self) -> usize {
        let n = self.records();
        self.waiting.clear();
        self.handed.clear();
        self.unacked.clear();
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn place_h(q: u8) -> Placement {
        Placement {
            route: Route::Height,
            qos: q,
            retain: false,
        }
    }

    #[test]
    fn full_outbox_drops_oldest_non_final_then_oldest_final() {
        let mut o = Outbox::new(4, 2);
        assert_eq!(o.push(place_h(1), true, b"F1".to_vec()), Pushed::Stored);
        assert_eq!(o.push(place_h(0), false, b"n1".to_vec()), Pushed::Stored);
        assert_eq!(o.push(place_h(0), false, b"n2".to_vec()), Pushed::Stored);
        assert_eq!(o.push(place_h(1), true, b"F2".to_vec()), Pushed::Stored);
        assert_eq!(
            o.push(place_h(1), true, b"F3".to_vec()),
            Pushed::DroppedOldest
        );
        assert_eq!(
            o.push(place_h(0), false, b"n3".to_vec()),
            Pushed::DroppedOldest
        );
        // F1 F2 F3 n3: a new non-final displaces n3, the only non-final.
        assert_eq!(
            o.push(place_h(0), false, b"n4".to_vec()),
            Pushed::DroppedOldest
        );
        assert_eq!(
            o.push(place_h(1), true, b"F4".to_vec()),
            Pushed::DroppedOldest
        );
        // Only finals now.
        assert_eq!(
            o.push(place_h(0), false, b"n5".to_vec()),
            Pushed::DroppedNew
        );
        assert_eq!(
            o.push(place_h(1), true, b"F5".to_vec()),
            Pushed::DroppedOldestFinal
        );
        let mut got = Vec::new();
        o.pump(|e| {
            got.push(e.payload.clone());
            true
        });
        assert_eq!(got, vec![b"F2".to_vec(), b"F3".to_vec()]);
        assert_eq!(o.records(), 4);
    }

    #[test]
    fn unconfirmed_messages_return_in_order_after_a_connection_loss() {
        let mut o = Outbox::new(16, 3);
        for i in 0..5u8 {
            o.push(place_h(i % 2), false, vec![i]);
        }
        o.push_control_front(vec![(
            Placement {
                route: Route::Availability,
                qos: 1,
                retain: true,
            },
            b"online".to_vec(),
        )]);
        let mut sent = Vec::new();
        assert_eq!(
            o.pump(|e| {
                sent.push(e.payload.clone());
                true
            }),
            3
        );
        assert_eq!(sent[0], b"online");
        assert!(!o.written(7)); // online, QoS 1: awaits its ack
        assert!(o.written(0)); // payload 0, QoS 0: done
        assert!(!o.written(8)); // payload 1, QoS 1
        assert!(o.acked(8));
        assert!(!o.acked(99));
        // Window frees two slots.
        o.pump(|_| true);
        // Connection lost: online (control) is discarded, 2.. wait again in order.
        o.requeue();
        let mut order = Vec::new();
        let mut o2 = o;
        o2.pump(|e| {
            order.push(e.payload[0]);
            true
        });
        assert_eq!(order, vec![2, 3, 4]);
        assert_eq!(o2.records(), 3);
    }
}
