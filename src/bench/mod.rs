//! Benchmarks reported by `gridlight bench ...` (JSON lines), as opposed to tests:
//! speed is measured here, never asserted.
//!
//! - [`trace`]: single-thread throughput of the path-tracing kernel.

pub mod trace;
