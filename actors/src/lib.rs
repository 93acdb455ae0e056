//! gridlight's master runtime: the wire protocol and its codec, the scene-state
//! values that travel in it, and every actix actor of the master.
//!
//! This crate knows nothing of rendering, windows or wgpu: the display actor hands
//! frames to a sink trait, and the `gridlight` crate plugs the renderer, the
//! reconstruction and the window into it (DESIGN.md, Layout).
//!
//! # Layout
//! - Wire: [`protocol`] (messages and invariants), [`codec`] (length-prefixed
//!   MessagePack), [`auth`] (HMAC challenge), [`integrity`] (per-result tags),
//!   [`packing`] (RGB9E5), [`sets`] (pixel sets), [`discovery`] (the LAN announcement).
//! - Values: [`state`] (scene state), [`edit`] and [`script`] (changes to it).
//! - Actors, one per file: [`listener`], [`connection`], [`scheduler`], [`assembler`],
//!   [`display`], [`scene_holder`], [`announcer`]; their pure logic: [`job_queue`], [`handout_plan`],
//!   [`frame_table`], [`wait_heuristic`], [`accumulate`]; [`supervisor`] is the restart policy.
//! - Entry point: [`master::start`] → [`master::MasterHandle`]; frames leave through a
//!   [`sink::FrameSink`]; [`stats`], [`edit_latency`] and [`asset_store`] support them.

pub mod accumulate;
pub mod announcer;
pub mod assembler;
pub mod asset_store;
pub mod auth;
pub mod codec;
pub mod connection;
pub mod counted_io;
pub mod discovery;
pub mod display;
pub mod edit;
pub mod edit_latency;
pub mod frame_table;
pub mod handout_plan;
pub mod integrity;
pub mod job_queue;
pub mod listener;
pub mod master;
pub mod new_view;
pub mod packed_frame;
pub mod packing;
pub mod protocol;
pub mod scene_holder;
pub mod scheduler;
pub mod script;
pub mod sets;
pub mod sink;
pub mod state;
pub mod stats;
pub mod supervisor;
pub mod wait_heuristic;
pub mod workers;
