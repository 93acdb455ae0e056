//! Fuzzing the frame decoder with proptest (run on every `cargo test`): arbitrary
//! bytes, and valid frames with bytes flipped or cut, never panic either side's
//! decoder, never make it buffer more than the frame limit, and every error is a
//! typed `ProtocolError`. The same holds on an encrypted channel, both for what an
//! outsider can send (arbitrary records, altered records) and for what the decoder meets
//! *after* decryption: arbitrary plaintext sealed under the channel's own keys, as an
//! authenticated but malicious worker would send it. Message round-trips are covered by
//! `actors/tests/codec_roundtrip.rs`; RGB9E5, the only radiance on the wire, cannot
//! carry a negative or non-finite value, which the last property proves.

use bytes::BytesMut;
use gridlight_actors::channel::{initiate, respond, Psk, Sealer};
use gridlight_actors::channel_codec::{loopback_pair, KeySlot, MasterChannelCodec};
use gridlight_actors::codec::{to_frame, MasterCodec, ProtocolError, WorkerCodec, LEN_PREFIX};
use gridlight_actors::packing::decode_rgb9e5;
use gridlight_actors::protocol::{JobResult, PackedRadiance, WorkerMsg, MAX_FRAME_LEN};
use proptest::prelude::*;
use tokio_util::codec::{Decoder, Encoder};

/// Feeds `bytes` to a decoder in pieces of `step`, until an error or the end; checks
/// that the buffer never grows past one maximal frame.
fn feed<D: Decoder>(mut codec: D, bytes: &[u8], step: usize) -> Result<usize, D::Error> {
    let mut buf = BytesMut::new();
    let mut decoded = 0;
    for piece in bytes.chunks(step.max(1)) {
        buf.extend_from_slice(piece);
        while let Some(_msg) = codec.decode(&mut buf)? {
            decoded += 1;
        }
        assert!(buf.capacity() <= 2 * (LEN_PREFIX + MAX_FRAME_LEN), "decoder buffered too much");
    }
    Ok(decoded)
}

fn a_result() -> WorkerMsg {
    WorkerMsg::Result(JobResult {
        frame: 9,
        set: 2,
        state_version: 1,
        radiance: PackedRadiance::Rgb9e5((0..64).collect()),
        render_us: 5,
        tag: Some([0x5a; gridlight_actors::integrity::TAG_LEN]),
    })
}

/// A master's codec at the end of an encrypted channel, and the worker's sending half
/// of it: whatever the sealer seals, the codec opens and decodes.
fn channel() -> (Sealer, MasterChannelCodec) {
    let psk = Psk::derive(b"fuzz");
    let (init, first) = initiate(&psk).expect("initiate");
    let (answer, master) = respond(&psk, &first).expect("respond");
    let (sealer, _) = init.finish(&answer).expect("finish").split(None);
    let codec = MasterChannelCodec::new(KeySlot::new());
    codec.slot().install(master, None);
    (sealer, codec)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic_either_decoder(
        bytes in prop::collection::vec(any::<u8>(), 0..2048),
        step in 1usize..64,
    ) {
        let _ = feed(MasterCodec::new(), &bytes, step);
        let _ = feed(WorkerCodec::new(), &bytes, step);
    }

    #[test]
    fn a_small_length_with_an_arbitrary_body_never_panics(
        body in prop::collection::vec(any::<u8>(), 1..512),
    ) {
        let mut bytes = (body.len() as u32).to_be_bytes().to_vec();
        bytes.extend_from_slice(&body);
        // Either a message (random bytes may spell a valid one) or a typed error.
        let _ = feed(MasterCodec::new(), &bytes, bytes.len());
    }

    #[test]
    fn a_valid_frame_with_flipped_or_cut_bytes_never_panics(
        flips in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 0..8),
        cut in any::<prop::sample::Index>(),
    ) {
        let mut bytes = to_frame(&a_result()).expect("encode");
        for (at, x) in flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x;
        }
        let keep = cut.index(bytes.len() + 1);
        if let Ok(n) = feed(MasterCodec::new(), &bytes[..keep], 7) {
            prop_assert!(n <= 1);
        }
    }

    #[test]
    fn arbitrary_bytes_never_panic_an_encrypted_decoder(
        bytes in prop::collection::vec(any::<u8>(), 0..4096),
        step in 1usize..64,
    ) {
        let (_, codec) = channel();
        // Records that do not open are typed errors, never messages.
        match feed(codec, &bytes, step) {
            Ok(n) => prop_assert_eq!(n, 0),
            Err(e) => prop_assert!(matches!(e, ProtocolError::Channel(_)), "{}", e),
        }
    }

    #[test]
    fn arbitrary_plaintext_under_the_channels_keys_never_panics_the_decoder(
        plain in prop::collection::vec(any::<u8>(), 1..2048),
        frame_len in prop::option::of(1u32..(MAX_FRAME_LEN as u32 + 64)),
        step in 1usize..512,
    ) {
        // What an authenticated but malicious worker can send: any bytes, or a frame
        // prefix of any length before them, sealed correctly.
        let (mut sealer, codec) = channel();
        let mut stream = Vec::new();
        if let Some(n) = frame_len {
            stream.extend_from_slice(&n.to_be_bytes());
        }
        stream.extend_from_slice(&plain);
        let mut wire = BytesMut::new();
        sealer.seal(&stream, &mut wire).expect("seal");
        // Either messages (random bytes may spell a valid one) or a typed error.
        let _ = feed(codec, &wire, step);
    }

    #[test]
    fn an_encrypted_frame_with_flipped_or_cut_bytes_never_decodes_to_another_message(
        flips in prop::collection::vec((any::<prop::sample::Index>(), 1u8..=255), 1..8),
        cut in any::<prop::sample::Index>(),
    ) {
        let (mut worker, master) = loopback_pair(&Psk::derive(b"fuzz")).expect("handshake");
        let mut bytes = BytesMut::new();
        worker.encode(&a_result(), &mut bytes).expect("encode");
        for (at, x) in flips {
            let i = at.index(bytes.len());
            bytes[i] ^= x;
        }
        let keep = cut.index(bytes.len() + 1);
        let mut buf = BytesMut::new();
        let mut codec = master;
        for b in &bytes[..keep] {
            buf.extend_from_slice(&[*b]);
            match codec.decode(&mut buf) {
                Ok(None) => {}
                Ok(Some(m)) => prop_assert!(false, "an altered record decoded to {:?}", m),
                Err(e) => {
                    prop_assert!(matches!(e, ProtocolError::Channel(_)), "{}", e);
                    break;
                }
            }
        }
    }

    #[test]
    fn every_rgb9e5_word_is_finite_and_non_negative(word in any::<u32>()) {
        let v = decode_rgb9e5(word);
        prop_assert!(v.is_finite() && v.min_element() >= 0.0, "{word:#x} decodes to {v}");
    }
}

#[test]
fn an_intact_frame_decodes_to_the_same_message() {
    let bytes = to_frame(&a_result()).expect("encode");
    let mut buf = BytesMut::from(&bytes[..]);
    assert_eq!(MasterCodec::new().decode(&mut buf).expect("decode"), Some(a_result()));
}
