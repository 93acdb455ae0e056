//! Child processes that must not outlive their parent (the demo's local workers).
//!
//! [`Children`] kills and reaps every process it holds when dropped, so the demo leaves
//! no orphans however it ends (normal exit, error, Ctrl-C). On Linux each child also
//! asks the kernel for SIGKILL when its parent dies (`PR_SET_PDEATHSIG`), which covers
//! the one case a destructor cannot: the parent itself being killed.

use std::io;
use std::process::{Child, Command};

use tracing::{debug, warn};

/// A set of child processes killed together.
#[derive(Debug, Default)]
pub struct Children {
    procs: Vec<Child>,
}

impl Children {
    /// No children yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Starts `command` as a child that dies with this process.
    pub fn spawn(&mut self, mut command: Command) -> io::Result<u32> {
        die_with_parent(&mut command);
        let child = command.spawn()?;
        let pid = child.id();
        debug!(pid, "child started");
        self.procs.push(child);
        Ok(pid)
    }

    /// Process ids of the children, in start order.
    pub fn pids(&self) -> Vec<u32> {
        self.procs.iter().map(Child::id).collect()
    }

    /// Children that exited on their own, with their status, removed from the set.
    pub fn reap_exited(&mut self) -> Vec<(u32, std::process::ExitStatus)> {
        let mut exited = Vec::new();
        self.procs.retain_mut(|c| match c.try_wait() {
            Ok(Some(status)) => {
                exited.push((c.id(), status));
                false
            }
            _ => true,
        });
        exited
    }

    /// Number of children still held.
    pub fn len(&self) -> usize {
        self.procs.len()
    }

    /// True when no child is held.
    pub fn is_empty(&self) -> bool {
        self.procs.is_empty()
    }

    /// Kills and reaps every child.
    pub fn kill_all(&mut self) {
        for mut child in self.procs.drain(..) {
            let pid = child.id();
            if let Err(err) = child.kill() {
                // Already exited: nothing to kill, but it still needs reaping.
                debug!(pid, cause = %err, "kill");
            }
            if let Err(err) = child.wait() {
                warn!(pid, cause = %err, "cannot reap child");
            }
        }
    }
}

impl Drop for Children {
    fn drop(&mut self) {
        self.kill_all();
    }
}

/// Makes `command`'s process receive SIGKILL when this process dies (Linux).
#[cfg(target_os = "linux")]
pub fn die_with_parent(command: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: prctl is async-signal-safe and touches no memory of the parent.
    unsafe {
        command.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 {
                return Err(io::Error::last_os_error());
            }
            Ok(())
        });
    }
}

#[cfg(not(target_os = "linux"))]
pub fn die_with_parent(_command: &mut Command) {}

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    fn alive(pid: u32) -> bool {
        // Signal 0 checks for existence; a reaped child no longer exists.
        // SAFETY: kill with signal 0 sends nothing; it only checks the pid.
        unsafe { libc::kill(pid as i32, 0) == 0 }
    }

    #[test]
    fn dropping_the_set_kills_and_reaps_every_child() {
        let mut children = Children::new();
        for _ in 0..2 {
            let mut c = Command::new("sleep");
            c.arg("30");
            children.spawn(c).unwrap();
        }
        let pids = children.pids();
        assert!(pids.iter().all(|p| alive(*p)));
        drop(children);
        assert!(pids.iter().all(|p| !alive(*p)), "children survived their guard");
    }

    #[test]
    fn exited_children_are_reported_once() {
        let mut children = Children::new();
        children.spawn(Command::new("true")).unwrap();
        let mut exited = Vec::new();
        for _ in 0..200 {
            exited.extend(children.reap_exited());
            if !exited.is_empty() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        assert_eq!(exited.len(), 1);
        assert!(exited[0].1.success());
        assert!(children.is_empty());
        assert!(children.reap_exited().is_empty());
    }
}
