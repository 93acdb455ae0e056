//! Who may open a connection now, and the refusals summarised for the log: the listener's
//! defence against a flood, as plain data.
//!
//! A connection is *pending* from its accept until it authenticates (the worker is
//! welcomed). Pending connections are capped per address ([`MAX_PENDING_PER_ADDR`]) and
//! overall ([`MAX_PENDING`]), and each has [`HANDSHAKE_DEADLINE`] to authenticate (the
//! listener's phase timer, independent of what the handshake says); authenticated
//! connections never count against these caps, since one host may run many workers, only
//! against the master's `max_connections`. So a host that opens connections and stays
//! silent or sends garbage holds at most [`MAX_PENDING_PER_ADDR`] slots, each for at most
//! the deadline, and an honest worker from another address is served at once.
//!
//! Refusals (at a cap, at the deadline, or a connection rejected before it authenticated)
//! are counted per kind and address and logged as one summary line per pair every
//! [`SUMMARY_EVERY`], not one line per peer. A rejection before authentication still gets
//! its own line naming the peer (at info level), but only a few per period
//! (`shared::line_budget`): enough for a human's mistakes, not a flood's.

use std::collections::{BTreeMap, HashMap};
use std::net::IpAddr;
use std::time::Duration;

use crate::wire::protocol::ConnId;

/// Time a connection has from its accept to authenticate.
pub const HANDSHAKE_DEADLINE: Duration = Duration::from_secs(2);
/// Pending connections from one address (a GPU worker opens up to 32 at once).
pub const MAX_PENDING_PER_ADDR: usize = 64;
/// Pending connections from all addresses.
pub const MAX_PENDING: usize = 256;
/// Time between two summaries of the refusals.
pub const SUMMARY_EVERY: Duration = crate::shared::line_budget::PERIOD;

/// Why a connection was refused or ended before it authenticated, as the summary names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Refused {
    /// Too many pending connections from its address.
    PendingFromAddress,
    /// Too many pending connections overall.
    Pending,
    /// `max_connections` authenticated workers are connected.
    Full,
    /// It did not authenticate within [`HANDSHAKE_DEADLINE`].
    Deadline,
    /// Rejected before it authenticated (a rejection kind's name: bad frame, auth, ...).
    Rejected(&'static str),
}

impl Refused {
    pub fn as_str(self) -> &'static str {
        match self {
            Self::PendingFromAddress => "pending_from_address",
            Self::Pending => "pending",
            Self::Full => "full",
            Self::Deadline => "handshake_deadline",
            Self::Rejected(kind) => kind,
        }
    }
}

/// The pending connections and the authenticated count.
#[derive(Debug, Default)]
pub struct Admission {
    pending: HashMap<ConnId, IpAddr>,
    per_addr: HashMap<IpAddr, usize>,
    authenticated: usize,
}

impl Admission {
    /// Whether a connection from `ip` may open, with at most `max_connections`
    /// authenticated workers.
    pub fn admit(&self, ip: IpAddr, max_connections: usize) -> Result<(), Refused> {
        if self.authenticated >= max_connections {
            Err(Refused::Full)
        } else if self.per_addr.get(&ip).copied().unwrap_or(0) >= MAX_PENDING_PER_ADDR {
            Err(Refused::PendingFromAddress)
        } else if self.pending.len() >= MAX_PENDING {
            Err(Refused::Pending)
        } else {
            Ok(())
        }
    }

    /// Connection `id` from `ip` was opened: pending until it authenticates.
    pub fn opened(&mut self, id: ConnId, ip: IpAddr) {
        if self.pending.insert(id, ip).is_none() {
            *self.per_addr.entry(ip).or_default() += 1;
        }
    }

    /// Connection `id` authenticated: it no longer counts as pending.
    pub fn authenticated(&mut self, id: ConnId) {
        if self.unpend(id).is_some() {
            self.authenticated += 1;
        }
    }

    /// Connection `id` ended; the address it had while pending, if it still was.
    pub fn closed(&mut self, id: ConnId) -> Option<IpAddr> {
        let ip = self.unpend(id);
        if ip.is_none() {
            self.authenticated = self.authenticated.saturating_sub(1);
        }
        ip
    }

    /// The address of `id` while it is pending.
    pub fn pending(&self, id: ConnId) -> Option<IpAddr> {
        self.pending.get(&id).copied()
    }

