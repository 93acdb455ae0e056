//! One device on the master (issue 19): with `--reconstruct gpu`, the real `gridlight demo`
//! under Xvfb with Mesa's software Vulkan reconstructs on the window's device and draws
//! each frame from the reconstruction's texture: the window's probe
//! (`GRIDLIGHT_PANEL_PROBE`) must count frames drawn from the device and no frame read
//! back and no picture uploaded, and the converged picture on screen must match what a
//! headless demo writes for the same scene (cell by cell, so a wrong colour encoding,
//! channel order or orientation fails).
//!
//! Without `Xvfb` the test says it is skipped and why (`.ci/run` installs it).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::Value;
use x11rb::connection::Connection;
use x11rb::protocol::xproto::ConnectionExt as _;

mod support;
use support::xvfb::{find_window, request_close, Shot, Xvfb};

const WIDTH: u16 = 1280;
const HEIGHT: u16 = 800;
/// Frames the headless reference shows (accumulated: converged enough for cell means).
const REFERENCE_FRAMES: u64 = 12;
/// Frames the window must have drawn from the device before it is checked.
const WINDOW_FRAMES: u64 = 12;
/// Cells across and down in which screen and reference are compared.
const CELLS: (usize, usize) = (8, 6);

fn demo() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_gridlight"));
    cmd.current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("NODEVICE_SELECT", "1")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::inherit());
    cmd
}

/// The last frame a headless `demo --reconstruct gpu` writes into `out`.
fn headless_reference(out: &Path) -> image::RgbImage {
    let status = demo()
        .args(["demo", "--headless", "--workers", "2", "--reconstruct", "gpu", "--frames"])
        .arg(REFERENCE_FRAMES.to_string())
        .arg("--out")
        .arg(out)
        .status()
        .expect("the headless demo runs");
    assert!(status.success(), "headless demo: {status}");
    let mut frames: Vec<PathBuf> = std::fs::read_dir(out)
        .expect("output folder")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "png"))
        .collect();
    frames.sort();
    let last = frames.last().expect("the headless demo wrote frames");
    image::open(last).expect("a readable PNG").to_rgb8()
}

/// Mean RGB of each of `CELLS` cells of the region `(x, y, w, h)` of `pixel`.
fn cell_means(
    (x0, y0, w, h): (f64, f64, f64, f64),
    pixel: impl Fn(u32, u32) -> [u8; 3],
) -> Vec<[f64; 3]> {
    let (nx, ny) = CELLS;
    let mut means = Vec::new();
    for cy in 0..ny {
        for cx in 0..nx {
            // A pixel's margin inside each cell: the scaled picture's edges are filtered.
            let xs = (x0 + w * cx as f64 / nx as f64).ceil() as u32 + 1;
            let xe = (x0 + w * (cx + 1) as f64 / nx as f64).floor() as u32 - 1;
            let ys = (y0 + h * cy as f64 / ny as f64).ceil() as u32 + 1;
            let ye = (y0 + h * (cy + 1) as f64 / ny as f64).floor() as u32 - 1;
            let (mut sum, mut n) = ([0f64; 3], 0f64);
            for y in ys..ye {
                for x in xs..xe {
                    let p = pixel(x, y);
                    for c in 0..3 {
                        sum[c] += f64::from(p[c]);
                    }
                    n += 1.0;
                }
            }
            means.push(sum.map(|s| s / n.max(1.0)));
        }
    }
    means
}

fn read_probe(path: &Path) -> Option<Value> {
    serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()
}

#[test]
fn gpu_reconstruction_is_drawn_from_the_device_with_no_read_back_and_matches_headless() {
    let name = "gpu_reconstruction_is_drawn_from_the_device_with_no_read_back_and_matches_headless";
    let Some(xvfb) = Xvfb::start_or_skip(name, WIDTH, HEIGHT) else { return };
    let dir = tempfile::tempdir().unwrap();
    let reference = headless_reference(&dir.path().join("headless"));

    let probe = dir.path().join("probe.json");
    let mut window = demo()
        .args(["demo", "--workers", "2", "--reconstruct", "gpu", "--out"])
        .arg(dir.path().join("window"))
        .env("DISPLAY", &xvfb.display)
        .env_remove("WAYLAND_DISPLAY")
        .env("GRIDLIGHT_PANEL_PROBE", &probe)
        .spawn()
        .expect("gridlight demo starts");
    let deadline = Instant::now() + Duration::from_secs(600);
    let display = loop {
        if let Some(status) = window.try_wait().unwrap() {
            panic!("the windowed demo exited ({status}) before drawing {WINDOW_FRAMES} frames");
        }
        let display = read_probe(&probe).map(|p| p["display"].clone());
        let drawn = display.as_ref().and_then(|d| d["device_frames"].as_u64()).unwrap_or(0);
        if drawn >= WINDOW_FRAMES {
            break display.expect("read above");
        }
        assert!(Instant::now() < deadline, "{WINDOW_FRAMES} device frames not drawn: {display:?}");
        std::thread::sleep(Duration::from_millis(250));
    };
    let (conn, screen) = x11rb::connect(Some(&xvfb.display)).expect("connects to Xvfb");
    let root = conn.setup().roots[screen].root;
    let shot = Shot::take(&conn, root, &xvfb);
    shot.save("one-device.png");
    // Read after the shot: the picture rect and the counts of what is on screen now.
    let probe_now = read_probe(&probe).expect("the probe");
    let display_now = &probe_now["display"];
    assert_eq!(display["frames_read_back"], 0, "no frame read back: {display}");
    assert_eq!(display_now["frames_read_back"], 0, "no frame read back: {display_now}");
    assert_eq!(display_now["picture_uploads"], 0, "no picture uploaded: {display_now}");
    assert_ne!(display_now["reconstructor"], "cpu", "GPU reconstruction: {display_now}");

    let win = find_window(&conn, root, "gridlight demo").expect("the demo's window exists");
    let origin =
        conn.translate_coordinates(win, root, 0, 0).unwrap().reply().expect("window position");
    let rect: Vec<f64> = probe_now["picture"]
        .as_array()
        .expect("the picture's rect")
        .iter()
        .map(|v| v.as_f64().expect("a number"))
        .collect();
    let on_screen =
        (rect[0] + f64::from(origin.dst_x), rect[1] + f64::from(origin.dst_y), rect[2], rect[3]);
    let screen_cells = cell_means(on_screen, |x, y| shot.rgb[(y * u32::from(WIDTH) + x) as usize]);
    let (rw, rh) = reference.dimensions();
    let reference_cells =
        cell_means((0.0, 0.0, f64::from(rw), f64::from(rh)), |x, y| reference.get_pixel(x, y).0);
    let diffs: Vec<f64> = screen_cells
        .iter()
        .zip(&reference_cells)
        .flat_map(|(s, r)| (0..3).map(move |c| (s[c] - r[c]).abs()))
        .collect();
    let worst = diffs.iter().copied().fold(0.0, f64::max);
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    assert!(
        worst < 12.0 && mean < 4.0,
        "screen vs headless cell means (0–255): worst {worst:.1}, mean {mean:.1}\n\
         screen {screen_cells:?}\nheadless {reference_cells:?}"
    );

    request_close(&conn, win);
    let deadline = Instant::now() + Duration::from_secs(30);
    let status = loop {
        if let Some(status) = window.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the demo did not exit after the close request");
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "the demo exits cleanly after its window closes: {status}");
}
