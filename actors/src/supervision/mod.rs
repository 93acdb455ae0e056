//! Our restart policy (STYLE.md item 6): actix 0.13's `Supervisor` restarts only actors
//! that *stop*, never on panic, with no limit and no back-off, so the policy is ours.
//!
//! - [`contain`] runs a handler body under `catch_unwind`: a panic becomes an error at
//!   the actor boundary instead of unwinding through the actix arbiter (which would
//!   take the whole master down).
//! - [`RestartPolicy`] is one-for-one with an intensity limit (at most `max_restarts`
//!   within `window`) and exponential back-off; past the limit the failure escalates
//!   and the master stops, as in OTP.
//!
//! Core actors (scheduler, assembler, display, scene holder) keep their logic in pure
//! structs; a contained panic makes them replace that struct with a fresh one (keeping
//! only the monotonic counters: frame numbers, the displayed boundary) after the
//! back-off. A connection actor's state is its socket: restarting it means ending it —
//! its jobs are not recomputed — and serving the worker again when it reconnects. (A
//! per-peer back-off for workers whose connections keep failing is not written yet.)
//!
//! Escalation: past the intensity, [`after_panic`] records why in
//! `Counters::escalation` (the actor, its panics, the last one) and stops the actor
//! system with code 1; the master thread then finishes the report with that error and
//! `MasterHandle::stop` returns it, so a headless master exits non-zero naming the actor.

use std::any::Any;
use std::collections::VecDeque;
use std::panic::{catch_unwind, AssertUnwindSafe};
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

/// Runs `f`, turning a panic into `Err(message)`.
pub fn contain<R>(f: impl FnOnce() -> R) -> Result<R, String> {
    catch_unwind(AssertUnwindSafe(f)).map_err(|p| panic_message(&*p))
}

fn panic_message(p: &(dyn Any + Send)) -> String {
    if let Some(s) = p.downcast_ref::<&str>() {
        (*s).to_owned()
    } else if let Some(s) = p.downcast_ref::<String>() {
        s.clone()
    } else {
        "panic with a non-string payload".to_owned()
    }
}

/// Test hook for the fault-injection suites: the receiving actor panics inside its
/// handler, under the same containment as every other message.
#[derive(actix::Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct InjectPanic;

/// Applies the policy after a panic contained in actor `who`: logs it, counts it and
/// either pauses the actor's mailbox for the back-off and returns `true` (the caller
/// then replaces its logic with a fresh one), or stops the actor system (escalation)
/// and returns `false`.
pub fn after_panic<A>(
    who: &str,
    message: &str,
    tracker: &mut RestartTracker,
    counters: &crate::presenter::stats::Counters,
    ctx: &mut actix::Context<A>,
) -> bool
where
    A: actix::Actor<Context = actix::Context<A>>,
{
    use actix::AsyncContext;
    crate::presenter::stats::Counters::add(&counters.panics_contained, 1);
    match tracker.on_failure(Instant::now()) {
        RestartDecision::Restart { after } => {
            tracing::error!(
                actor = who,
                cause = message,
                backoff_ms = after.as_millis() as u64,
                "panic contained; restarting"
            );
            ctx.wait(actix::fut::wrap_future::<_, A>(actix::clock::sleep(after)));
            true
        }
        RestartDecision::GiveUp => {
            tracing::error!(
                actor = who,
                cause = message,
                "restart intensity exceeded; stopping the master"
            );
            let why = format!(
                "the {who} panicked {} times within {:?} (more than its restart intensity allows); last panic: {message}",
                tracker.recent_failures(),
                tracker.policy().window,
            );
            let mut slot = counters.escalation.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert(why);
            actix::System::current().stop_with_code(1);
            false
        }
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

    #[test]
    fn contain_turns_a_panic_into_its_message() {
        assert_eq!(contain(|| 4), Ok(4));
        assert_eq!(contain(|| -> u32 { panic!("boom {}", 7) }), Err("boom 7".to_owned()));
        assert_eq!(contain(|| -> u32 { panic!("static") }), Err("static".to_owned()));
    }
}
