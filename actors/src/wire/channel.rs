//! The encrypted channel of a connection with a shared secret: a Noise `NNpsk0`
//! handshake (the `snow` crate) and the records that carry every frame after it.
//!
//! # Why Noise `NNpsk0`
//! The grid's only credential is the shared secret: no certificates, no per-host keys.
//! `NNpsk0` is the Noise pattern for exactly that: both sides send a fresh ephemeral
//! X25519 key, and the pre-shared key is mixed into the handshake before the first
//! one, so every key that follows depends on the secret *and* on the ephemeral
//! Diffie-Hellman result:
//! - **Mutual authentication**: the worker's first message carries an AEAD tag under a
//!   key derived from the PSK (the master checks it before it answers anything), and the
//!   master's answer carries one under a key derived from the PSK and both ephemerals
//!   (the worker checks it before it sends anything else). Neither side proves anything
//!   by sending the secret.
//! - **Forward secrecy**: the transport keys come from an ephemeral-ephemeral DH; a secret
//!   that leaks later does not decrypt a recorded session.
//! - **No replay**: a recorded handshake replayed to the master meets a fresh master
//!   ephemeral, so the recorded records do not decrypt under the new keys.
//!
//! The suite is `25519_AESGCM_SHA256`: X25519 from curve25519-dalek, AES-256-GCM and
//! SHA-256 from ring (snow's `ring-accelerated` resolver: BoringSSL's audited assembly,
//! constant-time bitsliced AES where a CPU lacks AES instructions). It was measured, on
//! the project's 2-core Xeon (Sapphire Rapids VM), on a 640×480 / 64-set result of
//! 19.2 kB: about 6 µs per side to seal or open, where the keyed BLAKE3 tag it replaces
//! took 7–8 µs per side and the pure-Rust AEADs (RustCrypto AES-GCM and
//! ChaCha20-Poly1305, snow's default resolver) 25–35 µs.
//!
//! # The PSK
//! `PSK = BLAKE3-derive_key("gridlight channel psk v1", secret)`: 32 bytes whatever the
//! secret file holds. A PSK handshake lets an eavesdropper test guesses of the secret
//! offline against one recorded handshake, so the secret must be random (the README says
//! how to make one); [`Psk::derive`]'s caller warns about a short one.
//!
//! # Records
//! After the handshake each direction is a sequence of records: a 2-byte big-endian
//! length `n` (`TAG_LEN < n <= MAX_RECORD`), then `n` bytes of AEAD ciphertext and tag.
//! The nonce is the record's index in its direction, counted by both sides and never
//! sent, so a dropped, repeated or reordered record fails authentication like an altered
//! one. The plaintexts, concatenated, are the protocol's ordinary frame stream (length
//! prefix and MessagePack, `wire::codec`), so the frame decoder and its limits apply
//! unchanged to what the records carry; one frame is cut into as many records as it
//! needs (Noise messages are at most 65535 bytes), and no record holds two frames.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use bytes::{BufMut, BytesMut};
use snow::{Builder, HandshakeState, StatelessTransportState};
use thiserror::Error;

/// The Noise protocol name: pattern, DH, cipher, hash.
pub const NOISE_PARAMS: &str = "Noise_NNpsk0_25519_AESGCM_SHA256";
/// Bytes of an AEAD tag.
pub const TAG_LEN: usize = 16;
/// Largest record (ciphertext and tag): Noise's message limit.
pub const MAX_RECORD: usize = 65535;
/// Largest plaintext one record carries.
pub const MAX_RECORD_PLAINTEXT: usize = MAX_RECORD - TAG_LEN;
/// Bytes of a record's length prefix.
pub const RECORD_PREFIX: usize = 2;
/// Bytes of a handshake message: an X25519 public key and the tag of its (empty) payload.
pub const HANDSHAKE_LEN: usize = 32 + TAG_LEN;

/// Separates the PSK from any other key derived from the secret.
const PSK_CONTEXT: &str = "gridlight channel psk v1";

/// What can go wrong on the channel; every one ends the connection.
#[derive(Debug, Error)]
pub enum ChannelError {
    #[error("encrypted handshake failed: the peer does not hold the same shared secret, or the handshake was altered or replayed")]
    Handshake,
    #[error("a record failed authentication: altered, dropped, replayed or reordered on the way")]
    Decrypt,
    #[error("record of {len} bytes: a record holds 1 to {max} bytes of ciphertext past its {TAG_LEN}-byte tag", max = MAX_RECORD_PLAINTEXT)]
    RecordLen { len: usize },
    #[error("the channel's record counter is exhausted")]
    Exhausted,
}

