//! Separate network hosts on one Linux machine, for proving gridlight across hosts rather
//! than on loopback (issue 14): `gridlight bench lan` and `tests/lan.rs`.
//!
//! A [`Testbed`] is one network namespace per host (a master and N worker hosts) plus one
//! for the switch, a Linux bridge. Each host has one veth link to the switch, rate-limited
//! in both directions by a token bucket (`tc qdisc ... tbf`; `netem` is not available on
//! the machines this runs on, so there is no added latency: the fault proxy in
//! `src/faults/proxy.rs` delays where that is wanted). Every interface lives inside the
//! testbed's own namespaces, none in the machine's, so traffic can only go between the
//! testbed's hosts; addresses are private (10.77.0.0/24) and cannot clash with another
//! testbed's, which has its own namespaces.
//!
//! - [`ip`]: running `ip` and `tc`, with their errors.
//! - [`testbed`]: building and tearing down the namespaces (a drop guard: also on error and
//!   panic), link counters.
//! - [`netns`]: running a closure on a thread inside a host's namespace (the benchmark's
//!   in-process master).
//!
//! Needs Linux, root (`CAP_NET_ADMIN`) and iproute2; [`Testbed::unavailable`] says why
//! not. Elsewhere the module compiles, its system calls gated to Linux, and every entry
//! point answers [`LanError::NotLinux`].

pub mod ip;
pub mod netns;
pub mod testbed;

pub use testbed::{Host, LinkCounters, Testbed, TestbedSpec};

/// Why a testbed could not be built or used.
#[derive(Debug, thiserror::Error)]
pub enum LanError {
    #[error("network namespaces are Linux's: this machine runs {}", std::env::consts::OS)]
    NotLinux,
    #[error("network namespaces need root (CAP_NET_ADMIN); this process runs as uid {0}")]
    NotRoot(u32),
    #[error("`{0}` was not found: install iproute2")]
    MissingTool(&'static str),
    #[error("`{command}` failed: {stderr}")]
    Command { command: String, stderr: String },
    #[error("cannot run `{command}`: {source}")]
    Spawn {
        command: String,
        #[source]
        source: std::io::Error,
    },
    #[error("unexpected output of `{command}`: {why}")]
    Output { command: String, why: String },
    #[error("cannot enter network namespace {name}: {source}")]
    Enter {
        name: String,
        #[source]
        source: std::io::Error,
    },
    #[error("bad testbed: {0}")]
    Spec(String),
}
