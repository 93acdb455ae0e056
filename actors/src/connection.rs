//! The connection actor: one per worker socket (protocol phases in `protocol.rs`).
//!
//! It runs the handshake (version, HMAC challenge), sends `Welcome` with the sets
//! configuration and the asset manifest, serves asset chunks (manifest hashes only),
//! turns the worker's `Ready` credits into requests to the scheduler (never more than
//! `k` jobs held), sends each state version before the first job naming it, validates
//! every result (its integrity tag first, then against the jobs it holds) and forwards
//! it to the frame assembler, lets a worker pause while its desk's owner is active (the
//! jobs it held are lost, it gets none until it resumes, it is counted apart), and
//! keeps the link alive with heartbeats and a silence timeout. Any protocol violation
//! ends this connection only, after a `Rejected` that names the problem; every log
//! line names the peer. The jobs it held are never handed out again.

use std::collections::{HashMap, HashSet, VecDeque};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::{Duration, Instant};

use actix::io::{FramedWrite, WriteHandler};
use actix::prelude::*;
use tokio::net::tcp::OwnedWriteHalf;

use crate::assembler::ResultArrived;
use crate::asset_store::AssetStore;
use crate::auth;
use crate::codec::{MasterCodec, ProtocolError};
use crate::counted_io::CountedWrite;
use crate::frame_table::ConnId;
use crate::integrity::ResultKey;
use crate::protocol::{
    AssetHash, FrameNo, JobResult, MasterMsg, PauseReason, SetNo, WorkerMsg, ASSET_CHUNK_LEN,
    PROTOCOL_VERSION,
};
use crate::scheduler::{JobAnswered, JobsAssigned, WorkerLeft, WorkerReady};
use crate::sets::SetTable;
use crate::state::StateVersion;
use crate::stats::Counters;
use crate::supervisor::{contain, InjectPanic};

/// Answered (frame, set) pairs remembered to tell duplicates from unknown results.
const ANSWERED_MEMORY: usize = 4096;
/// Longest worker name accepted.
const MAX_NAME_LEN: usize = 256;
/// How long a rejected peer gets to read its `Rejected` before the socket is dropped.
const CLOSE_GRACE: Duration = Duration::from_secs(2);

/// Test hook: end this connection abruptly, as a crash would (no `Rejected`).
#[derive(Message)]
#[rtype(result = "()")]
pub struct Kill;

/// To the listener: this connection ended; `failed` when it ended on an error.
#[derive(Message)]
#[rtype(result = "()")]
pub struct ConnectionEnded {
    pub conn: ConnId,
    pub failed: bool,
}

/// What every connection shares.
pub struct ConnectionConfig {
    pub secret: Option<Vec<u8>>,
    pub sets: Arc<SetTable>,
    pub assets: Arc<AssetStore>,
    /// k: jobs a worker may hold at once.
    pub pipeline: u32,
    pub heartbeat: Duration,
    pub peer_timeout: Duration,
}

/// Where a connection's messages go.
#[derive(Clone)]
pub struct ConnectionLinks {
    pub ready_to: Recipient<WorkerReady>,
    pub left_to: Recipient<WorkerLeft>,
    /// The scheduler measures each worker's job time from its answers.
    pub answered_to: Recipient<JobAnswered>,
    pub results_to: Recipient<ResultArrived>,
    pub ended_to: Recipient<ConnectionEnded>,
}

#[derive(Debug)]
enum Phase {
    /// Waiting for `Hello`.
    Hello,
    /// `Challenge` sent with this nonce; waiting for `Auth`.
    Auth { nonce: [u8; 32] },
    /// Welcomed: assets and jobs; results are tagged with this connection's key.
    Work { key: ResultKey },
    /// `Rejected` sent; waiting for it to drain.
    Closing,
}

type Writer = FramedWrite<MasterMsg, CountedWrite<OwnedWriteHalf>, MasterCodec>;

