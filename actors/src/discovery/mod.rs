//! Zero-configuration discovery: what a master announces on the LAN, on the wire.
//!
//! A master sends one UDP datagram every [`ANNOUNCE_INTERVAL`] to a broadcast address on
//! [`DISCOVERY_PORT`] (docs/design.md, decision 10); `gridlight worker` without `--master`
//! listens there and joins the master it hears. A datagram is the 4 bytes
//! [`MAGIC`], one byte [`ANNOUNCE_FORMAT`], then an [`Announcement`] as MessagePack
//! (positional fields), then, from a master with a shared secret, a [`tag::TAG_LEN`]-byte
//! tag over everything before it; at most [`MAX_ANNOUNCEMENT_LEN`] bytes in all, names at
//! most [`MAX_NAME_LEN`] bytes. A change of the datagram's layout bumps the format byte;
//! a change of the TCP protocol shows in `protocol`, so a worker tells "another gridlight
//! version" apart from noise.
//!
//! Nothing in an announcement is secret (whether a secret is *required* is not). Without
//! a secret a forged announcement can point a worker at a wrong address, as a wrong
//! `--master` could; a worker with a secret believes only announcements whose tag
//! verifies, that are recent and not replayed ([`tag`]), and the connection's handshake
//! proves the secret again in any case.

pub mod announcer;
pub mod tag;

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// UDP port masters announce on and workers listen on, unless told otherwise.
pub const DISCOVERY_PORT: u16 = 7841;
/// Time between two announcements of one master ("a few times a second").
pub const ANNOUNCE_INTERVAL: Duration = Duration::from_millis(300);
/// First bytes of every announcement.
pub const MAGIC: [u8; 4] = *b"GLMA";
/// Layout version of the datagram (the byte after [`MAGIC`]).
pub const ANNOUNCE_FORMAT: u8 = 2;
/// Largest datagram sent or accepted, in bytes.
pub const MAX_ANNOUNCEMENT_LEN: usize = 512;
/// Longest master or scene name carried, in bytes (longer ones are cut on a char boundary).
pub const MAX_NAME_LEN: usize = 64;

/// What a master says about itself.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Announcement {
    /// The TCP protocol version it speaks ([`crate::wire::protocol::PROTOCOL_VERSION`]).
    pub protocol: u32,
    /// The address it listens on. An unspecified IP (`0.0.0.0`) means "the address this
    /// datagram came from" ([`Announcement::address`]).
    pub listen: SocketAddr,
    /// The master's name (`gridlight master --name`, default the host name); workers
    /// choose among several masters by it (`--master-name`).
    pub name: String,
    /// The scene it serves (the file's stem), for humans.
    pub scene: String,
    /// Whether workers must prove a shared secret (`--secret-file`).
    pub secret_required: bool,
    /// The sender's clock when it sent this, in milliseconds since the Unix epoch.
    pub sent_ms: u64,
    /// A random id of the sending master process (its counter starts again with it).
    pub boot: u64,
    /// The announcement's number since the master process started (from 1).
    pub seq: u64,
}

/// A datagram read as an announcement: the announcement, the bytes its tag covers, and
/// the tag when there is one.
#[derive(Debug)]
pub struct Received<'a> {
    pub announcement: Announcement,
    signed: &'a [u8],
    tag: Option<[u8; tag::TAG_LEN]>,
}

/// Why a datagram is not an announcement.
#[derive(Debug, PartialEq, Eq, thiserror::Error)]
pub enum DiscoveryError {
    #[error("datagram of {0} bytes exceeds the {MAX_ANNOUNCEMENT_LEN}-byte announcement limit")]
    TooLong(usize),
    #[error("not a gridlight announcement (wrong magic bytes)")]
    NotAnnouncement,
    #[error("announcement format {0} is not understood (this gridlight reads format {ANNOUNCE_FORMAT}; run the same version on master and workers)")]
    Format(u8),
    #[error("malformed announcement: {0}")]
    Malformed(String),
}

