//! `gridlight render` end to end on a small Cornell box: writes PNG and EXR of the scene's
//! size (or `--resolution`'s), rejects a bad extension and a bad `--resolution` (on
//! `master` and `demo` too), and gives the same image on any number of threads.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;

use gridlight::cli::render::render_image;
use gridlight::render::RenderScene;
use gridlight::scene::{self, AssetSearchPath};

/// The Cornell box at `width`×`height`, written into `dir`.
fn small_cornell(dir: &Path, width: u32, height: u32) -> PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(repo.join("scenes/cornell-box.toml")).expect("scene");
    let text = text
        .replace("width = 640", &format!("width = {width}"))
        .replace("height = 480", &format!("height = {height}"));
    let path = dir.join("small.toml");
    std::fs::write(&path, text).expect("write scene");
    path
}

fn gridlight(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .expect("run gridlight")
}

#[test]
fn renders_png_and_exr_of_the_scene_size() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 32, 24);
    let scene = scene.to_str().expect("utf-8 path");
    for name in ["c.png", "c.exr"] {
        let out = dir.path().join(name);
        let run = gridlight(&[
            "render",
            scene,
            "--spp",
            "2",
            "--quiet",
            "--out",
            out.to_str().expect("utf-8"),
        ]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let image = image::open(&out).expect("readable image").to_rgb32f();
        assert_eq!(image.dimensions(), (32, 24));
        // The light is visible near the top centre and the room is lit.
        let mean: f32 =
            image.pixels().map(|p| p[0] + p[1] + p[2]).sum::<f32>() / (32.0 * 24.0 * 3.0);
        assert!(mean > 0.05, "{name}: image too dark ({mean})");
    }
}

#[test]
fn resolution_flag_overrides_the_scene_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 8, 8);
    let out = dir.path().join("c.png");
    let run = gridlight(&[
        "render",
        scene.to_str().expect("utf-8"),
        "--spp",
        "1",
        "--quiet",
        "--resolution",
        "20x12",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let image = image::open(&out).expect("readable image").to_rgb8();
    assert_eq!(image.dimensions(), (20, 12));
}

#[test]
fn scale_flag_scales_the_file_or_the_resolution_flag() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 8, 8);
    let out = dir.path().join("c.png");
    let cases: [(&[&str], (u32, u32)); 2] =
        [(&["--scale", "2.5"], (20, 20)), (&["--resolution", "20x12", "--scale", "0.5"], (10, 6))];
    for (flags, size) in cases {
        let mut args = vec!["render", scene.to_str().expect("utf-8"), "--spp", "1", "--quiet"];
        args.extend_from_slice(flags);
        args.extend(["--out", out.to_str().expect("utf-8")]);
        let run = gridlight(&args);
        assert!(run.status.success(), "{flags:?}: {}", String::from_utf8_lossy(&run.stderr));
        let image = image::open(&out).expect("readable image").to_rgb8();
        assert_eq!(image.dimensions(), size, "{flags:?}");
        std::fs::remove_file(&out).expect("output written");
    }
}

/// `render`, `master` and `demo` refuse a bad `--scale` before loading anything, and a
/// scale that makes a side too large once the scene's size is known.
#[test]
fn bad_scale_is_a_clear_error_on_every_command() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 8, 8);
    let scene = scene.to_str().expect("utf-8");
    let out = dir.path().join("c.png");
    let out = out.to_str().expect("utf-8");
    let cases = [
        ("0", "`0` is not a scale factor"),
        ("abc", "`abc` is not a scale factor"),
        ("4096", "--scale 4096 makes the width 32768 pixels"),
    ];
    for (value, expected) in cases {
        let commands: [&[&str]; 3] = [
            &["render", scene, "--out", out, "--scale", value],
            &["master", scene, "--headless", "--scale", value],
            &["demo", scene, "--headless", "--scale", value],
        ];
        for args in commands {
            let run = gridlight(args);
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert!(!run.status.success(), "{args:?} succeeded");
            assert!(stderr.contains("--scale") && stderr.contains(expected), "{args:?}: {stderr}");
        }
    }
    assert!(!dir.path().join("c.png").exists());
}

