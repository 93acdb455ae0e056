//! gridlight's master runtime: the wire protocol and its codec, the scene-state
//! values that travel in it, and every actix actor of the master.
//!
//! This crate knows nothing of rendering, windows or wgpu: the presenter hands
//! frames to a sink trait, and the `gridlight` crate plugs the renderer, the
//! reconstruction and the window into it (docs/design.md, "Layout").
//!
//! # Layout: one folder per role
//! - [`wire`]: what travels between master and workers (messages, codec, auth,
//!   integrity, packing, counted sockets). [`scene`]: the values it carries (scene state,
//!   edits, scripts, assets).
//! - One folder per actor, the actor in its `mod.rs` and its pure partners beside it:
//!   [`listener`], [`connection`] (+ its protocol state), [`scheduler`] (+ job queue,
//!   hand-out plan), [`assembler`] (a frame's whole life: + frame table, pacer, wait
//!   heuristic, the rule around edits, accumulation), [`presenter`] (shown frames to the
//!   sink: + sink, stats, edit latency), [`scene_holder`], [`discovery`] (+ the announcer
//!   actor); [`supervision`] is the restart policy they share.
//! - [`shared`]: the values several actors share (pixel sets, jobs, pacing, packed
//!   frames, the worker table, the counters); [`messages`]: every message between the
//!   actors, by topic.
//! - Entry point: [`master::start`] → [`master::MasterHandle`].
//!
//! # Where messages live
//! Every message between actors, and from the master's handle to an actor, lives in
//! [`messages`]; an actor's messages to itself stay in its folder. Wire messages live in
//! [`wire::protocol`]. An actor folder imports no other actor's folder (the listener
//! alone makes connection actors): `actors/tests/layout.rs`.
//!
//! # The result path runs one way
//! Scheduler → (connection → worker → connection) → assembler → presenter → sink thread.
//! Each fact has one keeper: who holds which job, the record in [`shared::holdings`]
//! (entered at hand-out, taken back by the connection); every check of a result, the
//! connection's protocol state; a frame's results, its timing and the decision to show it, the
//! assembler; the dropped counts, `Counters`; accumulation, the assembler's decision,
//! carried with the frame. Where an answer must go back (a frame displayed, a sink
//! place freed, jobs for credits), the request carries the address, so the actors are
//! made in one direction ([`master`]).
//!
//! # The crate's face
//! The modules that the worker side and the `gridlight` binary use are re-exported at
//! the crate root under their own names (`gridlight_actors::protocol`, `::state`, ...),
//! so that callers name what they use, not where it sits inside this crate.

pub mod assembler;
pub mod connection;
pub mod discovery;
pub mod listener;
pub mod master;
pub mod messages;
pub mod presenter;
pub mod scene;
pub mod scene_holder;
pub mod scheduler;
pub mod shared;
pub mod supervision;
pub mod wire;

pub use assembler::{accumulation, wait_heuristic};
pub use discovery::announcer;
pub use presenter::{sink, stats};
pub use scene::{asset_store, edit, script, state};
pub use shared::{counters, cpu_clock, pacing, packed_frame, sets, workers};
pub use wire::{auth, channel, channel_codec, codec, integrity, packing, protocol, rejection};
