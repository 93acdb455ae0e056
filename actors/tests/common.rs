//! Scripted protocol peers and a collecting sink for the master's loopback tests.
#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::time::Duration;

use bytes::BytesMut;
use glam::Vec3;
use gridlight_actors::auth;
use gridlight_actors::channel::{initiate, Psk};
use gridlight_actors::channel_codec::{KeySlot, WorkerChannelCodec};
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::master::{MasterConfig, ShownFrame, SinkError};
use gridlight_actors::pacing::{Heuristic, Pacing};
use gridlight_actors::packing::pack;
use gridlight_actors::protocol::*;
use gridlight_actors::sets::SetTable;
use gridlight_actors::sink::FrameSink;
use gridlight_actors::state::*;
use tokio_util::codec::{Decoder, Encoder};

pub const W: u32 = 32;
pub const H: u32 = 24;
pub const S: u32 = 8;

pub fn sets() -> SetsConfig {
    SetsConfig { sets: S, partition: Partition::QuasiRandom }
}

pub fn table() -> SetTable {
    SetTable::new(Resolution { width: W, height: H }, sets()).expect("sets")
}

pub fn scene() -> SceneState {
    let camera = Camera::pinhole(Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, 1.0, 0.0), 40.0);
    SceneState { seed: 7, ..SceneState::empty(Resolution { width: W, height: H }, camera) }
        .with_object(
            Object::new("box", Geometry::Cube),
            Material::diffuse("white", Vec3::splat(0.8)),
        )
}

/// A fast configuration on an ephemeral loopback port.
pub fn config() -> MasterConfig {
    let mut c = MasterConfig::new("127.0.0.1:0".parse().expect("addr"), sets());
    c.pacing = Pacing::Heuristic(Heuristic::default());
    c.initial_frame_time = Duration::from_millis(40);
    c
}

/// Passes every shown frame to the test.
pub struct CollectSink(pub Sender<ShownFrame>);

impl FrameSink for CollectSink {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        self.0.send(frame).map_err(|_| SinkError::Closed)
    }
}

pub fn collect_sink() -> (Box<dyn FrameSink>, Receiver<ShownFrame>) {
    let (tx, rx) = channel();
    (Box::new(CollectSink(tx)), rx)
}

/// A scripted worker speaking the protocol by hand over a blocking socket (encrypted
/// once [`Peer::handshake`] was given a secret).
pub struct Peer {
    stream: TcpStream,
    codec: WorkerChannelCodec,
    buf: BytesMut,
    /// The connection's result key, once the handshake saw the nonce.
    key: Option<ResultKey>,
}

