//! How a test that cannot run on this machine says so, shared by the unit tests and the
//! integration suites (one helper, one wording).
//!
//! The line goes to the process's real stderr, not through `eprintln!`, which the test
//! harness captures and shows only for failing tests: a skip is visible in the output of
//! every `cargo test`. Under CI (`CI=true`), where `.ci/run` installs Mesa's lavapipe,
//! Xvfb, Slurm, munge, iproute2 and systemd and points `GRIDLIGHT_ASSETS` at the public
//! assets, a missing adapter, display, tool or asset means the set-up broke: the test fails
//! instead of passing without having checked anything. What CI cannot promise (root, the
//! right to make network namespaces, a free port, a CPU feature) still skips there.

use std::fmt::Display;
use std::io::Write;

/// What a skipped test lacked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Missing {
    /// A wgpu adapter (lavapipe in CI).
    Adapter,
    /// An X display (Xvfb in CI).
    Display,
    /// The public test assets (`GRIDLIGHT_ASSETS`).
    Assets,
    /// A program `.ci/run` installs (Slurm, munge, iproute2's `ip` and `tc`,
    /// `systemd-analyze`).
    Tool,
    /// A CPU feature (AVX2 and friends).
    CpuFeature,
    /// A privilege or a right of the machine (root, making network namespaces, a free
    /// port).
    System,
}

impl Missing {
    /// Whether CI provides it, so that its absence there is a failure.
    pub fn required_in_ci(self) -> bool {
        matches!(self, Missing::Adapter | Missing::Display | Missing::Tool | Missing::Assets)
    }
}

/// Whether this run is CI's (`CI=true` or `CI=1`).
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Reports that `test` cannot run here because `missing` is absent (`why` says how it
/// failed), on the real stderr; panics instead under CI when CI provides it. The caller
/// returns after it.
pub fn skip(test: &str, missing: Missing, why: impl Display) {
    if in_ci() && missing.required_in_ci() {
        panic!("{test}: {missing:?} missing under CI=true (.ci/run installs it): {why}");
    }
    let line = format!("skipped: {test}: no {missing:?} here: {why}\n");
    // Best effort: a closed stderr must not fail the test.
    let _ = std::io::stderr().lock().write_all(line.as_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ci_requires_what_ci_installs_only() {
        let required: Vec<Missing> = [
            Missing::Adapter,
            Missing::Display,
            Missing::Assets,
            Missing::Tool,
            Missing::CpuFeature,
            Missing::System,
        ]
        .into_iter()
        .filter(|m| m.required_in_ci())
        .collect();
        let installed = [Missing::Adapter, Missing::Display, Missing::Assets, Missing::Tool];
        assert_eq!(required, installed);
    }
}