/// One worker's link.
pub struct Connection {
    id: ConnId,
    peer: SocketAddr,
    /// The worker's name from `Hello` (empty before).
    name: String,
    /// Render threads the worker said it has (`Hello`).
    cores: u32,
    phase: Phase,
    config: Arc<ConnectionConfig>,
    links: ConnectionLinks,
    writer: Writer,
    /// State versions already sent on this connection.
    sent_versions: HashSet<StateVersion>,
    /// Jobs sent and not yet answered, with the version they name.
    held: HashMap<(FrameNo, SetNo), StateVersion>,
    answered: VecDeque<(FrameNo, SetNo)>,
    answered_set: HashSet<(FrameNo, SetNo)>,
    /// Credits passed to the scheduler and not yet filled.
    requested: u32,
    /// Why the worker paused; `None` while it takes jobs.
    paused: Option<PauseReason>,
    last_recv: Instant,
    last_sent: Instant,
    counters: Arc<Counters>,
    welcomed: bool,
    failed: bool,
}

impl Connection {
    pub fn new(
        id: ConnId,
        peer: SocketAddr,
        writer: Writer,
        config: Arc<ConnectionConfig>,
        links: ConnectionLinks,
        counters: Arc<Counters>,
    ) -> Self {
        let now = Instant::now();
        Self {
            id,
            peer,
            name: String::new(),
            cores: 0,
            phase: Phase::Hello,
            config,
            links,
            writer,
            sent_versions: HashSet::new(),
            held: HashMap::new(),
            answered: VecDeque::new(),
            answered_set: HashSet::new(),
            requested: 0,
            paused: None,
            last_recv: now,
            last_sent: now,
            counters,
            welcomed: false,
            failed: false,
        }
    }
}

impl Actor for Connection {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        tracing::debug!(conn = self.id, peer = %self.peer, "connection opened");
        let tick = (self.config.heartbeat / 2)
            .min(self.config.peer_timeout / 4)
            .max(Duration::from_millis(10));
        ctx.run_interval(tick, |act, ctx| act.keep_alive(ctx));
    }

    fn stopped(&mut self, _: &mut Context<Self>) {
        self.links.left_to.do_send(WorkerLeft { conn: self.id });
        if self.welcomed {
            let c = &self.counters;
            let count = if self.paused.is_some() { &c.paused_workers } else { &c.workers };
            count.fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
            c.workers_table.left(self.id);
        }
        self.links.ended_to.do_send(ConnectionEnded { conn: self.id, failed: self.failed });
        tracing::info!(conn = self.id, worker = %self.name, peer = %self.peer,
            jobs_lost = self.held.len(), "connection closed");
    }
}

impl StreamHandler<Result<WorkerMsg, ProtocolError>> for Connection {
    fn handle(&mut self, item: Result<WorkerMsg, ProtocolError>, ctx: &mut Context<Self>) {
        if matches!(self.phase, Phase::Closing) {
            return;
        }
        self.last_recv = Instant::now();
        if self.welcomed {
            self.counters.workers_table.heard(self.id, 0);
        }
        match item {
            Ok(msg) => {
                if let Err(panic) = contain(|| self.on_message(msg, ctx)) {
                    self.on_panic(&panic, ctx);
                }
            }
            Err(ProtocolError::Io(e)) => {
                tracing::info!(conn = self.id, worker = %self.name, peer = %self.peer, cause = %e, "read failed");
                self.counters.note_rejection("io");
                self.failed = true;
                ctx.stop();
            }
            Err(e) => self.reject(format!("bad frame: {e}"), ctx),
        }
    }

    fn finished(&mut self, ctx: &mut Context<Self>) {
        // While closing, the writer's end stops the actor once `Rejected` is out.
        if !matches!(self.phase, Phase::Closing) {
            ctx.stop();
        }
    }
}

impl WriteHandler<ProtocolError> for Connection {
    fn error(&mut self, err: ProtocolError, _: &mut Context<Self>) -> Running {
        tracing::warn!(conn = self.id, worker = %self.name, peer = %self.peer, cause = %err, "write failed");
        self.failed = true;
        Running::Stop
    }
}

