//! A budget of log lines per period: lines that name one peer each (a connection rejected
//! before it authenticated) are written up to [`PEER_LINES`] per [`PERIOD`], so a flood
//! cannot fill the log with them; the listener's summaries count every one.

use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The period of the budget (the listener's summary period).
pub const PERIOD: Duration = Duration::from_secs(5);

/// Lines allowed per [`PERIOD`].
pub const PEER_LINES: u32 = 32;

/// How many lines naming a refused peer may still be written in this period.
#[derive(Debug)]
pub struct LineBudget(Mutex<(Instant, u32)>);

impl Default for LineBudget {
    fn default() -> Self {
        Self(Mutex::new((Instant::now(), 0)))
    }
}

impl LineBudget {
    /// True when one more line may be written at `now`.
    pub fn allow(&self, now: Instant) -> bool {
        let mut b = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if now.saturating_duration_since(b.0) >= PERIOD {
            *b = (now, 0);
        }
        b.1 += 1;
        b.1 <= PEER_LINES
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_naming_peers_are_limited_per_period() {
        let b = LineBudget::default();
        let t = Instant::now();
        assert!((0..PEER_LINES).all(|_| b.allow(t)));
        assert!(!b.allow(t));
        assert!(b.allow(t + PERIOD), "a new period");
    }
}
