//! The wire between master and workers: what travels and how it is framed, checked and
//! counted. Both sides use these modules; none of them knows an actor.
//!
//! [`protocol`] (every message, the phases and [`protocol::ConnId`]), [`codec`]
//! (length-prefixed, bounded MessagePack), [`auth`] (HMAC challenge, the secret file),
//! [`channel`] (the encrypted channel: Noise handshake and records), [`channel_codec`]
//! (plain frames until the channel's keys arrive, records after), [`integrity`]
//! (per-result checksums), [`rejection`] (why a connection is ended), [`packing`] (RGB9E5
//! radiance), [`counted_io`] (byte counters around a socket).

pub mod auth;
pub mod channel;
pub mod channel_codec;
pub mod codec;
pub mod counted_io;
pub mod integrity;
pub mod packing;
pub mod protocol;
pub mod rejection;
