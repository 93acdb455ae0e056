//! Why the master ends a connection: a typed [`Rejection`] whose [`RejectionKind`] is what
//! the fault counters count and whose message is what the worker reads.
//!
//! The kind is decided where the rejection is made, never recovered from the sentence, so
//! rewording a message cannot move it to another counter. On the wire a rejection stays
//! `MasterMsg::Rejected { reason }` (the sentence only): it is the one message a worker
//! of any protocol version must be able to decode, since a version mismatch is told
//! with it. A worker tells a final rejection (version, secret) from one worth retrying by
//! [`is_final`], which checks the same prefixes the messages are built from.

use thiserror::Error;

use crate::wire::protocol::{FrameNo, SetNo};

/// How every version-mismatch message starts.
const VERSION_PREFIX: &str = "protocol version mismatch";
/// How every authentication message starts.
const AUTH_PREFIX: &str = "authentication failed";

/// The kind of a rejection, as the fault counters name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum RejectionKind {
    Corrupt,
    Version,
    Auth,
    EmptyFrame,
    OversizedFrame,
    BadFrame,
    /// A record of the encrypted channel failed authentication (altered on the way, or
    /// not from the peer that made the handshake).
    Decrypt,
    UnknownResult,
    PixelCount,
    StateVersion,
    SetRange,
    Asset,
    Timeout,
    Phase,
    /// Refused at the connection cap.
    Full,
    /// Refused for a while: the worker's connections kept failing (per-peer back-off).
    BackedOff,
    /// A broken stream (no `Rejected` sent: nobody would read it).
    Io,
    /// Anything else: a bad name, an unreadable asset, an internal error.
    Other,
}

impl RejectionKind {
    /// The counter's name (fault reports, `--stats`).
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Corrupt => "corrupt",
            Self::Version => "version",
            Self::Auth => "auth",
            Self::EmptyFrame => "empty_frame",
            Self::OversizedFrame => "oversized_frame",
            Self::BadFrame => "bad_frame",
            Self::Decrypt => "decrypt",
            Self::UnknownResult => "unknown_result",
            Self::PixelCount => "pixel_count",
            Self::StateVersion => "state_version",
            Self::SetRange => "set_range",
            Self::Asset => "asset",
            Self::Timeout => "timeout",
            Self::Phase => "phase",
            Self::Full => "full",
            Self::BackedOff => "backed_off",
            Self::Io => "io",
            Self::Other => "other",
        }
    }
}

/// Why a connection was ended; `Display` is the sentence the worker receives.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum Rejection {
    #[error("{VERSION_PREFIX}: worker speaks {worker}, master speaks {master}")]
    Version { worker: u32, master: u32 },
    #[error("worker name must be 1 to {max} bytes")]
    Name { max: usize },
    #[error("{AUTH_PREFIX}: the master requires a shared secret (--secret-file) and an encrypted connection; the worker sent none")]
    NoSecret,
    #[error("{AUTH_PREFIX}: wrong shared secret")]
    WrongSecret,
    #[error("{AUTH_PREFIX}: the worker has a shared secret and asks for an encrypted connection, but this master has none and does not encrypt (start it with the same --secret-file, or the worker without one)")]
    NotEncrypting,
    #[error("unexpected {message} during the {phase} phase")]
    Phase { message: &'static str, phase: &'static str },
    #[error("unexpected {message} while the worker is paused")]
    WhilePaused { message: &'static str },
    #[error("unexpected Resumed while the worker is not paused")]
    NotPaused,
    #[error("result for frame {frame} set {set} failed its integrity check (payload corrupted or forged)")]
    Corrupt { frame: FrameNo, set: SetNo },
    #[error("result for set {set}, but there are only {sets} sets")]
    SetRange { set: SetNo, sets: u32 },
    #[error("result for frame {frame} set {set} names state version {got}, the job named {job}")]
    StateVersion { frame: FrameNo, set: SetNo, got: u64, job: u64 },
    #[error("result for frame {frame} set {set} holds {got} pixels, the set has {set_len}")]
    PixelCount { frame: FrameNo, set: SetNo, got: usize, set_len: usize },
    #[error("result for frame {frame} set {set}, which was not given to this worker")]
    UnknownResult { frame: FrameNo, set: SetNo },
    #[error("asset {hash} is not in the manifest")]
    NotInManifest { hash: String },
    #[error("the master cannot read asset {path}: {cause}")]
    AssetUnreadable { path: String, cause: String },
    #[error("no message from the worker for {secs:.1} s")]
    Timeout { secs: f32 },
    #[error("bad frame: {cause}")]
    BadFrame { kind: RejectionKind, cause: String },
    #[error("the master is full ({max} connections)")]
    Full { max: usize },
    #[error("internal error in the master; reconnect")]
    Internal,
    #[error("worker {worker}: {failures} failed connections within {window_s:.0} s; refused for now, retry in {retry_in_s:.0} s")]
    BackedOff { worker: String, failures: usize, window_s: f32, retry_in_s: f32 },
}

impl Rejection {
    /// The counter this rejection is counted under.
    pub fn kind(&self) -> RejectionKind {
        match self {
            Self::Version { .. } => RejectionKind::Version,
            Self::NoSecret | Self::WrongSecret | Self::NotEncrypting => RejectionKind::Auth,
            Self::Phase { .. } | Self::WhilePaused { .. } | Self::NotPaused => RejectionKind::Phase,
            Self::Corrupt { .. } => RejectionKind::Corrupt,
            Self::SetRange { .. } => RejectionKind::SetRange,
            Self::StateVersion { .. } => RejectionKind::StateVersion,
            Self::PixelCount { .. } => RejectionKind::PixelCount,
            Self::UnknownResult { .. } => RejectionKind::UnknownResult,
            Self::NotInManifest { .. } => RejectionKind::Asset,
            Self::Timeout { .. } => RejectionKind::Timeout,
            Self::BadFrame { kind, .. } => *kind,
            Self::Full { .. } => RejectionKind::Full,
            Self::BackedOff { .. } => RejectionKind::BackedOff,
            Self::Name { .. } | Self::AssetUnreadable { .. } | Self::Internal => {
                RejectionKind::Other
            }
        }
    }
}

/// True for a rejection that says "never", not "later": the protocol version or the
/// secret is wrong, and reconnecting cannot change it.
pub fn is_final(reason: &str) -> bool {
    reason.starts_with(VERSION_PREFIX) || reason.starts_with(AUTH_PREFIX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kind_is_the_variant_not_the_sentence() {
        assert_eq!(Rejection::WrongSecret.kind(), RejectionKind::Auth);
        assert_eq!(Rejection::NotPaused.kind(), RejectionKind::Phase);
        let empty = Rejection::BadFrame { kind: RejectionKind::EmptyFrame, cause: "x".into() };
        assert_eq!(empty.kind().as_str(), "empty_frame");
        assert_eq!(Rejection::Internal.kind().as_str(), "other");
    }

    #[test]
    fn only_version_and_secret_rejections_are_final() {
        assert!(is_final(&Rejection::Version { worker: 1, master: 2 }.to_string()));
        assert!(is_final(&Rejection::NoSecret.to_string()));
        assert!(is_final(&Rejection::WrongSecret.to_string()));
        assert!(is_final(&Rejection::NotEncrypting.to_string()));
        for retry in [
            Rejection::Timeout { secs: 1.0 },
            Rejection::Internal,
            Rejection::Full { max: 3 },
            Rejection::BadFrame { kind: RejectionKind::BadFrame, cause: "x".into() },
        ] {
            assert!(!is_final(&retry.to_string()), "{retry}");
        }
    }
}
