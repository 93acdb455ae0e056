//! How a test that cannot run on this machine says so, shared by the unit tests and the
//! integration suites (one helper, one wording).
//!
//! The line goes to the process's real stderr, not through `eprintln!`, which the test
//! harness captures and shows only for failing tests: a skip is visible in the output of
//! every `cargo test`. Under CI (`CI=true`), where `.ci/run` installs Mesa's lavapipe and
//! Xvfb, a missing GPU adapter or display means the set-up broke: the test fails instead
//! of passing without having checked anything.

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
    /// A CPU feature (AVX2 and friends).
    CpuFeature,
    /// A privilege or system service (root, namespaces, systemd, Slurm, a free port).
    System,
}

impl Missing {
    /// Whether CI provides it, so that its absence there is a failure.
    pub fn required_in_ci(self) -> bool {
        matches!(self, Missing::Adapter | Missing::Display)
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
    fn ci_requires_the_adapter_and_the_display_only() {
        let required: Vec<Missing> = [
            Missing::Adapter,
            Missing::Display,
            Missing::Assets,
            Missing::CpuFeature,
            Missing::System,
        ]
        .into_iter()
        .filter(|m| m.required_in_ci())
        .collect();
        assert_eq!(required, vec![Missing::Adapter, Missing::Display]);
    }
}