impl Handler<JobsAssigned> for Connection {
    type Result = ();
    fn handle(&mut self, msg: JobsAssigned, _: &mut Context<Self>) {
        if !matches!(self.phase, Phase::Work { .. }) || self.paused.is_some() {
            // Closing, or paused before these credits were served: these jobs are lost
            // like any other, never redone.
            tracing::debug!(conn = self.id, worker = %self.name, jobs_lost = msg.0.len(), "jobs not sent");
            return;
        }
        for job in msg.0 {
            self.requested = self.requested.saturating_sub(1);
            let version = job.state.version;
            if self.sent_versions.insert(version) {
                self.send(MasterMsg::State(Box::new((*job.state).clone())));
            }
            self.held.insert((job.frame, job.set), version);
            self.send(MasterMsg::Job { frame: job.frame, set: job.set, state_version: version });
        }
    }
}

impl Handler<Kill> for Connection {
    type Result = ();
    fn handle(&mut self, _: Kill, ctx: &mut Context<Self>) {
        tracing::warn!(conn = self.id, worker = %self.name, peer = %self.peer, "connection killed (fault injection)");
        self.failed = true;
        ctx.stop();
    }
}

impl Handler<InjectPanic> for Connection {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        if let Err(panic) = contain(|| panic!("injected panic in connection {}", self.id)) {
            self.on_panic(&panic, ctx);
        }
    }
}

impl Connection {
    fn on_message(&mut self, msg: WorkerMsg, ctx: &mut Context<Self>) {
        match (&self.phase, msg) {
            (Phase::Hello, WorkerMsg::Hello { protocol, name, cores }) => {
                self.name = sanitize(&name);
                self.cores = cores;
                if protocol != PROTOCOL_VERSION {
                    return self.reject(
                        format!("protocol version mismatch: worker speaks {protocol}, master speaks {PROTOCOL_VERSION}"),
                        ctx,
                    );
                }
                if name.is_empty() || name.len() > MAX_NAME_LEN {
                    return self
                        .reject(format!("worker name must be 1 to {MAX_NAME_LEN} bytes"), ctx);
                }
                tracing::debug!(conn = self.id, worker = %self.name, peer = %self.peer, cores, "hello");
                let nonce = auth::nonce();
                self.phase = Phase::Auth { nonce };
                self.send(MasterMsg::Challenge {
                    nonce,
                    auth_required: self.config.secret.is_some(),
                });
            }
            (Phase::Auth { nonce }, WorkerMsg::Auth { mac }) => {
                if let Some(secret) = &self.config.secret {
                    let ok = mac.is_some_and(|m| auth::verify(secret, nonce, &m));
                    if !ok {
                        let why = if mac.is_none() {
                            "authentication failed: the master requires a shared secret (--secret-file) and the worker sent none"
                        } else {
                            "authentication failed: wrong shared secret"
                        };
                        return self.reject(why.to_owned(), ctx);
                    }
                }
                let key = ResultKey::derive(self.config.secret.as_deref(), nonce);
                self.phase = Phase::Work { key };
                self.welcomed = true;
                Counters::add(&self.counters.workers, 1);
                self.counters.workers_table.joined(self.id, &self.name, self.cores);
                self.counters.workers_table.located(self.id, &self.peer.ip().to_string());
                tracing::info!(conn = self.id, worker = %self.name, peer = %self.peer, "worker joined");
                self.send(MasterMsg::Welcome {
                    worker_id: self.id,
                    sets: self.config.sets.config(),
                    assets: self.config.assets.manifest().to_vec(),
                });
            }
            (Phase::Work { .. }, WorkerMsg::AssetRequest { hash }) => self.serve_asset(hash, ctx),
            (Phase::Work { .. }, WorkerMsg::Paused { reason }) => self.pause(reason),
            (Phase::Work { .. }, msg @ (WorkerMsg::Ready { .. } | WorkerMsg::Result(_)))
                if self.paused.is_some() =>
            {
                let what = kind(&msg);
                self.reject(format!("unexpected {what} while the worker is paused"), ctx)
            }
            (Phase::Work { .. }, WorkerMsg::Resumed) => self.resume(ctx),
            (Phase::Work { .. }, WorkerMsg::Ready { credits }) => self.grant(credits, ctx),
            (Phase::Work { .. }, WorkerMsg::Superseded { frame, set }) => {
                self.superseded(frame, set)
            }
            (Phase::Work { key }, WorkerMsg::Result(result)) => {
                // Checked before anything else reads the result: a corrupted frame or
                // set number must not be mistaken for a stale or foreign result.
                if !key.verify(&result) {
                    return self.reject(
                        format!(
                            "result for frame {} set {} failed its integrity check (payload corrupted or forged)",
                            result.frame, result.set
                        ),
                        ctx,
                    );
                }
                self.on_result(result, ctx)
            }
            (_, WorkerMsg::Heartbeat) => {}
            (phase, msg) => {
                let what = kind(&msg);
                self.reject(
                    format!("unexpected {what} during the {} phase", phase_name(phase)),
                    ctx,
                )
            }
        }
    }

