//! A job: one set of one frame, with the scene state to render it with. The scheduler
//! makes it, the connection sends it and records who holds it.

use std::sync::Arc;

use crate::scene::state::SceneState;
use crate::wire::protocol::{FrameNo, SetNo};

/// One unit of work: render set `set` of frame `frame` with `state`.
#[derive(Clone, Debug)]
pub struct Job {
    pub frame: FrameNo,
    pub set: SetNo,
    pub state: Arc<SceneState>,
}