/// The 32-byte pre-shared key derived from the secret file's bytes.
#[derive(Clone)]
pub struct Psk([u8; 32]);

impl Psk {
    pub fn derive(secret: &[u8]) -> Self {
        Psk(blake3::derive_key(PSK_CONTEXT, secret))
    }
}

impl std::fmt::Debug for Psk {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Psk(..)") // never print key material
    }
}

/// A worker's handshake in progress: its first message is sent, the master's answer due.
pub struct Initiator(HandshakeState);

/// Starts a handshake as the worker: the state, and the first message to send.
pub fn initiate(psk: &Psk) -> Result<(Initiator, Vec<u8>), ChannelError> {
    let mut hs = builder(psk)?.build_initiator().map_err(|_| ChannelError::Handshake)?;
    let mut msg = vec![0; HANDSHAKE_LEN];
    let n = hs.write_message(&[], &mut msg).map_err(|_| ChannelError::Handshake)?;
    msg.truncate(n);
    Ok((Initiator(hs), msg))
}

impl Initiator {
    /// Reads the master's answer: the channel's keys, or [`ChannelError::Handshake`] when
    /// the master does not hold the secret (or the answer was altered or replayed).
    pub fn finish(mut self, answer: &[u8]) -> Result<Keys, ChannelError> {
        let mut payload = [0u8; HANDSHAKE_LEN];
        self.0.read_message(answer, &mut payload).map_err(|_| ChannelError::Handshake)?;
        Keys::from_handshake(self.0)
    }
}

/// Answers a worker's first message as the master: the answer to send and the channel's
/// keys, or [`ChannelError::Handshake`] when the worker does not hold the secret.
pub fn respond(psk: &Psk, first: &[u8]) -> Result<(Vec<u8>, Keys), ChannelError> {
    let mut hs = builder(psk)?.build_responder().map_err(|_| ChannelError::Handshake)?;
    let mut payload = [0u8; HANDSHAKE_LEN];
    hs.read_message(first, &mut payload).map_err(|_| ChannelError::Handshake)?;
    let mut answer = vec![0; HANDSHAKE_LEN];
    let n = hs.write_message(&[], &mut answer).map_err(|_| ChannelError::Handshake)?;
    answer.truncate(n);
    Ok((answer, Keys::from_handshake(hs)?))
}

fn builder(psk: &Psk) -> Result<Builder<'_>, ChannelError> {
    let params = NOISE_PARAMS.parse().map_err(|_| ChannelError::Handshake)?;
    Builder::new(params).psk(0, &psk.0).map_err(|_| ChannelError::Handshake)
}

/// A finished handshake's transport keys, both directions.
pub struct Keys {
    transport: Arc<StatelessTransportState>,
    /// The handshake hash: unique per handshake, so it names these keys.
    hash: [u8; 32],
}

impl Keys {
    fn from_handshake(hs: HandshakeState) -> Result<Self, ChannelError> {
        let mut hash = [0; 32];
        hash.copy_from_slice(&hs.get_handshake_hash()[..32]);
        let transport = hs.into_stateless_transport_mode().map_err(|_| ChannelError::Handshake)?;
        Ok(Self { transport: Arc::new(transport), hash })
    }

    /// The sending and the receiving half, each counting its own records; `timer`, when
    /// given, adds the nanoseconds both spend in the cipher.
    pub fn split(self, timer: Option<Arc<AtomicU64>>) -> (Sealer, Opener) {
        let t = &self.transport;
        let half = || Half { transport: t.clone(), records: 0, timer: timer.clone() };
        (Sealer(half()), Opener(half()))
    }
}

impl PartialEq for Keys {
    fn eq(&self, other: &Self) -> bool {
        self.hash == other.hash
    }
}

impl std::fmt::Debug for Keys {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Keys(..)") // never print key material
    }
}

struct Half {
    transport: Arc<StatelessTransportState>,
    /// Records sealed (or opened) so far: the next record's nonce.
    records: u64,
    timer: Option<Arc<AtomicU64>>,
}

impl Half {
    fn next_nonce(&mut self) -> Result<u64, ChannelError> {
        let n = self.records;
        self.records = n.checked_add(1).filter(|&m| m < u64::MAX).ok_or(ChannelError::Exhausted)?;
        Ok(n)
    }

    fn timed<T>(&self, f: impl FnOnce() -> T) -> T {
        let Some(timer) = &self.timer else { return f() };
        let start = Instant::now();
        let out = f();
        timer.fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        out
    }
}

/// The sending half: plaintext in, records out.
pub struct Sealer(Half);

