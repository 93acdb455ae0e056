//! The listener actor: accepts worker connections (up to a cap) and starts one
//! connection actor per socket; refused sockets get a `Rejected` saying why.
//!
//! It is the connections' supervisor: it knows every live connection (for the
//! fault-injection hooks), and a connection that ends — cleanly, on a protocol error,
//! a contained panic or a kill — is simply gone: its jobs are not redone and the worker
//! is served again by a fresh connection actor when it reconnects (workers reconnect
//! with back-off and jitter on their side).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;

use actix::prelude::*;
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio_util::codec::FramedRead;

use crate::connection::{Connection, ConnectionConfig, ConnectionLinks, Kill};
use crate::presenter::stats::Counters;
use crate::supervision::InjectPanic;
use crate::wire::codec::{to_frame, MasterCodec};
use crate::wire::counted_io::{CountedRead, CountedWrite};
use crate::wire::protocol::ConnId;
use crate::wire::protocol::MasterMsg;
use crate::wire::rejection::Rejection;

/// To the listener: this connection ended; `failed` when it ended on an error.
#[derive(Message)]
#[rtype(result = "()")]
pub struct ConnectionEnded {
    pub conn: ConnId,
    pub failed: bool,
}

/// Internal: one accepted socket (or accept error).
#[derive(Message)]
#[rtype(result = "()")]
struct Accepted(std::io::Result<(TcpStream, SocketAddr)>);

/// Test hook: end connection `conn` abruptly. Answers whether it existed.
#[derive(Message)]
#[rtype(result = "bool")]
pub struct KillConnection(pub ConnId);

/// Test hook: make connection `conn` panic inside a handler. Answers whether it existed.
#[derive(Message)]
#[rtype(result = "bool")]
pub struct PanicConnection(pub ConnId);

/// The ids of the live connections, in id order.
#[derive(Message)]
#[rtype(result = "Vec<ConnId>")]
pub struct ListConnections;

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
}

impl Listener {
    /// `links.ended_to` must lead back to this listener.
    pub fn new(
        socket: TcpListener,
        max_connections: usize,
        config: Arc<ConnectionConfig>,
        links: ConnectionLinks,
        counters: Arc<Counters>,
    ) -> Self {
        Self {
            socket: Some(socket),
            max_connections,
            next_id: 1,
            conns: HashMap::new(),
            config,
            links,
            counters,
        }
    }
}

impl Actor for Listener {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        let Some(socket) = self.socket.take() else { return };
        let accepts = futures::stream::unfold(socket, |s| async move {
            let r = s.accept().await;
            Some((Accepted(r), s))
        });
        ctx.add_message_stream(accepts);
    }
}

impl Handler<Accepted> for Listener {
    type Result = ();
    fn handle(&mut self, msg: Accepted, _: &mut Context<Self>) {
        let (stream, peer) = match msg.0 {
            Ok(s) => s,
            Err(e) => {
                tracing::warn!(cause = %e, "accept failed");
                return;
            }
        };
        if self.conns.len() >= self.max_connections {
            tracing::warn!(%peer, cap = self.max_connections, "connection refused: too many connections");
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
        let addr = Connection::create(move |ctx| {
            let read = CountedRead::new(read, counters.bytes_in.clone());
            ctx.add_stream(FramedRead::new(read, MasterCodec::new()));
            let write = CountedWrite::new(write, counters.bytes_out.clone());
            let writer = actix::io::FramedWrite::new(write, MasterCodec::new(), ctx);
            Connection::new(id, peer, writer, config, links, counters)
        });
        self.conns.insert(id, addr);
    }
}

impl Handler<ConnectionEnded> for Listener {
    type Result = ();
    fn handle(&mut self, msg: ConnectionEnded, _: &mut Context<Self>) {
        self.conns.remove(&msg.conn);
        if msg.failed {
            tracing::debug!(conn = msg.conn, "connection ended on an error");
        }
    }
}

impl Handler<KillConnection> for Listener {
    type Result = bool;
    fn handle(&mut self, msg: KillConnection, _: &mut Context<Self>) -> bool {
        self.conns.get(&msg.0).map(|a| a.do_send(Kill)).is_some()
    }
}

impl Handler<PanicConnection> for Listener {
    type Result = bool;
    fn handle(&mut self, msg: PanicConnection, _: &mut Context<Self>) -> bool {
        self.conns.get(&msg.0).map(|a| a.do_send(InjectPanic)).is_some()
    }
}

impl Handler<ListConnections> for Listener {
    type Result = MessageResult<ListConnections>;
    fn handle(&mut self, _: ListConnections, _: &mut Context<Self>) -> Self::Result {
        let mut ids: Vec<ConnId> = self.conns.keys().copied().collect();
        ids.sort_unstable();
        MessageResult(ids)
    }
}

/// Tells a refused peer why, then closes.
async fn refuse(mut stream: TcpStream, reason: String) {
    if let Ok(frame) = to_frame(&MasterMsg::Rejected { reason }) {
        let _ = stream.write_all(&frame).await;
    }
    let _ = stream.shutdown().await;
}
