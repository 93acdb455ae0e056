//! gridlight: interactive path tracing on a desktop grid.
//!
//! # Layout
//! - [`assets`]: loaded meshes, textures and environment maps.
//! - [`shapes`]: meshes of the built-in shapes (quad, cube, sphere).
//! - [`scene`]: scene files (TOML), loading them into a scene state and assets, the
//!   asset search path and the asset manifest.
//! - [`image_io`]: tonemapping and writing PNG/EXR images.
//! - [`cli`]: the command line (clap), one module per subcommand.
//! - [`children`]: child processes killed with their parent (the demo's workers).
//! - [`master`]: the master's glue: running it from a scene, composing shown frames
//!   (G-buffer, reconstruction, views), the headless sink.
//! - [`signals`]: Ctrl-C and SIGTERM as a callback (headless master and window).
//! - [`simgrid`]: simulated workers (modelled render time, cached real pixels) through
//!   the real worker link, for evaluating grids larger than this machine.
//! - [`testing`]: how a test that cannot run here says so (and fails under CI).
//! - [`worker`]: the worker runtime (connections, asset cache, render threads).
//! - [`gbuffer`]: the G-buffer (CPU primary rays or the wgpu raster pass, its WGSL beside it).
//! - [`reconstruct`]: spatio-temporal reconstruction, one module per pass (CPU kernel,
//!   WGSL, GPU binding), the CPU and GPU pipelines.
//! - [`gpu`]: device plumbing only (context, backend choice, compute passes, readback).
//! - [`render`]: the path tracer (BVHs, materials, lights, the per-pixel kernel).
//! - [`tools`]: benchmarks, evaluation, fault injection and the LAN testbed.
//! - [`window`]: the interactive window (winit + wgpu + egui) with live scene editing.
//!
//! The master's runtime (wire protocol, scene-state values, actors) lives in the
//! `gridlight-actors` crate, which this crate depends on and never the reverse.

pub mod assets;
pub mod children;
pub mod cli;
pub mod gbuffer;
pub mod gpu;
pub mod image_io;
pub mod master;
pub mod reconstruct;
pub mod render;
pub mod scene;
pub mod shapes;
pub mod signals;
pub mod simgrid;
pub mod testing;
pub mod tools;
pub mod window;
pub mod worker;

pub use gridlight_actors as actors;
