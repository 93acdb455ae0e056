//! The codec of a connection that may become encrypted: plain frames
//! (`wire::codec::FrameCodec`) until the channel's keys are installed, records of the
//! encrypted channel (`wire::channel`) from then on.
//!
//! Both sides start plain: the Noise handshake itself travels in two plain frames
//! (`WorkerMsg::Handshake`, `MasterMsg::Handshake`). Whoever completes it installs the
//! keys in the connection's [`KeySlot`]; each codec half takes its direction's key
//! before its next frame, so the first frame after the handshake is already a record.
//! The master's read and write halves are two codec values sharing one slot; the
//! worker's one `Framed` codec takes both.
//!
//! Encrypted, a decoded record's plaintext goes to the same frame decoder as a plain
//! connection's bytes, with the same limits; a record is opened (authenticated) before
//! any of its bytes is parsed, so an altered byte is a
//! [`ChannelError::Decrypt`](crate::wire::channel::ChannelError), never a message.

use std::marker::PhantomData;
use std::sync::atomic::AtomicU64;
use std::sync::{Arc, Mutex};

use bytes::{Buf, BytesMut};
use serde::de::DeserializeOwned;
use serde::Serialize;
use tokio_util::codec::{Decoder, Encoder};

use crate::wire::channel::{
    check_record_len, initiate, respond, ChannelError, Keys, Opener, Psk, Sealer, RECORD_PREFIX,
};
use crate::wire::codec::{encode_into, FrameCodec, ProtocolError};
use crate::wire::protocol::{MasterMsg, WorkerMsg};

/// The master's side: reads [`WorkerMsg`], writes [`MasterMsg`].
pub type MasterChannelCodec = ChannelCodec<WorkerMsg, MasterMsg>;
/// The worker's side: reads [`MasterMsg`], writes [`WorkerMsg`].
pub type WorkerChannelCodec = ChannelCodec<MasterMsg, WorkerMsg>;

/// Where a connection's handshake leaves its keys for the codec halves.
#[derive(Clone, Default)]
pub struct KeySlot(Arc<Mutex<Slot>>);

#[derive(Default)]
struct Slot {
    sealer: Option<Sealer>,
    opener: Option<Opener>,
    installed: bool,
}

impl KeySlot {
    /// An empty slot: its codecs are plain until [`KeySlot::install`].
    pub fn new() -> Self {
        Self::default()
    }

    /// Installs the handshake's keys; both codec halves switch to records. `timer`, when
    /// given, adds up the nanoseconds both halves spend in the cipher.
    pub fn install(&self, keys: Keys, timer: Option<Arc<AtomicU64>>) {
        let (sealer, opener) = keys.split(timer);
        let mut slot = self.0.lock().unwrap_or_else(|p| p.into_inner());
        *slot = Slot { sealer: Some(sealer), opener: Some(opener), installed: true };
    }

    /// Whether keys were installed (the connection is encrypted).
    pub fn encrypted(&self) -> bool {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).installed
    }

    fn take_sealer(&self) -> Option<Sealer> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).sealer.take()
    }

    fn take_opener(&self) -> Option<Opener> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).opener.take()
    }
}

/// Reads frames of `In`, writes frames of `Out`: plain until the slot has keys.
pub struct ChannelCodec<In, Out> {
    frames: FrameCodec<In, Out>,
    slot: KeySlot,
    sealer: Option<Sealer>,
    opener: Option<Opener>,
    /// Opened plaintext not yet decoded (at most one partial frame and one record).
    plain_in: BytesMut,
    /// One encoded frame before it is sealed.
    plain_out: BytesMut,
    _types: PhantomData<fn(Out) -> In>,
}

impl<In, Out> ChannelCodec<In, Out> {
    /// A codec half switched by `slot`.
    pub fn new(slot: KeySlot) -> Self {
        Self {
            frames: FrameCodec::new(),
            slot,
            sealer: None,
            opener: None,
            plain_in: BytesMut::new(),
            plain_out: BytesMut::new(),
            _types: PhantomData,
        }
    }

    /// The slot this codec switches by.
    pub fn slot(&self) -> &KeySlot {
        &self.slot
    }
}

impl<In: DeserializeOwned, Out> Decoder for ChannelCodec<In, Out> {
    type Item = In;
    type Error = ProtocolError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<In>, ProtocolError> {
        if self.opener.is_none() {
            self.opener = self.slot.take_opener();
        }
        let Some(opener) = &mut self.opener else { return self.frames.decode(src) };
        loop {
            if let Some(msg) = self.frames.decode(&mut self.plain_in)? {
                return Ok(Some(msg));
            }
            if src.len() < RECORD_PREFIX {
                return Ok(None);
            }
            let len = u16::from_be_bytes([src[0], src[1]]) as usize;
            check_record_len(len)?;
            if src.len() < RECORD_PREFIX + len {
                src.reserve(RECORD_PREFIX + len - src.len());
                return Ok(None);
            }
            src.advance(RECORD_PREFIX);
            let record = src.split_to(len);
            opener.open(&record, &mut self.plain_in)?;
        }
    }
}

