//! Supervision through the real binary: `gridlight master --headless` whose actors are
//! made to panic by the hidden `--inject-panic` test hook. Within the restart intensity
//! the master restarts them and finishes its frames; past it, it exits non-zero with a
//! message naming the actor and its panics instead of waiting forever.

mod support;

use support::*;

#[test]
fn a_master_past_its_restart_intensity_exits_non_zero_naming_the_actor() {
    let dir = tempfile::tempdir().expect("tempdir");
    let scene = dir.path().join("scene.toml");
    std::fs::write(&scene, SCENE).expect("scene");
    let mut master = Proc::spawn(
        &[
            "master",
            scene.to_str().expect("utf-8 path"),
            "--listen",
            "127.0.0.1:0",
            "--headless",
            "--no-announce",
            "--inject-panic",
            "scheduler:started",
        ],
        &[],
    );
    let status = master.wait(PATIENCE).expect("the master exits instead of waiting forever");
    let stderr = master.stderr();
    assert_eq!(status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("the scheduler panicked 6 times"), "{stderr}");
    assert!(
        stderr.contains("in its started: injected panic in the scheduler's started"),
        "{stderr}"
    );
}

#[test]
fn a_master_whose_actors_panic_a_few_times_restarts_them_and_finishes() {
    let dir = tempfile::tempdir().expect("tempdir");
    let panics = [
        "scheduler:started:1",
        "presenter:started:2",
        "assembler:handler:1",
        "listener:handler:1",
        "connection:handler:1",
    ];
    let mut extra = vec!["--no-announce", "--frames", "5"];
    for p in &panics {
        extra.extend(["--inject-panic", p]);
    }
    let mut master = Master::start(&dir.path().join("master"), "127.0.0.1:0", &extra);
    let _worker = worker(master.addr, &dir.path().join("cache"), "w", 1, &[]);
    let status = master.proc.wait(PATIENCE).expect("the master finishes its frames");
    let stderr = master.proc.stderr();
    assert!(status.success(), "{stderr}");
    assert_eq!(master.shown(), 5, "{stderr}");
    let restarts = stderr.matches("panic contained; restarting").count();
    let ended = stderr.matches("panic contained; ending").count();
    assert_eq!((restarts, ended), (5, 1), "{stderr}");
}
