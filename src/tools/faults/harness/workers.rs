//! The harness's worker processes: real `gridlight worker` binaries with the null
//! renderer, half of them behind the proxy, each with its own cache directory.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

use super::{Harness, HarnessError};

/// One worker process.
pub(super) struct WorkerProc {
    pub(super) child: Child,
    pub(super) frozen: bool,
    pub(super) proxied: bool,
}

/// A fresh directory under the system's temp dir, removed on drop.
pub(super) struct ScratchDir(PathBuf);

impl ScratchDir {
    pub(super) fn new() -> std::io::Result<Self> {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("gridlight-faults-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        Ok(Self(dir))
    }

    pub(super) fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub(super) fn signal(child: &Child, sig: libc::c_int) {
    // SAFETY: kill(2) on our own child's pid; it has not been reaped (we hold it).
    unsafe {
        libc::kill(child.id() as libc::pid_t, sig);
    }
}

impl Harness {
    /// Workers started from now on take `ms` per job (the null renderer's sleep); those
    /// running keep theirs.
    pub fn set_render_delay(&mut self, ms: u32) {
        self.config.render_delay_ms = ms;
    }

    /// Starts one more worker process; every other one goes through the proxy.
    pub fn spawn_worker(&mut self) -> Result<u32, HarnessError> {
        let proxied = self.proxy.is_some() && self.spawned % 2 == 1;
        let addr = match (&self.proxy, proxied) {
            (Some(p), true) => p.local_addr(),
            _ => self.listen,
        };
        let mut cmd = Command::new(&self.config.binary);
        cmd.arg("worker")
            .arg("--master")
            .arg(addr.to_string())
            .args(["--threads", "1", "--null-render", "--null-render-delay-ms"])
            .arg(self.config.render_delay_ms.to_string())
            // These workers stand for other machines: at the default idle priority their
            // simulated renders would wait behind every process of this (loaded) host.
            .args(["--priority", "normal"])
            .arg("--name")
            .arg(format!("fault-{}", self.spawned))
            .arg("--cache-dir")
            .arg(self.dir.path().join("cache"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        if self.config.secret.is_some() {
            cmd.arg("--secret-file").arg(self.dir.path().join("secret"));
        }
        crate::children::die_with_parent(&mut cmd);
        let binary = self.config.binary.clone();
        let child = cmd.spawn().map_err(|source| HarnessError::Spawn { binary, source })?;
        let pid = child.id();
        self.spawned += 1;
        self.workers.push(WorkerProc { child, frozen: false, proxied });
        self.note_live();
        Ok(pid)
    }

    /// Worker processes alive and not frozen.
    pub fn live_workers(&self) -> usize {
        self.workers.iter().filter(|w| !w.frozen).count()
    }

    /// Worker processes held (frozen ones included).
    pub fn workers(&self) -> usize {
        self.workers.len()
    }
}
