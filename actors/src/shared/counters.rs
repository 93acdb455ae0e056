//! Counters of the whole master run, shared by the actors.
//!
//! Plain atomics written by the actor that owns the event (connections count bytes, the
//! assembler counts dropped results, the scheduler jobs handed out) and read by the
//! presenter when it builds a frame's statistics. How many workers are connected is not a
//! counter: the worker table counts its rows (`WorkerTable::counts`).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use crate::wire::rejection::RejectionKind;

/// Monotonic counters of the whole master run.
#[derive(Debug, Default)]
pub struct Counters {
    /// Shared with every connection's socket wrappers.
    pub bytes_in: Arc<AtomicU64>,
    pub bytes_out: Arc<AtomicU64>,
    /// Nanoseconds every encrypted connection's codecs spent in the channel's cipher
    /// (shared with them like the byte counters).
    pub cipher_ns: Arc<AtomicU64>,
    pub dropped_late: AtomicU64,
    pub dropped_duplicate: AtomicU64,
    pub dropped_unknown: AtomicU64,
    /// Results accepted into a frame.
    pub results_accepted: AtomicU64,
    /// Results in frames that were shown (the presenter adds each shown frame's `jobs_back`):
    /// the useful ones. Accepted results of skipped frames are not used.
    pub results_used: AtomicU64,
    /// Results accepted into frames that were then skipped: never used.
    pub results_unused: AtomicU64,
    /// Jobs handed out by the scheduler.
    pub jobs_handed_out: AtomicU64,
    /// Queued jobs discarded because the scene state changed before they were handed out.
    pub jobs_discarded_stale: AtomicU64,
    /// Held jobs a worker dropped unrendered because a newer state's job came first.
    pub jobs_superseded: AtomicU64,
    /// Hand-outs of a (frame, set) that had been handed out before; the no-redundancy
    /// invariant (at most S jobs per frame) says this stays 0.
    pub jobs_handed_twice: AtomicU64,
    /// Connections ended with a protocol error (rejections included).
    pub connections_rejected: AtomicU64,
    /// Jobs held by connections when they ended (the worker left, failed, was killed or
    /// its connection actor panicked): lost, never handed out again.
    pub jobs_lost: AtomicU64,
    /// Panics contained at an actor boundary.
    pub panics_contained: AtomicU64,
    /// Why supervision gave up (an actor past the restart intensity), once it did: the
    /// master thread puts it in the report when the actor system has stopped.
    pub escalation: Mutex<Option<String>>,
    /// Connections ended on an error, by kind
    /// ([`RejectionKind::as_str`]); bounded: the kinds are fixed.
    pub rejected_by_kind: Mutex<BTreeMap<&'static str, u64>>,
}

impl Counters {
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    pub fn get(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
    }

    /// Counts one connection ended on an error of this kind.
    pub fn note_rejection(&self, kind: RejectionKind) {
        let kind = kind.as_str();
        *self
            .rejected_by_kind
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .entry(kind)
            .or_default() += 1;
    }

    /// Connections ended on an error so far, by kind.
    pub fn rejections(&self) -> BTreeMap<&'static str, u64> {
        self.rejected_by_kind.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejections_are_counted_by_kind() {
        let c = Counters::default();
        c.note_rejection(RejectionKind::Auth);
        c.note_rejection(RejectionKind::Auth);
        c.note_rejection(RejectionKind::Full);
        assert_eq!(c.rejections().into_iter().collect::<Vec<_>>(), [("auth", 2), ("full", 1)]);
    }
}