impl<In, Out: Serialize> Encoder<Out> for ChannelCodec<In, Out> {
    type Error = ProtocolError;

    fn encode(&mut self, msg: Out, dst: &mut BytesMut) -> Result<(), ProtocolError> {
        self.encode(&msg, dst)
    }
}

impl<In, Out: Serialize> Encoder<&Out> for ChannelCodec<In, Out> {
    type Error = ProtocolError;

    fn encode(&mut self, msg: &Out, dst: &mut BytesMut) -> Result<(), ProtocolError> {
        if self.sealer.is_none() {
            self.sealer = self.slot.take_sealer();
        }
        let Some(sealer) = &mut self.sealer else {
            return encode_into(msg, self.frames.max_len(), dst);
        };
        self.plain_out.clear();
        encode_into(msg, self.frames.max_len(), &mut self.plain_out)?;
        Ok(sealer.seal(&self.plain_out, dst)?)
    }
}

/// A worker's and a master's codec at the two ends of one encrypted channel, in memory
/// (for tests, benchmarks and the fuzzer: what one encodes the other decodes).
pub fn loopback_pair(psk: &Psk) -> Result<(WorkerChannelCodec, MasterChannelCodec), ChannelError> {
    let (init, first) = initiate(psk)?;
    let (answer, master_keys) = respond(psk, &first)?;
    let (w, m) = (WorkerChannelCodec::new(KeySlot::new()), MasterChannelCodec::new(KeySlot::new()));
    w.slot().install(init.finish(&answer)?, None);
    m.slot().install(master_keys, None);
    Ok((w, m))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::channel::MAX_RECORD_PLAINTEXT;
    use crate::wire::protocol::{JobResult, PackedRadiance};
    use bytes::BufMut;

    fn encrypted_pair() -> (WorkerChannelCodec, MasterChannelCodec) {
        loopback_pair(&Psk::derive(b"s")).expect("handshake")
    }

    fn result(pixels: usize) -> WorkerMsg {
        WorkerMsg::Result(JobResult {
            frame: 7,
            set: 3,
            state_version: 2,
            radiance: PackedRadiance::Rgb9e5((0..pixels as u32).collect()),
            render_us: 9,
            tag: None,
        })
    }

    #[test]
    fn plain_until_installed_then_records_byte_by_byte() {
        let slot = KeySlot::new();
        let mut plain = WorkerChannelCodec::new(slot.clone());
        let mut wire = BytesMut::new();
        plain.encode(&WorkerMsg::Heartbeat, &mut wire).expect("encode");
        assert_eq!(&wire[..], &crate::wire::codec::to_frame(&WorkerMsg::Heartbeat).unwrap()[..]);
        assert!(!slot.encrypted());

        let (mut w, mut m) = encrypted_pair();
        // A frame larger than a record: several records, fed one byte at a time.
        let msg = result(40_000);
        let mut wire = BytesMut::new();
        w.encode(&msg, &mut wire).expect("encode");
        assert!(wire.len() > 2 * MAX_RECORD_PLAINTEXT);
        let mut buf = BytesMut::new();
        let mut got = Vec::new();
        for b in wire.iter() {
            buf.put_u8(*b);
            got.extend(m.decode(&mut buf).expect("decode"));
        }
        assert_eq!(got, vec![msg]);
    }

    #[test]
    fn no_flipped_byte_of_an_encrypted_frame_decodes() {
        let (mut w, _) = encrypted_pair();
        let mut wire = BytesMut::new();
        w.encode(&result(100), &mut wire).expect("encode");
        for i in 0..wire.len() {
            let (mut w2, mut m2) = encrypted_pair();
            let mut fresh = BytesMut::new();
            w2.encode(&result(100), &mut fresh).expect("encode");
            fresh[i] ^= 0x04;
            match m2.decode(&mut fresh) {
                Err(ProtocolError::Channel(_)) | Ok(None) => {} // refused, or waits for a longer record
                other => panic!("byte {i}: {other:?}"),
            }
        }
    }

    #[test]
    fn plain_bytes_on_an_encrypted_connection_are_refused() {
        let (_, mut m) = encrypted_pair();
        let frame = crate::wire::codec::to_frame(&result(10)).expect("encode");
        let err = m.decode(&mut BytesMut::from(&frame[..])).expect_err("plain frame decoded");
        assert!(matches!(err, ProtocolError::Channel(_)), "{err}");
    }
}
