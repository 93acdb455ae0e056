//! Helpers of the tests that need an X display (`.ci/run` installs Xvfb): an Xvfb server of a chosen size, screenshots read
//! straight from the X server (x11rb `GetImage`), windows by name, the close request a
//! window manager sends, and the processes under a pid (from /proc).
#![allow(dead_code)] // each test binary uses its own part

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use x11rb::connection::Connection;
use x11rb::protocol::xproto::{
    AtomEnum, ClientMessageEvent, ConnectionExt as _, EventMask, ImageFormat, Window,
};
use x11rb::rust_connection::RustConnection;

/// An Xvfb server on a display of its own, killed when dropped.
pub struct Xvfb {
    child: Child,
    pub display: String,
    pub width: u16,
    pub height: u16,
}

impl Xvfb {
    /// Starts a server with one screen of `width`×`height`, or `None` after saying (with
    /// `gridlight::testing::skip`) that `test` cannot run without it; under `CI=true` a
    /// missing Xvfb fails the test instead.
    pub fn start_or_skip(test: &str, width: u16, height: u16) -> Option<Self> {
        match Self::start(width, height) {
            Ok(x) => Some(x),
            Err(why) => {
                gridlight::testing::skip(test, gridlight::testing::Missing::Display, why);
                None
            }
        }
    }

