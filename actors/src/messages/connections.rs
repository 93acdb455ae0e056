//! Connections and their supervisor, the listener: an ended connection reports to it, and
//! the test hooks that end or list connections go through it.

use actix::prelude::*;

use crate::wire::protocol::ConnId;
use crate::wire::rejection::RejectionKind;

/// To the listener: this connection ended; `failed` when it ended on an error.
#[derive(Message)]
#[rtype(result = "()")]
pub struct ConnectionEnded {
    pub conn: ConnId,
    pub failed: bool,
    /// The worker's name from its `Hello`: the per-peer back-off's key (`None` before
    /// the `Hello`, and for a connection that back-off refused).
    pub worker: Option<String>,
    /// The kind of the rejection it ended with, if it was rejected.
    pub rejected: Option<RejectionKind>,
}

/// To the listener: this connection authenticated (its worker was welcomed); it no longer
/// counts against the caps on pending connections.
#[derive(Message)]
#[rtype(result = "()")]
pub struct ConnectionAuthenticated(pub ConnId);

/// To a connection, from the listener: the handshake's deadline passed before it
/// authenticated; it ends without a word (the listener's summary counts it).
#[derive(Message)]
#[rtype(result = "()")]
pub struct HandshakeExpired;

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

/// Test hook: end this connection abruptly, as a crash would (no `Rejected`).
#[derive(Message)]
#[rtype(result = "()")]
pub struct Kill;