impl Sealer {
    /// Appends `plaintext` to `dst` as records (length prefix, ciphertext, tag), as many
    /// as it needs; on error `dst` is left as it was.
    pub fn seal(&mut self, plaintext: &[u8], dst: &mut BytesMut) -> Result<(), ChannelError> {
        let start = dst.len();
        let sealed = plaintext.chunks(MAX_RECORD_PLAINTEXT).try_for_each(|piece| {
            let nonce = self.0.next_nonce()?;
            let len = piece.len() + TAG_LEN;
            dst.put_u16(len as u16);
            let at = dst.len();
            dst.resize(at + len, 0);
            let out = &mut dst[at..];
            let t = &self.0.transport;
            self.0
                .timed(|| t.write_message(nonce, piece, out))
                .map_err(|_| ChannelError::Exhausted)?;
            Ok(())
        });
        if sealed.is_err() {
            dst.truncate(start);
        }
        sealed
    }
}

/// The receiving half: records in, plaintext out.
pub struct Opener(Half);

impl Opener {
    /// Checks and decrypts one record (without its length prefix), appending its
    /// plaintext to `dst`; on error `dst` is left as it was.
    pub fn open(&mut self, record: &[u8], dst: &mut BytesMut) -> Result<(), ChannelError> {
        check_record_len(record.len())?;
        let nonce = self.0.next_nonce()?;
        let start = dst.len();
        dst.resize(start + record.len() - TAG_LEN, 0);
        let out = &mut dst[start..];
        let t = &self.0.transport;
        match self.0.timed(|| t.read_message(nonce, record, out)) {
            Ok(n) if n == record.len() - TAG_LEN => Ok(()),
            _ => {
                dst.truncate(start);
                Err(ChannelError::Decrypt)
            }
        }
    }
}

