//! Who holds which job: the master's one record of it.
//!
//! A job enters the record when the scheduler hands it out, and leaves it when its
//! connection takes it back: its result came (checked against this entry), the worker
//! dropped it unrendered (`Superseded`), or the jobs were lost (the worker paused, the
//! connection ended, or jobs reached a connection that no longer takes them). The
//! connection checks results against it and the scheduler's hand-out plan forecasts from
//! it; nobody keeps a second copy that could drift from it.

use std::collections::HashMap;
use std::sync::{Mutex, MutexGuard};
use std::time::Instant;

use crate::scene::state::{Resolution, StateVersion};
use crate::wire::protocol::{ConnId, FrameNo, SetNo};

/// One job a connection holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeldJob {
    pub frame: FrameNo,
    pub set: SetNo,
    /// The scene-state version it names (its result must carry the same).
    pub version: StateVersion,
    /// Its state's image size: the result holds one pixel of the set at this size each.
    pub resolution: Resolution,
    /// When the scheduler handed it out.
    pub handed_at: Instant,
}

/// The jobs each connection holds, in hand-out order (the order its worker renders them).
#[derive(Debug, Default)]
pub struct Holdings {
    by_conn: HashMap<ConnId, Vec<HeldJob>>,
}

impl Holdings {
    /// `conn` holds `job` from now on (no change when it holds it already).
    pub fn hand(&mut self, conn: ConnId, job: HeldJob) {
        let held = self.by_conn.entry(conn).or_default();
        if !held.iter().any(|h| (h.frame, h.set) == (job.frame, job.set)) {
            held.push(job);
        }
    }

    /// Takes `(frame, set)` from what `conn` holds; `None` when it does not hold it.
    pub fn take(&mut self, conn: ConnId, frame: FrameNo, set: SetNo) -> Option<HeldJob> {
        let held = self.by_conn.get_mut(&conn)?;
        let i = held.iter().position(|h| (h.frame, h.set) == (frame, set))?;
        let job = held.remove(i);
        if held.is_empty() {
            self.by_conn.remove(&conn);
        }
        Some(job)
    }

    /// Takes every job `conn` holds (they are lost).
    pub fn release(&mut self, conn: ConnId) -> Vec<HeldJob> {
        self.by_conn.remove(&conn).unwrap_or_default()
    }

    /// The jobs `conn` holds, in hand-out order.
    pub fn of(&self, conn: ConnId) -> &[HeldJob] {
        self.by_conn.get(&conn).map_or(&[], Vec::as_slice)
    }

    /// Jobs held by all connections.
    pub fn total(&self) -> usize {
        self.by_conn.values().map(Vec::len).sum()
    }
}

/// The record, shared by the connections and the scheduler. They all run on the master's
/// one actor thread, so the lock is never contended; it is held for one decision at a
/// time, never across a message.
#[derive(Debug, Default)]
pub struct HeldJobs(Mutex<Holdings>);

impl HeldJobs {
    pub fn lock(&self) -> MutexGuard<'_, Holdings> {
        self.0.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job(frame: FrameNo, set: SetNo, at: Instant) -> HeldJob {
        HeldJob {
            frame,
            set,
            version: 1,
            resolution: Resolution { width: 8, height: 8 },
            handed_at: at,
        }
    }

    #[test]
    fn a_job_is_held_once_in_hand_out_order_until_taken_back() {
        let t0 = Instant::now();
        let mut h = Holdings::default();
        h.hand(1, job(3, 0, t0));
        h.hand(1, job(3, 1, t0));
        h.hand(1, job(3, 0, t0)); // the connection confirms what the scheduler handed out
        h.hand(2, job(4, 0, t0));
        assert_eq!(h.of(1), [job(3, 0, t0), job(3, 1, t0)]);
        assert_eq!(h.total(), 3);
        assert_eq!(h.take(1, 3, 0), Some(job(3, 0, t0)));
        assert_eq!(h.take(1, 3, 0), None, "taken once");
        assert_eq!(h.take(2, 3, 1), None, "another connection's job");
        assert_eq!(h.release(1), [job(3, 1, t0)]);
        assert!(h.of(1).is_empty() && h.release(1).is_empty());
        assert_eq!(h.total(), 1);
    }
}
