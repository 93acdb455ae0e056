//! Fault injection (issue 6): the parts that tests and `gridlight soak` use to prove
//! that nothing a desktop grid does can break the master.
//!
//! - [`proxy`]: a TCP proxy between workers and master that delays, drops, truncates,
//!   corrupts, stalls or cuts, and can capture the bytes it forwards.
//! - [`invariants`]: the checks every run makes on shown frames and counters.
//! - [`curve`]: the paper's resource curve R_i for varying the live workers.
//! - [`rss`]: resident-set sampling from `/proc`.
//! - [`harness`]: a master (in-process) and real worker processes on loopback, with
//!   every fault of the list at hand.
//! - [`soak`]: random faults for a bounded time (`gridlight soak`).
//!
//! The harness and the soak stop and continue worker processes with POSIX signals
//! (SIGSTOP, SIGCONT): they are compiled on Unix only, and `gridlight soak` says so
//! elsewhere.

pub mod curve;
#[cfg(unix)]
pub mod harness;
pub mod invariants;
pub mod proxy;
pub mod rss;
#[cfg(unix)]
pub mod soak;
