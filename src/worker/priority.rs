//! The CPU priority of render threads: a worker is a guest on someone's desk.
//!
//! By default every render thread asks for the lowest priority the OS offers, so that
//! any process of the desk's owner always runs first (docs/design.md, decision 9):
//! - **Linux**: `SCHED_IDLE` for the calling thread (`sched_setscheduler(0, ..)` acts on
//!   the thread, not the process). Such a thread runs only on a CPU nothing else wants;
//!   the kernel still gives it a sliver (its weight is 3 against a normal thread's 1024)
//!   so it is never starved for ever. Where `SCHED_IDLE` is refused (a seccomp filter, an
//!   old kernel) the thread falls back to nice 19.
//! - **Other Unix systems** (macOS, the BSDs): nice 19 for the calling thread where the
//!   OS allows it per thread, else for the process (`setpriority(PRIO_PROCESS, 0, 19)`);
//!   the owner's processes still come first, but less absolutely than with `SCHED_IDLE`.
//! - **Elsewhere**: the priority is left unchanged, and the worker says so.
//!
//! `--priority normal` leaves render threads at the priority they inherited. Only render
//! threads are lowered: the connection I/O (a few messages per job) and the owner
//! monitor stay at normal priority so that a pause reaches the master at once even when
//! the owner keeps every CPU busy.

use std::fmt;

/// Which priority render threads run at.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Priority {
    /// The lowest the OS offers (Linux: `SCHED_IDLE`).
    #[default]
    Idle,
    /// Unchanged: as any other process of the user.
    Normal,
}

/// What a thread actually got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Applied {
    /// Linux `SCHED_IDLE`.
    SchedIdle,
    /// Nice 19 (where `SCHED_IDLE` does not exist or was refused).
    Nice19,
    /// Left as it was (`--priority normal`).
    Unchanged,
}

impl fmt::Display for Applied {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Applied::SchedIdle => "SCHED_IDLE",
            Applied::Nice19 => "nice 19",
            Applied::Unchanged => "unchanged",
        })
    }
}

/// Lowers the calling thread to `priority`; the error says why it could not.
pub fn apply_to_current_thread(priority: Priority) -> std::io::Result<Applied> {
    match priority {
        Priority::Normal => Ok(Applied::Unchanged),
        Priority::Idle => lowest(),
    }
}

#[cfg(target_os = "linux")]
fn lowest() -> std::io::Result<Applied> {
    let param = libc::sched_param { sched_priority: 0 };
    // SAFETY: pid 0 is the calling thread; `param` outlives the call.
    if unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) } == 0 {
        return Ok(Applied::SchedIdle);
    }
    let refused = std::io::Error::last_os_error();
    tracing::debug!(cause = %refused, "SCHED_IDLE refused; trying nice 19");
    nice19()
}

#[cfg(all(unix, not(target_os = "linux")))]
fn lowest() -> std::io::Result<Applied> {
    nice19()
}

#[cfg(not(unix))]
fn lowest() -> std::io::Result<Applied> {
    Err(std::io::Error::new(
        std::io::ErrorKind::Unsupported,
        "lowering thread priority is not implemented on this OS",
    ))
}

#[cfg(unix)]
fn nice19() -> std::io::Result<Applied> {
    // On Linux `who = 0` with PRIO_PROCESS is the calling thread; elsewhere the process.
    // SAFETY: plain system call with integer arguments.
    if unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, 19) } == 0 {
        Ok(Applied::Nice19)
    } else {
        Err(std::io::Error::last_os_error())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calling thread's scheduling policy.
    #[cfg(target_os = "linux")]
    fn policy() -> i32 {
        // SAFETY: sched_getscheduler(0) only reads the calling thread's policy.
        unsafe { libc::sched_getscheduler(0) }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn idle_puts_only_the_calling_thread_at_sched_idle() {
        let before = policy();
        let got = std::thread::spawn(|| (apply_to_current_thread(Priority::Idle), policy()))
            .join()
            .unwrap();
        match got {
            (Ok(Applied::SchedIdle), p) => assert_eq!(p, libc::SCHED_IDLE),
            (Ok(Applied::Nice19), _) => eprintln!("SCHED_IDLE refused here; nice 19 applied"),
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(policy(), before, "another thread's priority changed");
    }

    #[test]
    fn normal_changes_nothing() {
        assert_eq!(apply_to_current_thread(Priority::Normal).unwrap(), Applied::Unchanged);
    }
}
