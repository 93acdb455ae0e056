//! The listener actor: accepts worker connections (up to a cap) and starts one
//! connection actor per socket; refused sockets get a `Rejected` saying why.
//!
//! It is the connections' supervisor (`supervision`'s tree): it knows every live
//! connection (for the fault-injection hooks), and a connection that ends — cleanly, on
//! a protocol error, a contained panic or a kill — is simply gone: its jobs are lost
//! (counted, never redone) and the worker is served again by a fresh connection actor
//! when it reconnects (workers reconnect with back-off and jitter on their side). A
//! worker whose connections keep ending on errors is refused for a while
//! ([`PeerBackoff`]): the listener records each failed end, the connection checks the
//! worker's name against the record when its `Hello` arrives.
//!
//! Against floods ([`admission`]): connections that have not authenticated are capped per
//! address and overall and ended at a deadline, and refusals are logged as periodic
//! summaries (a count per kind and address), not one line per peer.

pub mod admission;

use std::collections::HashMap;
use std::net::{IpAddr, SocketAddr};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use actix::prelude::*;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio_util::codec::FramedRead;

use crate::connection::{Connection, ConnectionConfig, ConnectionLinks, Outbox};
use crate::messages::{
    ConnectionAuthenticated, ConnectionEnded, HandshakeExpired, Kill, KillConnection,
    ListConnections, PanicConnection,
};
use crate::shared::counters::Counters;
use crate::supervision::{
    ActorKind, Guard, GuardedTimers, InjectPanic, PeerBackoff, PeerPolicy, RestartPolicy,
    Supervised, Supervision,
};
use crate::wire::channel_codec::{KeySlot, MasterChannelCodec};
use crate::wire::codec::to_frame;
use crate::wire::counted_io::{CountedRead, CountedWrite};
use crate::wire::protocol::ConnId;
use crate::wire::protocol::MasterMsg;
use crate::wire::rejection::{Rejection, RejectionKind};
use admission::{Admission, RefusalLog, Refused, HANDSHAKE_DEADLINE, SUMMARY_EVERY};

/// Internal: one accepted socket (or accept error).
#[derive(Message)]
#[rtype(result = "()")]
struct Accepted(std::io::Result<(TcpStream, SocketAddr)>);

/// The accepting socket and the live connections.
pub struct Listener {
    /// Taken when the actor starts.
    socket: Option<TcpListener>,
    max_connections: usize,
    next_id: ConnId,
    conns: HashMap<ConnId, Addr<Connection>>,
    config: Arc<ConnectionConfig>,
    links: ConnectionLinks,
    counters: Arc<Counters>,
    /// Failed ends per worker, shared with the connections that check it.
    peers: Arc<Mutex<PeerBackoff>>,
    /// Pending connections by address, and the authenticated count.
    admission: Admission,
    /// Refusals since the last summary.
    refusals: RefusalLog,
    supervision: Supervision,
}

impl Listener {
    /// `links.ended_to` must lead back to this listener.
    pub fn new(
        socket: TcpListener,
        max_connections: usize,
        config: Arc<ConnectionConfig>,
        links: ConnectionLinks,
        counters: Arc<Counters>,
        policy: (RestartPolicy, PeerPolicy),
    ) -> Self {
        Self {
            socket: Some(socket),
            max_connections,
            next_id: 1,
            conns: HashMap::new(),
            config,
            links,
            supervision: Supervision::restarting(ActorKind::Listener, policy.0, counters.clone()),
            counters,
            peers: Arc::new(Mutex::new(PeerBackoff::new(policy.1))),
            admission: Admission::default(),
            refusals: RefusalLog::default(),
        }
    }
}

impl Actor for Listener {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }
}

impl Supervised for Listener {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    /// Starts accepting (once: the socket moves into the accept stream).
    fn on_start(&mut self, ctx: &mut Context<Self>) {
        let Some(socket) = self.socket.take() else { return };
        ctx.run_interval_guarded(SUMMARY_EVERY, |l, _| l.summarise());
        let accepts = futures::stream::unfold(socket, |s| async move {
            let r = s.accept().await;
            Some((Accepted(r), s))
        });
        ctx.add_message_stream(accepts);
    }

    /// Nothing to replace: its state is the live connections and the peers' record,
    /// which a panic in one handler does not make wrong.
    fn restart(&mut self, _: &mut Context<Self>) {}
}

impl Handler<Accepted> for Listener {
    type Result = ();
    fn handle(&mut self, msg: Accepted, ctx: &mut Context<Self>) {
        self.guarded(ctx, |l, ctx| l.accepted(msg, ctx));
    }
}

