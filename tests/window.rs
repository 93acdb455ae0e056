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

/// `demo --resolution window`: the render size is the window's picture area (the window
/// left of the panel) in physical pixels, and a resize of the window changes it live.
#[test]
fn with_resolution_window_the_render_size_follows_the_window() {
    use std::io::{BufRead, BufReader};
    use std::sync::mpsc;
    use x11rb::protocol::xproto::{ConfigureWindowAux, ConnectionExt};

    let Some(xvfb) = Xvfb::start_or_skip(
        "with_resolution_window_the_render_size_follows_the_window",
        WIDTH,
        HEIGHT,
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut demo = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["demo", "--workers", "1", "--resolution", "window", "--out"])
        .arg(dir.path().join("out"))
        .env("DISPLAY", &xvfb.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("NODEVICE_SELECT", "1")
        .env("RUST_LOG", "info")
        .env("NO_COLOR", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gridlight demo starts");
    // Every size the window asks for, from its log line.
    let (sizes_tx, sizes) = mpsc::channel::<(u32, u32)>();
    let stderr = demo.stderr.take().expect("piped");
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            eprintln!("{line}");
            if !line.contains("render size follows the window") {
                continue;
            }
            let field = |name: &str| {
                let rest = line.split(&format!("{name}=")).nth(1)?;
                rest.split(|c: char| !c.is_ascii_digit()).next()?.parse::<u32>().ok()
            };
            if let (Some(w), Some(h)) = (field("width"), field("height")) {
                let _ = sizes_tx.send((w, h));
            }
        }
    });
    let (conn, screen) = x11rb::connect(Some(&xvfb.display)).expect("connects to Xvfb");
    let root = conn.setup().roots[screen].root;
    let deadline = Instant::now() + Duration::from_secs(60);
    let window = loop {
        if let Some(w) = find_window(&conn, root, "gridlight demo") {
            break w;
        }
        assert!(Instant::now() < deadline, "no demo window within 60 s");
        std::thread::sleep(Duration::from_millis(200));
    };
    let panel = 300; // window::panel::PANEL_WIDTH at one pixel per point (Xvfb)
    let wait_size = |what: &str| {
        sizes.recv_timeout(Duration::from_secs(60)).unwrap_or_else(|e| panic!("{what}: {e}"))
    };
    let geometry = conn.get_geometry(window).unwrap().reply().unwrap();
    let first = wait_size("the first size");
    assert_eq!(
        first,
        (u32::from(geometry.width) - panel, u32::from(geometry.height)),
        "the render size is the picture area of the {}x{} window",
        geometry.width,
        geometry.height
    );
    // The user makes the window smaller: the render size follows.
    conn.configure_window(window, &ConfigureWindowAux::new().width(1000).height(700)).unwrap();
    conn.flush().unwrap();
    assert_eq!(wait_size("the size after the resize"), (1000 - panel, 700));
    assert!(demo.try_wait().unwrap().is_none(), "the demo runs on at the new size");
    request_close(&conn, window);
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = demo.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the demo did not exit within 30 s of the close");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "the demo exits cleanly after its window closes: {status}");
}
