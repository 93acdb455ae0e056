//! The listener's per-peer policy: a worker whose connections keep failing (more than
//! `max_failures` within `window`) is refused for `backoff`, with a
//! [`Rejection::BackedOff`] that says why, so a crash-looping worker cannot churn the
//! master (each of its connections costs a handshake, a state and jobs that are lost).
//!
//! A peer is the worker's name from its `Hello` (the wire module's *Worker identity*):
//! every test worker, and every worker behind one NAT, shares an address. Pure and
//! bounded: a peer is forgotten once its failures are older than the window and its
//! back-off is over, and at most [`MAX_PEERS`] are remembered.

use std::collections::{HashMap, VecDeque};
use std::time::{Duration, Instant};

use crate::wire::rejection::Rejection;

/// Peers remembered at most; past it the one failed longest ago is forgotten.
pub const MAX_PEERS: usize = 4096;

/// How many failures make a peer crash-looping, and how long it is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeerPolicy {
    /// Failed connections allowed within `window`; one more backs the peer off.
    pub max_failures: usize,
    pub window: Duration,
    /// How long a backed-off peer is refused.
    pub backoff: Duration,
}

impl Default for PeerPolicy {
    fn default() -> Self {
        Self { max_failures: 5, window: Duration::from_secs(10), backoff: Duration::from_secs(30) }
    }
}

#[derive(Debug, Default)]
struct Peer {
    failures: VecDeque<Instant>,
    refused_until: Option<Instant>,
}

/// The failure history of the peers that failed recently.
#[derive(Debug)]
pub struct PeerBackoff {
    policy: PeerPolicy,
    peers: HashMap<String, Peer>,
}

impl PeerBackoff {
    pub fn new(policy: PeerPolicy) -> Self {
        Self { policy, peers: HashMap::new() }
    }

    /// Records a connection of `peer` that ended on an error at `now`.
    pub fn failed(&mut self, peer: &str, now: Instant) {
        self.forget_old(now);
        if !self.peers.contains_key(peer) && self.peers.len() >= MAX_PEERS {
            self.forget_oldest();
        }
        let window = self.policy.window;
        let p = self.peers.entry(peer.to_owned()).or_default();
        while p.failures.front().is_some_and(|t| now.duration_since(*t) > window) {
            p.failures.pop_front();
        }
        p.failures.push_back(now);
        if p.failures.len() > self.policy.max_failures {
            p.refused_until = Some(now + self.policy.backoff);
            tracing::warn!(
                worker = peer,
                failures = p.failures.len(),
                backoff_s = self.policy.backoff.as_secs_f32(),
                "worker backed off: its connections keep failing"
            );
        }
    }

    /// Whether `peer` may connect at `now`; the rejection to send when not.
    pub fn admit(&self, peer: &str, now: Instant) -> Result<(), Rejection> {
        let Some(p) = self.peers.get(peer) else { return Ok(()) };
        match p.refused_until {
            Some(until) if until > now => Err(Rejection::BackedOff {
                worker: peer.to_owned(),
                failures: p.failures.len(),
                window_s: self.policy.window.as_secs_f32(),
                retry_in_s: (until - now).as_secs_f32(),
            }),
            _ => Ok(()),
        }
    }

    /// Peers remembered now.
    pub fn len(&self) -> usize {
        self.peers.len()
    }

    /// True when no peer is remembered.
    pub fn is_empty(&self) -> bool {
        self.peers.is_empty()
    }

    fn forget_old(&mut self, now: Instant) {
        let window = self.policy.window;
        self.peers.retain(|_, p| {
            p.refused_until.is_some_and(|t| t > now)
                || p.failures.back().is_some_and(|t| now.duration_since(*t) <= window)
        });
    }

    fn forget_oldest(&mut self) {
        let oldest = self
            .peers
            .iter()
            .min_by_key(|(_, p)| p.failures.back().copied())
            .map(|(name, _)| name.clone());
        if let Some(name) = oldest {
            self.peers.remove(&name);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn policy() -> PeerPolicy {
        PeerPolicy {
            max_failures: 2,
            window: Duration::from_secs(10),
            backoff: Duration::from_secs(30),
        }
    }

    #[test]
    fn more_than_n_failures_in_t_back_the_peer_off_and_say_why() {
        let mut b = PeerBackoff::new(policy());
        let t0 = Instant::now();
        b.failed("w#0", t0);
        b.failed("w#0", t0 + Duration::from_secs(1));
        assert_eq!(b.admit("w#0", t0 + Duration::from_secs(2)), Ok(()), "N failures are allowed");
        b.failed("w#0", t0 + Duration::from_secs(2));
        let why = b.admit("w#0", t0 + Duration::from_secs(3)).expect_err("backed off");
        assert_eq!(why.kind().as_str(), "backed_off");
        let text = why.to_string();
        assert!(text.contains("w#0") && text.contains("3 failed connections"), "{text}");
        assert!(text.contains("retry in 29 s"), "{text}");
        assert_eq!(b.admit("w#1", t0 + Duration::from_secs(3)), Ok(()), "other peers are served");
        assert_eq!(b.admit("w#0", t0 + Duration::from_secs(33)), Ok(()), "the back-off ends");
    }

    #[test]
    fn failures_spread_wider_than_the_window_never_back_off() {
        let mut b = PeerBackoff::new(policy());
        let t0 = Instant::now();
        for i in 0..10 {
            let now = t0 + Duration::from_secs(6 * i);
            b.failed("slow", now);
            assert_eq!(b.admit("slow", now), Ok(()), "failure {i}");
        }
    }

    #[test]
    fn the_table_forgets_quiet_peers_and_stays_bounded() {
        let mut b = PeerBackoff::new(policy());
        let t0 = Instant::now();
        b.failed("old", t0);
        b.failed("new", t0 + Duration::from_secs(11));
        assert_eq!(b.len(), 1, "a peer quiet for a window is forgotten");
        for i in 0..MAX_PEERS + 10 {
            b.failed(&format!("p{i}"), t0 + Duration::from_secs(12));
        }
        assert_eq!(b.len(), MAX_PEERS);
    }
}
