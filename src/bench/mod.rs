//! Benchmarks reported by `gridlight bench ...` (JSON lines), as opposed to tests:
//! speed is measured here, never asserted.
//!
//! - [`trace`]: single-thread throughput of the path-tracing kernel.
//! - [`master`]: frames per second and CPU per job of the master with null-render workers.
//! - [`waste`]: the useful fraction of returned results at each grid size.

pub mod master;
pub mod trace;
pub mod waste;
