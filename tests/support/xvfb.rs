//! An Xvfb server for the tests that need an X display (`.ci/run` installs Xvfb).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// An Xvfb server on a display of its own, killed when dropped.
pub struct Xvfb {
    child: Child,
    /// `:N`, for `DISPLAY`.
    pub display: String,
}

impl Xvfb {
    /// A server with one screen of `width` × `height` at depth 24; `None` without `Xvfb`.
    pub fn start(width: u16, height: u16) -> Option<Self> {
        let which = Command::new("sh").args(["-c", "command -v Xvfb"]).output().ok()?;
        if !which.status.success() {
            return None;
        }
        for n in 0..50 {
            let number = 140 + (std::process::id() as usize + n) % 400;
            if Path::new(&format!("/tmp/.X{number}-lock")).exists() {
                continue;
            }
            let mut child = Command::new("Xvfb")
                .arg(format!(":{number}"))
                .args(["-screen", "0", &format!("{width}x{height}x24"), "-nolisten", "tcp"])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .ok()?;
            let socket = PathBuf::from(format!("/tmp/.X11-unix/X{number}"));
            let deadline = Instant::now() + Duration::from_secs(10);
            while Instant::now() < deadline {
                if socket.exists() {
                    return Some(Self { child, display: format!(":{number}") });
                }
                if child.try_wait().ok().flatten().is_some() {
                    break; // lost a race for this display number
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        None
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
