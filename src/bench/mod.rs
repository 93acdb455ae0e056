//! Benchmarks reported by `gridlight bench ...` (JSON lines), as opposed to tests:
//! speed is measured here, never asserted.
//!
//! - [`trace`]: single-thread throughput of the path-tracing kernel.
//! - [`master`]: frames per second and CPU per job of the master with null-render workers.

pub mod master;
pub mod trace;
