//! Running code inside a named network namespace (`ip netns add NAME`) from this process.
//!
//! `setns(CLONE_NEWNET)` moves only the calling thread, so [`run_in`] does it on a fresh
//! thread: sockets that thread creates belong to the namespace, and so do the threads it
//! spawns (they inherit its namespace), while the rest of the process stays where it was.
//! A listening socket keeps its namespace whichever thread later accepts on it, which is
//! all the benchmark's in-process master needs.

use std::path::PathBuf;

use super::LanError;

/// Where `ip netns add NAME` pins a namespace.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from("/run/netns").join(name)
}

/// Runs `f` on a new thread inside namespace `name` and returns what it returns (off
/// Linux, [`LanError::NotLinux`]).
#[cfg(not(target_os = "linux"))]
pub fn run_in<T: Send>(_name: &str, _f: impl FnOnce() -> T + Send) -> Result<T, LanError> {
    Err(LanError::NotLinux)
}

/// Runs `f` on a new thread inside namespace `name` and returns what it returns.
#[cfg(target_os = "linux")]
pub fn run_in<T: Send>(name: &str, f: impl FnOnce() -> T + Send) -> Result<T, LanError> {
    use std::os::fd::AsRawFd;
    let ns = std::fs::File::open(path(name))
        .map_err(|source| LanError::Enter { name: name.to_string(), source })?;
    std::thread::scope(|scope| {
        scope
            .spawn(|| {
                // SAFETY: setns only reads the descriptor, which `ns` keeps open.
                if unsafe { libc::setns(ns.as_raw_fd(), libc::CLONE_NEWNET) } != 0 {
                    let source = std::io::Error::last_os_error();
                    return Err(LanError::Enter { name: name.to_string(), source });
                }
                Ok(f())
            })
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })
}
