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
//! - [`headless`]: the headless frame sink (G-buffer, PNG frames, statistics).
//! - [`master_cmd`]: running a master from a scene file (`master` and `demo` commands).
//! - [`signals`]: Ctrl-C and SIGTERM as a callback (headless master and window).
//! - [`worker`]: the worker runtime (connections, asset cache, render threads).
//! - [`reconstruct`]: G-buffer and spatio-temporal reconstruction, CPU reference.
//! - [`eval`]: evaluation of reconstruction (paper Figures 3, 8, 9) and image metrics (FLIP, SSIM, RMSE).
//! - [`faults`]: fault injection: TCP proxy, invariant checks, worker harness, RSS.
//! - [`lan`]: separate network hosts on one machine (namespaces, bridge, rate-limited links).
//! - [`gpu`]: wgpu context and the reconstruction compute passes (WGSL in `shaders/`).
//! - [`render`]: the path tracer (BVHs, materials, lights, the per-pixel kernel).
//! - [`bench`]: benchmarks behind `gridlight bench` (kernel and master throughput).
//! - [`window`]: the interactive window (winit + wgpu + egui) with live scene editing.
//!
//! The master's runtime (wire protocol, scene-state values, actors) lives in the
//! `gridlight-actors` crate, which this crate depends on and never the reverse.

pub mod assets;
pub mod bench;
pub mod children;
pub mod cli;
pub mod compose;
pub mod eval;
pub mod faults;
pub mod gbuffer_ahead;
pub mod gpu;
pub mod headless;
pub mod image_io;
pub mod lan;
pub mod master_cmd;
pub mod reconstruct;
pub mod render;
pub mod scene;
pub mod shapes;
pub mod signals;
pub mod view;
pub mod window;
pub mod worker;

pub use gridlight_actors as actors;