    /// The worker's desk's owner is active: the jobs it holds are lost (never redone), its
    /// unserved credits void, and it is counted as paused, not live.
    fn pause(&mut self, reason: PauseReason) {
        if self.paused.is_none() {
            tracing::info!(conn = self.id, worker = %self.name, peer = %self.peer, %reason,
                jobs_lost = self.held.len(), "worker paused");
            self.held.clear();
            self.requested = 0;
            self.links.left_to.do_send(WorkerLeft { conn: self.id });
            Counters::add(&self.counters.paused_workers, 1);
            self.counters.workers.fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
        }
        self.counters.workers_table.paused(self.id, reason.clone());
        self.paused = Some(reason);
    }

    /// The worker takes jobs again; its `Ready` follows.
    fn resume(&mut self, ctx: &mut Context<Self>) {
        if self.paused.take().is_none() {
            return self.reject("unexpected Resumed while the worker is not paused".into(), ctx);
        }
        tracing::info!(conn = self.id, worker = %self.name, peer = %self.peer, "worker resumed");
        self.counters.paused_workers.fetch_sub(1, std::sync::atomic::Ordering::Relaxed);
        Counters::add(&self.counters.workers, 1);
        self.counters.workers_table.resumed(self.id);
    }

    /// The worker dropped a held job unrendered (a newer state's job came first): it is
    /// lost, and its slot is free for the `Ready` that follows. A job it does not hold
    /// (lost already, e.g. by a pause) changes nothing.
    fn superseded(&mut self, frame: FrameNo, set: SetNo) {
        if self.held.remove(&(frame, set)).is_some() {
            Counters::add(&self.counters.jobs_superseded, 1);
            tracing::debug!(conn = self.id, frame, set, "held job superseded");
        }
    }

    /// Passes new credits on to the scheduler, never letting the worker hold more than k.
    fn grant(&mut self, credits: u32, ctx: &mut Context<Self>) {
        let room = self.config.pipeline.saturating_sub(self.held.len() as u32 + self.requested);
        let grant = credits.min(room);
        if grant < credits {
            tracing::debug!(conn = self.id, worker = %self.name, credits, grant, "credits above k clamped");
        }
        if grant > 0 {
            self.requested += grant;
            self.links.ready_to.do_send(WorkerReady {
                conn: self.id,
                credits: grant,
                jobs_to: ctx.address().recipient(),
            });
        }
    }

