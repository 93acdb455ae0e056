//! gridlight: interactive path tracing on a desktop grid.
//!
//! # Layout
//! - [`assets`]: loaded meshes, textures and environment maps.
//! - [`shapes`]: meshes of the built-in shapes (quad, cube, sphere).
//! - [`cli`]: the command line (clap), one module per subcommand.
//! - [`children`]: child processes killed with their parent (the demo's workers).
//! - [`worker`]: the worker runtime (connections, asset cache, render threads).
//! - [`reconstruct`]: G-buffer and spatio-temporal reconstruction, CPU reference.
//! - [`gpu`]: wgpu context and the reconstruction compute passes (WGSL in `shaders/`).
//!
//! The master's runtime (wire protocol, scene-state values, actors) lives in the
//! `gridlight-actors` crate, which this crate depends on and never the reverse.

pub mod assets;
pub mod children;
pub mod cli;
pub mod gpu;
pub mod reconstruct;
pub mod shapes;
pub mod worker;

pub use gridlight_actors as actors;
