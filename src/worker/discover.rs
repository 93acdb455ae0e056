//! Finding a master without `--master`: listen for announcements on the LAN.
//!
//! The worker binds the discovery port (shared with other workers on the machine:
//! `SO_REUSEADDR`/`SO_REUSEPORT`, so each gets every broadcast), collects the masters it
//! hears, and picks one: the one named by `--master-name`, or the only one. Several
//! masters without a name, or none before the timeout, is an error that says how to
//! choose or name one. Announcements of another protocol version are reported, not
//! joined. Anything that is not an announcement is ignored (`discovery` decodes and
//! bounds every datagram).
//!
//! A worker with a secret believes only announcements tagged under it, recent and not
//! replayed (`discovery::tag`); it ignores the others, says so in one warning (the first
//! one it ignores, not one line per datagram), and counts them in the error it ends with
//! when no master verified. A worker without a secret cannot check tags and hears every
//! master, as before.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::net::{Ipv4Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use gridlight_actors::discovery::tag::{now_ms, Verifier};
use gridlight_actors::discovery::{Announcement, DISCOVERY_PORT, MAX_ANNOUNCEMENT_LEN};
use gridlight_actors::protocol::PROTOCOL_VERSION;
use socket2::{Domain, Protocol, Socket, Type};
use tracing::{debug, info, warn};

/// How long to wait for announcements when not told.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(10);
/// After the first master is heard, how long to listen for others (several masters
/// without `--master-name` are an error, so all of them must be heard): a few intervals.
pub const COLLECT: Duration = Duration::from_millis(1000);

/// What to listen for.
#[derive(Clone, Debug)]
pub struct DiscoverOptions {
    /// UDP port masters announce on.
    pub port: u16,
    /// Join only the master of this name.
    pub master_name: Option<String>,
    /// Give up after this long.
    pub timeout: Duration,
    /// The shared secret: only announcements tagged under it are believed.
    pub secret: Option<Vec<u8>>,
}

impl Default for DiscoverOptions {
    fn default() -> Self {
        Self { port: DISCOVERY_PORT, master_name: None, timeout: DEFAULT_TIMEOUT, secret: None }
    }
}

/// A master heard on the LAN.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Found {
    /// Where to connect.
    pub addr: SocketAddr,
    pub announcement: Announcement,
}

/// Why no master was chosen; each message says what to do.
#[derive(Debug, thiserror::Error)]
pub enum DiscoverError {
    #[error("cannot listen for master announcements on UDP port {port}: {cause}")]
    Listen { port: u16, cause: std::io::Error },
    #[error(
        "no gridlight master announced itself on UDP port {port} within {secs:.0} s{heard}; \
             start one on this network, or name it with --master HOST:PORT (needed when the \
             master runs with --no-announce or on another network segment)"
    )]
    NoneHeard { port: u16, secs: f64, heard: String },
    #[error(
        "no master named {name:?} announced itself within {secs:.0} s; heard:{heard}\n\
             choose one of these with --master-name NAME, or name a master with --master HOST:PORT"
    )]
    NameNotHeard { name: String, secs: f64, heard: String },
    #[error(
        "several masters announce themselves:{heard}\n\
             choose one with --master-name NAME, or name one with --master HOST:PORT"
    )]
    Several { heard: String },
}

/// Listens until a master can be chosen, the timeout passes, or the choice is ambiguous.
pub fn discover(opts: &DiscoverOptions) -> Result<Found, DiscoverError> {
    let socket =
        listen(opts.port).map_err(|cause| DiscoverError::Listen { port: opts.port, cause })?;
    info!(port = opts.port, master_name = ?opts.master_name, "listening for masters");
    let started = Instant::now();
    let mut heard: BTreeMap<(String, SocketAddr), Announcement> = BTreeMap::new();
    let mut first_heard: Option<Instant> = None;
    let mut buf = [0u8; MAX_ANNOUNCEMENT_LEN + 1];
    let mut verifier = opts.secret.as_deref().map(Verifier::new);
    let mut ignored: BTreeMap<&'static str, u64> = BTreeMap::new();
    loop {
        let now = Instant::now();
        let deadline = started + opts.timeout;
        let collect_end = first_heard.map(|t| t + COLLECT);
        if let Some(found) = choose(opts, &heard, collect_end.is_some_and(|e| now >= e))? {
            info!(master = %found.announcement.name, addr = %found.addr, scene = %found.announcement.scene, "master found");
            return Ok(found);
        }
        if now >= deadline {
            return Err(not_found(opts, &heard, &ignored));
        }
        let until = collect_end.map_or(deadline, |e| e.min(deadline));
        let wait = until.saturating_duration_since(now).max(Duration::from_millis(10));
        let _ = socket.set_read_timeout(Some(wait));
        let (n, from) = match socket.recv_from(&mut buf) {
            Ok(v) => v,
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                continue
            }
            Err(e) => return Err(DiscoverError::Listen { port: opts.port, cause: e }),
        };
        match Announcement::decode(&buf[..n]) {
            Ok(r) => {
                if let Some(v) = &mut verifier {
                    if let Err(why) = v.check(&r, now_ms()) {
                        if ignored.is_empty() {
                            warn!(%from, master = %r.announcement.name, cause = %why,
                                "announcement ignored: it does not verify with this worker's \
                                 secret (further ones are ignored without a word)");
                        }
                        *ignored.entry(why.kind()).or_default() += 1;
                        continue;
                    }
                }
                let a = r.announcement;
                let addr = a.address(from);
                if heard.insert((a.name.clone(), addr), a).is_none() {
                    debug!(%from, %addr, "announcement heard");
                    first_heard.get_or_insert_with(Instant::now);
                }
            }
            Err(e) => debug!(%from, cause = %e, "datagram ignored"),
        }
    }
}

