//! The master's side of one worker connection as plain logic: worker messages in,
//! [`Action`]s out (the worker side's twin is `gridlight::worker::link`).
//!
//! It holds the protocol's phases (`wire::protocol`): the encrypted channel's handshake
//! (and no plain `Hello` when a secret is set), the version check and the HMAC
//! challenge, `Welcome`, serving manifest assets, credits (never more than `k` jobs held
//! or asked for), each state version sent before the first job naming it, results
//! checked (integrity tag, or its absence on an encrypted channel, first, then set range, the job it answers, its state version
//! and pixel count) and the memory of answered jobs that tells a duplicate from a result
//! never handed out, pausing and resuming, and the silence timeout. It knows no actor,
//! socket or counter: the connection actor carries out the actions, so every rule here
//! is unit-tested without actix.
//!
//! This file holds the state, the phases and the routing of each message; the rules
//! live by what they decide: [`handshake`] (the channel, `Hello`, `Auth`, `Welcome`), [`assets`]
//! (serving the manifest) and [`jobs`] (credits, jobs, results, pausing).

mod assets;
mod handshake;
mod jobs;
#[cfg(test)]
mod tests;

use std::collections::{HashSet, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::connection::ConnectionConfig;
use crate::scene::state::StateVersion;
use crate::shared::holdings::HeldJob;
use crate::wire::channel::Keys;
use crate::wire::codec::ProtocolError;
use crate::wire::integrity::ResultKey;
use crate::wire::protocol::{ConnId, FrameNo, JobResult, MasterMsg, PauseReason, SetNo, WorkerMsg};
use crate::wire::rejection::{Rejection, RejectionKind};

pub use handshake::MAX_NAME_LEN;

/// What the connection actor must do, in order.
#[derive(Debug, PartialEq)]
pub enum Action {
    /// Send this message to the worker.
    Send(MasterMsg),
    /// The channel's handshake is done: every frame after the ones already sent, both
    /// ways, is a record under these keys.
    Encrypt(Keys),
    /// The handshake is done: the worker is live (counted and listed from now on).
    Joined,
    /// Ask the scheduler for this many more jobs.
    RequestJobs(u32),
    /// The worker paused; `first` when it was taking jobs until now (the jobs it held,
    /// `lost` by frame, are lost and the scheduler must forget it), not when it only
    /// changed its reason.
    Paused { reason: PauseReason, first: bool, lost: Vec<FrameNo> },
    /// The worker takes jobs again (its `Ready` follows).
    Resumed,
    /// The answer to a job this connection held since `handed_at`: to the assembler, and
    /// the scheduler measures the worker's job time from it.
    Answered { result: JobResult, handed_at: Instant },
    /// A second answer to a job already answered: dropped and counted here, the only
    /// place that knows.
    Duplicate { frame: FrameNo, set: SetNo },
    /// A result for a job never given to this worker: dropped and counted (a
    /// [`Action::Reject`] follows).
    Unknown { frame: FrameNo, set: SetNo },
    /// The worker dropped a job it held without rendering it (a newer state's job came
    /// first): lost like any other, its slot free for the `Ready` that follows.
    Superseded { frame: FrameNo, set: SetNo },
    /// Send `Rejected` with this reason and close.
    Reject(Rejection),
}

#[derive(Debug)]
enum Phase {
    /// Waiting for `Hello`.
    Hello,
    /// `Challenge` sent with this nonce; waiting for `Auth`.
    Auth { nonce: [u8; 32] },
    /// Welcomed: assets and jobs; results are tagged with this connection's key.
    Work { key: ResultKey },
    /// Rejected: nothing more is read.
    Closing,
}

/// One connection's protocol state.
pub struct ProtocolState {
    id: ConnId,
    config: Arc<ConnectionConfig>,
    phase: Phase,
    /// The worker's name from `Hello`, safe for logs (empty before).
    name: String,
    /// Render threads the worker said it has (`Hello`).
    cores: u32,
    /// State versions already sent on this connection.
    sent_versions: HashSet<StateVersion>,
    answered: VecDeque<(FrameNo, SetNo)>,
    answered_set: HashSet<(FrameNo, SetNo)>,
    /// Credits passed to the scheduler and not yet filled.
    requested: u32,
    /// Why the worker paused; `None` while it takes jobs.
    paused: Option<PauseReason>,
    /// The channel's handshake succeeded: everything after it is encrypted.
    encrypted: bool,
    welcomed: bool,
    last_recv: Instant,
    last_sent: Instant,
}

impl ProtocolState {
    pub fn new(id: ConnId, config: Arc<ConnectionConfig>, now: Instant) -> Self {
        Self {
            id,
            config,
            phase: Phase::Hello,
            name: String::new(),
            cores: 0,
            sent_versions: HashSet::new(),
            answered: VecDeque::new(),
            answered_set: HashSet::new(),
            requested: 0,
            paused: None,
            encrypted: false,
            welcomed: false,
            last_recv: now,
            last_sent: now,
        }
    }

    /// The worker's name (empty before `Hello`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Render threads the worker said it has.
    pub fn cores(&self) -> u32 {
        self.cores
    }

    /// Jobs sent and not yet answered (lost if the connection ends now), as the master's
    /// one record of held jobs (`ConnectionConfig::held`) has them.
    pub fn held(&self) -> usize {
        self.config.held.lock().of(self.id).len()
    }

    /// The connection ends: every job it holds is lost, taken out of the record.
    pub fn release_held(&mut self) -> Vec<HeldJob> {
        self.config.held.lock().release(self.id)
    }

    /// Whether the handshake finished (the worker was counted).
    pub fn welcomed(&self) -> bool {
        self.welcomed
    }

    /// Whether the worker is paused now.
    pub fn paused(&self) -> bool {
        self.paused.is_some()
    }

    /// Whether the connection was rejected and reads nothing more.
    pub fn closing(&self) -> bool {
        matches!(self.phase, Phase::Closing)
    }

    /// A decoded message from the worker at `now`.
    pub fn on_message(&mut self, msg: WorkerMsg, now: Instant) -> Vec<Action> {
        if self.closing() {
            return Vec::new();
        }
        self.last_recv = now;
        let mut out = Vec::new();
        if let Err(why) = self.dispatch(msg, &mut out) {
            self.reject_into(why, &mut out);
        }
        self.note_sent(&out, now);
        out
    }

    /// A frame from the worker that could not be decoded.
    pub fn on_bad_frame(&mut self, err: &ProtocolError) -> Vec<Action> {
        let kind = match err {
            ProtocolError::EmptyFrame => RejectionKind::EmptyFrame,
            ProtocolError::FrameTooLong { .. } => RejectionKind::OversizedFrame,
            ProtocolError::Channel(_) => RejectionKind::Decrypt,
            _ => RejectionKind::BadFrame,
        };
        self.reject(Rejection::BadFrame { kind, cause: err.to_string() })
    }

    /// The keep-alive tick: ends a silent peer, sends a heartbeat on a quiet link.
    pub fn tick(&mut self, now: Instant) -> Vec<Action> {
        if self.closing() {
            return Vec::new();
        }
        let silent = now.saturating_duration_since(self.last_recv);
        if silent >= self.config.peer_timeout {
            return self.reject(Rejection::Timeout { secs: silent.as_secs_f32() });
        }
        let quiet = now.saturating_duration_since(self.last_sent) >= self.config.heartbeat;
        if matches!(self.phase, Phase::Work { .. }) && quiet {
            self.last_sent = now;
            return vec![Action::Send(MasterMsg::Heartbeat)];
        }
        Vec::new()
    }

    /// Ends the connection for this reason (also for the actor's own faults).
    pub fn reject(&mut self, why: Rejection) -> Vec<Action> {
        let mut out = Vec::new();
        if !self.closing() {
            self.reject_into(why, &mut out);
        }
        out
    }

    /// How often the actor should call [`ProtocolState::tick`].
    pub fn tick_interval(&self) -> Duration {
        (self.config.heartbeat / 2).min(self.config.peer_timeout / 4).max(Duration::from_millis(10))
    }

    /// Routes a message by phase to the rule that decides it.
    fn dispatch(&mut self, msg: WorkerMsg, out: &mut Vec<Action>) -> Result<(), Rejection> {
        match (&self.phase, msg) {
            (Phase::Hello, WorkerMsg::Handshake { protocol, noise }) if !self.encrypted => {
                self.on_channel(protocol, &noise, out)?
            }
            (Phase::Hello, WorkerMsg::Hello { protocol, name, cores }) => {
                self.on_hello(protocol, &name, cores, out)?
            }
            (Phase::Auth { nonce }, WorkerMsg::Auth { mac }) => {
                let nonce = *nonce;
                self.on_auth(nonce, mac, out)?
            }
            (Phase::Work { .. }, WorkerMsg::AssetRequest { hash }) => {
                self.serve_asset(hash, out)?
            }
            (Phase::Work { .. }, WorkerMsg::Paused { reason }) => self.on_paused(reason, out),
            (Phase::Work { .. }, msg @ (WorkerMsg::Ready { .. } | WorkerMsg::Result(_)))
                if self.paused.is_some() =>
            {
                return Err(Rejection::WhilePaused { message: kind(&msg) });
            }
            (Phase::Work { .. }, WorkerMsg::Resumed) => self.on_resumed(out)?,
            (Phase::Work { .. }, WorkerMsg::Ready { credits }) => self.on_ready(credits, out),
            (Phase::Work { .. }, WorkerMsg::Superseded { frame, set }) => {
                self.on_superseded(frame, set, out)
            }
            (Phase::Work { key }, WorkerMsg::Result(result)) => {
                // Checked before anything else reads the result: a corrupted frame or
                // set number must not be mistaken for a stale or foreign result.
                if !key.verify(&result) {
                    return Err(Rejection::Corrupt { frame: result.frame, set: result.set });
                }
                self.on_result(result, out)?;
            }
            (_, WorkerMsg::Heartbeat) => {}
            (phase, msg) => {
                return Err(Rejection::Phase { message: kind(&msg), phase: phase_name(phase) });
            }
        }
        Ok(())
    }

    fn reject_into(&mut self, why: Rejection, out: &mut Vec<Action>) {
        self.phase = Phase::Closing;
        out.push(Action::Reject(why));
    }

    fn note_sent(&mut self, out: &[Action], now: Instant) {
        if out.iter().any(|a| matches!(a, Action::Send(_))) {
            self.last_sent = now;
        }
    }
}

fn kind(msg: &WorkerMsg) -> &'static str {
    match msg {
        WorkerMsg::Hello { .. } => "Hello",
        WorkerMsg::Auth { .. } => "Auth",
        WorkerMsg::AssetRequest { .. } => "AssetRequest",
        WorkerMsg::Ready { .. } => "Ready",
        WorkerMsg::Result(_) => "Result",
        WorkerMsg::Heartbeat => "Heartbeat",
        WorkerMsg::Paused { .. } => "Paused",
        WorkerMsg::Resumed => "Resumed",
        WorkerMsg::Superseded { .. } => "Superseded",
        WorkerMsg::Handshake { .. } => "Handshake",
    }
}

fn phase_name(phase: &Phase) -> &'static str {
    match phase {
        Phase::Hello => "hello",
        Phase::Auth { .. } => "authentication",
        Phase::Work { .. } => "work",
        Phase::Closing => "closing",
    }
}
