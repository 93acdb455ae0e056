//! The master's side of one worker connection as plain logic: worker messages in,
//! [`Action`]s out (the worker side's twin is `gridlight::worker::session`).
//!
//! It holds the protocol's phases (`wire::protocol`): the version check and the HMAC
//! challenge, `Welcome`, serving manifest assets, credits (never more than `k` jobs held
//! or asked for), each state version sent before the first job naming it, results
//! checked (integrity tag first, then set range, the job it answers, its state version
//! and pixel count) and the memory of answered jobs that tells a duplicate from a result
//! never handed out, pausing and resuming, and the silence timeout. It knows no actor,
//! socket or counter: the connection actor carries out the actions, so every rule here
//! is unit-tested without actix.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::connection::ConnectionConfig;
use crate::scene::state::StateVersion;
use crate::scheduler::job_queue::Job;
use crate::wire::auth;
use crate::wire::codec::ProtocolError;
use crate::wire::integrity::ResultKey;
use crate::wire::protocol::{
    AssetHash, ConnId, FrameNo, JobResult, MasterMsg, PauseReason, SetNo, WorkerMsg,
    ASSET_CHUNK_LEN, PROTOCOL_VERSION,
};
use crate::wire::rejection::{Rejection, RejectionKind};

/// Answered (frame, set) pairs remembered to tell duplicates from unknown results.
const ANSWERED_MEMORY: usize = 4096;
/// Longest worker name accepted.
pub const MAX_NAME_LEN: usize = 256;

