//! Counters shared by the actors and the per-frame statistics the presenter publishes.
//!
//! Counters are plain atomics written by the actor that owns the event (connections
//! count bytes and workers, the assembler counts dropped results) and read by the
//! display when it builds a frame's [`FrameStats`]; nothing else is shared.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;

use crate::scene::state::StateVersion;
use crate::wire::protocol::FrameNo;
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
    /// Connections that passed the handshake, have not ended and are not paused.
    pub workers: AtomicU64,
    /// Connections whose worker paused (its desk's owner is active) and has not resumed.
    pub paused_workers: AtomicU64,
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

/// Statistics of one shown frame; one JSON line each in `--stats` files.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    pub frame: FrameNo,
    pub state_version: StateVersion,
    /// Results of this frame that came back in time.
    pub jobs_back: u32,
    /// Jobs of this frame (S).
    pub jobs_total: u32,
    /// Q_t when the frame was shown.
    pub q: f64,
    /// I_t when the frame was shown.
    pub i: f64,
    /// Time from the start of this frame to its display.
    pub wait_ms: f64,
    /// When the presenter showed it, in milliseconds since the master started (frame
    /// periods and edit latencies line up on this clock).
    pub shown_at_ms: f64,
    /// Frames skipped (Q_min not reached by I_max) since the previous shown frame.
    pub skipped: u64,
    pub dropped_late: u64,
    pub dropped_duplicate: u64,
    pub dropped_unknown: u64,
    /// Live workers: connected and taking jobs (paused ones are not counted).
    pub workers: u64,
    /// Connected workers that paused because their desk's owner is active.
    pub paused_workers: u64,
    /// Those workers, each with its reason.
    pub paused: Vec<crate::connection::workers::PausedWorker>,
    pub bytes_in: u64,
    pub bytes_out: u64,
    /// Frames shown so far in this run, this one included.
    pub shown: u64,
    /// Frames since the scene state last changed whose results are accumulated.
    pub accumulated_frames: u32,
    /// When the edits this frame shows first happened (not written: instants have no
    /// meaning outside this process).
    #[serde(skip)]
    pub edits_at: Vec<Instant>,
    /// Edit-to-display latency of each of those edits, in milliseconds: from the edit
    /// (input event or scripted time) to the moment this frame was shown.
    pub edit_latency_ms: Vec<f64>,
    /// Results so far in shown frames (this one included).
    pub results_used: u64,
    /// Results so far that came back for a job (accepted, or dropped as late).
    pub results_returned: u64,
    /// `results_used / results_returned`: the share of the grid's returned work that reached
    /// an image (docs/design.md, decision 8); `None` (JSON `null`) before any result returned.
    pub useful_fraction: Option<f64>,
    /// Queued jobs discarded so far because the scene state changed before they were
    /// handed out (never handed out afterwards).
    pub jobs_discarded_stale: u64,
    /// Held jobs workers dropped unrendered so far, a newer state's job having come first.
    pub jobs_superseded: u64,
}

impl FrameStats {
    /// Sets `edit_latency_ms` for a frame shown at `now` (the sink calls it when the
    /// frame is really shown; the presenter calls it when it hands the frame over).
    pub fn stamp_edit_latency(&mut self, now: Instant) {
        self.edit_latency_ms = self
            .edits_at
            .iter()
            .map(|at| now.saturating_duration_since(*at).as_secs_f64() * 1e3)
            .collect();
    }
}

/// The useful fraction of returned results: used ÷ (accepted + dropped as late); duplicates
/// and unknown results answer no job and do not count. `None` when nothing returned.
pub fn useful_fraction(used: u64, accepted: u64, late: u64) -> Option<f64> {
    let returned = accepted + late;
    (returned > 0).then(|| used as f64 / returned as f64)
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

    #[test]
    fn the_useful_fraction_counts_late_and_unused_results_as_waste() {
        assert_eq!(useful_fraction(0, 0, 0), None);
        assert_eq!(useful_fraction(30, 40, 10), Some(0.6), "10 late, 10 in skipped frames");
        assert_eq!(useful_fraction(8, 8, 0), Some(1.0));
    }
}
