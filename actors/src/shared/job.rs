//! A job: one set of one frame, with the scene state to render it with and the samples per
//! pixel to take. The scheduler makes it, the connection sends it and records who holds it.

use std::sync::Arc;

use crate::scene::state::SceneState;
use crate::wire::protocol::{FrameNo, SetNo};

/// One unit of work: render set `set` of frame `frame` with `state`, `spp` samples per
/// pixel (every job of a frame takes the same: the scheduler's `JobSize` when the frame
/// was opened).
#[derive(Clone, Debug)]
pub struct Job {
    pub frame: FrameNo,
    pub set: SetNo,
    pub state: Arc<SceneState>,
    pub spp: u32,
}
