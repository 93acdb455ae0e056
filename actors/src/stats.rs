//! Counters shared by the actors and the per-frame statistics the display emits.
//!
//! Counters are plain atomics written by the actor that owns the event (connections
//! count bytes and workers, the assembler counts dropped results) and read by the
//! display when it builds a frame's [`FrameStats`]; nothing else is shared.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use serde::Serialize;

use crate::protocol::FrameNo;
use crate::state::StateVersion;

/// Monotonic counters of the whole master run.
#[derive(Debug, Default)]
pub struct Counters {
    /// Shared with every connection's socket wrappers.
    pub bytes_in: Arc<AtomicU64>,
    pub bytes_out: Arc<AtomicU64>,
    /// Connections that passed the handshake and have not ended.
    pub workers: AtomicU64,
    pub dropped_late: AtomicU64,
    pub dropped_duplicate: AtomicU64,
    pub dropped_unknown: AtomicU64,
    /// Results accepted into a frame.
    pub results_accepted: AtomicU64,
    /// Jobs handed out by the scheduler.
    pub jobs_handed_out: AtomicU64,
    /// Connections ended with a protocol error (rejections included).
    pub connections_rejected: AtomicU64,
    /// Panics contained at an actor boundary.
    pub panics_contained: AtomicU64,
}

impl Counters {
    pub fn add(counter: &AtomicU64, n: u64) {
        counter.fetch_add(n, Ordering::Relaxed);
    }

    pub fn get(counter: &AtomicU64) -> u64 {
        counter.load(Ordering::Relaxed)
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
    /// Frames skipped (Q_min not reached by I_max) since the previous shown frame.
    pub skipped: u64,
    pub dropped_late: u64,
    pub dropped_duplicate: u64,
    pub dropped_unknown: u64,
    pub workers: u64,
    pub bytes_in: u64,
    pub bytes_out: u64,
    /// Frames shown so far in this run, this one included.
    pub shown: u64,
    /// Frames since the scene state last changed whose results are accumulated.
    pub accumulated_frames: u32,
}
