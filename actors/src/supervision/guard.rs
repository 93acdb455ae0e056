//! The one panic guard of the master's actors: every handler body ([`Guard::guarded`]),
//! timer callback ([`GuardedTimers`]) and the start work ([`Supervised::on_start`], run
//! from `started` by [`Guard::start_guarded`]) runs under it.
//!
//! A panic is contained at the actor's boundary, counted (`Counters::panics_contained`),
//! logged with the actor and the site, and handled by the actor's [`OnPanic`]: a core
//! actor restarts in place (its [`Supervised::restart`] replaces its pure logic, its
//! mailbox waits out the back-off, then its start work runs again), and past its
//! restart intensity the failure escalates and the actor system stops with code 1. A
//! connection ends instead: its supervisor, the listener, serves the worker's
//! reconnection with a fresh actor. The fault-injection plan ([`super::inject`]) is
//! asked before every body, so the tests reach each site through this same path.

use std::sync::Arc;
use std::time::{Duration, Instant};

use actix::prelude::*;

use super::inject::PanicPlan;
use super::restart::{RestartDecision, RestartPolicy, RestartTracker};
use super::{contain, ActorKind, Site};
use crate::shared::counters::Counters;

/// What a contained panic does to an actor.
#[derive(Debug)]
pub enum OnPanic {
    /// A core actor: restart in place within the intensity, escalate past it.
    Restart(RestartTracker),
    /// A connection: end (its restart is the worker's reconnection, served by a fresh
    /// actor); the listener's per-peer back-off bounds how often.
    End,
}

/// What the guard keeps in each supervised actor.
#[derive(Debug)]
pub struct Supervision {
    actor: ActorKind,
    on_panic: OnPanic,
    counters: Arc<Counters>,
    faults: Arc<PanicPlan>,
}

impl Supervision {
    /// A core actor that restarts under `policy`.
    pub fn restarting(actor: ActorKind, policy: RestartPolicy, counters: Arc<Counters>) -> Self {
        let on_panic = OnPanic::Restart(RestartTracker::new(policy));
        Self { actor, on_panic, counters, faults: Arc::default() }
    }

    /// An actor that ends on a panic (a connection).
    pub fn ending(actor: ActorKind, counters: Arc<Counters>) -> Self {
        Self { actor, on_panic: OnPanic::End, counters, faults: Arc::default() }
    }

    /// The actor this guards.
    pub fn actor(&self) -> ActorKind {
        self.actor
    }

    /// The injected panics, for the children this actor starts.
    pub fn faults(&self) -> Arc<PanicPlan> {
        Arc::clone(&self.faults)
    }
}

/// An actor under the guard.
pub trait Supervised: Actor<Context = Context<Self>> {
    /// Its guard's state.
    fn supervision(&mut self) -> &mut Supervision;

    /// The work of `started`; run again after each restart (its back-off over).
    fn on_start(&mut self, _ctx: &mut Context<Self>) {}

    /// After a contained panic: replace the pure logic with a fresh one
    /// ([`OnPanic::Restart`]), or end the actor ([`OnPanic::End`]).
    fn restart(&mut self, ctx: &mut Context<Self>);

    /// The same actor with injected panics (tests; see [`super::inject`]).
    fn with_faults(mut self, faults: Arc<PanicPlan>) -> Self
    where
        Self: Sized,
    {
        self.supervision().faults = faults;
        self
    }
}

/// Running bodies under the guard; implemented for every [`Supervised`] actor.
pub trait Guard: Supervised + Sized {
    /// Runs a handler body; `None` when it panicked (the actor's [`OnPanic`] has been
    /// applied).
    fn guarded<R>(
        &mut self,
        ctx: &mut Context<Self>,
        f: impl FnOnce(&mut Self, &mut Context<Self>) -> R,
    ) -> Option<R> {
        guard(self, ctx, Site::Handler, f)
    }

    /// Runs [`Supervised::on_start`]; call it from `Actor::started`.
    fn start_guarded(&mut self, ctx: &mut Context<Self>) {
        guard(self, ctx, Site::Started, |a, c| a.on_start(c));
    }
}

