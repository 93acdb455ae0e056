//! Reconnect delays: exponential back-off with full jitter.
//!
//! When the master goes away (restart, network trouble) every worker of a grid tries to
//! come back at once; jitter spreads those attempts out so a restarted master is not hit
//! by a synchronised storm. The delay grows from `base` by `factor` per failed attempt up
//! to `max`, and each wait is drawn uniformly from `[cap/2, cap]` so it never collapses to
//! zero ("equal jitter"). A successful link resets it.

use std::time::Duration;

use rand::Rng;

/// First reconnect delay (before jitter).
pub const DEFAULT_BASE: Duration = Duration::from_millis(200);

/// Largest reconnect delay (before jitter).
pub const DEFAULT_MAX: Duration = Duration::from_secs(10);

/// Growth of the delay per failed attempt.
pub const DEFAULT_FACTOR: f64 = 2.0;

/// The reconnect delay schedule of one worker connection.
#[derive(Clone, Debug)]
pub struct Backoff {
    base: Duration,
    max: Duration,
    factor: f64,
    /// Failed attempts since the last reset.
    attempts: u32,
}

impl Default for Backoff {
    fn default() -> Self {
        Self::new(DEFAULT_BASE, DEFAULT_MAX, DEFAULT_FACTOR)
    }
}

impl Backoff {
    /// A schedule from `base` growing by `factor` per attempt up to `max`.
    pub fn new(base: Duration, max: Duration, factor: f64) -> Self {
        Self { base, max: max.max(base), factor: factor.max(1.0), attempts: 0 }
    }

    /// The delay cap of the next attempt, without jitter.
    pub fn current_cap(&self) -> Duration {
        // powi on a bounded exponent: past ~64 doublings every cap is `max` anyway.
        let grown = self.base.as_secs_f64() * self.factor.powi(self.attempts.min(64) as i32);
        Duration::from_secs_f64(grown.min(self.max.as_secs_f64()))
    }

    /// The delay to wait before the next attempt; advances the schedule.
    pub fn next_delay(&mut self, rng: &mut impl Rng) -> Duration {
        let cap = self.current_cap();
        self.attempts = self.attempts.saturating_add(1);
        let half = cap / 2;
        half + Duration::from_secs_f64(rng.gen::<f64>() * (cap - half).as_secs_f64())
    }

    /// Failed attempts since the last reset.
    pub fn attempts(&self) -> u32 {
        self.attempts
    }

    /// Back to the first delay, after a link that got as far as doing work.
    pub fn reset(&mut self) {
        self.attempts = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::SeedableRng;

    #[test]
    fn delays_grow_exponentially_up_to_the_max() {
        let mut b = Backoff::new(Duration::from_millis(100), Duration::from_secs(1), 2.0);
        let caps: Vec<_> = (0..6)
            .map(|_| {
                let c = b.current_cap();
                b.attempts += 1;
                c.as_millis()
            })
            .collect();
        assert_eq!(caps, vec![100, 200, 400, 800, 1000, 1000]);
    }

    #[test]
    fn every_delay_lies_between_half_the_cap_and_the_cap() {
        let mut rng = StdRng::seed_from_u64(7);
        let mut b = Backoff::new(Duration::from_millis(100), Duration::from_secs(5), 2.0);
        for _ in 0..50 {
            let cap = b.current_cap();
            let d = b.next_delay(&mut rng);
            assert!(d >= cap / 2 && d <= cap, "{d:?} outside [{:?}, {cap:?}]", cap / 2);
        }
    }

    #[test]
    fn jitter_spreads_workers_apart() {
        // Two workers failing at the same moment must not retry in lockstep.
        let mut rng = StdRng::seed_from_u64(1);
        let delays: Vec<_> = (0..20).map(|_| Backoff::default().next_delay(&mut rng)).collect();
        let distinct = delays.iter().collect::<std::collections::HashSet<_>>().len();
        assert!(distinct > 15, "only {distinct} distinct delays out of 20");
    }

    #[test]
    fn reset_returns_to_the_first_delay() {
        let mut rng = StdRng::seed_from_u64(3);
        let mut b = Backoff::default();
        for _ in 0..5 {
            b.next_delay(&mut rng);
        }
        assert_eq!(b.attempts(), 5);
        b.reset();
        assert_eq!(b.current_cap(), DEFAULT_BASE);
    }

    #[test]
    fn huge_attempt_counts_stay_at_the_max() {
        let mut b = Backoff { attempts: u32::MAX, ..Backoff::default() };
        assert_eq!(b.current_cap(), DEFAULT_MAX);
        let mut rng = StdRng::seed_from_u64(0);
        assert!(b.next_delay(&mut rng) <= DEFAULT_MAX);
    }
}
