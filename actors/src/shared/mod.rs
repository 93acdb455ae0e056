//! Values several actors share, none of them an actor's own: they live here, not in one
//! actor's folder, so that no two actor folders import each other
//! (`actors/tests/layout.rs`).
//!
//! - [`sets`]: the pixel sets (`SetTable`), derived the same way by master and workers;
//! - [`job`]: one set of one frame with its scene state; [`holdings`]: who holds which
//!   job, the master's one record of it;
//! - [`pacing`]: how frames are paced (the wait heuristic's parameters or a fixed rate);
//! - [`packed_frame`]: a frame's accepted results, packed, and the frame closed for display;
//! - [`workers`]: the table of connected workers (the status panel's rows);
//! - [`counters`]: the master run's counters;
//! - [`cpu_clock`]: the calling thread's CPU time (the master's cost per result).

pub mod counters;
pub mod cpu_clock;
pub mod holdings;
pub mod job;
pub mod line_budget;
pub mod pacing;
pub mod packed_frame;
pub mod sets;
pub mod workers;
