//! The connection actor: one per worker socket, a thin shell around its [`ProtocolState`].
//!
//! The [`ProtocolState`] holds the protocol (phases, authentication, credits, state versions,
//! result checks, the answered memory); this actor feeds it what arrives (worker
//! messages, the scheduler's jobs, a keep-alive tick) and carries out the actions it
//! returns: writing to the socket (switching both codec halves to the encrypted channel's
//! records when the channel's handshake is done), asking the scheduler for jobs,
//! forwarding the answers to its jobs to the frame assembler (duplicates and unknown
//! results stop here, counted),
//! keeping the worker table and the counters, and closing after a
//! `Rejected` that names the problem. Any protocol violation ends this connection only;
//! every log line names the peer. The jobs it held are never handed out again.
//!
//! Every body runs under the supervision guard; a panic ends the connection with
//! `Rejected` (internal error), and its supervisor, the listener, serves the worker's
//! reconnection with a fresh actor unless the worker is backed off.

pub mod protocol_state;

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use actix::io::{FramedWrite, WriteHandler};
use actix::prelude::*;
use tokio::net::tcp::OwnedWriteHalf;

use crate::messages::{
    ConnectionAuthenticated, ConnectionEnded, HandshakeExpired, JobAnswered, JobsAssigned, Kill,
    ResultArrived, WorkerLeft, WorkerReady,
};
use crate::scene::asset_store::AssetStore;
use crate::shared::counters::Counters;
use crate::shared::holdings::HeldJobs;
use crate::shared::sets::SetTables;
use crate::shared::workers::WorkerTable;
use crate::supervision::{
    ActorKind, Guard, GuardedTimers, InjectPanic, PeerBackoff, Supervised, Supervision,
};
use crate::wire::channel_codec::{KeySlot, MasterChannelCodec};
use crate::wire::codec::ProtocolError;
use crate::wire::counted_io::CountedWrite;
use crate::wire::protocol::{ConnId, MasterMsg, WorkerMsg};
use crate::wire::rejection::{Rejection, RejectionKind};
use protocol_state::{Action, ProtocolState};

/// How long a rejected peer gets to read its `Rejected` before the socket is dropped.
const CLOSE_GRACE: Duration = Duration::from_secs(2);

/// What every connection shares.
pub struct ConnectionConfig {
    pub secret: Option<Vec<u8>>,
    /// The pixel sets of every resolution the run has used.
    pub sets: Arc<SetTables>,
    pub assets: Arc<AssetStore>,
    /// k: jobs a worker may hold at once.
    pub pipeline: u32,
    pub heartbeat: Duration,
    pub peer_timeout: Duration,
    /// The connected workers, for the status panel; each connection writes its row.
    pub workers: Arc<WorkerTable>,
    /// Who holds which job: the master's one record, shared with the scheduler.
    pub held: Arc<HeldJobs>,
    /// Lines naming a peer rejected before it authenticated, limited per period (the
    /// listener summarises them all).
    pub refusal_lines: crate::shared::line_budget::LineBudget,
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
    /// The listener counts connections that have not authenticated yet.
    pub authenticated_to: Recipient<ConnectionAuthenticated>,
}

type Writer = FramedWrite<MasterMsg, CountedWrite<OwnedWriteHalf>, MasterChannelCodec>;

/// What the actor writes to: the socket's framed sending half, and the slot from which
/// both codec halves (this one and the reading one) take the channel's keys.
pub struct Outbox {
    pub writer: Writer,
    pub keys: KeySlot,
}

/// One worker's link.
pub struct Connection {
    id: ConnId,
    peer: SocketAddr,
    protocol: ProtocolState,
    config: Arc<ConnectionConfig>,
    links: ConnectionLinks,
    writer: Writer,
    /// Where the channel's keys go once its handshake is done (none without a secret).
    keys: KeySlot,
    counters: Arc<Counters>,
    /// Ended on an error (the listener's per-peer policy counts these).
    failed: bool,
    /// The listener's record of failed ends per worker, checked at `Hello`.
    peers: Arc<Mutex<PeerBackoff>>,
    /// The worker's name from its `Hello`, the record's key; `None` before it, and
    /// when the record refused the worker (a refusal is not a new failure).
    worker: Option<String>,
    /// The kind of the rejection this connection was closed with.
    rejected: Option<RejectionKind>,
    supervision: Supervision,
}

impl Connection {
    pub fn new(
        id: ConnId,
        peer: SocketAddr,
        outbox: Outbox,
        config: Arc<ConnectionConfig>,
        links: ConnectionLinks,
        counters: Arc<Counters>,
        peers: Arc<Mutex<PeerBackoff>>,
    ) -> Self {
        let protocol = ProtocolState::new(id, config.clone(), Instant::now());
        let supervision = Supervision::ending(ActorKind::Connection, counters.clone());
        Self {
            id,
            peer,
            protocol,
            config,
            links,
            writer: outbox.writer,
            keys: outbox.keys,
            counters,
            failed: false,
            rejected: None,
            peers,
            worker: None,
            supervision,
        }
    }
}

