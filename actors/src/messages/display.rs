//! The display: the assembler hands shown and skipped frames to the presenter, which frees
//! the sink's places; the scene holder tells the presenter when each edit happened.

use std::sync::Arc;
use std::time::{Duration, Instant};

use actix::prelude::*;

use crate::scene::state::{SceneState, StateVersion};
use crate::shared::packed_frame::ClosedFrame;
use crate::wire::protocol::FrameNo;

/// To the presenter: the assembler shows this frame.
#[derive(Message)]
#[rtype(result = "()")]
pub struct FrameShown {
    pub closed: ClosedFrame,
    /// Q_t and I_t when it was decided.
    pub q: f64,
    pub i: f64,
    /// Time from the start of the frame to its decision.
    pub wait: Duration,
    /// Shown frames of its scene state, this one included (1: accumulation starts over).
    pub accumulated_frames: u32,
    /// Told when the sink is done with it.
    pub freed_to: Recipient<SinkFreed>,
}

/// To the presenter: the assembler skipped `frame` (Q_min not reached by I_max, or
/// passed over), with `back` results that are never used.
#[derive(Message, Clone, Copy, Debug)]
#[rtype(result = "()")]
pub struct FrameSkipped {
    pub frame: FrameNo,
    pub back: u32,
}

/// To the presenter: a new scene state; the sink may prepare for it (G-buffer ahead).
#[derive(Message)]
#[rtype(result = "()")]
pub struct PrepareState(pub Arc<SceneState>);

/// The sink is done with a frame handed over with [`FrameShown`] (or never took it).
#[derive(Message)]
#[rtype(result = "()")]
pub struct SinkFreed;

/// To the presenter: the scene holder applied the edit that made `version`; the edit
/// happened at `at` (for the edit-to-display latency of the first frame that shows it).
#[derive(Message, Clone, Copy, Debug)]
#[rtype(result = "()")]
pub struct EditApplied {
    pub version: StateVersion,
    pub at: Instant,
}

/// Stop showing frames, let the sink finish, then stop the actor system.
#[derive(Message)]
#[rtype(result = "()")]
pub struct Shutdown;
