//! Work: credits (never more than `k` jobs held or asked for), the jobs sent with each
//! state version before the first job naming it, results checked against the jobs held
//! and the memory of answered ones, superseded jobs, and pausing and resuming.
//!
//! Which jobs this connection holds is read from and written to the master's one record
//! of it (`ConnectionConfig::held`): the scheduler enters a job when it hands it out, and
//! this connection takes it back out when it is answered, dropped or lost.

use std::time::Instant;

use super::{Action, Phase, ProtocolState};
use crate::shared::holdings::HeldJob;
use crate::shared::job::Job;
use crate::wire::protocol::{FrameNo, JobResult, MasterMsg, PauseReason, SetNo};
use crate::wire::rejection::Rejection;

/// Answered (frame, set) pairs remembered to tell duplicates from unknown results.
const ANSWERED_MEMORY: usize = 4096;

impl ProtocolState {
    /// Jobs the scheduler assigned in answer to this connection's credits.
    pub fn on_jobs(&mut self, jobs: Vec<Job>, now: Instant) -> Vec<Action> {
        let mut out = Vec::new();
        let mut held = self.config.held.lock();
        if !matches!(self.phase, Phase::Work { .. }) || self.paused.is_some() {
            // Closing, or paused before these credits were served: these jobs are lost
            // like any other, never redone.
            for job in jobs {
                held.take(self.id, job.frame, job.set);
            }
            return out;
        }
        for job in jobs {
            self.requested = self.requested.saturating_sub(1);
            let version = job.state.version;
            if self.sent_versions.insert(version) {
                out.push(Action::Send(MasterMsg::State(Box::new((*job.state).clone()))));
            }
            // The scheduler entered it when it handed it out; entered here if not.
            let (frame, set, resolution) = (job.frame, job.set, job.state.resolution);
            held.hand(self.id, HeldJob { frame, set, version, resolution, handed_at: now });
            out.push(Action::Send(MasterMsg::Job {
                frame: job.frame,
                set: job.set,
                state_version: version,
                spp: job.spp,
            }));
        }
        drop(held);
        self.note_sent(&out, now);
        out
    }

    /// `Paused`: the first one loses the jobs held and the credits asked for.
    pub(super) fn on_paused(&mut self, reason: PauseReason, out: &mut Vec<Action>) {
        let first = self.paused.is_none();
        let mut lost = Vec::new();
        if first {
            lost = self.release_held().iter().map(|h| h.frame).collect();
            self.requested = 0;
        }
        self.paused = Some(reason.clone());
        out.push(Action::Paused { reason, first, lost });
    }

    /// `Resumed`: only a paused worker may send it.
    pub(super) fn on_resumed(&mut self, out: &mut Vec<Action>) -> Result<(), Rejection> {
        if self.paused.take().is_none() {
            return Err(Rejection::NotPaused);
        }
        out.push(Action::Resumed);
        Ok(())
    }

    /// `Ready`: credits granted up to `k` jobs held or asked for.
    pub(super) fn on_ready(&mut self, credits: u32, out: &mut Vec<Action>) {
        let room = self.config.pipeline.saturating_sub(self.held() as u32 + self.requested);
        let grant = credits.min(room);
        if grant > 0 {
            self.requested += grant;
            out.push(Action::RequestJobs(grant));
        }
    }

    /// `Superseded`: a job it does not hold (lost already, e.g. by a pause) changes nothing.
    pub(super) fn on_superseded(&mut self, frame: FrameNo, set: SetNo, out: &mut Vec<Action>) {
        if self.config.held.lock().take(self.id, frame, set).is_some() {
            out.push(Action::Superseded { frame, set });
        }
    }

    /// Validates a result against the jobs this connection holds.
    pub(super) fn on_result(
        &mut self,
        r: JobResult,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        let sets = self.config.sets.config().sets;
        if r.set >= sets {
            return Err(Rejection::SetRange { set: r.set, sets });
        }
        let key = (r.frame, r.set);
        let taken = self.config.held.lock().take(self.id, r.frame, r.set);
        let Some(job) = taken else {
            let (frame, set) = key;
            if self.answered_set.contains(&key) {
                out.push(Action::Duplicate { frame, set });
                return Ok(());
            }
            out.push(Action::Unknown { frame, set });
            return Err(Rejection::UnknownResult { frame, set });
        };
        let (frame, set) = key;
        if job.version != r.state_version {
            let (got, job) = (r.state_version, job.version);
            return Err(Rejection::StateVersion { frame, set, got, job });
        }
        // Its state's resolution was checked against S before any job named it.
        let set_len = self.config.sets.checked(job.resolution).set_len(r.set);
        if r.radiance.len() != set_len {
            return Err(Rejection::PixelCount { frame, set, got: r.radiance.len(), set_len });
        }
        self.remember_answered(key);
        out.push(Action::Answered { result: r, handed_at: job.handed_at });
        Ok(())
    }

    fn remember_answered(&mut self, key: (FrameNo, SetNo)) {
        self.answered.push_back(key);
        self.answered_set.insert(key);
        if self.answered.len() > ANSWERED_MEMORY {
            if let Some(old) = self.answered.pop_front() {
                self.answered_set.remove(&old);
            }
        }
    }
}