    /// Starts a server with one screen of `width`×`height`; the error says why not.
    pub fn start(width: u16, height: u16) -> Result<Self, String> {
        let which = Command::new("sh")
            .args(["-c", "command -v Xvfb"])
            .output()
            .map_err(|e| format!("cannot run sh: {e}"))?;
        if !which.status.success() {
            return Err("Xvfb is not installed (apt-get install xvfb; .ci/run does)".into());
        }
        // Each attempt of this process takes a number of its own: two tests starting at
        // once used to pick the same one, and the loser, seeing the winner's socket, went
        // on as if the server were its own (both windows on one screen).
        static ATTEMPTS: AtomicUsize = AtomicUsize::new(0);
        for _ in 0..50 {
            let n = ATTEMPTS.fetch_add(1, Ordering::Relaxed);
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
                .map_err(|e| format!("cannot start Xvfb: {e}"))?;
            let socket = PathBuf::from(format!("/tmp/.X11-unix/X{number}"));
            let deadline = Instant::now() + Duration::from_secs(10);
            while Instant::now() < deadline {
                if child.try_wait().ok().flatten().is_some() {
                    break; // lost a race for this display number
                }
                if socket.exists() {
                    return Ok(Self { child, display: format!(":{number}"), width, height });
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        Err("no Xvfb display came up on 50 display numbers".into())
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One screenshot of the whole screen, RGB.
pub struct Shot {
    pub width: u16,
    pub height: u16,
    pub rgb: Vec<[u8; 3]>,
}

/// Counts and mean x of pixels of one dominant hue.
#[derive(Debug, Default)]
pub struct Hue {
    pub count: usize,
    pub mean_x: f64,
}

impl Shot {
    /// The whole screen of `xvfb`.
    pub fn take(conn: &RustConnection, root: Window, xvfb: &Xvfb) -> Self {
        let (width, height) = (xvfb.width, xvfb.height);
        let reply = conn
            .get_image(ImageFormat::Z_PIXMAP, root, 0, 0, width, height, !0)
            .expect("GetImage sent")
            .reply()
            .expect("GetImage answered");
        assert_eq!(reply.depth, 24, "Xvfb runs at depth 24");
        // Depth 24 in a Z pixmap: 32 bits per pixel, B, G, R, unused (little-endian server).
        let rgb = reply.data.chunks_exact(4).map(|p| [p[2], p[1], p[0]]).collect();
        Self { width, height, rgb }
    }

    pub fn hue(&self, pick: impl Fn([u8; 3]) -> bool) -> Hue {
        let (mut count, mut sum_x) = (0usize, 0f64);
        for (i, &p) in self.rgb.iter().enumerate() {
            if pick(p) {
                count += 1;
                sum_x += (i % self.width as usize) as f64;
            }
        }
        Hue { count, mean_x: if count > 0 { sum_x / count as f64 } else { 0.0 } }
    }

    pub fn red(&self) -> Hue {
        self.hue(|[r, g, b]| {
            r > 60 && u16::from(r) > 2 * u16::from(g) && u16::from(r) > 2 * u16::from(b)
        })
    }

    pub fn green(&self) -> Hue {
        self.hue(|[r, g, b]| {
            g > 50 && u16::from(g) * 2 > 3 * u16::from(r) && u16::from(g) * 2 > 3 * u16::from(b)
        })
    }

    pub fn blue(&self) -> Hue {
        self.hue(|[r, g, b]| {
            b > 40 && u16::from(b) * 2 > 3 * u16::from(r) && u16::from(b) * 2 > 3 * u16::from(g)
        })
    }

    pub fn lit_fraction(&self) -> f64 {
        let lit = self.rgb.iter().filter(|p| p.iter().any(|&c| c > 24)).count();
        lit as f64 / self.rgb.len() as f64
    }

    pub fn save(&self, name: &str) {
        let Some(dir) = std::env::var_os("GRIDLIGHT_WINDOW_SHOTS") else { return };
        let bytes: Vec<u8> = self.rgb.iter().flatten().copied().collect();
        let img = image::RgbImage::from_raw(u32::from(self.width), u32::from(self.height), bytes)
            .unwrap();
        let path = Path::new(&dir).join(name);
        img.save(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
}

/// The top-level window whose name contains `needle`.
pub fn find_window(conn: &RustConnection, root: Window, needle: &str) -> Option<Window> {
    let children = conn.query_tree(root).ok()?.reply().ok()?.children;
    children.into_iter().find(|&w| {
        let name = conn
            .get_property(false, w, AtomEnum::WM_NAME, AtomEnum::ANY, 0, 1024)
            .ok()
            .and_then(|c| c.reply().ok())
            .map(|r| r.value)
            .unwrap_or_default();
        String::from_utf8_lossy(&name).contains(needle)
    })
}

/// Asks `window` to close the way a window manager's close button does.
pub fn request_close(conn: &RustConnection, window: Window) {
    let atom = |name: &[u8]| conn.intern_atom(false, name).unwrap().reply().unwrap().atom;
    let protocols = atom(b"WM_PROTOCOLS");
    let delete = atom(b"WM_DELETE_WINDOW");
    let event = ClientMessageEvent::new(32, window, protocols, [delete, 0, 0, 0, 0]);
    conn.send_event(false, window, EventMask::NO_EVENT, event).unwrap();
    conn.flush().unwrap();
}

/// Pids of the live children of `parent` (from /proc).
pub fn children_of(parent: u32) -> Vec<u32> {
    let Ok(dir) = std::fs::read_dir("/proc") else { return Vec::new() };
    dir.filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
            // Fields after the parenthesised command: state, ppid, ...
            let rest = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
            let mut fields = rest.split_whitespace();
            let state = fields.next().unwrap_or("");
            let ppid: u32 = fields.next().and_then(|p| p.parse().ok()).unwrap_or(0);
            ppid == parent && state != "Z"
        })
        .collect()
}

pub fn alive(pid: u32) -> bool {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    let state = stat.rsplit_once(')').map(|(_, r)| r.trim_start()).unwrap_or("");
    !stat.is_empty() && !state.starts_with('Z')
}

/// Polls screenshots until `ok` holds; panics with `what` after `timeout`.
pub fn wait_for_shot(
    conn: &RustConnection,
    root: Window,
    xvfb: &Xvfb,
    demo: &mut Child,
    timeout: Duration,
    what: &str,
    ok: impl Fn(&Shot) -> bool,
) -> Shot {
    let deadline = Instant::now() + timeout;
    loop {
        let shot = Shot::take(conn, root, xvfb);
        if ok(&shot) {
            return shot;
        }
        if let Ok(Some(status)) = demo.try_wait() {
            panic!("the demo exited ({status}) before {what}");
        }
        if Instant::now() > deadline {
            shot.save("timeout.png");
            panic!(
                "{what}: not seen within {timeout:?} (lit {:.2}, red {:?}, green {:?}, blue {:?})",
                shot.lit_fraction(),
                shot.red(),
                shot.green(),
                shot.blue()
            );
        }
        std::thread::sleep(Duration::from_millis(250));
    }
}