impl<A: Supervised> Guard for A {}

/// `run_later` and `run_interval` with their callbacks under the guard.
pub trait GuardedTimers<A: Supervised> {
    fn run_later_guarded<F>(&mut self, after: Duration, f: F) -> SpawnHandle
    where
        F: FnOnce(&mut A, &mut Context<A>) + 'static;

    fn run_interval_guarded<F>(&mut self, every: Duration, f: F) -> SpawnHandle
    where
        F: FnMut(&mut A, &mut Context<A>) + 'static;
}

impl<A: Supervised> GuardedTimers<A> for Context<A> {
    fn run_later_guarded<F>(&mut self, after: Duration, f: F) -> SpawnHandle
    where
        F: FnOnce(&mut A, &mut Context<A>) + 'static,
    {
        self.run_later(after, move |act, ctx| {
            guard(act, ctx, Site::Timer, f);
        })
    }

    fn run_interval_guarded<F>(&mut self, every: Duration, mut f: F) -> SpawnHandle
    where
        F: FnMut(&mut A, &mut Context<A>) + 'static,
    {
        self.run_interval(every, move |act, ctx| {
            guard(act, ctx, Site::Timer, |a, c| f(a, c));
        })
    }
}

/// Runs `f` at `site`; a panic (the injected ones included) goes to [`contained`].
fn guard<A: Supervised, R>(
    act: &mut A,
    ctx: &mut Context<A>,
    site: Site,
    f: impl FnOnce(&mut A, &mut Context<A>) -> R,
) -> Option<R> {
    let (actor, faults) = {
        let s = act.supervision();
        // Only the tests arm the plan: the hot path (every result) pays no clone.
        (s.actor, s.faults.armed().then(|| Arc::clone(&s.faults)))
    };
    let ran = contain(|| {
        if let Some(faults) = faults {
            faults.fire(actor, site);
        }
        f(act, ctx)
    });
    match ran {
        Ok(r) => Some(r),
        Err(panic) => {
            contained(act, ctx, site, &panic);
            None
        }
    }
}

/// Applies the actor's [`OnPanic`] after a panic at `site`.
fn contained<A: Supervised>(act: &mut A, ctx: &mut Context<A>, site: Site, panic: &str) {
    let s = act.supervision();
    let actor = s.actor;
    Counters::add(&s.counters.panics_contained, 1);
    let decision = match &mut s.on_panic {
        OnPanic::End => None,
        OnPanic::Restart(tracker) => Some(tracker.on_failure(Instant::now())),
    };
    match decision {
        None => {
            tracing::error!(actor = %actor, %site, cause = panic, "panic contained; ending");
            act.restart(ctx);
        }
        Some(RestartDecision::Restart { after }) => {
            tracing::error!(actor = %actor, %site, cause = panic,
                backoff_ms = after.as_millis() as u64, "panic contained; restarting");
            act.restart(ctx);
            // The mailbox waits out the back-off; then the start work runs again.
            let backoff = actix::fut::wrap_future::<_, A>(actix::clock::sleep(after));
            ctx.wait(backoff.map(|_, act, ctx| act.start_guarded(ctx)));
        }
        Some(RestartDecision::GiveUp) => escalate(s, site, panic),
    }
}

/// Past the restart intensity: records why and stops the actor system (code 1).
fn escalate(s: &Supervision, site: Site, panic: &str) {
    let OnPanic::Restart(tracker) = &s.on_panic else { return };
    let why = format!(
        "the {} panicked {} times within {:?} (more than its restart intensity allows); last panic, in its {site}: {panic}",
        s.actor,
        tracker.recent_failures(),
        tracker.policy().window,
    );
    tracing::error!(actor = %s.actor, %site, cause = panic, "restart intensity exceeded; stopping the master");
    let mut slot = s.counters.escalation.lock().unwrap_or_else(|p| p.into_inner());
    slot.get_or_insert(why);
    System::current().stop_with_code(1);
}
