//! One worker connection's join, timed: connect, the encrypted channel's handshake (with a
//! secret), `Hello`, `Challenge`, `Auth`, until `Welcome`; for `bench master`'s
//! `handshake_ms`. A blocking, scripted worker: the real one's join is the same messages
//! on its async runtime, whose scheduling would only add noise here.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use gridlight_actors::auth;
use gridlight_actors::channel::{initiate, Psk};
use gridlight_actors::channel_codec::{KeySlot, WorkerChannelCodec};
use gridlight_actors::protocol::{MasterMsg, WorkerMsg, PROTOCOL_VERSION};
use tokio_util::bytes::BytesMut;
use tokio_util::codec::{Decoder, Encoder};

/// Milliseconds one join took (the `i`-th, named after it); the connection is closed after.
pub fn time_join(master: SocketAddr, secret: Option<&[u8]>, i: usize) -> anyhow::Result<f64> {
    let start = Instant::now();
    let mut link = Link::connect(master)?;
    if let Some(secret) = secret {
        let (init, noise) = initiate(&Psk::derive(secret))?;
        link.send(&WorkerMsg::Handshake { protocol: PROTOCOL_VERSION, noise })?;
        let MasterMsg::Handshake { noise } = link.recv()? else { bail!("no handshake answer") };
        link.codec.slot().install(init.finish(&noise)?, None);
    }
    let name = format!("bench-join-{i}");
    link.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name, cores: 1 })?;
    let MasterMsg::Challenge { nonce, .. } = link.recv()? else { bail!("no challenge") };
    link.send(&WorkerMsg::Auth { mac: secret.map(|s| auth::mac(s, &nonce)) })?;
    match link.recv()? {
        MasterMsg::Welcome { .. } => Ok(start.elapsed().as_secs_f64() * 1e3),
        other => bail!("joining: expected Welcome, got {other:?}"),
    }
}

/// A blocking socket with the worker's codec.
struct Link {
    stream: TcpStream,
    codec: WorkerChannelCodec,
    buf: BytesMut,
}

impl Link {
    fn connect(master: SocketAddr) -> anyhow::Result<Self> {
        let stream = TcpStream::connect(master).context("connecting to the master")?;
        stream.set_nodelay(true)?;
        stream.set_read_timeout(Some(Duration::from_secs(10)))?;
        Ok(Self { stream, codec: WorkerChannelCodec::new(KeySlot::new()), buf: BytesMut::new() })
    }

    fn send(&mut self, msg: &WorkerMsg) -> anyhow::Result<()> {
        let mut frame = BytesMut::new();
        self.codec.encode(msg, &mut frame)?;
        Ok(self.stream.write_all(&frame)?)
    }

    /// The next message other than a heartbeat.
    fn recv(&mut self) -> anyhow::Result<MasterMsg> {
        loop {
            match self.codec.decode(&mut self.buf)? {
                Some(MasterMsg::Heartbeat) => continue,
                Some(MasterMsg::Rejected { reason }) => bail!("the master refused: {reason}"),
                Some(msg) => return Ok(msg),
                None => {}
            }
            let mut chunk = [0u8; 4096];
            let n = self.stream.read(&mut chunk).context("reading from the master")?;
            if n == 0 {
                bail!("the master closed the connection");
            }
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }
}
