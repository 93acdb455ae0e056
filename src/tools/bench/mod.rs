//! Benchmarks reported by `gridlight bench ...` (JSON lines), as opposed to tests:
//! speed is measured here, never asserted.
//!
//! - [`trace`]: single-thread throughput of the path-tracing kernel.
//! - [`master`]: frames per second and CPU per job of the master with null-render workers
//!   ([`join`]: one worker connection's join, timed).
//! - [`lan`]: frames per second and bytes per frame across namespace hosts behind
//!   rate-limited links, beside the bandwidth bound.
//! - [`owner_impact`]: a desk owner's CPU-bound program alone and beside a rendering
//!   worker ([`busy_loop`] is that program).
//! - [`waste`]: the useful fraction of returned results at each grid size.
//! - [`reconstruct`]: milliseconds per frame of reconstruction and of the G-buffer.
//! - [`compose`]: the master's compose per shown frame, stage by stage, moving and resting.

pub mod busy_loop;
pub mod compose;
pub mod join;
pub mod lan;
pub mod master;
pub mod owner_impact;
pub mod reconstruct;
pub mod trace;
pub mod trace_gpu;
pub mod waste;