impl Actor for Connection {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }

    fn stopped(&mut self, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, _| c.ended());
    }
}

impl Connection {
    /// Tells the scheduler, the worker table and the listener that this connection is
    /// gone; the jobs it held are lost and counted.
    fn ended(&mut self) {
        let lost = self.protocol.release_held();
        let frames = lost.iter().map(|h| h.frame).collect();
        self.links.left_to.do_send(WorkerLeft { conn: self.id, lost: frames });
        if self.protocol.welcomed() {
            self.config.workers.left(self.id);
        }
        Counters::add(&self.counters.jobs_lost, lost.len() as u64);
        let worker = self.worker.take();
        let (conn, failed, rejected) = (self.id, self.failed, self.rejected);
        self.links.ended_to.do_send(ConnectionEnded { conn, failed, worker, rejected });
        tracing::info!(conn = self.id, worker = %self.protocol.name(), peer = %self.peer,
            jobs_lost = lost.len(), "connection closed");
    }
}

impl Supervised for Connection {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    fn on_start(&mut self, ctx: &mut Context<Self>) {
        tracing::debug!(conn = self.id, peer = %self.peer, "connection opened");
        ctx.run_interval_guarded(self.protocol.tick_interval(), |act, ctx| {
            let actions = act.protocol.tick(Instant::now());
            act.apply(actions, ctx);
        });
    }

    /// A connection's restart is its end: `Rejected` (internal error), then close; the
    /// jobs it held are lost and counted, and the worker's reconnection is served by a
    /// fresh actor.
    fn restart(&mut self, ctx: &mut Context<Self>) {
        let actions = self.protocol.reject(Rejection::Internal);
        self.apply(actions, ctx);
    }
}

impl StreamHandler<Result<WorkerMsg, ProtocolError>> for Connection {
    fn handle(&mut self, item: Result<WorkerMsg, ProtocolError>, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, ctx| c.received(item, ctx));
    }

    fn finished(&mut self, ctx: &mut Context<Self>) {
        // While closing, the writer's end stops the actor once `Rejected` is out.
        self.guarded(ctx, |c, ctx| {
            if !c.protocol.closing() {
                ctx.stop();
            }
        });
    }
}

impl Connection {
    /// One frame from the worker (or a read error).
    fn received(&mut self, item: Result<WorkerMsg, ProtocolError>, ctx: &mut Context<Self>) {
        if self.protocol.closing() {
            return;
        }
        if self.protocol.welcomed() {
            self.config.workers.heard(self.id, 0);
        }
        match item {
            Ok(WorkerMsg::Hello { ref name, .. }) if self.backed_off(name, ctx) => {}
            Ok(msg) => {
                let actions = self.protocol.on_message(msg, Instant::now());
                self.apply(actions, ctx);
            }
            Err(ProtocolError::Io(e)) => {
                tracing::info!(conn = self.id, worker = %self.protocol.name(), peer = %self.peer, cause = %e, "read failed");
                self.counters.note_rejection(RejectionKind::Io);
                self.failed = true;
                ctx.stop();
            }
            Err(e) => {
                let actions = self.protocol.on_bad_frame(&e);
                self.apply(actions, ctx);
            }
        }
    }

    /// Refuses a worker the listener's record backs off (true), else notes its name as
    /// this connection's key in the record.
    fn backed_off(&mut self, name: &str, ctx: &mut Context<Self>) -> bool {
        let admitted =
            self.peers.lock().unwrap_or_else(|p| p.into_inner()).admit(name, Instant::now());
        match admitted {
            Ok(()) => {
                self.worker = Some(name.to_owned());
                false
            }
            Err(why) => {
                let actions = self.protocol.reject(why);
                self.apply(actions, ctx);
                true
            }
        }
    }
}

impl WriteHandler<ProtocolError> for Connection {
    fn error(&mut self, err: ProtocolError, ctx: &mut Context<Self>) -> Running {
        self.guarded(ctx, |c, _| {
            if c.protocol.welcomed() {
                tracing::warn!(conn = c.id, worker = %c.protocol.name(), peer = %c.peer, cause = %err, "write failed");
            }
            c.failed = true;
        });
        Running::Stop
    }
}

impl Handler<JobsAssigned> for Connection {
    type Result = ();
    fn handle(&mut self, msg: JobsAssigned, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, ctx| {
            let count = msg.0.len();
            let actions = c.protocol.on_jobs(msg.0, Instant::now());
            if actions.is_empty() && count > 0 {
                tracing::debug!(conn = c.id, worker = %c.protocol.name(), jobs_lost = count, "jobs not sent");
            }
            c.apply(actions, ctx);
        });
    }
}