impl Announcement {
    /// An announcement with names cut to [`MAX_NAME_LEN`].
    pub fn new(
        protocol: u32,
        listen: SocketAddr,
        name: &str,
        scene: &str,
        secret_required: bool,
    ) -> Self {
        Self {
            protocol,
            listen,
            name: truncate(name, MAX_NAME_LEN).to_owned(),
            scene: truncate(scene, MAX_NAME_LEN).to_owned(),
            secret_required,
            sent_ms: 0,
            boot: 0,
            seq: 0,
        }
    }

    /// The datagram: magic, format byte, MessagePack body, and the tag under `key`.
    pub fn encode(&self, key: Option<&tag::AnnounceKey>) -> Result<Vec<u8>, DiscoveryError> {
        let mut out = Vec::with_capacity(64 + tag::TAG_LEN);
        out.extend_from_slice(&MAGIC);
        out.push(ANNOUNCE_FORMAT);
        rmp_serde::encode::write(&mut out, self)
            .map_err(|e| DiscoveryError::Malformed(e.to_string()))?;
        if let Some(key) = key {
            let tag = key.tag(&out);
            out.extend_from_slice(&tag);
        }
        if out.len() > MAX_ANNOUNCEMENT_LEN {
            return Err(DiscoveryError::TooLong(out.len()));
        }
        Ok(out)
    }

    /// Reads a datagram, checking its size, magic, format and name lengths; the tag, if
    /// any, is checked by a [`tag::Verifier`].
    pub fn decode(bytes: &[u8]) -> Result<Received<'_>, DiscoveryError> {
        if bytes.len() > MAX_ANNOUNCEMENT_LEN {
            return Err(DiscoveryError::TooLong(bytes.len()));
        }
        if bytes.len() < MAGIC.len() + 1 || bytes[..MAGIC.len()] != MAGIC {
            return Err(DiscoveryError::NotAnnouncement);
        }
        let format = bytes[MAGIC.len()];
        if format != ANNOUNCE_FORMAT {
            return Err(DiscoveryError::Format(format));
        }
        let mut body = std::io::Cursor::new(&bytes[MAGIC.len() + 1..]);
        let a: Announcement = rmp_serde::decode::from_read(&mut body)
            .map_err(|e| DiscoveryError::Malformed(e.to_string()))?;
        let signed = &bytes[..MAGIC.len() + 1 + body.position() as usize];
        let tag = match &bytes[signed.len()..] {
            [] => None,
            rest => Some(<[u8; tag::TAG_LEN]>::try_from(rest).map_err(|_| {
                DiscoveryError::Malformed(format!("{} bytes after the body", rest.len()))
            })?),
        };
        if a.name.len() > MAX_NAME_LEN || a.scene.len() > MAX_NAME_LEN {
            return Err(DiscoveryError::Malformed(format!(
                "a name is longer than {MAX_NAME_LEN} bytes"
            )));
        }
        if a.listen.port() == 0 {
            return Err(DiscoveryError::Malformed("listen port 0".into()));
        }
        Ok(Received { announcement: a, signed, tag })
    }

    /// Where to connect: the announced address, or for an unspecified IP the IP the
    /// datagram came `from` with the announced port.
    pub fn address(&self, from: SocketAddr) -> SocketAddr {
        if self.listen.ip().is_unspecified() {
            SocketAddr::new(from.ip(), self.listen.port())
        } else {
            self.listen
        }
    }
}

/// Where a master listening on `listen` announces by default: the loopback broadcast
/// address for a loopback master (no other host could reach it), else the LAN's.
pub fn default_target(listen: SocketAddr) -> SocketAddr {
    let ip = if listen.ip().is_loopback() {
        Ipv4Addr::new(127, 255, 255, 255)
    } else {
        Ipv4Addr::BROADCAST
    };
    SocketAddr::new(IpAddr::V4(ip), DISCOVERY_PORT)
}

