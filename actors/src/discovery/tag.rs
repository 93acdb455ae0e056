//! Announcements that a host without the shared secret cannot forge or replay.
//!
//! A master with a secret appends a keyed BLAKE3 tag over the whole datagram (magic,
//! format and body). The key is derived from the secret with BLAKE3's key derivation
//! under its own context string ([`KEY_CONTEXT`]), so the announcement key is never the
//! secret and never another key gridlight derives from it. The body carries the sender's
//! wall clock (`sent_ms`), a random id of the master process (`boot`) and a counter
//! (`seq`): a worker with the secret accepts an announcement only when its tag verifies,
//! its clock is within [`MAX_CLOCK_SKEW`] of the worker's, and its counter is newer than
//! the last one heard from that master process ([`Verifier`]). A captured announcement
//! can thus be replayed only to a worker that never heard the original, only within the
//! skew window, and it names the genuine master anyway; the connection's own handshake
//! then proves the master has the secret.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use super::{Announcement, Received};

/// The key derivation's context: unique to this use of the secret (BLAKE3 `derive_key`).
pub const KEY_CONTEXT: &str = "gridlight 2026-12-06 LAN announcement tag v1";
/// Bytes of the tag appended to an authenticated announcement.
pub const TAG_LEN: usize = 32;
/// Largest difference between an announcement's clock and the listener's that is
/// accepted: LAN hosts that keep time by NTP differ by far less, and a replay is confined
/// to this window.
pub const MAX_CLOCK_SKEW: Duration = Duration::from_secs(30);

/// The announcement key derived from a shared secret.
#[derive(Clone)]
pub struct AnnounceKey([u8; 32]);

impl std::fmt::Debug for AnnounceKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("AnnounceKey(..)")
    }
}

impl AnnounceKey {
    /// The key for `secret` (never the secret itself).
    pub fn derive(secret: &[u8]) -> Self {
        Self(blake3::derive_key(KEY_CONTEXT, secret))
    }

    /// The tag of the signed bytes of a datagram.
    pub fn tag(&self, signed: &[u8]) -> [u8; TAG_LEN] {
        *blake3::keyed_hash(&self.0, signed).as_bytes()
    }

    /// True when `tag` is the tag of `signed`; compares in constant time.
    fn verify(&self, signed: &[u8], tag: &[u8; TAG_LEN]) -> bool {
        blake3::keyed_hash(&self.0, signed) == blake3::Hash::from(*tag)
    }
}

/// Why an announcement was ignored by a worker with a secret.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Unverified {
    #[error(
        "it carries no tag (the master has no secret, or the sender is not a gridlight master)"
    )]
    Untagged,
    #[error("its tag does not verify (a different secret, or forged)")]
    BadTag,
    #[error("its clock is {off_s:.0} s from this host's (more than {max_s} s: stale or replayed)", max_s = MAX_CLOCK_SKEW.as_secs())]
    Stale { off_s: f64 },
    #[error(
        "its counter {seq} is not newer than {last}, already heard from that master (replayed)"
    )]
    Replayed { seq: u64, last: u64 },
}

impl Unverified {
    /// A short name of the kind, for counts in logs and errors.
    pub fn kind(&self) -> &'static str {
        match self {
            Self::Untagged => "untagged",
            Self::BadTag => "bad tag",
            Self::Stale { .. } => "stale",
            Self::Replayed { .. } => "replayed",
        }
    }
}

/// A listener's check of announcements against its secret, with the last counter heard
/// per master process. Only verified announcements add entries, so a forger cannot fill it.
#[derive(Debug)]
pub struct Verifier {
    key: AnnounceKey,
    last: HashMap<(String, SocketAddr, u64), u64>,
}

impl Verifier {
    pub fn new(secret: &[u8]) -> Self {
        Self { key: AnnounceKey::derive(secret), last: HashMap::new() }
    }

    /// Accepts `r` heard at `now_ms` (milliseconds since the Unix epoch) or says why not.
    pub fn check(&mut self, r: &Received<'_>, now_ms: u64) -> Result<(), Unverified> {
        let tag = r.tag.ok_or(Unverified::Untagged)?;
        if !self.key.verify(r.signed, &tag) {
            return Err(Unverified::BadTag);
        }
        let a = &r.announcement;
        let off_ms = now_ms.abs_diff(a.sent_ms);
        if off_ms > MAX_CLOCK_SKEW.as_millis() as u64 {
            return Err(Unverified::Stale { off_s: off_ms as f64 / 1000.0 });
        }
        let last = self.last.entry((a.name.clone(), a.listen, a.boot)).or_insert(0);
        if a.seq <= *last {
            return Err(Unverified::Replayed { seq: a.seq, last: *last });
        }
        *last = a.seq;
        Ok(())
    }
}

