//! What the master's handle asks of the actors (edits, scripts, pacing), and the scene
//! holder's news for the scheduler.

use std::sync::Arc;
use std::time::{Duration, Instant};

use actix::prelude::*;

use crate::scene::edit::{Edit, EditError};
use crate::scene::state::{SceneState, StateVersion};
use crate::shared::pacing::{Pacing, PacingError};

/// Apply one edit; answers the new version.
#[derive(Message, Debug, Clone)]
#[rtype(result = "Result<StateVersion, EditError>")]
pub struct ApplyEdit(pub Edit);

/// Apply an edit made at `at` (the window's input event); nothing is answered.
#[derive(Message, Debug, Clone)]
#[rtype(result = "()")]
pub struct EditMade {
    pub edit: Edit,
    pub at: Instant,
}

/// Apply each edit at its time after now.
#[derive(Message)]
#[rtype(result = "()")]
pub struct PlayScript(pub Vec<(Duration, Edit)>);

/// The current state.
#[derive(Message)]
#[rtype(result = "Arc<SceneState>")]
pub struct CurrentState;

/// The scene state changed: new frames use it.
#[derive(Message, Clone)]
#[rtype(result = "()")]
pub struct StateChanged(pub Arc<SceneState>);

/// Frames are paced this way from now on (the quota and deadlines follow).
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct PacingChanged(pub Pacing);

/// Changes how frames are paced from now on (the window's sliders).
#[derive(Message)]
#[rtype(result = "Result<(), PacingError>")]
pub struct SetPacing(pub Pacing);