/// `s` cut to at most `max` bytes on a char boundary.
fn truncate(s: &str, max: usize) -> &str {
    if s.len() <= max {
        return s;
    }
    let mut end = max;
    while !s.is_char_boundary(end) {
        end -= 1;
    }
    &s[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Announcement {
        Announcement::new(6, "0.0.0.0:7840".parse().unwrap(), "lab-3", "cornell-box", true)
    }

    #[test]
    fn an_announcement_round_trips_and_stays_small() {
        let a = sample();
        let bytes = a.encode(None).unwrap();
        assert!(bytes.len() < 64, "{} bytes", bytes.len());
        assert_eq!(Announcement::decode(&bytes).unwrap().announcement, a);
        let key = tag::AnnounceKey::derive(b"s");
        let tagged = a.encode(Some(&key)).unwrap();
        assert_eq!(tagged.len(), bytes.len() + tag::TAG_LEN);
        let r = Announcement::decode(&tagged).unwrap();
        assert_eq!((r.announcement, r.signed, r.tag.is_some()), (a, &bytes[..], true));
    }

    #[test]
    fn long_names_are_cut_so_that_every_announcement_fits() {
        let long = "é".repeat(200);
        let a = Announcement::new(6, "[::1]:7840".parse().unwrap(), &long, &long, false);
        assert!(a.name.len() <= MAX_NAME_LEN && a.name.chars().all(|c| c == 'é'));
        let bytes = a.encode(Some(&tag::AnnounceKey::derive(b"s"))).unwrap();
        assert!(bytes.len() <= MAX_ANNOUNCEMENT_LEN);
        assert_eq!(Announcement::decode(&bytes).unwrap().announcement, a);
    }

    #[test]
    fn foreign_oversized_and_future_datagrams_are_refused() {
        let err = |b: &[u8]| Announcement::decode(b).unwrap_err();
        assert_eq!(err(b"hello world"), DiscoveryError::NotAnnouncement);
        assert_eq!(err(b"GLM"), DiscoveryError::NotAnnouncement);
        let mut bytes = sample().encode(None).unwrap();
        bytes[4] = ANNOUNCE_FORMAT + 1;
        assert_eq!(err(&bytes), DiscoveryError::Format(ANNOUNCE_FORMAT + 1));
        let big = vec![0u8; MAX_ANNOUNCEMENT_LEN + 1];
        assert_eq!(err(&big), DiscoveryError::TooLong(big.len()));
        let mut cut = sample().encode(None).unwrap();
        cut.truncate(cut.len() - 3);
        assert!(matches!(err(&cut), DiscoveryError::Malformed(_)));
        let mut odd_tail = sample().encode(None).unwrap();
        odd_tail.extend_from_slice(&[0; 5]);
        assert!(matches!(err(&odd_tail), DiscoveryError::Malformed(_)));
    }

    #[test]
    fn a_name_over_the_limit_on_the_wire_is_refused() {
        let mut a = sample();
        a.name = "x".repeat(MAX_NAME_LEN + 1); // built by hand: `new` would cut it
        let bytes = a.encode(None).unwrap();
        assert!(matches!(Announcement::decode(&bytes), Err(DiscoveryError::Malformed(_))));
    }

    #[test]
    fn an_unspecified_listen_address_means_the_sender() {
        let from: SocketAddr = "10.1.2.3:50000".parse().unwrap();
        assert_eq!(sample().address(from), "10.1.2.3:7840".parse().unwrap());
        let mut a = sample();
        a.listen = "10.9.9.9:7000".parse().unwrap();
        assert_eq!(a.address(from), a.listen);
    }

    #[test]
    fn a_loopback_master_announces_on_loopback_only() {
        let lo = default_target("127.0.0.1:0".parse().unwrap());
        assert_eq!(lo, "127.255.255.255:7841".parse().unwrap());
        let lan = default_target("0.0.0.0:7840".parse().unwrap());
        assert_eq!(lan, "255.255.255.255:7841".parse().unwrap());
    }
}
