//! Where shown frames go: the [`FrameSink`] trait the headless writer, the
//! reconstruction and the window implement, and the thread that drives it.
//!
//! The sink runs on its own thread so that writing files or reconstructing never
//! blocks the actor system; the assembler lets at most a couple of frames at a time reach it
//! and waits for it (back-pressure) rather than queueing frames without bound.

use std::sync::mpsc::{Receiver, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;

use glam::Vec3;
use thiserror::Error;

use crate::presenter::stats::FrameStats;
use crate::scene::state::SceneState;
use crate::shared::packed_frame::PackedFrame;
use crate::shared::sets::SetTable;
use crate::supervision::contain;
use crate::wire::protocol::ConnId;
use crate::wire::protocol::{FrameNo, SetNo};

/// One frame the frame assembler decided to show.
#[derive(Clone, Debug)]
pub struct ShownFrame {
    pub frame: FrameNo,
    /// The scene state the frame was rendered with.
    pub state: Arc<SceneState>,
    /// This frame's results only, as workers sent them: reflected radiance per pixel, not
    /// demodulated (zero where not covered).
    pub current: Vec<Vec3>,
    /// Pixels covered by a result of this frame.
    pub current_mask: Vec<bool>,
    /// Which worker rendered which pixels (the `workers` view).
    pub owners: Owners,
    pub stats: FrameStats,
}

/// Which connection's result covers each set of a frame.
#[derive(Clone, Debug, Default)]
pub struct Owners {
    /// Per set: the connection whose result was accepted.
    pub per_set: Vec<Option<ConnId>>,
    /// The frame's pixel sets (`None`: unknown, every pixel is unowned).
    pub sets: Option<Arc<SetTable>>,
}

impl Owners {
    /// The owner of each of the frame's `n` pixels (`None` for holes).
    pub fn per_pixel(&self, n: usize) -> Vec<Option<ConnId>> {
        let mut out = vec![None; n];
        let Some(sets) = &self.sets else { return out };
        for (set, owner) in self.per_set.iter().enumerate() {
            let Some(owner) = owner else { continue };
            for &p in sets.pixels(set as SetNo).unwrap_or(&[]) {
                if let Some(slot) = out.get_mut(p as usize) {
                    *slot = Some(*owner);
                }
            }
        }
        out
    }
}

/// A shown frame on its way to the sink thread, its results still packed: unpacking
/// them is the sink thread's work, not the actor system's.
#[derive(Debug)]
pub struct PackedShownFrame {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
    pub results: PackedFrame,
    /// Per set, the connection whose result was accepted.
    pub owners: Vec<Option<ConnId>>,
    pub stats: FrameStats,
}

impl PackedShownFrame {
    /// The frame with per-pixel radiance and coverage.
    pub fn unpack(self) -> ShownFrame {
        let (current, current_mask) = self.results.unpack();
        let owners = Owners { per_set: self.owners, sets: Some(self.results.set_table().clone()) };
        ShownFrame {
            frame: self.frame,
            state: self.state,
            current,
            current_mask,
            owners,
            stats: self.stats,
        }
    }
}

/// Why a sink could not take a frame; the master stops when its sink fails.
#[derive(Debug, Error)]
pub enum SinkError {
    #[error("i/o error: {0}")]
    Io(#[from] std::io::Error),
    /// The window (or whatever consumes frames) went away.
    #[error("the frame consumer was closed")]
    Closed,
    /// Anything else the sink's own code reports (composing, writing a file, ...).
    #[error("{0}")]
    Other(#[source] Box<dyn std::error::Error + Send + Sync>),
}

/// Told each new scene state as soon as the scene changes (on the actor thread: it must
/// not block), so that a sink can prepare what frames of that state will need.
pub type Preparer = Box<dyn Fn(Arc<SceneState>) + Send>;

/// Consumes shown frames, in frame order, on the sink thread.
pub trait FrameSink: Send + 'static {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError>;
    /// What to tell about new scene states before any of their frames is shown (the
    /// compose computes their G-buffers ahead); asked once, before the sink thread starts.
    fn preparer(&mut self) -> Option<Preparer> {
        None
    }
    /// Called once after the last frame, when the master stops.
    fn finish(&mut self) {}
}

/// What the sink thread reports back after each frame.
pub type SinkOutcome = Result<(), SinkFailure>;

/// A frame the sink did not show; the master stops on it.
#[derive(Debug, Error)]
pub enum SinkFailure {
    #[error("frame sink failed on frame {frame}: {source}")]
    Failed { frame: FrameNo, source: SinkError },
    #[error("frame sink panicked on frame {frame}: {panic}")]
    Panicked { frame: FrameNo, panic: String },
}

/// Starts the sink thread: it unpacks and shows every frame received on the returned sender and
/// calls `done` after each; when the sender is dropped it calls `finish` and ends.
pub fn spawn_sink(
    mut sink: Box<dyn FrameSink>,
    capacity: usize,
    done: impl Fn(SinkOutcome) + Send + 'static,
) -> std::io::Result<(SyncSender<PackedShownFrame>, JoinHandle<()>)> {
    let (tx, rx): (SyncSender<PackedShownFrame>, Receiver<PackedShownFrame>) =
        std::sync::mpsc::sync_channel(capacity);
    let thread = std::thread::Builder::new().name("gridlight-sink".into()).spawn(move || {
        while let Ok(frame) = rx.recv() {
            let n = frame.frame;
            let outcome = match contain(|| sink.show(frame.unpack())) {
                Ok(Ok(())) => Ok(()),
                Ok(Err(source)) => Err(SinkFailure::Failed { frame: n, source }),
                Err(panic) => Err(SinkFailure::Panicked { frame: n, panic }),
            };
            let failed = outcome.is_err();
            done(outcome);
            if failed {
                break;
            }
        }
        if let Err(p) = contain(|| sink.finish()) {
            tracing::error!(cause = %p, "frame sink panicked in finish");
        }
    })?;
    Ok((tx, thread))
}
