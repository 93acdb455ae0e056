//! A simulated desktop grid: workers that model render time instead of spending it and
//! return real path-traced pixels, so that grids of up to hundreds of workers can be
//! evaluated on one small machine (issue 15, `gridlight eval`).
//!
//! What is modelled: each job's render time ([`cost`]: the per-core throughput measured
//! by the real path tracer on this machine for this scene, with its spread) and which
//! workers are available ([`availability`]). What is real: the pixels (path-traced once
//! beforehand, [`frames`]), the worker link and protocol, every TCP connection, the
//! master with its scheduler, wait heuristic and reconstruction.
//!
//! - [`cost`]: measuring and sampling job times.
//! - [`frames`]: the cache of path-traced frames, found by scene-state content.
//! - [`availability`]: `R_i` curves.
//! - [`renderer`]: the renderer that stands in a worker's render thread.
//! - [`process`]: many simulated workers in one process (`gridlight simgrid`).

pub mod availability;
pub mod cost;
pub mod frames;
pub mod process;
pub mod renderer;

pub use availability::{Availability, Curve};
pub use cost::CostModel;
pub use frames::FrameCache;
pub use renderer::{SimConnection, SimGrid};
