//! The master's supervision tree, written once (STYLE.md item 6: actix 0.13's
//! `Supervisor` restarts only actors that *stop*, never on panic, with no limit and no
//! back-off, so the policy is ours).
//!
//! ```text
//! root: the actor system on the `gridlight-master` thread (master::start); one-for-one,
//! │     each child with a restart intensity (RestartPolicy: at most N restarts in T,
//! │     exponential back-off); past it the root stops: escalation
//! ├── scheduler        restart: a fresh job queue (frame numbers go on; queued jobs lost)
//! ├── frame assembler  restart: a fresh frame table (frames in flight lost and skipped,
//! │                    shown ones stay refused), the oldest frame decided afresh
//! ├── presenter        restart: nothing to replace (the frame it was handing over is lost)
//! ├── scene holder     restart: keeps the last good state (an immutable value)
//! ├── announcer        restart: nothing to replace (one datagram, repeated)
//! └── listener         restart: keeps its live connections; it supervises
//!     └── connection*  one per worker socket; a panic ends it with `Rejected`
//!                      (internal error): its held jobs are lost and counted
//!                      (`Counters::jobs_lost`), never redone, and the worker's
//!                      reconnection gets a fresh connection actor. A worker whose
//!                      connections keep failing (more than N in T) is refused for a
//!                      while and told why ([`peers`]: `Rejection::BackedOff`).
//! ```
//!
//! - [`guard`]: the one guard every actor runs its bodies under — handlers, timers
//!   (`run_later`/`run_interval` through [`GuardedTimers`]) and `started`
//!   ([`Supervised::on_start`]). A panic becomes an error at the actor's boundary
//!   instead of unwinding through the arbiter; the guard counts it and applies the
//!   actor's [`OnPanic`].
//! - [`restart`]: the restart intensity and back-off of a core actor (pure).
//! - [`peers`]: the listener's per-peer back-off (pure).
//! - [`inject`]: the fault-injection hook the tests drive the guard with.
//!
//! Escalation: past an actor's intensity the guard records why in
//! `Counters::escalation` (the actor, where, its panics, the last one) and stops the
//! actor system with code 1; the master thread then finishes the report with that
//! error and `MasterHandle::stop` returns it, so `gridlight master` exits non-zero
//! with a message naming the actor (`tests/supervision_escalation.rs`).

pub mod guard;
pub mod inject;
pub mod peers;
pub mod restart;

use std::any::Any;
use std::fmt;
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use guard::{Guard, GuardedTimers, OnPanic, Supervised, Supervision};
pub use inject::{PanicInjection, PanicPlan};
pub use peers::{PeerBackoff, PeerPolicy};
pub use restart::{RestartDecision, RestartPolicy, RestartTracker};

/// Which actor of the master: in log lines, escalation messages and fault injection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ActorKind {
    Scheduler,
    Assembler,
    Presenter,
    SceneHolder,
    Listener,
    Connection,
    Announcer,
}

impl ActorKind {
    /// Every actor, in the order of [`ActorKind::NAMES`].
    pub const ALL: [ActorKind; 7] = [
        Self::Scheduler,
        Self::Assembler,
        Self::Presenter,
        Self::SceneHolder,
        Self::Listener,
        Self::Connection,
        Self::Announcer,
    ];
    /// The names `--inject-panic` takes.
    pub const NAMES: [&'static str; 7] = [
        "scheduler",
        "assembler",
        "presenter",
        "scene-holder",
        "listener",
        "connection",
        "announcer",
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        Self::NAMES[Self::ALL.iter().position(|a| *a == self).unwrap_or_default()]
    }

    /// The actor of a command-line name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::NAMES.iter().position(|n| *n == name).map(|i| Self::ALL[i])
    }
}

impl fmt::Display for ActorKind {
    /// As a sentence names it ("the frame assembler panicked ...").
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Assembler => "frame assembler",
            Self::SceneHolder => "scene holder",
            other => other.name(),
        })
    }
}

/// Where in an actor a guarded body runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Site {
    /// `started`, and the start work re-run after each restart.
    Started,
    /// A message handler.
    Handler,
    /// A `run_later` or `run_interval` callback.
    Timer,
}

impl Site {
    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Started => "started",
            Self::Handler => "handler",
            Self::Timer => "timer",
        }
    }

    /// The site of a command-line name.
    pub fn from_name(name: &str) -> Option<Self> {
        [Self::Started, Self::Handler, Self::Timer].into_iter().find(|s| s.name() == name)
    }
}

impl fmt::Display for Site {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
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
/// handler, under the same guard as every other message.
#[derive(actix::Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct InjectPanic;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contain_turns_a_panic_into_its_message() {
        assert_eq!(contain(|| 4), Ok(4));
        assert_eq!(contain(|| -> u32 { panic!("boom {}", 7) }), Err("boom 7".to_owned()));
        assert_eq!(contain(|| -> u32 { panic!("static") }), Err("static".to_owned()));
    }

    #[test]
    fn every_actor_has_one_name_that_parses_back() {
        for actor in ActorKind::ALL {
            assert_eq!(ActorKind::from_name(actor.name()), Some(actor));
        }
        assert_eq!(ActorKind::Assembler.to_string(), "frame assembler");
        assert_eq!(Site::from_name("timer"), Some(Site::Timer));
    }
}
