//! Length-prefixed MessagePack framing for the wire protocol (see `protocol.rs`).
//!
//! One frame is a 4-byte big-endian length `n` followed by `n` bytes of positional
//! MessagePack (rmp-serde). The length is checked (`0 < n <= MAX_FRAME_LEN`) before a
//! single byte of the body is buffered, so a hostile peer cannot make us allocate
//! (STYLE.md item 10). The codec is generic over what it reads and what it writes, so
//! the master uses [`MasterCodec`] and the worker [`WorkerCodec`] over the same code.

use std::io;
use std::marker::PhantomData;

use bytes::{Buf, BufMut, BytesMut};
use serde::de::DeserializeOwned;
use serde::Serialize;
use thiserror::Error;
use tokio_util::codec::{Decoder, Encoder};

use crate::wire::channel::ChannelError;
use crate::wire::protocol::{MasterMsg, WorkerMsg, MAX_FRAME_LEN};

/// Bytes of the length prefix.
pub const LEN_PREFIX: usize = 4;

/// Everything that can be wrong with the byte stream of a connection.
#[derive(Debug, Error)]
pub enum ProtocolError {
    #[error("i/o error: {0}")]
    Io(#[from] io::Error),
    #[error("empty frame (length prefix 0)")]
    EmptyFrame,
    #[error("frame of {len} bytes exceeds the maximum of {max} bytes")]
    FrameTooLong { len: usize, max: usize },
    #[error("undecodable message: {0}")]
    Decode(#[from] rmp_serde::decode::Error),
    #[error("unencodable message: {0}")]
    Encode(#[from] rmp_serde::encode::Error),
    #[error(transparent)]
    Channel(#[from] ChannelError),
}

/// Reads frames of `In`, writes frames of `Out`.
pub struct FrameCodec<In, Out> {
    max_len: usize,
    _types: PhantomData<fn(Out) -> In>,
}

/// The master's side: reads [`WorkerMsg`], writes [`MasterMsg`].
pub type MasterCodec = FrameCodec<WorkerMsg, MasterMsg>;

/// The worker's side: reads [`MasterMsg`], writes [`WorkerMsg`].
pub type WorkerCodec = FrameCodec<MasterMsg, WorkerMsg>;

impl<In, Out> FrameCodec<In, Out> {
    /// A codec with the protocol's [`MAX_FRAME_LEN`].
    pub fn new() -> Self {
        Self::with_max_len(MAX_FRAME_LEN)
    }

    /// A codec with a smaller (or, for tests, different) frame limit.
    pub fn with_max_len(max_len: usize) -> Self {
        Self { max_len, _types: PhantomData }
    }

    /// The largest frame body this codec accepts.
    pub fn max_len(&self) -> usize {
        self.max_len
    }
}

impl<In, Out> Default for FrameCodec<In, Out> {
    fn default() -> Self {
        Self::new()
    }
}

impl<In, Out> Clone for FrameCodec<In, Out> {
    fn clone(&self) -> Self {
        Self::with_max_len(self.max_len)
    }
}

impl<In: DeserializeOwned, Out> Decoder for FrameCodec<In, Out> {
    type Item = In;
    type Error = ProtocolError;

    fn decode(&mut self, src: &mut BytesMut) -> Result<Option<In>, ProtocolError> {
        if src.len() < LEN_PREFIX {
            return Ok(None);
        }
        let mut prefix = [0u8; LEN_PREFIX];
        prefix.copy_from_slice(&src[..LEN_PREFIX]);
        let len = u32::from_be_bytes(prefix) as usize;
        // Validate before reserving anything for the body.
        if len == 0 {
            return Err(ProtocolError::EmptyFrame);
        }
        if len > self.max_len {
            return Err(ProtocolError::FrameTooLong { len, max: self.max_len });
        }
        if src.len() < LEN_PREFIX + len {
            src.reserve(LEN_PREFIX + len - src.len());
            return Ok(None);
        }
        src.advance(LEN_PREFIX);
        let body = src.split_to(len);
        Ok(Some(rmp_serde::from_slice(&body)?))
    }
}

impl<In, Out: Serialize> Encoder<Out> for FrameCodec<In, Out> {
    type Error = ProtocolError;

    fn encode(&mut self, msg: Out, dst: &mut BytesMut) -> Result<(), ProtocolError> {
        encode_into(&msg, self.max_len, dst)
    }
}

impl<In, Out: Serialize> Encoder<&Out> for FrameCodec<In, Out> {
    type Error = ProtocolError;

    fn encode(&mut self, msg: &Out, dst: &mut BytesMut) -> Result<(), ProtocolError> {
        encode_into(msg, self.max_len, dst)
    }
}

/// Appends one frame to `dst`; on error `dst` is left as it was.
pub(crate) fn encode_into<T: Serialize>(
    msg: &T,
    max_len: usize,
    dst: &mut BytesMut,
) -> Result<(), ProtocolError> {
    let start = dst.len();
    dst.put_u32(0); // patched below, once the body length is known
    let mut writer = dst.writer();
    let written = rmp_serde::encode::write(&mut writer, msg);
    let dst = writer.into_inner();
    if let Err(err) = written {
        dst.truncate(start);
        return Err(err.into());
    }
    let len = dst.len() - start - LEN_PREFIX;
    if len == 0 || len > max_len {
        dst.truncate(start);
        return Err(if len == 0 {
            ProtocolError::EmptyFrame
        } else {
            ProtocolError::FrameTooLong { len, max: max_len }
        });
    }
    dst[start..start + LEN_PREFIX].copy_from_slice(&(len as u32).to_be_bytes());
    Ok(())
}

/// Encodes one message as a complete frame (prefix included); for tests and tools.
pub fn to_frame<T: Serialize>(msg: &T) -> Result<Vec<u8>, ProtocolError> {
    let mut buf = BytesMut::new();
    encode_into(msg, MAX_FRAME_LEN, &mut buf)?;
    Ok(buf.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::integrity::TAG_LEN;
    use crate::wire::protocol::{JobResult, PackedRadiance, Partition, SetsConfig};

    fn roundtrip_master(msg: MasterMsg) -> MasterMsg {
        let mut out = WorkerCodec::new();
        let mut buf = BytesMut::new();
        MasterCodec::new().encode(&msg, &mut buf).expect("encode");
        out.decode(&mut buf).expect("decode").expect("one whole frame")
    }

    #[test]
    fn frames_roundtrip_and_split_reads_wait_for_more() {
        let msg = WorkerMsg::Result(JobResult {
            frame: 7,
            set: 3,
            state_version: 2,
            radiance: PackedRadiance::Rgb9e5(vec![1, 2, 3]),
            render_us: 99,
            tag: Some([7; TAG_LEN]),
        });
        let bytes = to_frame(&msg).expect("encode");
        let mut codec = MasterCodec::new();
        let mut buf = BytesMut::new();
        for (i, b) in bytes.iter().enumerate() {
            buf.put_u8(*b);
            let got = codec.decode(&mut buf).expect("decode");
            if i + 1 < bytes.len() {
                assert!(got.is_none(), "decoded before the frame was complete");
            } else {
                assert_eq!(got, Some(msg.clone()));
            }
        }
        assert!(buf.is_empty());
    }

    #[test]
    fn zero_length_is_rejected() {
        let mut buf = BytesMut::from(&[0u8, 0, 0, 0, 1][..]);
        let err = MasterCodec::new().decode(&mut buf).unwrap_err();
        assert!(matches!(err, ProtocolError::EmptyFrame), "{err}");
    }

    #[test]
    fn oversized_length_is_rejected_before_allocating() {
        let len = (MAX_FRAME_LEN as u32 + 1).to_be_bytes();
        let mut buf = BytesMut::from(&len[..]);
        let cap = buf.capacity();
        let err = MasterCodec::new().decode(&mut buf).unwrap_err();
        assert!(matches!(err, ProtocolError::FrameTooLong { len, .. } if len == MAX_FRAME_LEN + 1));
        assert_eq!(buf.capacity(), cap, "buffer grew for a frame that was refused");
    }

    #[test]
    fn garbage_body_is_a_decode_error() {
        let mut buf = BytesMut::from(&[0u8, 0, 0, 3, 0xc1, 0xc1, 0xc1][..]);
        let err = MasterCodec::new().decode(&mut buf).unwrap_err();
        assert!(matches!(err, ProtocolError::Decode(_)), "{err}");
    }

    #[test]
    fn encoder_refuses_frames_over_its_limit() {
        let mut codec = FrameCodec::<WorkerMsg, MasterMsg>::with_max_len(16);
        let mut buf = BytesMut::from(&b"keep"[..]);
        let msg = MasterMsg::Rejected { reason: "x".repeat(64) };
        let err = codec.encode(&msg, &mut buf).unwrap_err();
        assert!(matches!(err, ProtocolError::FrameTooLong { .. }), "{err}");
        assert_eq!(&buf[..], b"keep", "a refused frame left bytes behind");
    }

    #[test]
    fn radiance_travels_as_four_bytes_per_pixel_and_ragged_bytes_are_refused() {
        let result = |n: usize| {
            WorkerMsg::Result(JobResult {
                frame: 1,
                set: 2,
                state_version: 3,
                radiance: PackedRadiance::Rgb9e5(vec![0xdead_beef; n]),
                render_us: 4,
                tag: Some([0; TAG_LEN]),
            })
        };
        let (small, big) =
            (to_frame(&result(0)).expect("encode"), to_frame(&result(1000)).expect("encode"));
        assert_eq!(
            big.len() - small.len(),
            4000 + 1,
            "4 bytes per pixel; a bin16 header is one byte longer"
        );
        // Corrupt the bin length so that it is not whole words: a decode error, not a panic.
        let mut bytes = to_frame(&result(1)).expect("encode");
        let bin = bytes.windows(2).position(|w| w == [0xc4, 4]).expect("bin8 header");
        bytes[bin + 1] = 3;
        bytes.remove(bin + 2);
        let len = (bytes.len() - LEN_PREFIX) as u32;
        bytes[..LEN_PREFIX].copy_from_slice(&len.to_be_bytes());
        let err = MasterCodec::new().decode(&mut BytesMut::from(&bytes[..])).unwrap_err();
        assert!(err.to_string().contains("whole u32 words"), "{err}");
    }

    #[test]
    fn master_messages_roundtrip() {
        let msg = MasterMsg::Welcome {
            worker_id: 5,
            sets: SetsConfig { sets: 64, partition: Partition::QuasiRandom },
            assets: vec![],
        };
        assert_eq!(roundtrip_master(msg.clone()), msg);
    }
}