/// What the connection actor must do, in order.
#[derive(Debug, PartialEq)]
pub enum Action {
    /// Send this message to the worker.
    Send(MasterMsg),
    /// The handshake is done: the worker is live (counted and listed from now on).
    Joined,
    /// Ask the scheduler for this many more jobs.
    RequestJobs(u32),
    /// The worker paused; `first` when it was taking jobs until now (the jobs it held are
    /// lost and the scheduler must forget it), not when it only changed its reason.
    Paused { reason: PauseReason, first: bool },
    /// The worker takes jobs again (its `Ready` follows).
    Resumed,
    /// The answer to a job this connection holds: to the assembler, and the scheduler
    /// measures the worker's job time from it.
    Answered(JobResult),
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
pub struct Session {
    id: ConnId,
    config: Arc<ConnectionConfig>,
    phase: Phase,
    /// The worker's name from `Hello`, safe for logs (empty before).
    name: String,
    /// Render threads the worker said it has (`Hello`).
    cores: u32,
    /// State versions already sent on this connection.
    sent_versions: HashSet<StateVersion>,
    /// Jobs sent and not yet answered, with the version they name: the master's only
    /// record of who holds which job (a result is checked against it, here, once).
    held: HashMap<(FrameNo, SetNo), StateVersion>,
    answered: VecDeque<(FrameNo, SetNo)>,
    answered_set: HashSet<(FrameNo, SetNo)>,
    /// Credits passed to the scheduler and not yet filled.
    requested: u32,
    /// Why the worker paused; `None` while it takes jobs.
    paused: Option<PauseReason>,
    welcomed: bool,
    last_recv: Instant,
    last_sent: Instant,
}

impl Session {
    pub fn new(id: ConnId, config: Arc<ConnectionConfig>, now: Instant) -> Self {
        Self {
            id,
            config,
            phase: Phase::Hello,
            name: String::new(),
            cores: 0,
            sent_versions: HashSet::new(),
            held: HashMap::new(),
            answered: VecDeque::new(),
            answered_set: HashSet::new(),
            requested: 0,
            paused: None,
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

    /// Jobs sent and not yet answered (lost if the connection ends now).
    pub fn held(&self) -> usize {
        self.held.len()
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
            _ => RejectionKind::BadFrame,
        };
        self.reject(Rejection::BadFrame { kind, cause: err.to_string() })
    }

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

    /// How often the actor should call [`Session::tick`].
    pub fn tick_interval(&self) -> Duration {
        (self.config.heartbeat / 2).min(self.config.peer_timeout / 4).max(Duration::from_millis(10))
    }

    fn dispatch(&mut self, msg: WorkerMsg, out: &mut Vec<Action>) -> Result<(), Rejection> {
        match (&self.phase, msg) {
            (Phase::Hello, WorkerMsg::Hello { protocol, name, cores }) => {
                self.name = sanitize(&name);
                self.cores = cores;
                if protocol != PROTOCOL_VERSION {
                    return Err(Rejection::Version { worker: protocol, master: PROTOCOL_VERSION });
                }
                if name.is_empty() || name.len() > MAX_NAME_LEN {
                    return Err(Rejection::Name { max: MAX_NAME_LEN });
                }
                let nonce = auth::nonce();
                self.phase = Phase::Auth { nonce };
                let auth_required = self.config.secret.is_some();
                out.push(Action::Send(MasterMsg::Challenge { nonce, auth_required }));
            }
            (Phase::Auth { nonce }, WorkerMsg::Auth { mac }) => {
                let nonce = *nonce;
                if let Some(secret) = &self.config.secret {
                    match mac {
                        None => return Err(Rejection::NoSecret),
                        Some(m) if !auth::verify(secret, &nonce, &m) => {
                            return Err(Rejection::WrongSecret)
                        }
                        Some(_) => {}
                    }
                }
                let key = ResultKey::derive(self.config.secret.as_deref(), &nonce);
                self.phase = Phase::Work { key };
                self.welcomed = true;
                out.push(Action::Joined);
                out.push(Action::Send(MasterMsg::Welcome {
                    worker_id: self.id,
                    sets: self.config.sets.config(),
                    assets: self.config.assets.manifest().to_vec(),
                }));
            }
            (Phase::Work { .. }, WorkerMsg::AssetRequest { hash }) => {
                self.serve_asset(hash, out)?
            }
            (Phase::Work { .. }, WorkerMsg::Paused { reason }) => {
                let first = self.paused.is_none();
                if first {
                    self.held.clear();
                    self.requested = 0;
                }
                self.paused = Some(reason.clone());
                out.push(Action::Paused { reason, first });
            }
            (Phase::Work { .. }, msg @ (WorkerMsg::Ready { .. } | WorkerMsg::Result(_)))
                if self.paused.is_some() =>
            {
                return Err(Rejection::WhilePaused { message: kind(&msg) });
            }
            (Phase::Work { .. }, WorkerMsg::Resumed) => {
                if self.paused.take().is_none() {
                    return Err(Rejection::NotPaused);
                }
                out.push(Action::Resumed);
            }
            (Phase::Work { .. }, WorkerMsg::Ready { credits }) => {
                let room =
                    self.config.pipeline.saturating_sub(self.held.len() as u32 + self.requested);
                let grant = credits.min(room);
                if grant > 0 {
                    self.requested += grant;
                    out.push(Action::RequestJobs(grant));
                }
            }
            (Phase::Work { .. }, WorkerMsg::Superseded { frame, set }) => {
                // A job it does not hold (lost already, e.g. by a pause) changes nothing.
                if self.held.remove(&(frame, set)).is_some() {
                    out.push(Action::Superseded { frame, set });
                }
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

    /// Validates a result against the jobs this connection holds.
    fn on_result(&mut self, r: JobResult, out: &mut Vec<Action>) -> Result<(), Rejection> {
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

    /// Every chunk of a manifest asset.
    fn serve_asset(&self, hash: AssetHash, out: &mut Vec<Action>) -> Result<(), Rejection> {
        let assets = &self.config.assets;
        let not_listed = || Rejection::NotInManifest { hash: hex(&hash) };
        let entry = assets.entry(&hash).ok_or_else(not_listed)?;
        let mut offset = 0u64;
        loop {
            let chunk = match assets.read_chunk(&hash, offset, ASSET_CHUNK_LEN) {
                Some(Ok(c)) => c,
                Some(Err(e)) => {
                    let (path, cause) = (entry.path.clone(), e.to_string());
                    return Err(Rejection::AssetUnreadable { path, cause });
                }
                None => return Err(not_listed()),
            };
            let n = chunk.len() as u64;
            out.push(Action::Send(MasterMsg::AssetChunk {
                hash,
                offset,
                len: entry.len,
                data: chunk,
            }));
            offset += n;
            if offset >= entry.len || n == 0 {
                return Ok(());
            }
        }
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

/// A name safe to put in logs (no control characters).
fn sanitize(name: &str) -> String {
    name.chars().take(MAX_NAME_LEN).map(|c| if c.is_control() { '?' } else { c }).collect()
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

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::connection::workers::WorkerTable;
    use crate::scene::asset_store::AssetStore;
    use crate::scene::state::{Camera, Resolution, SceneState};
    use crate::scheduler::sets::SetTable;
    use crate::wire::protocol::{PackedRadiance, Partition, SetsConfig};
    use glam::Vec3;

    const SECRET: &[u8] = b"shared";

    fn config(secret: Option<&[u8]>) -> Arc<ConnectionConfig> {
        let sets = SetsConfig { sets: 4, partition: Partition::QuasiRandom };
        Arc::new(ConnectionConfig {
            secret: secret.map(<[u8]>::to_vec),
            sets: Arc::new(SetTable::new(Resolution { width: 8, height: 4 }, sets).expect("sets")),
            assets: Arc::new(AssetStore::new()),
            pipeline: 2,
            heartbeat: Duration::from_secs(1),
            peer_timeout: Duration::from_secs(10),
            workers: Arc::new(WorkerTable::default()),
        })
    }

    fn hello() -> WorkerMsg {
        WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "w".into(), cores: 2 }
    }

    fn rejection(actions: &[Action]) -> Option<&Rejection> {
        actions.iter().find_map(|a| match a {
            Action::Reject(r) => Some(r),
            _ => None,
        })
    }

    /// A session through the handshake, with the key its results must carry.
    fn welcomed(now: Instant) -> (Session, ResultKey) {
        let mut s = Session::new(7, config(None), now);
        let out = s.on_message(hello(), now);
        let Some(Action::Send(MasterMsg::Challenge { nonce, auth_required: false })) = out.first()
        else {
            panic!("no challenge: {out:?}");
        };
        let key = ResultKey::derive(None, nonce);
        let out = s.on_message(WorkerMsg::Auth { mac: None }, now);
        assert_eq!(out[0], Action::Joined);
        assert!(matches!(&out[1], Action::Send(MasterMsg::Welcome { worker_id: 7, .. })));
        (s, key)
    }

    fn job(frame: FrameNo, set: SetNo, version: StateVersion) -> Job {
        let camera = Camera::pinhole(Vec3::Z, Vec3::ZERO, 40.0);
        let state =
            SceneState { version, ..SceneState::empty(Resolution { width: 8, height: 4 }, camera) };
        Job { frame, set, state: Arc::new(state) }
    }

    fn answer(
        s: &Session,
        key: &ResultKey,
        frame: FrameNo,
        set: SetNo,
        v: StateVersion,
    ) -> WorkerMsg {
        let pixels = s.config.sets.set_len(set);
        let radiance = PackedRadiance::Rgb9e5(vec![0; pixels]);
        WorkerMsg::Result(key.seal(frame, set, v, radiance, 10))
    }

    #[test]
    fn a_wrong_protocol_version_is_rejected_as_final() {
        let now = Instant::now();
        let mut s = Session::new(1, config(None), now);
        let out = s.on_message(
            WorkerMsg::Hello { protocol: PROTOCOL_VERSION + 1, name: "w".into(), cores: 1 },
            now,
        );
        let why = rejection(&out).expect("rejected");
        assert_eq!(why.kind(), RejectionKind::Version);
        assert!(crate::wire::rejection::is_final(&why.to_string()));
        assert!(s.closing());
        assert!(s.on_message(hello(), now).is_empty(), "a closing session reads nothing");
    }

    #[test]
    fn with_a_secret_a_missing_or_wrong_mac_is_rejected_and_the_right_one_welcomed() {
        let now = Instant::now();
        for (mac, want) in [
            (None, Some(Rejection::NoSecret)),
            (Some([0u8; 32]), Some(Rejection::WrongSecret)),
            (Some([1u8; 32]), None),
        ] {
            let mut s = Session::new(1, config(Some(SECRET)), now);
            let out = s.on_message(hello(), now);
            let Some(Action::Send(MasterMsg::Challenge { nonce, auth_required: true })) =
                out.first()
            else {
                panic!("no challenge: {out:?}");
            };
            let mac = mac.map(|m| if m == [1u8; 32] { auth::mac(SECRET, nonce) } else { m });
            let out = s.on_message(WorkerMsg::Auth { mac }, now);
            assert_eq!(rejection(&out), want.as_ref());
            assert_eq!(s.welcomed(), want.is_none());
        }
    }

    #[test]
    fn messages_out_of_phase_are_rejected() {
        let now = Instant::now();
        let mut s = Session::new(1, config(None), now);
        let out = s.on_message(WorkerMsg::Ready { credits: 1 }, now);
        assert_eq!(rejection(&out), Some(&Rejection::Phase { message: "Ready", phase: "hello" }));
    }

    #[test]
    fn credits_never_let_a_worker_hold_more_than_k() {
        let now = Instant::now();
        let (mut s, _) = welcomed(now);
        assert_eq!(s.on_message(WorkerMsg::Ready { credits: 5 }, now), [Action::RequestJobs(2)]);
        assert!(
            s.on_message(WorkerMsg::Ready { credits: 1 }, now).is_empty(),
            "k already asked for"
        );
        s.on_jobs(vec![job(0, 0, 1)], now);
        assert!(
            s.on_message(WorkerMsg::Ready { credits: 1 }, now).is_empty(),
            "one held, one asked"
        );
    }

    #[test]
    fn a_state_version_is_sent_once_before_the_first_job_that_names_it() {
        let now = Instant::now();
        let (mut s, _) = welcomed(now);
        let out = s.on_jobs(vec![job(0, 0, 1), job(0, 1, 1), job(1, 0, 2)], now);
        let names: Vec<_> = out
            .iter()
            .map(|a| match a {
                Action::Send(MasterMsg::State(st)) => format!("state {}", st.version),
                Action::Send(MasterMsg::Job { frame, set, state_version }) => {
                    format!("job {frame}/{set}@{state_version}")
                }
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(names, ["state 1", "job 0/0@1", "job 0/1@1", "state 2", "job 1/0@2"]);
    }

    #[test]
    fn results_are_checked_once_answered_duplicate_or_unknown() {
        let now = Instant::now();
        let (mut s, key) = welcomed(now);
        s.on_jobs(vec![job(3, 1, 1)], now);
        let out = s.on_message(answer(&s, &key, 3, 1, 1), now);
        assert!(matches!(out[..], [Action::Answered(_)]), "{out:?}");
        assert_eq!(s.held(), 0);
        let out = s.on_message(answer(&s, &key, 3, 1, 1), now);
        assert!(
            out[..] == [Action::Duplicate { frame: 3, set: 1 }],
            "a second answer is a duplicate: {out:?}"
        );
        let out = s.on_message(answer(&s, &key, 3, 2, 1), now);
        assert_eq!(out[0], Action::Unknown { frame: 3, set: 2 });
        assert_eq!(rejection(&out), Some(&Rejection::UnknownResult { frame: 3, set: 2 }));
    }

    #[test]
    fn a_bad_result_is_rejected_with_its_kind() {
        let now = Instant::now();
        type Make = fn(&Session, &ResultKey) -> WorkerMsg;
        let cases: [(Make, RejectionKind); 4] = [
            (|s, k| answer(s, k, 0, 9, 1), RejectionKind::SetRange),
            (|s, k| answer(s, k, 0, 0, 2), RejectionKind::StateVersion),
            (
                |_, k| WorkerMsg::Result(k.seal(0, 0, 1, PackedRadiance::Rgb9e5(vec![0; 1]), 1)),
                RejectionKind::PixelCount,
            ),
            (
                |s, k| {
                    let WorkerMsg::Result(mut r) = answer(s, k, 0, 0, 1) else { unreachable!() };
                    r.frame = 1;
                    WorkerMsg::Result(r)
                },
                RejectionKind::Corrupt,
            ),
        ];
        for (make, kind) in cases {
            let (mut s, key) = welcomed(now);
            s.on_jobs(vec![job(0, 0, 1)], now);
            let msg = make(&s, &key);
            let out = s.on_message(msg, now);
            assert_eq!(rejection(&out).map(Rejection::kind), Some(kind), "{out:?}");
        }
    }

    #[test]
    fn a_paused_worker_loses_its_jobs_and_may_not_ask_for_more() {
        let now = Instant::now();
        let (mut s, _) = welcomed(now);
        s.on_message(WorkerMsg::Ready { credits: 2 }, now);
        s.on_jobs(vec![job(0, 0, 1)], now);
        let reason = PauseReason::OwnerInput { seconds_ago: 1.0 };
        let out = s.on_message(WorkerMsg::Paused { reason: reason.clone() }, now);
        assert_eq!(out, [Action::Paused { reason: reason.clone(), first: true }]);
        assert_eq!(s.held(), 0, "the held job is lost");
        assert!(s.on_jobs(vec![job(0, 1, 1)], now).is_empty(), "no job reaches a paused worker");
        let again = s.on_message(WorkerMsg::Paused { reason: reason.clone() }, now);
        assert_eq!(again, [Action::Paused { reason, first: false }]);
        assert_eq!(s.on_message(WorkerMsg::Resumed, now), [Action::Resumed]);
        let out = s.on_message(WorkerMsg::Resumed, now);
        assert_eq!(rejection(&out), Some(&Rejection::NotPaused));
    }

    #[test]
    fn a_quiet_link_gets_heartbeats_and_a_silent_peer_is_ended() {
        let now = Instant::now();
        let (mut s, _) = welcomed(now);
        assert!(s.tick(now + Duration::from_millis(500)).is_empty());
        assert_eq!(s.tick(now + Duration::from_secs(1)), [Action::Send(MasterMsg::Heartbeat)]);
        let out = s.tick(now + Duration::from_secs(11));
        assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Timeout));
    }

    #[test]
    fn an_asset_not_in_the_manifest_is_refused() {
        let now = Instant::now();
        let (mut s, _) = welcomed(now);
        let out = s.on_message(WorkerMsg::AssetRequest { hash: [3; 32] }, now);
        assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Asset));
    }
}
