//! The announcer actor: tells the LAN a few times a second that this master is here.
//!
//! It sends one [`Announcement`] datagram every interval to a broadcast address
//! (`discovery` has the format and why it carries nothing secret). A failed send (no
//! route to the broadcast address, a full socket buffer) is logged once and retried at the
//! next tick: discovery is a convenience and never stops a master.

use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::time::Duration;

use actix::prelude::*;

use crate::discovery::{Announcement, DiscoveryError};

/// Where and how often a master announces itself, and under which names.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AnnounceConfig {
    /// Destination of the datagrams (a broadcast address and the discovery port).
    pub to: SocketAddr,
    /// The master's name workers choose by (`--master-name`).
    pub name: String,
    /// The scene's name, for humans.
    pub scene: String,
    pub interval: Duration,
}

/// The socket and the datagram it repeats.
pub struct Announcer {
    socket: UdpSocket,
    to: SocketAddr,
    datagram: Vec<u8>,
    interval: Duration,
    /// Sends that failed in a row (the first is logged as a warning, the rest quietly).
    failures: u64,
}

impl Announcer {
    /// Binds a broadcast-capable UDP socket for `announcement`.
    pub fn new(config: &AnnounceConfig, announcement: &Announcement) -> std::io::Result<Self> {
        let datagram = announcement
            .encode()
            .map_err(|e: DiscoveryError| std::io::Error::other(e.to_string()))?;
        let any: SocketAddr = match config.to {
            SocketAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, 0).into(),
            SocketAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, 0).into(),
        };
        let socket = UdpSocket::bind(any)?;
        socket.set_broadcast(true)?;
        socket.set_nonblocking(true)?;
        Ok(Self { socket, to: config.to, datagram, interval: config.interval, failures: 0 })
    }
}

impl Actor for Announcer {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        tracing::info!(to = %self.to, "announcing this master (--no-announce turns it off)");
        self.announce();
        ctx.run_interval(self.interval, |act, _| act.announce());
    }
}

impl Announcer {
    fn announce(&mut self) {
        match self.socket.send_to(&self.datagram, self.to) {
            Ok(_) => {
                if self.failures > 0 {
                    tracing::info!(to = %self.to, "announcements go out again");
                }
                self.failures = 0;
            }
            Err(e) => {
                if self.failures == 0 {
                    tracing::warn!(to = %self.to, cause = %e, "cannot announce this master; workers must name it with --master");
                }
                self.failures += 1;
            }
        }
    }
}
