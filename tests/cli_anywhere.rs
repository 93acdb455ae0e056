//! The binary outside the repository, as a new user runs it after `cargo install`: from an
//! empty directory, built-in scenes render by name, `gridlight scenes` lists them and the
//! scene files on the asset search path, a headless demo runs on the built-in Cornell
//! box, and `render` to a path it cannot write fails at once with a clear error.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Runs gridlight in `dir` with no asset folders of the environment.
fn gridlight_in(dir: &Path, args: &[&str]) -> Output {
    run_in(Path::new(env!("CARGO_BIN_EXE_gridlight")), dir, args)
}

/// Runs `binary` in `dir` with no asset folders of the environment and no display.
fn run_in(binary: &Path, dir: &Path, args: &[&str]) -> Output {
    Command::new(binary)
        .args(args)
        .current_dir(dir)
        .env("RUST_LOG", "warn")
        .env_remove("GRIDLIGHT_ASSETS")
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run gridlight")
}

fn text(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

#[test]
fn a_builtin_scene_renders_by_name_from_an_empty_directory() {
    let dir = tempfile::tempdir().unwrap();
    let run = gridlight_in(
        dir.path(),
        &["render", "cornell-box", "--spp", "1", "--quiet", "--out", "x.png"],
    );
    assert!(run.status.success(), "{}", text(&run));
    let image = image::open(dir.path().join("x.png")).expect("x.png was written").to_rgb8();
    assert_eq!(image.dimensions(), (640, 480));
    let lit = image.pixels().filter(|p| p.0.iter().any(|&c| c > 40)).count();
    assert!(lit > 640 * 480 / 4, "the Cornell box is lit ({lit} pixels)");
    // A file path works as before, and an unknown name says what exists.
    std::fs::write(dir.path().join("mine.toml"), gridlight::scene::builtin::BUILTINS[0].text)
        .unwrap();
    let run = gridlight_in(
        dir.path(),
        &["render", "mine.toml", "--spp", "1", "--quiet", "--out", "y.png"],
    );
    assert!(run.status.success(), "{}", text(&run));
    let run = gridlight_in(dir.path(), &["render", "no-such-scene", "--out", "z.png"]);
    assert!(!run.status.success());
    let err = text(&run);
    assert!(err.contains("no-such-scene") && err.contains("glossy-glass"), "{err}");
    assert!(!dir.path().join("z.png").exists(), "no empty image left behind");
}

#[test]
fn scenes_lists_builtins_and_scene_files_on_the_asset_search_path() {
    let dir = tempfile::tempdir().unwrap();
    let assets = dir.path().join("my-assets");
    std::fs::create_dir(&assets).unwrap();
    std::fs::write(assets.join("room.toml"), "").unwrap();
    let run = gridlight_in(dir.path(), &["--assets", "my-assets", "scenes"]);
    assert!(run.status.success(), "{}", text(&run));
    let out = String::from_utf8_lossy(&run.stdout);
    for name in ["cornell-box", "glossy-glass", "room.toml"] {
        assert!(out.contains(name), "`gridlight scenes` lists {name}: {out}");
    }
}

#[test]
fn the_headless_demo_runs_the_builtin_cornell_box_from_an_empty_directory() {
    let dir = tempfile::tempdir().unwrap();
    let run = gridlight_in(dir.path(), &["demo", "--headless", "--workers", "1", "--frames", "2"]);
    assert!(run.status.success(), "{}", text(&run));
    let out = String::from_utf8_lossy(&run.stdout);
    assert!(out.contains("demo: 2 frames shown"), "{out}");
    let stats = std::fs::read_to_string(dir.path().join("gridlight-demo/stats.jsonl")).unwrap();
    let first: serde_json::Value = serde_json::from_str(stats.lines().next().unwrap()).unwrap();
    assert!(first["edit_latency_ms"].is_array(), "every frame line has its edits: {first}");
}

/// `render` with an output it cannot write, and so many samples that rendering first
/// would take hours: it must fail at once, naming the file.
fn fails_before_rendering(dir: &Path, out: &str, expect: &str) {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .args(["render", "cornell-box", "--spp", "1000000", "--quiet", "--out", out])
        .current_dir(dir)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run gridlight");
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("`render --out {out}` started rendering instead of failing");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!status.success(), "{out}: {err}");
    assert!(err.contains(out) && err.contains(expect), "{out}: {err}");
}

#[test]
fn render_to_an_unwritable_path_fails_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    fails_before_rendering(dir.path(), "no-such-folder/x.png", "No such file or directory");
    std::fs::create_dir(dir.path().join("a-folder.png")).unwrap();
    fails_before_rendering(dir.path(), "a-folder.png", "Is a directory");
    // A bad setting found after the output was claimed leaves no empty file behind.
    let run =
        gridlight_in(dir.path(), &["render", "cornell-box", "--spp", "0", "--out", "new.png"]);
    assert!(!run.status.success());
    assert!(!dir.path().join("new.png").exists(), "the claimed output is removed again");
}

/// What `cargo install --path .` then `gridlight demo` and `gridlight render cornell-box
/// --out x.png` in an empty directory do, as far as a test can: the binary copied out of
/// the build tree (as `cargo install` copies it into `--root`/bin), run from an empty
/// directory far from the sources, with none of cargo's variables.
#[test]
fn an_installed_copy_of_the_binary_runs_the_demo_and_renders_from_an_empty_directory() {
    let root = tempfile::tempdir().unwrap();
    let bin = root.path().join("bin");
    std::fs::create_dir(&bin).unwrap();
    let installed = bin.join("gridlight");
    std::fs::copy(env!("CARGO_BIN_EXE_gridlight"), &installed).expect("copy the binary");
    let empty = tempfile::tempdir().unwrap();
    let cargo_free = |args: &[&str]| {
        let mut cmd = Command::new(&installed);
        cmd.args(args).current_dir(empty.path()).env("RUST_LOG", "warn");
        for (key, _) in std::env::vars_os() {
            let key = key.to_string_lossy().into_owned();
            if key.starts_with("CARGO") || key == "GRIDLIGHT_ASSETS" || key.ends_with("DISPLAY") {
                cmd.env_remove(key);
            }
        }
        cmd.stdin(Stdio::null()).output().expect("run the installed gridlight")
    };
    let demo = cargo_free(&["demo", "--workers", "1", "--frames", "2"]);
    assert!(demo.status.success(), "{}", text(&demo));
    assert!(
        String::from_utf8_lossy(&demo.stdout).contains("demo: 2 frames shown"),
        "{}",
        text(&demo)
    );
    let render = cargo_free(&["render", "cornell-box", "--spp", "1", "--quiet", "--out", "x.png"]);
    assert!(render.status.success(), "{}", text(&render));
    let image = image::open(empty.path().join("x.png")).expect("x.png was written");
    assert_eq!((image.width(), image.height()), (640, 480));
}
