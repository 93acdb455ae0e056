//! Every message the master's actors send one another, and those the master's handle
//! sends them, by topic (ARCHITECTURE.md's message map lists who sends each to whom):
//!
//! - [`jobs`]: connection ↔ scheduler (credits, jobs, answers, a worker gone);
//! - [`frames`]: scheduler ↔ assembler, connection → assembler (a frame's life, results);
//! - [`display`]: assembler ↔ presenter, scene holder → presenter (shown and skipped
//!   frames, the sink's places, when edits happened);
//! - [`control`]: the handle → scene holder, scheduler, assembler (edits, pacing), and
//!   the scene holder's new states;
//! - [`connections`]: connection ↔ listener (an ended connection, test hooks).
//!
//! An actor's messages to itself (an accepted socket, the sink thread's news) stay in its
//! folder. Messages are imported from here, never from another actor's folder
//! (`actors/tests/layout.rs`).

pub mod connections;
pub mod control;
pub mod display;
pub mod frames;
pub mod jobs;

pub use connections::*;
pub use control::*;
pub use display::*;
pub use frames::*;
pub use jobs::*;
