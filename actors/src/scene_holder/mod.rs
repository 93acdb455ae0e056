//! The scene-state holder actor: owns the current [`SceneState`], applies edits (live
//! or from an interaction script), bumps the version on every change and tells the
//! scheduler, and the presenter when the edit happened (for the edit-to-display
//! latency). It is the only place a [`StateVersion`] is created.

use std::sync::Arc;
use std::time::Instant;

use actix::prelude::*;

use crate::messages::{ApplyEdit, CurrentState, EditApplied, EditMade, PlayScript, StateChanged};
use crate::scene::edit::{apply, Edit, EditError};
use crate::scene::state::{SceneState, StateVersion};
use crate::shared::counters::Counters;
use crate::shared::sets::SetTables;
use crate::supervision::{
    ActorKind, Guard, GuardedTimers, InjectPanic, RestartPolicy, Supervised, Supervision,
};

/// The current scene state and who hears about changes.
pub struct SceneHolder {
    state: Arc<SceneState>,
    changes_to: Recipient<StateChanged>,
    /// The presenter, which times each edit until a frame shows it.
    edits_to: Recipient<EditApplied>,
    /// The master's pixel sets: a new resolution must admit S sets before a state has it.
    sets: Option<Arc<SetTables>>,
    supervision: Supervision,
}

impl SceneHolder {
    pub fn new(
        state: Arc<SceneState>,
        changes_to: Recipient<StateChanged>,
        edits_to: Recipient<EditApplied>,
        counters: Arc<Counters>,
        policy: RestartPolicy,
    ) -> Self {
        let supervision = Supervision::restarting(ActorKind::SceneHolder, policy, counters);
        Self { state, changes_to, edits_to, sets: None, supervision }
    }

    /// Checks every new resolution against (and makes its tables in) `sets`.
    pub fn with_sets(mut self, sets: Arc<SetTables>) -> Self {
        self.sets = Some(sets);
        self
    }

    /// Applies an edit that happened at `at` (logged for the edit-to-display latency).
    fn apply(&mut self, edit: &Edit, at: Instant) -> Result<StateVersion, EditError> {
        let mut next = (*self.state).clone();
        apply(&mut next, edit)?;
        if let Some(sets) = self.sets.as_ref().filter(|_| next.resolution != self.state.resolution)
        {
            let res = next.resolution;
            sets.get(res).map_err(|e| EditError::Resolution {
                width: res.width,
                height: res.height,
                why: e.to_string(),
            })?;
        }
        next.version = self.state.version + 1;
        let version = next.version;
        self.state = Arc::new(next);
        self.edits_to.do_send(EditApplied { version, at });
        self.changes_to.do_send(StateChanged(self.state.clone()));
        Ok(version)
    }
}

impl Actor for SceneHolder {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }
}

impl Supervised for SceneHolder {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    /// Nothing to replace: the state is an immutable value, and keeping the last good
    /// one is the restart.
    fn restart(&mut self, _: &mut Context<Self>) {}
}

impl Handler<ApplyEdit> for SceneHolder {
    type Result = Result<StateVersion, EditError>;
    fn handle(&mut self, msg: ApplyEdit, ctx: &mut Context<Self>) -> Self::Result {
        self.guarded(ctx, |s, _| s.apply(&msg.0, Instant::now())).unwrap_or(Err(
            EditError::BadValue {
                field: "edit",
                expected: "an edit that applies",
                value: "one that made the scene holder panic (the last good state is kept)".into(),
            },
        ))
    }
}

impl Handler<PlayScript> for SceneHolder {
    type Result = ();
    fn handle(&mut self, msg: PlayScript, ctx: &mut Context<Self>) {
        for (at, edit) in msg.0 {
            ctx.run_later_guarded(at, move |act, _| match act.apply(&edit, Instant::now()) {
                Ok(version) => tracing::debug!(version, ?edit, "script edit applied"),
                Err(e) => tracing::warn!(cause = %e, ?edit, "script edit refused"),
            });
        }
    }
}

impl Handler<EditMade> for SceneHolder {
    type Result = ();
    fn handle(&mut self, msg: EditMade, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| match s.apply(&msg.edit, msg.at) {
            Ok(version) => tracing::trace!(version, "edit applied"),
            Err(e) => tracing::warn!(cause = %e, edit = ?msg.edit, "edit refused"),
        });
    }
}

impl Handler<CurrentState> for SceneHolder {
    type Result = Arc<SceneState>;
    fn handle(&mut self, _: CurrentState, _: &mut Context<Self>) -> Arc<SceneState> {
        self.state.clone()
    }
}

impl Handler<InjectPanic> for SceneHolder {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the scene holder"));
    }
}