impl Peer {
    pub fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).expect("connect");
        stream.set_read_timeout(Some(Duration::from_secs(30))).expect("timeout");
        stream.set_nodelay(true).expect("nodelay");
        let codec = WorkerChannelCodec::new(KeySlot::new());
        Self { stream, codec, buf: BytesMut::new(), key: None }
    }

    /// This peer's own address (what the master's logs name).
    pub fn local_addr(&self) -> SocketAddr {
        self.stream.local_addr().expect("local addr")
    }

    /// A second handle on the socket (to half-close it or write from another thread).
    pub fn stream_clone(&self) -> TcpStream {
        self.stream.try_clone().expect("clone socket")
    }

    pub fn send(&mut self, msg: &WorkerMsg) {
        assert!(self.try_send(msg), "send");
    }

    /// Sends (a record of the channel once encrypted); false when the master went away.
    pub fn try_send(&mut self, msg: &WorkerMsg) -> bool {
        let frame = self.encode(msg);
        self.stream.write_all(&frame).is_ok()
    }

    /// The bytes `msg` takes on the wire (sealed records once encrypted), unsent: a test
    /// may alter them and send them with [`Peer::send_raw`].
    pub fn encode(&mut self, msg: &WorkerMsg) -> BytesMut {
        let mut frame = BytesMut::new();
        self.codec.encode(msg, &mut frame).expect("encode");
        frame
    }

    pub fn send_raw(&mut self, bytes: &[u8]) {
        self.stream.write_all(bytes).expect("send raw");
    }

    /// The next message, or `Err` with what happened (EOF, timeout, bad frame).
    pub fn recv(&mut self) -> Result<MasterMsg, String> {
        loop {
            if let Some(m) = self.codec.decode(&mut self.buf).map_err(|e| e.to_string())? {
                return Ok(m);
            }
            let mut chunk = [0u8; 65536];
            let n = self.stream.read(&mut chunk).map_err(|e| e.to_string())?;
            if n == 0 {
                return Err("eof".into());
            }
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }

    /// The next message other than a heartbeat within `wait`, `None` if none came.
    pub fn recv_within(&mut self, wait: Duration) -> Option<MasterMsg> {
        let deadline = std::time::Instant::now() + wait;
        let msg = loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                break None;
            }
            self.stream.set_read_timeout(Some(left)).expect("timeout");
            match self.recv() {
                Ok(MasterMsg::Heartbeat) => continue,
                Ok(m) => break Some(m),
                Err(_) => break None,
            }
        };
        self.stream.set_read_timeout(Some(Duration::from_secs(30))).expect("timeout");
        msg
    }

    /// Skips heartbeats.
    pub fn recv_non_heartbeat(&mut self) -> Result<MasterMsg, String> {
        loop {
            match self.recv()? {
                MasterMsg::Heartbeat => continue,
                m => return Ok(m),
            }
        }
    }

    /// Expects `Rejected` and returns its reason.
    pub fn expect_rejected(&mut self) -> String {
        match self.recv_non_heartbeat() {
            Ok(MasterMsg::Rejected { reason }) => reason,
            other => panic!("expected Rejected, got {other:?}"),
        }
    }

    /// Hello + Auth; returns the Welcome's worker id or the rejection. Each scripted peer
    /// is a worker of its own (named after its port): the master's per-peer back-off
    /// must not take the bad peers of a case table for one crash-looping worker.
    pub fn handshake(&mut self, secret: Option<&[u8]>) -> Result<u64, String> {
        let name = format!("test-peer-{}", self.local_addr().port());
        self.handshake_as(&name, secret)
    }

    /// [`Peer::handshake`] under the worker name `name` (the master's per-peer key).
    pub fn handshake_as(&mut self, name: &str, secret: Option<&[u8]>) -> Result<u64, String> {
        if let Some(secret) = secret {
            self.encrypt(secret)?;
        }
        self.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: name.into(), cores: 1 });
        let nonce = match self.recv_non_heartbeat()? {
            MasterMsg::Challenge { nonce, .. } => {
                let encrypted = self.codec.slot().encrypted();
                self.key = Some(ResultKey::for_connection(encrypted, &nonce));
                nonce
            }
            MasterMsg::Rejected { reason } => return Err(reason),
            m => return Err(format!("unexpected {m:?}")),
        };
        self.send(&WorkerMsg::Auth { mac: secret.map(|s| auth::mac(s, &nonce)) });
        match self.recv_non_heartbeat()? {
            MasterMsg::Welcome { worker_id, .. } => Ok(worker_id),
            MasterMsg::Rejected { reason } => Err(reason),
            m => Err(format!("unexpected {m:?}")),
        }
    }

    /// The encrypted channel's handshake with `secret`, as a worker with one starts;
    /// `Err` with the master's rejection.
    pub fn encrypt(&mut self, secret: &[u8]) -> Result<(), String> {
        let (init, noise) = initiate(&Psk::derive(secret)).map_err(|e| e.to_string())?;
        self.send(&WorkerMsg::Handshake { protocol: PROTOCOL_VERSION, noise });
        match self.recv_non_heartbeat()? {
            MasterMsg::Handshake { noise } => {
                let keys = init.finish(&noise).map_err(|e| e.to_string())?;
                self.codec.slot().install(keys, None);
                Ok(())
            }
            MasterMsg::Rejected { reason } => Err(reason),
            m => Err(format!("unexpected {m:?}")),
        }
    }

    /// The next job, with the state sent just before it if any.
    pub fn next_job(
        &mut self,
    ) -> Result<(FrameNo, SetNo, StateVersion, Option<SceneState>), String> {
        let mut state = None;
        loop {
            match self.recv_non_heartbeat()? {
                MasterMsg::State(s) => state = Some(*s),
                MasterMsg::Job { frame, set, state_version, .. } => {
                    return Ok((frame, set, state_version, state))
                }
                m => return Err(format!("expected a job, got {m:?}")),
            }
        }
    }

    /// Answers a job with constant radiance `value` over the whole set.
    pub fn answer(
        &mut self,
        table: &SetTable,
        frame: FrameNo,
        set: SetNo,
        version: StateVersion,
        value: f32,
    ) -> bool {
        let n = table.set_len(set);
        let radiance = pack(&vec![Vec3::splat(value); n]).expect("pack");
        let msg = self.result(frame, set, version, radiance);
        self.try_send(&msg)
    }

    /// A result tagged with this connection's key, as an honest worker sends it (before
    /// the handshake: a key no master holds).
    pub fn result(
        &self,
        frame: FrameNo,
        set: SetNo,
        version: StateVersion,
        radiance: PackedRadiance,
    ) -> WorkerMsg {
        let key = self.key.clone().unwrap_or_else(|| ResultKey::checksum(&[0; 32]));
        WorkerMsg::Result(key.seal(frame, set, version, radiance, 1))
    }
}

/// Radiance a null peer sends for `frame`, so a test can tell frames apart in images.
pub fn frame_value(frame: FrameNo) -> f32 {
    (frame % 64) as f32 + 1.0
}