/// A record holds at least one byte of plaintext and at most [`MAX_RECORD`] bytes.
pub fn check_record_len(len: usize) -> Result<(), ChannelError> {
    if len <= TAG_LEN || len > MAX_RECORD {
        return Err(ChannelError::RecordLen { len });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(worker: &[u8], master: &[u8]) -> Result<(Keys, Keys), ChannelError> {
        let (init, first) = initiate(&Psk::derive(worker))?;
        let (answer, master_keys) = respond(&Psk::derive(master), &first)?;
        Ok((init.finish(&answer)?, master_keys))
    }

    /// Seals `plain` on one side and opens every record on the other.
    fn through(sealer: &mut Sealer, opener: &mut Opener, plain: &[u8]) -> Vec<u8> {
        let mut wire = BytesMut::new();
        sealer.seal(plain, &mut wire).expect("seal");
        let mut out = BytesMut::new();
        let mut at = 0;
        while at < wire.len() {
            let n = u16::from_be_bytes([wire[at], wire[at + 1]]) as usize;
            opener.open(&wire[at + 2..at + 2 + n], &mut out).expect("open");
            at += 2 + n;
        }
        out.to_vec()
    }

    #[test]
    fn both_directions_carry_frames_of_any_size() {
        let (w, m) = pair(b"s", b"s").expect("same secret");
        assert_eq!(w, m, "both sides name the same handshake");
        let ((mut ws, mut wo), (mut ms, mut mo)) = (w.split(None), m.split(None));
        for len in [1, 17, MAX_RECORD_PLAINTEXT, MAX_RECORD_PLAINTEXT + 1, 4 << 20] {
            let plain: Vec<u8> = (0..len).map(|i| (i * 7 % 251) as u8).collect();
            assert_eq!(through(&mut ws, &mut mo, &plain), plain, "{len} bytes up");
            assert_eq!(through(&mut ms, &mut wo, &plain), plain, "{len} bytes down");
        }
    }

    #[test]
    fn records_are_bounded_and_cost_a_tag_and_a_prefix_each() {
        let (w, _) = pair(b"s", b"s").expect("handshake");
        let (mut s, _) = w.split(None);
        let mut wire = BytesMut::new();
        s.seal(&vec![0; 2 * MAX_RECORD_PLAINTEXT + 5], &mut wire).expect("seal");
        assert_eq!(wire.len(), 2 * MAX_RECORD_PLAINTEXT + 5 + 3 * (RECORD_PREFIX + TAG_LEN));
        assert_eq!(u16::from_be_bytes([wire[0], wire[1]]) as usize, MAX_RECORD);
    }

    #[test]
    fn a_wrong_secret_fails_the_handshake_on_both_sides() {
        // The master refuses the worker's first message ...
        let (_, first) = initiate(&Psk::derive(b"worker's")).expect("initiate");
        assert!(matches!(respond(&Psk::derive(b"master's"), &first), Err(ChannelError::Handshake)));
        // ... and a worker refuses an impostor's answer (one that answers with its own PSK).
        let (init, first) = initiate(&Psk::derive(b"worker's")).expect("initiate");
        let mut impostor = builder(&Psk::derive(b"impostor")).unwrap().build_responder().unwrap();
        let _ = impostor.read_message(&first, &mut [0; 64]);
        let mut answer = vec![0; HANDSHAKE_LEN];
        let n = impostor.write_message(&[], &mut answer).unwrap_or(0);
        answer.truncate(n);
        assert!(matches!(init.finish(&answer), Err(ChannelError::Handshake)));
    }

    #[test]
    fn any_flipped_byte_of_a_handshake_or_record_is_refused() {
        let (init, first) = initiate(&Psk::derive(b"s")).expect("initiate");
        for i in 0..first.len() {
            let mut bad = first.clone();
            bad[i] ^= 0x01;
            assert!(respond(&Psk::derive(b"s"), &bad).is_err(), "first message byte {i}");
        }
        let (answer, m) = respond(&Psk::derive(b"s"), &first).expect("respond");
        let w = init.finish(&answer).expect("finish");
        let ((mut ws, _), (_, mut mo)) = (w.split(None), m.split(None));
        let mut wire = BytesMut::new();
        ws.seal(b"radiance of frame 7, set 3", &mut wire).expect("seal");
        let record = &wire[RECORD_PREFIX..];
        for i in 0..record.len() {
            let mut bad = record.to_vec();
            bad[i] ^= 0x80;
            let mut out = BytesMut::new();
            let err = mo.open(&bad, &mut out).expect_err("flipped record opened");
            assert!(matches!(err, ChannelError::Decrypt), "byte {i}: {err}");
            assert!(out.is_empty(), "plaintext of a refused record was kept");
            mo.0.records -= 1; // try the next flip at the same position in the stream
        }
    }

    #[test]
    fn a_replayed_or_reordered_record_is_refused() {
        let (w, m) = pair(b"s", b"s").expect("handshake");
        let ((mut ws, _), (_, mut mo)) = (w.split(None), m.split(None));
        let (mut a, mut b) = (BytesMut::new(), BytesMut::new());
        ws.seal(b"first", &mut a).expect("seal");
        ws.seal(b"second", &mut b).expect("seal");
        let mut out = BytesMut::new();
        assert!(mo.open(&b[RECORD_PREFIX..], &mut out).is_err(), "reordered");
        let (w, m) = pair(b"s", b"s").expect("handshake");
        let ((mut ws, _), (_, mut mo)) = (w.split(None), m.split(None));
        let mut a = BytesMut::new();
        ws.seal(b"first", &mut a).expect("seal");
        mo.open(&a[RECORD_PREFIX..], &mut out).expect("in order");
        assert!(mo.open(&a[RECORD_PREFIX..], &mut out).is_err(), "replayed");
    }

    #[test]
    fn a_recorded_session_does_not_decrypt_under_a_replayed_handshake() {
        let psk = Psk::derive(b"s");
        let (init, first) = initiate(&psk).expect("initiate");
        let (answer, m1) = respond(&psk, &first).expect("respond");
        let (mut ws, _) = init.finish(&answer).expect("finish").split(None);
        let mut recorded = BytesMut::new();
        ws.seal(b"Hello", &mut recorded).expect("seal");
        drop(m1);
        // The attacker replays the worker's first message: the master answers with a
        // fresh ephemeral, and the recorded record no longer opens.
        let (_, m2) = respond(&psk, &first).expect("a replayed first message is answered");
        let (_, mut mo) = m2.split(None);
        let err = mo.open(&recorded[RECORD_PREFIX..], &mut BytesMut::new()).expect_err("opened");
        assert!(matches!(err, ChannelError::Decrypt));
    }

    #[test]
    fn record_lengths_outside_the_bounds_are_refused() {
        for len in [0, 1, TAG_LEN, MAX_RECORD + 1] {
            assert!(matches!(check_record_len(len), Err(ChannelError::RecordLen { .. })), "{len}");
        }
        assert!(check_record_len(TAG_LEN + 1).is_ok() && check_record_len(MAX_RECORD).is_ok());
    }

    #[test]
    fn the_psk_depends_on_every_byte_of_the_secret_and_is_not_it() {
        let a = Psk::derive(b"correct horse battery staple");
        assert_ne!(a.0, Psk::derive(b"correct horse battery stapLe").0);
        assert_ne!(&a.0[..], &b"correct horse battery staple"[..28]);
        assert_eq!(format!("{a:?}"), "Psk(..)");
    }
}
