//! The restart policy of a core actor: one-for-one, at most `max_restarts` within
//! `window`, with an exponential back-off between restarts (OTP's restart intensity).
//! Pure: the guard ([`super::guard`]) asks a [`RestartTracker`] what to do.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Restart limits and back-off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestartPolicy {
    /// Restarts allowed within `window` before the failure escalates.
    pub max_restarts: usize,
    pub window: Duration,
    /// Back-off before the first restart; doubled for each further one in the window.
    pub backoff: Duration,
    pub max_backoff: Duration,
}

impl Default for RestartPolicy {
    fn default() -> Self {
        Self {
            max_restarts: 5,
            window: Duration::from_secs(10),
            backoff: Duration::from_millis(10),
            max_backoff: Duration::from_secs(1),
        }
    }
}

/// What to do after a failure.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RestartDecision {
    /// Restart after this back-off.
    Restart { after: Duration },
    /// Too many failures in the window: escalate.
    GiveUp,
}

/// Failure history of one supervised child.
#[derive(Clone, Debug)]
pub struct RestartTracker {
    policy: RestartPolicy,
    failures: VecDeque<Instant>,
}

impl RestartTracker {
    pub fn new(policy: RestartPolicy) -> Self {
        Self { policy, failures: VecDeque::new() }
    }

    /// Records a failure at `now` and says what to do.
    pub fn on_failure(&mut self, now: Instant) -> RestartDecision {
        while self.failures.front().is_some_and(|t| now.duration_since(*t) > self.policy.window) {
            self.failures.pop_front();
        }
        self.failures.push_back(now);
        let n = self.failures.len();
        if n > self.policy.max_restarts {
            return RestartDecision::GiveUp;
        }
        let factor = 1u32 << (n - 1).min(16);
        RestartDecision::Restart {
            after: (self.policy.backoff * factor).min(self.policy.max_backoff),
        }
    }

    /// The policy this tracker applies.
    pub fn policy(&self) -> &RestartPolicy {
        &self.policy
    }

    /// Failures within the window as of the last one.
    pub fn recent_failures(&self) -> usize {
        self.failures.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backs_off_exponentially_then_gives_up() {
        let policy = RestartPolicy {
            max_restarts: 3,
            window: Duration::from_secs(10),
            backoff: Duration::from_millis(10),
            max_backoff: Duration::from_millis(25),
        };
        let mut t = RestartTracker::new(policy);
        let t0 = Instant::now();
        assert_eq!(t.on_failure(t0), RestartDecision::Restart { after: Duration::from_millis(10) });
        assert_eq!(t.on_failure(t0), RestartDecision::Restart { after: Duration::from_millis(20) });
        assert_eq!(t.on_failure(t0), RestartDecision::Restart { after: Duration::from_millis(25) });
        assert_eq!(t.on_failure(t0), RestartDecision::GiveUp);
    }

    #[test]
    fn failures_outside_the_window_are_forgotten() {
        let policy =
            RestartPolicy { max_restarts: 1, window: Duration::from_secs(1), ..Default::default() };
        let mut t = RestartTracker::new(policy);
        let t0 = Instant::now();
        assert!(matches!(t.on_failure(t0), RestartDecision::Restart { .. }));
        assert!(matches!(
            t.on_failure(t0 + Duration::from_secs(2)),
            RestartDecision::Restart { .. }
        ));
        assert_eq!(t.recent_failures(), 1);
    }
}
