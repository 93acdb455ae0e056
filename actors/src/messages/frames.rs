//! A frame's life before the display decides on it: the scheduler tells the assembler of
//! each frame and its first hand-out, the connections bring the results, and the assembler
//! tells the scheduler which frames are displayed.

use std::sync::Arc;

use actix::prelude::*;

use crate::scene::state::SceneState;
use crate::wire::protocol::{ConnId, FrameNo, JobResult};

/// To the assembler: all sets of `frame` were queued with `state`. `displayed_to` is where
/// its display is told (the scheduler's own address: replies travel with the request, so
/// the actors are wired in one direction).
#[derive(Message, Clone)]
#[rtype(result = "()")]
pub struct FrameScheduled {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
    /// Samples per pixel of each of its jobs.
    pub spp: u32,
    pub displayed_to: Recipient<FrameDisplayed>,
}

/// To the assembler: the first job of `frame` was handed out (the start of its
/// computation, from which the wait heuristic measures its time).
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct FrameStarted {
    pub frame: FrameNo,
}

/// To the assembler: frames before `before` were made with an outdated scene state; their
/// queued jobs were discarded, so only results already held by workers can still come.
/// Such a frame is shown at once with what it has (or skipped when empty) instead of
/// waiting for them ([`new_view`](crate::assembler::new_view)).
#[derive(Message, Debug, Clone)]
#[rtype(result = "()")]
pub struct FramesOutdated {
    pub before: FrameNo,
    /// The new state, which the frames from `before` on have.
    pub state: Arc<SceneState>,
}

/// To the assembler: frames before `before` lost their queued jobs (the scheduler
/// restarted) and will get no results beyond those already handed out. Waiting for them
/// says nothing about the workers' speed, so they are decided at once.
#[derive(Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct FramesAbandoned {
    pub before: FrameNo,
}

/// The assembler showed or skipped `frame`: jobs of it and earlier frames are discarded.
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct FrameDisplayed {
    pub frame: FrameNo,
}

/// A connection received the answer to a job it holds, checked by its protocol state.
#[derive(Message)]
#[rtype(result = "()")]
pub struct ResultArrived {
    pub conn: ConnId,
    pub result: JobResult,
}