impl Handler<Kill> for Connection {
    type Result = ();
    fn handle(&mut self, _: Kill, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, ctx| {
            tracing::warn!(conn = c.id, worker = %c.protocol.name(), peer = %c.peer, "connection killed (fault injection)");
            c.failed = true;
            ctx.stop();
        });
    }
}

impl Handler<HandshakeExpired> for Connection {
    type Result = ();
    fn handle(&mut self, _: HandshakeExpired, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, ctx| {
            tracing::debug!(conn = c.id, peer = %c.peer, "handshake deadline passed");
            ctx.stop();
        });
    }
}

impl Handler<InjectPanic> for Connection {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |c, _| panic!("injected panic in connection {}", c.id));
    }
}

impl Connection {
    /// Carries out the protocol state's actions, in order.
    fn apply(&mut self, actions: Vec<Action>, ctx: &mut Context<Self>) {
        for action in actions {
            match action {
                Action::Send(msg) => self.writer.write(msg),
                // After the handshake's answer, written plain above; before anything else.
                Action::Encrypt(keys) => {
                    self.keys.install(keys, Some(self.counters.cipher_ns.clone()))
                }
                Action::Joined => {
                    let (name, cores) = (self.protocol.name(), self.protocol.cores());
                    self.config.workers.joined(self.id, name, cores);
                    self.config.workers.located(self.id, &self.peer.ip().to_string());
                    tracing::info!(conn = self.id, worker = %name, peer = %self.peer, "worker joined");
                    self.links.authenticated_to.do_send(ConnectionAuthenticated(self.id));
                }
                Action::RequestJobs(credits) => self.links.ready_to.do_send(WorkerReady {
                    conn: self.id,
                    credits,
                    jobs_to: ctx.address().recipient(),
                }),
                Action::Paused { reason, first, lost } => {
                    if first {
                        tracing::info!(conn = self.id, worker = %self.protocol.name(), peer = %self.peer,
                            %reason, "worker paused");
                        self.links.left_to.do_send(WorkerLeft { conn: self.id, lost });
                    }
                    self.config.workers.paused(self.id, reason);
                }
                Action::Resumed => {
                    tracing::info!(conn = self.id, worker = %self.protocol.name(), peer = %self.peer, "worker resumed");
                    self.config.workers.resumed(self.id);
                }
                Action::Answered { result, handed_at } => {
                    self.config.workers.heard(self.id, 1);
                    self.config.workers.timed(self.id, result.render_us);
                    let (frame, render_us) = (result.frame, result.render_us);
                    self.links.answered_to.do_send(JobAnswered {
                        conn: self.id,
                        frame,
                        handed_at,
                        render_us,
                    });
                    self.links.results_to.do_send(ResultArrived { conn: self.id, result });
                }
                Action::Duplicate { frame, set } => {
                    Counters::add(&self.counters.dropped_duplicate, 1);
                    tracing::debug!(conn = self.id, frame, set, "duplicate result dropped");
                }
                Action::Unknown { frame, set } => {
                    Counters::add(&self.counters.dropped_unknown, 1);
                    tracing::debug!(conn = self.id, frame, set, "unknown result dropped");
                }
                Action::Superseded { frame, set } => {
                    Counters::add(&self.counters.jobs_superseded, 1);
                    tracing::debug!(conn = self.id, frame, set, "held job superseded");
                }
                Action::Reject(why) => self.close_rejected(why, ctx),
            }
        }
    }

    /// Sends `Rejected` naming the problem, then closes once it is written.
    fn close_rejected(&mut self, why: Rejection, ctx: &mut Context<Self>) {
        // Before it authenticated, the listener's summary counts it (a flood writes no
        // line per peer); after, the line names the worker.
        if self.protocol.welcomed() {
            tracing::warn!(conn = self.id, worker = %self.protocol.name(), peer = %self.peer,
                reason = %why, kind = why.kind().as_str(), "connection rejected");
        } else if self.config.refusal_lines.allow(Instant::now()) {
            tracing::info!(conn = self.id, peer = %self.peer, reason = %why,
                kind = why.kind().as_str(), "connection rejected");
        } else {
            tracing::debug!(conn = self.id, peer = %self.peer, reason = %why, "connection rejected");
        }
        self.rejected = Some(why.kind());
        Counters::add(&self.counters.connections_rejected, 1);
        self.counters.note_rejection(why.kind());
        self.failed = true;
        self.writer.write(MasterMsg::Rejected { reason: why.to_string() });
        self.writer.close();
        ctx.run_later_guarded(CLOSE_GRACE, |_, ctx| ctx.stop());
    }
}
