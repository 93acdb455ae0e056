//! The announcer actor: tells the LAN a few times a second that this master is here.
//!
//! It sends one [`Announcement`] datagram every interval to a broadcast address
//! (`discovery` has the format and why it carries nothing secret), each with a fresh
//! clock reading and counter, tagged when the master has a secret (`discovery::tag`).
//! A failed send (no
//! route to the broadcast address, a full socket buffer) is logged once and retried at the
//! next tick: discovery is a convenience and never stops a master.

use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::time::Duration;

use actix::prelude::*;

use crate::discovery::tag::{now_ms, Sender};
use crate::discovery::{Announcement, DiscoveryError};
use crate::supervision::{Guard, GuardedTimers, InjectPanic, Supervised, Supervision};

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

/// The socket and the announcements it sends.
pub struct Announcer {
    socket: UdpSocket,
    to: SocketAddr,
    sender: Sender,
    interval: Duration,
    /// Sends that failed in a row (the first is logged as a warning, the rest quietly).
    failures: u64,
    /// The repeating timer, replaced when the start work runs again after a restart.
    ticking: Option<SpawnHandle>,
    supervision: Supervision,
}

impl Announcer {
    /// Binds a broadcast-capable UDP socket for `announcement`, tagged under `secret`.
    pub fn new(
        config: &AnnounceConfig,
        announcement: &Announcement,
        secret: Option<&[u8]>,
        supervision: Supervision,
    ) -> std::io::Result<Self> {
        let mut sender = Sender::new(announcement.clone(), secret);
        // Only the clock and the counter change: a datagram that fits now always will.
        sender.next(u64::MAX).map_err(|e: DiscoveryError| std::io::Error::other(e.to_string()))?;
        let any: SocketAddr = match config.to {
            SocketAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, 0).into(),
            SocketAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, 0).into(),
        };
        let socket = UdpSocket::bind(any)?;
        socket.set_broadcast(true)?;
        socket.set_nonblocking(true)?;
        let interval = config.interval;
        Ok(Self {
            socket,
            to: config.to,
            sender,
            interval,
            failures: 0,
            ticking: None,
            supervision,
        })
    }
}

impl Actor for Announcer {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }
}

impl Supervised for Announcer {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    fn on_start(&mut self, ctx: &mut Context<Self>) {
        tracing::info!(to = %self.to, "announcing this master (--no-announce turns it off)");
        if let Some(old) = self.ticking.take() {
            ctx.cancel_future(old);
        }
        self.announce();
        self.ticking = Some(ctx.run_interval_guarded(self.interval, |act, _| act.announce()));
    }

    /// Nothing to replace: the counter goes on.
    fn restart(&mut self, _: &mut Context<Self>) {}
}

impl Handler<InjectPanic> for Announcer {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the announcer"));
    }
}

impl Announcer {
    fn announce(&mut self) {
        let datagram = match self.sender.next(now_ms()) {
            Ok(d) => d,
            Err(e) => {
                tracing::error!(cause = %e, "cannot encode this master's announcement");
                return;
            }
        };
        match self.socket.send_to(&datagram, self.to) {
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
