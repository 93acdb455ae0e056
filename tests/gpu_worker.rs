//! A mixed grid, end to end with real processes: one CPU worker and one GPU worker
//! (`gridlight worker --gpu`, on lavapipe where there is no GPU) on one headless master
//! render the Cornell box. Both contribute results, no (frame, set) reaches both, and the
//! master's last frame agrees with `gridlight render` in mean colour: a GPU worker's
//! results cannot be told from a CPU worker's but by their speed.

mod support;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use gridlight::gpu::GpuContext;
use gridlight::testing::{skip, Missing};
use support::{assert_nothing_handed_out_twice, eventually, Proc};

const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
const FRAMES: u32 = 40;
/// Lavapipe compiles the trace pass and calibrates before the GPU worker connects.
const PATIENCE: Duration = Duration::from_secs(300);

fn scene(dir: &Path) -> PathBuf {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml");
    let text = std::fs::read_to_string(source).expect("the Cornell box scene");
    let text = text
        .replace("width = 640", &format!("width = {WIDTH}"))
        .replace("height = 480", &format!("height = {HEIGHT}"));
    assert!(text.contains(&format!("width = {WIDTH}")), "the scene's resolution changed form");
    let path = dir.join("cornell.toml");
    std::fs::write(&path, text).expect("writing the scene");
    path
}

fn read_exr(path: &Path) -> Vec<Vec3> {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!((img.width(), img.height()), (WIDTH, HEIGHT));
    img.to_rgb32f().pixels().map(|p| Vec3::from_array(p.0)).collect()
}

fn mean(img: &[Vec3]) -> DVec3 {
    img.iter().map(|c| c.as_dvec3()).sum::<DVec3>() / img.len() as f64
}

fn worker(addr: &str, cache: &Path, name: &str, extra: &[&str]) -> Proc {
    let mut args = vec!["worker", "--master", addr, "--threads", "1", "--name", name];
    args.extend_from_slice(&["--priority", "normal", "--cache-dir", cache.to_str().unwrap()]);
    args.extend_from_slice(extra);
    Proc::spawn(&args, &[("RUST_LOG", "info,gridlight::worker=debug"), ("NODEVICE_SELECT", "1")])
}

#[test]
fn a_cpu_and_a_gpu_worker_render_one_scene_together() {
    if let Err(err) = GpuContext::new() {
        skip("a_cpu_and_a_gpu_worker_render_one_scene_together", Missing::Adapter, err);
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(dir.path());
    let out = dir.path().join("frames");
    let frames = FRAMES.to_string();
    let mut master = Proc::spawn(
        &[
            "master",
            scene.to_str().unwrap(),
            "--listen",
            "127.0.0.1:0",
            "--sets",
            "16",
            "--headless",
            "--frames",
            &frames,
            "--exr",
            "--out",
            out.to_str().unwrap(),
            "--reconstruct",
            "cpu",
        ],
        &[],
    );
    let addr = eventually("the master's listening line", || {
        let text = master.stdout.lock().unwrap().clone();
        text.lines()
            .find_map(|l| l.strip_prefix(gridlight::master::launch::LISTENING_PREFIX))
            .map(|a| a.trim().to_string())
    });
    // The GPU worker first: the CPU one joins once the GPU's results flow, so that both
    // serve the same frames.
    let gpu = worker(&addr, &dir.path().join("gpu-cache"), "gpu", &["--gpu"]);
    let deadline = Instant::now() + PATIENCE;
    while gpu.results_sent().is_empty() {
        assert!(Instant::now() < deadline, "the GPU worker sent nothing:\n{}", gpu.stderr());
        std::thread::sleep(Duration::from_millis(100));
    }
    let cpu = worker(&addr, &dir.path().join("cpu-cache"), "cpu", &[]);
    let status = loop {
        if let Some(status) = master.wait(Duration::from_millis(100)) {
            break status;
        }
        assert!(Instant::now() < deadline, "the master did not show {FRAMES} frames");
    };
    assert!(status.success(), "the master failed:\n{}", master.stderr());
    let (from_gpu, from_cpu) = (gpu.results_sent().len(), cpu.results_sent().len());
    println!("results sent: GPU worker {from_gpu}, CPU worker {from_cpu}");
    assert!(from_gpu > 0 && from_cpu > 0, "GPU {from_gpu}, CPU {from_cpu} results");
    assert!(gpu.stderr().contains("GPU batch rendered"), "the GPU worker did not use the GPU");
    assert_nothing_handed_out_twice(&[&gpu, &cpu]);

    let last = std::fs::read_dir(&out)
        .expect("frames written")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "exr"))
        .max()
        .expect("an EXR frame");
    let shown = read_exr(&last);
    assert!(shown.iter().all(|c| c.is_finite()), "non-finite pixels");
    let reference_path = dir.path().join("reference.exr");
    let run = std::process::Command::new(support::EXE)
        .args(["render", scene.to_str().unwrap(), "--spp", "64", "--out"])
        .arg(&reference_path)
        .output()
        .expect("gridlight render runs");
    assert!(run.status.success(), "render: {}", String::from_utf8_lossy(&run.stderr));
    let (want, got) = (mean(&read_exr(&reference_path)), mean(&shown));
    let ratio = got / want;
    println!("mean colour: render {want:.4?}, mixed grid {got:.4?}");
    assert!((ratio - DVec3::ONE).abs().max_element() < 0.03, "ratio {ratio:.4?}");
}
