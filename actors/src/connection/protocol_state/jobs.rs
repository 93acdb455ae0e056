//! Work: credits (never more than `k` jobs held or asked for), the jobs sent with each
//! state version before the first job naming it, results checked against the jobs held
//! and the memory of answered ones, superseded jobs, and pausing and resuming.

use std::time::Instant;

use super::{Action, Phase, ProtocolState};
use crate::shared::job::Job;
use crate::wire::protocol::{FrameNo, JobResult, MasterMsg, PauseReason, SetNo};
use crate::wire::rejection::Rejection;

/// Answered (frame, set) pairs remembered to tell duplicates from unknown results.
const ANSWERED_MEMORY: usize = 4096;

impl ProtocolState {
    /// Jobs the scheduler assigned in answer to this connection's credits.
    pub fn on_jobs(&mut self, jobs: Vec<Job>, now: Instant) -> Vec<Action> {
        let mut out = Vec::new();
        if !matches!(self.phase, Phase::Work { .. }) || self.paused.is_some() {
            // Closing, or paused before these credits were served: these jobs are lost
            // like any other, never redone.
            return out;
        }
        for job in jobs {
            self.requested = self.requested.saturating_sub(1);
            let version = job.state.version;
            if self.sent_versions.insert(version) {
                out.push(Action::Send(MasterMsg::State(Box::new((*job.state).clone()))));
            }
            self.held.insert((job.frame, job.set), version);
            out.push(Action::Send(MasterMsg::Job {
                frame: job.frame,
                set: job.set,
                state_version: version,
            }));
        }
        self.note_sent(&out, now);
        out
    }

    /// `Paused`: the first one loses the jobs held and the credits asked for.
    pub(super) fn on_paused(&mut self, reason: PauseReason, out: &mut Vec<Action>) {
        let first = self.paused.is_none();
        if first {
            self.held.clear();
            self.requested = 0;
        }
        self.paused = Some(reason.clone());
        out.push(Action::Paused { reason, first });
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
        let room = self.config.pipeline.saturating_sub(self.held.len() as u32 + self.requested);
        let grant = credits.min(room);
        if grant > 0 {
            self.requested += grant;
            out.push(Action::RequestJobs(grant));
        }
    }

    /// `Superseded`: a job it does not hold (lost already, e.g. by a pause) changes nothing.
    pub(super) fn on_superseded(&mut self, frame: FrameNo, set: SetNo, out: &mut Vec<Action>) {
        if self.held.remove(&(frame, set)).is_some() {
            out.push(Action::Superseded { frame, set });
        }
    }

    /// Validates a result against the jobs this connection holds.
    pub(super) fn on_result(
        &mut self,
        r: JobResult,
        out: &mut Vec<Action>,
    ) -> Result<(), Rejection> {
        let sets = self.config.sets.sets();
        if r.set >= sets {
            return Err(Rejection::SetRange { set: r.set, sets });
        }
        let key = (r.frame, r.set);
        let Some(job) = self.held.remove(&key) else {
            let (frame, set) = key;
            if self.answered_set.contains(&key) {
                out.push(Action::Duplicate { frame, set });
                return Ok(());
            }
            out.push(Action::Unknown { frame, set });
            return Err(Rejection::UnknownResult { frame, set });
        };
        let (frame, set) = key;
        if job != r.state_version {
            return Err(Rejection::StateVersion { frame, set, got: r.state_version, job });
        }
        let set_len = self.config.sets.set_len(r.set);
        if r.radiance.len() != set_len {
            return Err(Rejection::PixelCount { frame, set, got: r.radiance.len(), set_len });
        }
        self.remember_answered(key);
        out.push(Action::Answered(r));
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
