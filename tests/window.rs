//! The window, end to end: the real `gridlight demo` under Xvfb with Mesa's software
//! Vulkan. Its window must show the Cornell box (not black, the red wall left of the green
//! one), an edit played through the master's edit path (the interaction script, applied
//! by the same scene holder as the panel's edits) must change the picture, and closing the
//! window (WM_DELETE_WINDOW, what a window manager's close button sends) must end the demo
//! and its local workers with no orphans.
//!
//! Screenshots are read straight from the X server (x11rb `GetImage`, `common/xvfb.rs`);
//! they are written as PNG into `$GRIDLIGHT_WINDOW_SHOTS` when set, to be looked at.
//! Without `Xvfb` on the machine the test says it is skipped and why (`.ci/run` installs it).

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use x11rb::connection::Connection;

mod support;
use support::xvfb::{alive, children_of, find_window, request_close, wait_for_shot, Xvfb};

const WIDTH: u16 = 1280;
const HEIGHT: u16 = 800;
/// Seconds after the start at which the script turns the red wall blue.
const EDIT_AT_S: f64 = 25.0;

#[test]
fn the_demo_window_shows_the_cornell_box_follows_edits_and_closes_cleanly() {
    let Some(xvfb) = Xvfb::start_or_skip(
        "the_demo_window_shows_the_cornell_box_follows_edits_and_closes_cleanly",
        WIDTH,
        HEIGHT,
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("blue-wall.toml");
    std::fs::write(
        &script,
        format!("[[edit]]\nat = {EDIT_AT_S}\nmaterial = {{ name = \"red\", base_color = [0.04, 0.05, 0.6] }}\n"),
    )
    .unwrap();
    let started = Instant::now();
    let mut demo = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["demo", "--workers", "2", "--out"])
        .arg(dir.path().join("out"))
        .arg("--script")
        .arg(&script)
        .env("DISPLAY", &xvfb.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("NODEVICE_SELECT", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("gridlight demo starts");
    let (conn, screen) = x11rb::connect(Some(&xvfb.display)).expect("connects to Xvfb");
    let root = conn.setup().roots[screen].root;

    // The Cornell box: lit, the red wall on the left of the green one.
    let before = wait_for_shot(
        &conn,
        root,
        &xvfb,
        &mut demo,
        Duration::from_secs(EDIT_AT_S as u64 - 3),
        "the Cornell box",
        |s| {
            let (red, green) = (s.red(), s.green());
            s.lit_fraction() > 0.15
                && red.count > 2000
                && green.count > 2000
                && red.mean_x + 100.0 < green.mean_x
        },
    );
    before.save("before-edit.png");
    assert!(
        started.elapsed() < Duration::from_secs_f64(EDIT_AT_S),
        "the first picture must be checked before the scripted edit"
    );
    let (red_before, green) = (before.red(), before.green());

    // The scripted edit turns the red wall blue, in the same place.
    let after = wait_for_shot(
        &conn,
        root,
        &xvfb,
        &mut demo,
        Duration::from_secs(60),
        "the blue wall",
        |s| {
            // Shaded parts of a dark blue wall fail the hue test, so ask for a third of the area.
            s.blue().count > red_before.count / 3 && s.red().count < red_before.count / 10
        },
    );
    after.save("after-edit.png");
    let blue = after.blue();
    assert!(
        (blue.mean_x - red_before.mean_x).abs() < 60.0 && blue.mean_x + 100.0 < green.mean_x,
        "the blue wall is where the red one was: blue {blue:?}, red before {red_before:?}, green {green:?}"
    );

    // Closing the window ends the demo and its workers.
    let workers = children_of(demo.id());
    assert_eq!(workers.len(), 2, "two local worker processes run under the demo: {workers:?}");
    let window = find_window(&conn, root, "gridlight demo").expect("the demo's window exists");
    request_close(&conn, window);
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = demo.try_wait().unwrap() {
            break status;
        }
        assert!(
            Instant::now() < deadline,
            "the demo did not exit within 30 s of the close request"
        );
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "the demo exits cleanly after its window closes: {status}");
    let orphans: Vec<u32> = workers.into_iter().filter(|&p| alive(p)).collect();
    assert!(orphans.is_empty(), "worker processes outlived the demo: {orphans:?}");
}
