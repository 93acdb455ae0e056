//! The per-frame statistics the presenter publishes, built from the shared
//! [`Counters`](crate::shared::counters::Counters) and the worker table.

use std::time::Instant;

use serde::Serialize;

use crate::scene::state::StateVersion;
use crate::shared::workers::PausedWorker;
use crate::wire::protocol::FrameNo;

/// Statistics of one shown frame; one JSON line each in `--stats` files.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    pub frame: FrameNo,
    pub state_version: StateVersion,
    /// Results of this frame that came back in time.
    pub jobs_back: u32,
    /// Samples per pixel of each of them (the scheduler sizes jobs to the grid:
    /// `scheduler::job_size`).
    pub spp: u32,
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
    pub paused: Vec<PausedWorker>,
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
    fn the_useful_fraction_counts_late_and_unused_results_as_waste() {
        assert_eq!(useful_fraction(0, 0, 0), None);
        assert_eq!(useful_fraction(30, 40, 10), Some(0.6), "10 late, 10 in skipped frames");
        assert_eq!(useful_fraction(8, 8, 0), Some(1.0));
    }
}
