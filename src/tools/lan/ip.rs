//! Running iproute2's `ip` and `tc`: one function that runs a command and turns a failure
//! into a [`LanError`] naming the command and what it printed.

use std::process::{Command, Stdio};

use super::LanError;

/// Runs `tool args...` and returns its standard output.
pub fn run(tool: &'static str, args: &[&str]) -> Result<String, LanError> {
    let command = format!("{tool} {}", args.join(" "));
    let out =
        Command::new(tool).args(args).stdin(Stdio::null()).output().map_err(
            |source| match source.kind() {
                std::io::ErrorKind::NotFound => LanError::MissingTool(tool),
                _ => LanError::Spawn { command: command.clone(), source },
            },
        )?;
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
        return Err(LanError::Command { command, stderr });
    }
    String::from_utf8(out.stdout)
        .map_err(|e| LanError::Output { command, why: format!("not UTF-8: {e}") })
}

/// `ip args...`.
pub fn ip(args: &[&str]) -> Result<String, LanError> {
    run("ip", args)
}

/// `tc args...`.
pub fn tc(args: &[&str]) -> Result<String, LanError> {
    run("tc", args)
}