/// `render`, `master` and `demo` refuse a bad `--resolution` before loading anything.
#[test]
fn bad_resolution_is_a_clear_error_on_every_command() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 8, 8);
    let scene = scene.to_str().expect("utf-8");
    let out = dir.path().join("c.png");
    let out = out.to_str().expect("utf-8");
    let cases = [
        ("0x5", "width 0 is not in 1..=16384"),
        ("abc", "`abc` is not WIDTHxHEIGHT"),
        ("100000x100000", "width 100000 is not in 1..=16384"),
    ];
    for (value, expected) in cases {
        let commands: [&[&str]; 3] = [
            &["render", scene, "--out", out, "--resolution", value],
            &["master", scene, "--headless", "--resolution", value],
            &["demo", scene, "--headless", "--resolution", value],
        ];
        for args in commands {
            let run = gridlight(args);
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert!(!run.status.success(), "{args:?} succeeded");
            assert!(
                stderr.contains("--resolution") && stderr.contains(expected),
                "{args:?}: {stderr}"
            );
        }
    }
    assert!(!dir.path().join("c.png").exists());
}

#[test]
fn bad_output_extension_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = small_cornell(dir.path(), 8, 8);
    let out = dir.path().join("c.jpg");
    let run = gridlight(&[
        "render",
        scene.to_str().expect("utf-8"),
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("c.jpg") && stderr.contains(".png or .exr"), "{stderr}");
    assert!(!out.exists());
}

#[test]
fn image_does_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = small_cornell(dir.path(), 24, 16);
    let loaded = scene::load(&path, &AssetSearchPath::from_dirs(vec![])).expect("scene loads");
    let mut state = loaded.state;
    state.render.spp = 1;
    let render = RenderScene::new(Arc::new(loaded.assets), &state).expect("renderable");
    let hidden = indicatif::ProgressBar::hidden();
    let one = render_image(&render, 3, 1, &hidden);
    let three = render_image(&render, 3, 3, &hidden);
    assert_eq!(one.len(), 24 * 16);
    assert_eq!(one, three);
    assert!(one.iter().any(|p| p.max_element() > 0.0));
}

/// `gridlight render model.glb`: the file's camera (4:3 → 640×480 unless `--resolution`),
/// its point light and its materials; the lit orange quad shows its base colour in front
/// of the dimmer grey wall.
#[test]
fn renders_a_glb_file_directly() {
    use gridlight::scene::gltf::fixture::lit_scene;

    let dir = tempfile::tempdir().expect("tempdir");
    let f = lit_scene(serde_json::json!({ "name": "orange", "pbrMetallicRoughness": {
        "baseColorFactor": [1.0, 0.4, 0.0, 1.0], "metallicFactor": 0.0 } }));
    let glb = dir.path().join("lit.glb");
    std::fs::write(&glb, f.glb()).expect("write glb");
    let out = dir.path().join("lit.png");
    let run = gridlight(&[
        "render",
        glb.to_str().expect("utf-8"),
        "--spp",
        "16",
        "--quiet",
        "--resolution",
        "40x30",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let image = image::open(&out).expect("readable image").to_rgb32f();
    assert_eq!(image.dimensions(), (40, 30));
    let centre = image.get_pixel(20, 15);
    let corner = image.get_pixel(1, 1);
    assert!(centre[0] > 0.3 && centre[0] > 3.0 * centre[2], "not orange: {centre:?}");
    assert!((corner[0] - corner[2]).abs() < 0.05, "the wall is not grey: {corner:?}");
    assert!(centre[0] > corner[0], "the lit quad is not brighter: {centre:?} {corner:?}");
}