/// This host's clock in milliseconds since the Unix epoch (0 before it).
pub fn now_ms() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64)
}

/// A master's announcements as they go out: the counter advances and the clock is read
/// for each one.
#[derive(Debug)]
pub struct Sender {
    announcement: Announcement,
    key: Option<AnnounceKey>,
}

impl Sender {
    /// Announces `announcement`, tagged when `secret` is given; `boot` is drawn here.
    pub fn new(mut announcement: Announcement, secret: Option<&[u8]>) -> Self {
        announcement.boot = rand::random();
        announcement.seq = 0;
        Self { announcement, key: secret.map(AnnounceKey::derive) }
    }

    /// The next datagram, stamped with `now_ms`.
    pub fn next(&mut self, now_ms: u64) -> Result<Vec<u8>, super::DiscoveryError> {
        self.announcement.seq += 1;
        self.announcement.sent_ms = now_ms;
        self.announcement.encode(self.key.as_ref())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOW: u64 = 1_800_000_000_000;

    fn sender(secret: Option<&[u8]>) -> Sender {
        let a = Announcement::new(6, "10.0.0.5:7840".parse().unwrap(), "lab", "box", true);
        Sender::new(a, secret)
    }

    fn check(v: &mut Verifier, bytes: &[u8], now: u64) -> Result<(), Unverified> {
        v.check(&Announcement::decode(bytes).unwrap(), now)
    }

    #[test]
    fn the_key_is_derived_not_the_secret_and_differs_per_secret() {
        let k = AnnounceKey::derive(b"s3cret");
        assert_ne!(k.0[..6], b"s3cret"[..]);
        assert_ne!(k.0, AnnounceKey::derive(b"s3cret2").0);
        assert_ne!(k.0, *blake3::hash(b"s3cret").as_bytes(), "a KDF with a context, not a hash");
        assert_eq!(format!("{k:?}"), "AnnounceKey(..)", "never printed");
    }

    #[test]
    fn the_masters_announcements_verify_one_after_another() {
        let mut s = sender(Some(b"s3cret"));
        let mut v = Verifier::new(b"s3cret");
        for i in 0..3 {
            assert_eq!(check(&mut v, &s.next(NOW + i * 300).unwrap(), NOW + i * 300), Ok(()));
        }
    }

    #[test]
    fn no_secret_a_wrong_secret_or_a_changed_byte_do_not_verify() {
        let mut v = Verifier::new(b"s3cret");
        let untagged = sender(None).next(NOW).unwrap();
        assert_eq!(check(&mut v, &untagged, NOW), Err(Unverified::Untagged));
        let wrong = sender(Some(b"guess")).next(NOW).unwrap();
        assert_eq!(check(&mut v, &wrong, NOW), Err(Unverified::BadTag));
        // A forger who keeps a genuine tag but changes where the master listens.
        let mut s = sender(Some(b"s3cret"));
        let good = s.next(NOW).unwrap();
        let mut a = Announcement::decode(&good).unwrap().announcement;
        a.listen = "10.6.6.6:7840".parse().unwrap();
        let mut forged = a.encode(None).unwrap();
        forged.extend_from_slice(&good[good.len() - TAG_LEN..]);
        assert_eq!(check(&mut v, &forged, NOW), Err(Unverified::BadTag));
    }

    #[test]
    fn a_replayed_or_stale_announcement_is_refused() {
        let mut s = sender(Some(b"s3cret"));
        let mut v = Verifier::new(b"s3cret");
        let first = s.next(NOW).unwrap();
        let second = s.next(NOW + 300).unwrap();
        assert_eq!(check(&mut v, &second, NOW + 300), Ok(()));
        assert_eq!(
            check(&mut v, &second, NOW + 400),
            Err(Unverified::Replayed { seq: 2, last: 2 })
        );
        assert_eq!(check(&mut v, &first, NOW + 400), Err(Unverified::Replayed { seq: 1, last: 2 }));
        // Heard by a worker that never heard it, but long after it was sent (either way).
        let mut fresh = Verifier::new(b"s3cret");
        let late = NOW + 10 * 60 * 1000;
        assert!(matches!(check(&mut fresh, &first, late), Err(Unverified::Stale { .. })));
        assert!(matches!(check(&mut fresh, &first, NOW - 31_000), Err(Unverified::Stale { .. })));
        assert_eq!(check(&mut fresh, &first, NOW + 29_000), Ok(()), "within the skew");
        // A restarted master (a new boot id) starts its counter again.
        let restarted = sender(Some(b"s3cret")).next(NOW + 500).unwrap();
        assert_eq!(check(&mut v, &restarted, NOW + 500), Ok(()));
    }
}
