//! The worker's side of the encrypted channel's handshake (with `--secret-file`): it runs
//! on a fresh connection before anything else is sent, so a worker with a secret talks
//! only to a master that proves the same secret, and encrypts everything after.
//!
//! The worker's `Handshake` (its protocol version and Noise's first message) goes out
//! plain; the master's answer must authenticate under the secret before the worker sends
//! its `Hello`. A plain `Rejected` instead is the master's word (a version or secret
//! mismatch, a master without a secret that does not encrypt: final), and any other
//! answer, or one that fails its check (an impostor, an altered answer), ends this
//! connection only: the worker says why and tries again later.

use futures::{SinkExt, StreamExt};
use gridlight_actors::channel::{initiate, Psk};
use gridlight_actors::channel_codec::WorkerChannelCodec;
use gridlight_actors::protocol::{MasterMsg, WorkerMsg, PEER_TIMEOUT, PROTOCOL_VERSION};
use gridlight_actors::rejection::is_final;
use tokio::net::TcpStream;
use tokio_util::codec::Framed;

use super::WorkerError;

/// Runs the handshake on `framed`; on success its codec encrypts every later frame.
pub(crate) async fn encrypt(
    framed: &mut Framed<TcpStream, WorkerChannelCodec>,
    secret: &[u8],
) -> Result<(), WorkerError> {
    let (initiator, noise) = initiate(&Psk::derive(secret))?;
    let closed = |e: gridlight_actors::codec::ProtocolError| WorkerError::Connection(e.to_string());
    framed
        .send(WorkerMsg::Handshake { protocol: PROTOCOL_VERSION, noise })
        .await
        .map_err(closed)?;
    let answer = tokio::time::timeout(PEER_TIMEOUT, framed.next())
        .await
        .map_err(|_| WorkerError::Connection(format!("master silent for {PEER_TIMEOUT:?}")))?;
    match answer {
        Some(Ok(MasterMsg::Handshake { noise })) => {
            let keys = initiator.finish(&noise)?;
            framed.codec().slot().install(keys, None);
            Ok(())
        }
        Some(Ok(MasterMsg::Rejected { reason })) => {
            Err(WorkerError::Rejected { fatal: is_final(&reason), reason })
        }
        Some(Ok(_)) => Err(WorkerError::Protocol(
            "the master answered the encrypted handshake in the clear: it does not encrypt, \
             and a worker with a secret talks only to one that does"
                .into(),
        )),
        Some(Err(e)) => Err(closed(e)),
        None => Err(WorkerError::Connection(
            "master closed the connection during the encrypted handshake".into(),
        )),
    }
}