    /// Validates a result against the jobs this connection holds and forwards it.
    fn on_result(&mut self, r: JobResult, ctx: &mut Context<Self>) {
        let sets = self.config.sets.sets();
        if r.set >= sets {
            return self
                .reject(format!("result for set {}, but there are only {sets} sets", r.set), ctx);
        }
        let key = (r.frame, r.set);
        match self.held.remove(&key) {
            Some(version) => {
                if version != r.state_version {
                    return self.reject(
                        format!(
                            "result for frame {} set {} names state version {}, the job named {version}",
                            r.frame, r.set, r.state_version
                        ),
                        ctx,
                    );
                }
                let expected = self.config.sets.set_len(r.set);
                if r.radiance.len() != expected {
                    return self.reject(
                        format!(
                            "result for frame {} set {} holds {} pixels, the set has {expected}",
                            r.frame,
                            r.set,
                            r.radiance.len()
                        ),
                        ctx,
                    );
                }
                self.remember_answered(key);
                self.counters.workers_table.heard(self.id, 1);
                self.counters.workers_table.timed(self.id, r.render_us);
                let (frame, set) = key;
                self.links.answered_to.do_send(JobAnswered { conn: self.id, frame, set });
                self.links.results_to.do_send(ResultArrived { conn: self.id, result: r });
            }
            None if self.answered_set.contains(&key) => {
                // A second answer to one job: dropped and counted by the assembler.
                self.links.results_to.do_send(ResultArrived { conn: self.id, result: r });
            }
            None => {
                let (frame, set) = key;
                self.links.results_to.do_send(ResultArrived { conn: self.id, result: r });
                self.reject(
                    format!(
                        "result for frame {frame} set {set}, which was not given to this worker"
                    ),
                    ctx,
                );
            }
        }
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

    /// Sends every chunk of a manifest asset.
    fn serve_asset(&mut self, hash: AssetHash, ctx: &mut Context<Self>) {
        let Some(entry) = self.config.assets.entry(&hash).cloned() else {
            return self.reject(format!("asset {} is not in the manifest", hex(&hash)), ctx);
        };
        let mut offset = 0u64;
        loop {
            let chunk = match self.config.assets.read_chunk(&hash, offset, ASSET_CHUNK_LEN) {
                Some(Ok(c)) => c,
                Some(Err(e)) => {
                    tracing::error!(conn = self.id, worker = %self.name, peer = %self.peer, cause = %e, "asset unreadable");
                    return self
                        .reject(format!("the master cannot read asset {}: {e}", entry.path), ctx);
                }
                None => {
                    return self.reject(format!("asset {} is not in the manifest", hex(&hash)), ctx)
                }
            };
            let n = chunk.len() as u64;
            self.send(MasterMsg::AssetChunk { hash, offset, len: entry.len, data: chunk });
            offset += n;
            if offset >= entry.len || n == 0 {
                break;
            }
        }
    }

    /// Heartbeats when quiet; ends a silent peer.
    fn keep_alive(&mut self, ctx: &mut Context<Self>) {
        if matches!(self.phase, Phase::Closing) {
            return;
        }
        let silent = self.last_recv.elapsed();
        if silent >= self.config.peer_timeout {
            let secs = silent.as_secs_f32();
            return self.reject(format!("no message from the worker for {secs:.1} s"), ctx);
        }
        if matches!(self.phase, Phase::Work { .. })
            && self.last_sent.elapsed() >= self.config.heartbeat
        {
            self.send(MasterMsg::Heartbeat);
        }
    }

    fn send(&mut self, msg: MasterMsg) {
        self.last_sent = Instant::now();
        self.writer.write(msg);
    }

    /// Sends `Rejected` naming the problem, then closes once it is written.
    fn reject(&mut self, reason: String, ctx: &mut Context<Self>) {
        tracing::warn!(conn = self.id, worker = %self.name, peer = %self.peer, %reason, "connection rejected");
        Counters::add(&self.counters.connections_rejected, 1);
        self.counters.note_rejection(crate::stats::rejection_kind(&reason));
        self.failed = true;
        self.send(MasterMsg::Rejected { reason });
        self.phase = Phase::Closing;
        self.writer.close();
        ctx.run_later(CLOSE_GRACE, |_, ctx| ctx.stop());
    }

    /// A panic contained in a handler: this connection ends (its supervisor's restart
    /// is the worker reconnecting); the master goes on.
    fn on_panic(&mut self, panic: &str, ctx: &mut Context<Self>) {
        Counters::add(&self.counters.panics_contained, 1);
        tracing::error!(conn = self.id, worker = %self.name, peer = %self.peer, cause = panic, "panic contained");
        self.reject("internal error in the master; reconnect".to_owned(), ctx);
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
