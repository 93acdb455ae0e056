//! Tools beside the core: measuring and stress-testing gridlight, never on a master's or a
//! worker's path.
//!
//! - [`bench`]: `gridlight bench ...` (kernel, master, reconstruction, waste, across
//!   hosts, a desk owner's program beside a worker).
//! - [`eval`]: evaluation of reconstruction (paper Figures 3, 8, 9) and image metrics.
//! - [`faults`]: fault injection: TCP proxy, invariant checks, worker harness, soak, RSS.
//! - [`lan`]: separate network hosts on one machine (namespaces, bridge, rate-limited
//!   links) for `bench lan` and `tests/lan.rs`.

pub mod bench;
pub mod eval;
pub mod faults;
pub mod lan;