/// The master to join, once it can be told: `done` says the collection time is over.
fn choose(
    opts: &DiscoverOptions,
    heard: &BTreeMap<(String, SocketAddr), Announcement>,
    done: bool,
) -> Result<Option<Found>, DiscoverError> {
    let usable = heard.iter().filter(|(_, a)| a.protocol == PROTOCOL_VERSION);
    let found = |((_, addr), a): (&(String, SocketAddr), &Announcement)| Found {
        addr: *addr,
        announcement: a.clone(),
    };
    if let Some(name) = &opts.master_name {
        // A named master is joined as soon as it is heard.
        return Ok(usable.filter(|(k, _)| &k.0 == name).map(found).next());
    }
    if !done {
        return Ok(None);
    }
    let all: Vec<Found> = usable.map(found).collect();
    match all.len() {
        0 => Ok(None),
        1 => Ok(all.into_iter().next()),
        _ => Err(DiscoverError::Several { heard: list(heard) }),
    }
}

fn not_found(
    opts: &DiscoverOptions,
    heard: &BTreeMap<(String, SocketAddr), Announcement>,
    ignored: &BTreeMap<&'static str, u64>,
) -> DiscoverError {
    let secs = opts.timeout.as_secs_f64();
    let mut unverified = String::new();
    if !ignored.is_empty() {
        let counts: Vec<String> = ignored.iter().map(|(k, n)| format!("{n} {k}")).collect();
        unverified = format!(
            " (announcements ignored because they do not verify with this worker's secret: {}; \
             give master and worker the same --secret-file)",
            counts.join(", ")
        );
    }
    match &opts.master_name {
        Some(name) if !heard.is_empty() => {
            DiscoverError::NameNotHeard { name: name.clone(), secs, heard: list(heard) }
        }
        _ => DiscoverError::NoneHeard {
            port: opts.port,
            secs,
            heard: if heard.is_empty() {
                unverified
            } else {
                format!("{unverified} in this worker's protocol;{}", list(heard))
            },
        },
    }
}

/// One line per master heard: name, scene, address, and what stands in the way.
fn list(heard: &BTreeMap<(String, SocketAddr), Announcement>) -> String {
    let mut out = String::new();
    for ((name, addr), a) in heard {
        let _ = write!(out, "\n  {name:?} (scene {:?}) at {addr}", a.scene);
        if a.secret_required {
            out.push_str(", secret required");
        }
        if a.protocol != PROTOCOL_VERSION {
            let _ = write!(
                out,
                ", speaks protocol {} but this worker speaks {PROTOCOL_VERSION}: run the same gridlight version",
                a.protocol
            );
        }
    }
    out
}

/// A UDP socket on the discovery port that other listeners on this machine may share.
fn listen(port: u16) -> std::io::Result<UdpSocket> {
    let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP))?;
    socket.set_reuse_address(true)?;
    #[cfg(all(unix, not(any(target_os = "solaris", target_os = "illumos"))))]
    socket.set_reuse_port(true)?;
    socket.bind(&SocketAddr::from((Ipv4Addr::UNSPECIFIED, port)).into())?;
    Ok(socket.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn heard(entries: &[(&str, u32)]) -> BTreeMap<(String, SocketAddr), Announcement> {
        entries
            .iter()
            .enumerate()
            .map(|(i, (name, protocol))| {
                let addr: SocketAddr = format!("10.0.0.{}:7840", i + 1).parse().unwrap();
                let a = Announcement::new(*protocol, addr, name, "cornell-box", false);
                ((name.to_string(), addr), a)
            })
            .collect()
    }

    fn opts(name: Option<&str>) -> DiscoverOptions {
        DiscoverOptions { master_name: name.map(str::to_owned), ..DiscoverOptions::default() }
    }

    #[test]
    fn the_only_master_is_chosen_once_the_collection_time_is_over() {
        let h = heard(&[("lab", PROTOCOL_VERSION)]);
        assert!(choose(&opts(None), &h, false).unwrap().is_none());
        let found = choose(&opts(None), &h, true).unwrap().unwrap();
        assert_eq!(found.addr, "10.0.0.1:7840".parse().unwrap());
    }

    #[test]
    fn a_named_master_is_chosen_at_once_among_several() {
        let h = heard(&[("a", PROTOCOL_VERSION), ("b", PROTOCOL_VERSION)]);
        let found = choose(&opts(Some("b")), &h, false).unwrap().unwrap();
        assert_eq!(found.announcement.name, "b");
        assert!(choose(&opts(Some("c")), &h, true).unwrap().is_none());
    }

    #[test]
    fn several_masters_without_a_name_is_an_error_listing_them() {
        let h = heard(&[("a", PROTOCOL_VERSION), ("b", PROTOCOL_VERSION)]);
        let err = choose(&opts(None), &h, true).unwrap_err().to_string();
        assert!(
            err.contains("\"a\"") && err.contains("\"b\"") && err.contains("--master-name"),
            "{err}"
        );
    }

    #[test]
    fn a_master_of_another_protocol_is_reported_not_joined() {
        let h = heard(&[("old", PROTOCOL_VERSION - 1)]);
        assert!(choose(&opts(None), &h, true).unwrap().is_none());
        let err = not_found(&opts(None), &h, &BTreeMap::new()).to_string();
        assert!(err.contains("speaks protocol") && err.contains("--master HOST:PORT"), "{err}");
    }
}
