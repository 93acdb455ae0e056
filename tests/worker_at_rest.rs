//! What a worker leaves on its disk, between real processes on loopback: with `--cache
//! none` nothing at all (the assets it fetched stay in its memory), and with
//! `--forget-on-exit` nothing of the scene it rendered once it leaves the grid (SIGTERM,
//! or the master gone), while another scene's entries in the same cache stay.
//! Unix only: it stops the worker with SIGTERM.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use sha2::{Digest, Sha256};

mod support;
use support::*;

/// A one-triangle scene whose mesh is the asset `name`, with `bytes` as its file.
fn scene_with_mesh(dir: &Path, name: &str, bytes: &str) -> String {
    std::fs::create_dir_all(dir.join("assets")).unwrap();
    std::fs::write(dir.join("assets").join(name), bytes).unwrap();
    format!(
        "{SCENE}\n[[materials]]\nname = \"white\"\nbase_color = [0.8, 0.8, 0.8]\n\n\
         [[objects]]\nname = \"tri\"\nmesh = \"{name}\"\nmaterial = \"white\"\n"
    )
}

const MESH_A: &str = "# scene a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const MESH_B: &str = "# scene b\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 3 2\n";

fn blob(cache: &Path, bytes: &str) -> PathBuf {
    cache.join("blobs").join(hex::encode(Sha256::digest(bytes.as_bytes())))
}

fn views(cache: &Path) -> usize {
    std::fs::read_dir(cache.join("views")).map_or(0, |d| d.count())
}

/// Every file under `dir`, recursively.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            out.extend(files_under(&path));
        } else {
            out.push(path);
        }
    }
    out
}

/// Waits until `master` has results from a worker.
fn rendering(master: &Master) {
    eventually("results from the worker", || {
        master.stats().iter().any(|s| u(s, "workers") >= 1 && u(s, "jobs_back") > 0).then_some(())
    });
}

fn stop(mut w: Proc) -> String {
    w.signal(libc::SIGTERM);
    let status = w.wait(PATIENCE).expect("the worker stops on SIGTERM");
    assert!(status.success(), "{status:?}: {}", w.stderr());
    w.stderr()
}

#[test]
fn with_cache_none_the_worker_writes_nothing_to_disk() {
    let dir = tempfile::tempdir().unwrap();
    let m = dir.path().join("m");
    let master =
        Master::start_scene(&m, &scene_with_mesh(&m, "tri.obj", MESH_A), "127.0.0.1:0", &[]);
    // Every place a worker could write by default: its home, cache, temporary and
    // working directories, all empty and all the worker's.
    let home = dir.path().join("home");
    for sub in ["", ".cache", "xdg", "tmp", "cwd"] {
        std::fs::create_dir_all(home.join(sub)).unwrap();
    }
    let addr = master.addr.to_string();
    let mut cmd = Command::new(EXE);
    cmd.args(["worker", "--master", &addr, "--threads", "2", "--name", "mem", "--null-render"])
        .args(["--priority", "normal", "--cache", "none"])
        .env("HOME", &home)
        .env("XDG_CACHE_HOME", home.join("xdg"))
        .env("TMPDIR", home.join("tmp"))
        .env("RUST_LOG", "info")
        .current_dir(home.join("cwd"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let stdout = collect(child.stdout.take().unwrap());
    let stderr = collect(child.stderr.take().unwrap());
    let worker = Proc { child, stdout, stderr };
    rendering(&master);
    let log = stop(worker);
    assert!(log.contains("fetching asset") && log.contains("tri.obj"), "{log}");
    assert_eq!(files_under(&home), Vec::<PathBuf>::new(), "the worker wrote to disk");
}

#[test]
fn forget_on_exit_wipes_the_scene_it_rendered_and_keeps_the_others() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let (ma, mb) = (dir.path().join("a"), dir.path().join("b"));
    let a = Master::start_scene(&ma, &scene_with_mesh(&ma, "a.obj", MESH_A), "127.0.0.1:0", &[]);
    let b = Master::start_scene(&mb, &scene_with_mesh(&mb, "b.obj", MESH_B), "127.0.0.1:0", &[]);

    // Scene a is cached by a worker that keeps it.
    let keeper = worker(a.addr, &cache, "keeper", 2, &[]);
    rendering(&a);
    stop(keeper);
    assert!(blob(&cache, MESH_A).is_file());
    assert_eq!(views(&cache), 1);

    // Scene b by one that forgets it on SIGTERM.
    let forgetful = worker(b.addr, &cache, "forgetful", 2, &["--forget-on-exit"]);
    rendering(&b);
    assert!(blob(&cache, MESH_B).is_file(), "fetched into the cache while rendering");
    let log = stop(forgetful);
    assert!(log.contains("wiped"), "{log}");
    assert!(!blob(&cache, MESH_B).exists(), "scene b's mesh left behind");
    assert_eq!(views(&cache), 1, "scene b's view left behind");
    assert!(blob(&cache, MESH_A).is_file(), "scene a's mesh was wiped too");
    assert_eq!(std::fs::read_to_string(blob(&cache, MESH_A)).unwrap(), MESH_A);

    // And when the master goes away while the worker keeps running.
    let forgetful = worker(b.addr, &cache, "forgetful", 2, &["--forget-on-exit"]);
    eventually("jobs for the new worker", || (!forgetful.jobs_received().is_empty()).then_some(()));
    assert!(blob(&cache, MESH_B).is_file());
    drop(b);
    eventually("scene b wiped once its master is gone", || {
        (!blob(&cache, MESH_B).exists() && views(&cache) == 1).then_some(())
    });
    assert!(blob(&cache, MESH_A).is_file());
    stop(forgetful);
}
