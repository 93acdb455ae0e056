//! How long ago the desk's owner last used the keyboard or mouse, where the platform
//! tells; where it does not, the answer is [`InputIdle::Unknown`], never "idle".
//!
//! Sources, asked in this order each time; the first that knows answers:
//! - **X11**: the MIT-SCREEN-SAVER extension's `ms_since_user_input` on `$DISPLAY` (the
//!   X server counts every key and pointer event of its screen).
//! - **logind**: the manager's `IdleHint`/`IdleSinceHint` (`loginctl show-session`
//!   without a session: all sessions together). Desktops set the hint only after their
//!   own idle delay (often 5 minutes), so "not idle" from logind is taken as input now;
//!   no session at all (`IdleSinceHint=0`) is unknown.

use std::process::Command;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use x11rb::connection::Connection;
use x11rb::protocol::screensaver::ConnectionExt as _;
use x11rb::rust_connection::RustConnection;

/// Time since the last keyboard or mouse input, if the platform tells.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InputIdle {
    Known(Duration),
    /// Nothing here can tell (no X server, no logind session): not a claim of idleness.
    Unknown,
}

/// Something that may know when the owner last touched the machine.
pub trait InputSource: Send {
    /// What to call it in logs.
    fn name(&self) -> &'static str;
    fn idle(&mut self) -> InputIdle;
}

/// The first source that knows, each time.
pub struct FirstKnown(pub Vec<Box<dyn InputSource>>);

impl FirstKnown {
    /// Every source this machine might have: X11 where `$DISPLAY` answers, then logind.
    pub fn detect() -> Self {
        let mut sources: Vec<Box<dyn InputSource>> = Vec::new();
        match X11::connect() {
            Ok(x) => sources.push(Box::new(x)),
            Err(why) => tracing::debug!(%why, "no X11 input idle time"),
        }
        sources.push(Box::new(Logind));
        Self(sources)
    }
}

impl InputSource for FirstKnown {
    fn name(&self) -> &'static str {
        "first known"
    }

    fn idle(&mut self) -> InputIdle {
        self.0
            .iter_mut()
            .map(|s| s.idle())
            .find(|i| *i != InputIdle::Unknown)
            .unwrap_or(InputIdle::Unknown)
    }
}

/// The X server's screen-saver extension.
pub struct X11 {
    conn: RustConnection,
    root: u32,
}

impl X11 {
    /// Connects to `$DISPLAY` and checks that the extension answers.
    pub fn connect() -> Result<Self, String> {
        Self::connect_to(None)
    }

    /// Connects to `display` (`:N`; `None`: `$DISPLAY`) and checks the extension.
    pub fn connect_to(display: Option<&str>) -> Result<Self, String> {
        let (conn, screen) = x11rb::connect(display).map_err(|e| e.to_string())?;
        let root = conn.setup().roots.get(screen).ok_or("no such X screen")?.root;
        let mut x = Self { conn, root };
        match x.query() {
            Some(_) => Ok(x),
            None => Err("the X server has no MIT-SCREEN-SAVER extension".into()),
        }
    }

    fn query(&mut self) -> Option<Duration> {
        let reply = self.conn.screensaver_query_info(self.root).ok()?.reply().ok()?;
        Some(Duration::from_millis(reply.ms_since_user_input.into()))
    }
}

impl InputSource for X11 {
    fn name(&self) -> &'static str {
        "X11 screen saver"
    }

    fn idle(&mut self) -> InputIdle {
        self.query().map_or(InputIdle::Unknown, InputIdle::Known)
    }
}

/// systemd-logind, through `loginctl`.
pub struct Logind;

impl InputSource for Logind {
    fn name(&self) -> &'static str {
        "logind"
    }

    fn idle(&mut self) -> InputIdle {
        let out = Command::new("loginctl")
            .args(["--no-pager", "show-session", "-p", "IdleHint", "-p", "IdleSinceHint"])
            .output();
        match out {
            Ok(out) if out.status.success() => {
                let now = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
                parse_logind(&String::from_utf8_lossy(&out.stdout), now)
            }
            _ => InputIdle::Unknown,
        }
    }
}

/// Reads `loginctl show-session -p IdleHint -p IdleSinceHint` output at wall time `now`.
pub fn parse_logind(text: &str, now: Duration) -> InputIdle {
    let value = |key: &str| {
        text.lines().find_map(|l| l.strip_prefix(key)?.strip_prefix('=')).map(str::trim)
    };
    let since = value("IdleSinceHint").and_then(|v| v.parse::<u64>().ok());
    match (value("IdleHint"), since) {
        // No session has ever reported: nothing is known.
        (_, Some(0)) | (_, None) | (None, _) => InputIdle::Unknown,
        (Some("no"), Some(_)) => InputIdle::Known(Duration::ZERO),
        (Some("yes"), Some(us)) => InputIdle::Known(now.saturating_sub(Duration::from_micros(us))),
        (Some(_), Some(_)) => InputIdle::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOW: Duration = Duration::from_secs(1_764_600_000);

    #[test]
    fn logind_idle_since_gives_the_idle_time() {
        let since = (NOW - Duration::from_secs(90)).as_micros();
        let text = format!("IdleHint=yes\nIdleSinceHint={since}\n");
        assert_eq!(parse_logind(&text, NOW), InputIdle::Known(Duration::from_secs(90)));
    }

    #[test]
    fn logind_not_idle_is_input_now() {
        let text = format!("IdleHint=no\nIdleSinceHint={}\n", NOW.as_micros() - 5);
        assert_eq!(parse_logind(&text, NOW), InputIdle::Known(Duration::ZERO));
    }

    #[test]
    fn no_session_or_no_answer_is_unknown_not_idle() {
        assert_eq!(parse_logind("IdleHint=yes\nIdleSinceHint=0\n", NOW), InputIdle::Unknown);
        assert_eq!(parse_logind("", NOW), InputIdle::Unknown);
        assert_eq!(parse_logind("IdleHint=maybe\nIdleSinceHint=5\n", NOW), InputIdle::Unknown);
    }

    struct Fixed(InputIdle);
    impl InputSource for Fixed {
        fn name(&self) -> &'static str {
            "fixed"
        }
        fn idle(&mut self) -> InputIdle {
            self.0
        }
    }

    #[test]
    fn the_first_source_that_knows_answers() {
        let known = InputIdle::Known(Duration::from_secs(4));
        let mut s = FirstKnown(vec![Box::new(Fixed(InputIdle::Unknown)), Box::new(Fixed(known))]);
        assert_eq!(s.idle(), known);
        let mut none = FirstKnown(vec![Box::new(Fixed(InputIdle::Unknown))]);
        assert_eq!(none.idle(), InputIdle::Unknown);
    }
}