    fn unpend(&mut self, id: ConnId) -> Option<IpAddr> {
        let ip = self.pending.remove(&id)?;
        if let Some(n) = self.per_addr.get_mut(&ip) {
            *n -= 1;
            if *n == 0 {
                self.per_addr.remove(&ip);
            }
        }
        Some(ip)
    }
}

/// Refusals since the last summary, per kind and address (bounded: pairs beyond
/// [`MAX_SUMMARY_PAIRS`] are counted under the unspecified address).
#[derive(Debug, Default)]
pub struct RefusalLog {
    counts: BTreeMap<(Refused, IpAddr), u64>,
}

/// Distinct (kind, address) pairs kept between two summaries.
pub const MAX_SUMMARY_PAIRS: usize = 1024;

impl RefusalLog {
    pub fn note(&mut self, why: Refused, ip: IpAddr) {
        let full = self.counts.len() >= MAX_SUMMARY_PAIRS && !self.counts.contains_key(&(why, ip));
        let ip = if full { IpAddr::from([0, 0, 0, 0]) } else { ip };
        *self.counts.entry((why, ip)).or_default() += 1;
    }

    /// The counts since the last call, which starts them again.
    pub fn take(&mut self) -> Vec<(Refused, IpAddr, u64)> {
        std::mem::take(&mut self.counts).into_iter().map(|((w, ip), n)| (w, ip, n)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ip(last: u8) -> IpAddr {
        IpAddr::from([10, 0, 0, last])
    }

    #[test]
    fn one_address_holds_at_most_its_share_of_pending_slots_and_others_are_served() {
        let mut a = Admission::default();
        for id in 0..MAX_PENDING_PER_ADDR as u64 {
            assert_eq!(a.admit(ip(2), 1000), Ok(()));
            a.opened(id, ip(2));
        }
        assert_eq!(a.admit(ip(2), 1000), Err(Refused::PendingFromAddress));
        assert_eq!(a.admit(ip(1), 1000), Ok(()), "an honest host is served during the flood");
        assert_eq!(a.closed(0), Some(ip(2)));
        assert_eq!(a.admit(ip(2), 1000), Ok(()), "a slot freed by an end is free again");
    }

    #[test]
    fn authenticated_workers_never_count_as_pending_only_against_the_connection_cap() {
        let mut a = Admission::default();
        // One host runs more workers than its pending share.
        for id in 0..(MAX_PENDING_PER_ADDR as u64 + 10) {
            assert_eq!(a.admit(ip(1), 100), Ok(()), "worker {id}");
            a.opened(id, ip(1));
            a.authenticated(id);
        }
        assert_eq!(a.pending(3), None);
        assert_eq!(a.admit(ip(1), MAX_PENDING_PER_ADDR + 10), Err(Refused::Full));
        assert_eq!(a.closed(3), None, "it was authenticated, not pending");
        assert_eq!(a.admit(ip(1), MAX_PENDING_PER_ADDR + 10), Ok(()));
    }

    #[test]
    fn the_overall_pending_cap_holds_across_addresses() {
        let mut a = Admission::default();
        for id in 0..MAX_PENDING as u64 {
            a.opened(id, IpAddr::from([10, 0, (id / 200) as u8, (id % 200) as u8]));
        }
        assert_eq!(a.admit(ip(250), 1000), Err(Refused::Pending));
    }

    #[test]
    fn refusals_are_counted_per_kind_and_address_and_start_again_after_a_summary() {
        let mut log = RefusalLog::default();
        for _ in 0..500 {
            log.note(Refused::Deadline, ip(2));
            log.note(Refused::Rejected("bad_frame"), ip(2));
        }
        log.note(Refused::PendingFromAddress, ip(3));
        let summary = log.take();
        assert_eq!(summary.len(), 3);
        assert!(summary.contains(&(Refused::Deadline, ip(2), 500)));
        assert!(summary.contains(&(Refused::Rejected("bad_frame"), ip(2), 500)));
        assert!(log.take().is_empty());
        for i in 1..=(MAX_SUMMARY_PAIRS as u32 + 50) {
            log.note(Refused::Deadline, IpAddr::from(i.to_be_bytes()));
        }
        assert_eq!(log.take().len(), MAX_SUMMARY_PAIRS + 1, "bounded");
    }
}