impl Listener {
    /// Starts a connection actor for an accepted socket, or refuses it at a cap.
    fn accepted(&mut self, msg: Accepted, ctx: &mut Context<Self>) {
        let (stream, peer) = match msg.0 {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(cause = %e, "accept failed");
                return;
            }
        };
        if let Err(why) = self.admission.admit(peer.ip(), self.max_connections) {
            self.refusals.note(why, peer.ip());
            Counters::add(&self.counters.connections_rejected, 1);
            let why = Rejection::Full { max: self.max_connections };
            self.counters.note_rejection(why.kind());
            actix::spawn(refuse(stream, why.to_string()));
            return;
        }
        let _ = stream.set_nodelay(true);
        let id = self.next_id;
        self.next_id += 1;
        let (read, write) = stream.into_split();
        let (config, links, counters) =
            (self.config.clone(), self.links.clone(), self.counters.clone());
        let (peers, faults) = (self.peers.clone(), self.supervision.faults());
        let addr = Connection::create(move |ctx| {
            let read = CountedRead::new(read, counters.bytes_in.clone());
            // Plain until the channel's handshake installs keys in the slot (with a secret).
            let keys = KeySlot::new();
            ctx.add_stream(FramedRead::new(read, MasterChannelCodec::new(keys.clone())));
            let write = CountedWrite::new(write, counters.bytes_out.clone());
            let codec = MasterChannelCodec::new(keys.clone());
            let writer = actix::io::FramedWrite::new(write, codec, ctx);
            let outbox = Outbox { writer, keys };
            Connection::new(id, peer, outbox, config, links, counters, peers).with_faults(faults)
        });
        self.conns.insert(id, addr);
        self.admission.opened(id, peer.ip());
        ctx.run_later_guarded(HANDSHAKE_DEADLINE, move |l, _| l.deadline(id));
    }

    /// Ends connection `id` if it has not authenticated by now.
    fn deadline(&mut self, id: ConnId) {
        let Some(ip) = self.admission.pending(id) else { return };
        if let Some(conn) = self.conns.get(&id) {
            self.refusals.note(Refused::Deadline, ip);
            Counters::add(&self.counters.connections_rejected, 1);
            self.counters.note_rejection(RejectionKind::Timeout);
            conn.do_send(HandshakeExpired);
        }
    }

    /// One warning line per kind and address refused since the last summary.
    fn summarise(&mut self) {
        for (why, addr, count) in self.refusals.take() {
            tracing::warn!(%addr, kind = why.as_str(), count, every_s = SUMMARY_EVERY.as_secs(),
                "connections refused (summary)");
        }
    }

    fn ended_pending(&mut self, ip: IpAddr, rejected: Option<RejectionKind>) {
        if let Some(kind) = rejected {
            self.refusals.note(Refused::Rejected(kind.as_str()), ip);
        }
    }
}

impl Handler<ConnectionAuthenticated> for Listener {
    type Result = ();
    fn handle(&mut self, msg: ConnectionAuthenticated, ctx: &mut Context<Self>) {
        self.guarded(ctx, |l, _| l.admission.authenticated(msg.0));
    }
}

impl Handler<ConnectionEnded> for Listener {
    type Result = ();
    fn handle(&mut self, msg: ConnectionEnded, ctx: &mut Context<Self>) {
        self.guarded(ctx, |l, _| {
            l.conns.remove(&msg.conn);
            if let Some(ip) = l.admission.closed(msg.conn) {
                l.ended_pending(ip, msg.rejected);
            }
            if !msg.failed {
                return;
            }
            tracing::debug!(conn = msg.conn, "connection ended on an error");
            if let Some(worker) = &msg.worker {
                l.peers.lock().unwrap_or_else(|p| p.into_inner()).failed(worker, Instant::now());
            }
        });
    }
}

impl Handler<KillConnection> for Listener {
    type Result = bool;
    fn handle(&mut self, msg: KillConnection, ctx: &mut Context<Self>) -> bool {
        self.guarded(ctx, |l, _| l.conns.get(&msg.0).map(|a| a.do_send(Kill)).is_some())
            .unwrap_or(false)
    }
}

impl Handler<PanicConnection> for Listener {
    type Result = bool;
    fn handle(&mut self, msg: PanicConnection, ctx: &mut Context<Self>) -> bool {
        self.guarded(ctx, |l, _| l.conns.get(&msg.0).map(|a| a.do_send(InjectPanic)).is_some())
            .unwrap_or(false)
    }
}

impl Handler<ListConnections> for Listener {
    type Result = MessageResult<ListConnections>;
    fn handle(&mut self, _: ListConnections, ctx: &mut Context<Self>) -> Self::Result {
        let ids = self.guarded(ctx, |l, _| {
            let mut ids: Vec<ConnId> = l.conns.keys().copied().collect();
            ids.sort_unstable();
            ids
        });
        MessageResult(ids.unwrap_or_default())
    }
}

impl Handler<InjectPanic> for Listener {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the listener"));
    }
}

/// Tells a refused peer why, then closes.
async fn refuse(mut stream: TcpStream, reason: String) {
    if let Ok(frame) = to_frame(&MasterMsg::Rejected { reason }) {
        let _ = stream.write_all(&frame).await;
    }
    let _ = stream.shutdown().await;
}
