//! gridlight as separate processes on loopback: a real `gridlight master` and real
//! `gridlight worker`s, faults injected with signals and hostile raw clients.
//!
//! The workers use the null renderer (hidden `--null-render`), whose radiance encodes the
//! frame number (`worker::render::null_radiance`), and the master writes each frame's
//! own results as EXR (hidden `--dump-current`), so a test can tell which frame every
//! shown pixel came from. Images are tiny and frames few: the suite runs on 2 cores.

// Kills, stops and interrupts processes with POSIX signals.
#![cfg(unix)]

use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;

use gridlight::worker::render::null_radiance;
use gridlight_actors::channel::{initiate, Psk};
use gridlight_actors::channel_codec::{KeySlot, WorkerChannelCodec};
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::protocol::{MasterMsg, PackedRadiance, WorkerMsg, PROTOCOL_VERSION};
use serde_json::Value;
use tokio_util::codec::{Decoder, Encoder};

mod support;
use support::*;

/// Checks every dumped frame: each pixel is either a hole (0) or the null radiance of
/// that very frame, and the covered pixels are exactly the returned sets. The master
/// writes a frame's image before its stats line, so every frame listed has one: a missing
/// image fails, and so does a run with no frame at all. Returns the frames checked.
fn check_frames_hold_only_their_own_results(master: &Master) -> usize {
    let set_len = (WIDTH * HEIGHT / SETS) as usize;
    let mut checked = 0;
    for line in master.stats() {
        let frame = u(&line, "frame");
        let path = master.dir.join("frames").join(format!("frame-{frame:06}.current.exr"));
        let img = image::open(&path)
            .unwrap_or_else(|e| panic!("frame {frame} is listed but its image is not: {e}"));
        let img = img.to_rgb32f();
        let own = null_radiance(frame).x;
        let mut covered = 0;
        for p in img.pixels() {
            if p.0 == [0.0; 3] {
                continue;
            }
            assert_eq!(p.0, [own; 3], "frame {frame} shows a pixel from another frame");
            covered += 1;
        }
        let jobs_back = u(&line, "jobs_back") as usize;
        assert!(jobs_back <= SETS as usize, "frame {frame}: {jobs_back} results for {SETS} sets");
        assert_eq!(covered, jobs_back * set_len, "frame {frame}: covered pixels vs results back");
        checked += 1;
    }
    assert!(checked > 0, "no frame was shown, so none could be checked");
    checked
}

#[test]
fn two_worker_processes_fill_every_frame_with_that_frames_results_only() {
    let dir = tempfile::tempdir().unwrap();
    let master = Master::start(dir.path(), "127.0.0.1:0", &["--frames", "12"]);
    let cache = dir.path().join("cache");
    let a = worker(master.addr, &cache, "a", 2, &[]);
    let b = worker(master.addr, &cache, "b", 2, &[]);
    let mut master = master;
    let status = master.proc.wait(PATIENCE).expect("master stops after 12 frames");
    assert!(status.success(), "master failed: {}", master.proc.stderr());
    let stats = master.stats();
    assert_eq!(stats.len(), 12);
    for key in [
        "frame",
        "state_version",
        "jobs_back",
        "q",
        "i",
        "wait_ms",
        "skipped",
        "dropped_late",
        "dropped_duplicate",
        "dropped_unknown",
        "workers",
        "bytes_in",
        "bytes_out",
    ] {
        assert!(stats[0].get(key).is_some(), "stats line lacks `{key}`: {}", stats[0]);
    }
    assert!(stats.iter().any(|s| u(s, "workers") == 2), "both workers took part");
    assert!(stats.iter().all(|s| u(s, "dropped_duplicate") == 0), "no result arrived twice");
    assert_nothing_handed_out_twice(&[&a, &b]);
    assert_eq!(check_frames_hold_only_their_own_results(&master), 12);
    assert!(dir.path().join("frames/summary.json").is_file(), "summary written at the end");
}

#[test]
fn frames_go_on_when_a_worker_is_killed_mid_frame() {
    let dir = tempfile::tempdir().unwrap();
    let master = Master::start(dir.path(), "127.0.0.1:0", &[]);
    let cache = dir.path().join("cache");
    // The victim is slow, so it always holds jobs when it dies.
    let victim = worker(master.addr, &cache, "victim", 150, &[]);
    let steady = worker(master.addr, &cache, "steady", 5, &[]);
    eventually("the victim renders", || (!victim.results_sent().is_empty()).then_some(()));
    master.wait_more_frames(2);
    victim.signal(libc::SIGKILL);
    let killed_at = master.shown();
    master.wait_more_frames(8);
    let stats = master.stats();
    let after: Vec<_> = stats[killed_at + 2..].iter().collect();
    assert!(after.iter().all(|s| u(s, "workers") == 1), "the dead worker is gone from the master");
    assert!(stats.iter().all(|s| u(s, "dropped_duplicate") == 0), "no result arrived twice");
    // The jobs the victim held when it died were lost, never handed to the steady worker.
    assert_nothing_handed_out_twice(&[&victim, &steady]);
    check_frames_hold_only_their_own_results(&master);
}

#[test]
fn a_stopped_worker_has_its_late_result_dropped_and_then_gets_new_work() {
    let dir = tempfile::tempdir().unwrap();
    let master = Master::start(dir.path(), "127.0.0.1:0", &[]);
    let cache = dir.path().join("cache");
    let sleeper = worker(master.addr, &cache, "sleeper", 40, &[]);
    let steady = worker(master.addr, &cache, "steady", 5, &[]);
    eventually("the sleeper renders", || (sleeper.results_sent().len() >= 2).then_some(()));
    sleeper.signal(libc::SIGSTOP);
    // Its held jobs' frames are shown without it (well within the master's peer timeout).
    master.wait_more_frames(4);
    let before = sleeper.results_sent().len();
    let late_before = master.stats().last().map_or(0, |s| u(s, "dropped_late"));
    sleeper.signal(libc::SIGCONT);
    eventually("late results dropped and counted", || {
        master.stats().last().is_some_and(|s| u(s, "dropped_late") > late_before).then_some(())
    });
    // More results than the k = 2 it held: it was given new work after waking up.
    eventually("the sleeper gets new work", || {
        (sleeper.results_sent().len() > before + 2).then_some(())
    });
    // The sleeper's jobs, late or not, were never handed to the steady worker as well.
    assert_nothing_handed_out_twice(&[&sleeper, &steady]);
    check_frames_hold_only_their_own_results(&master);
}

#[test]
fn a_worker_joining_mid_run_gets_work_within_a_frame() {
    let dir = tempfile::tempdir().unwrap();
    let master = Master::start(dir.path(), "127.0.0.1:0", &[]);
    let cache = dir.path().join("cache");
    let _first = worker(master.addr, &cache, "first", 30, &[]);
    master.wait_more_frames(2);
    let late = worker(master.addr, &cache, "late", 30, &[]);
    let joined_at = eventually("the late worker is welcomed", || {
        late.stderr().contains("welcomed").then(|| master.shown())
    });
    let first_result_at = eventually("the late worker's first result", || {
        (!late.results_sent().is_empty()).then(|| master.shown())
    });
    assert!(
        first_result_at <= joined_at + 1,
        "the new worker waited {} frames for work",
        first_result_at - joined_at
    );
}

#[test]
fn workers_reconnect_by_themselves_when_the_master_restarts() {
    let dir = tempfile::tempdir().unwrap();
    let first = Master::start(&dir.path().join("m1"), "127.0.0.1:0", &[]);
    let addr = first.addr;
    let cache = dir.path().join("cache");
    let w = worker(addr, &cache, "w", 5, &[]);
    first.wait_more_frames(2);
    first.proc.signal(libc::SIGKILL);
    drop(first);
    let second = Master::start(&dir.path().join("m2"), &addr.to_string(), &[]);
    eventually("the worker serves the restarted master", || {
        second.stats().iter().any(|s| u(s, "jobs_back") > 0).then_some(())
    });
    assert!(w.stderr().contains("reconnecting"), "the worker said it reconnects");
}

/// A raw TCP client speaking (or not) the protocol.
struct Raw {
    stream: TcpStream,
    codec: WorkerChannelCodec,
    buf: bytes::BytesMut,
    /// The result key of this connection, once `join` saw the nonce.
    key: Option<ResultKey>,
}

impl Raw {
    fn connect(addr: SocketAddr) -> Raw {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(15))).unwrap();
        let codec = WorkerChannelCodec::new(KeySlot::new());
        Raw { stream, codec, buf: bytes::BytesMut::new(), key: None }
    }

    /// Sends a frame (a record of the channel once encrypted).
    fn send(&mut self, msg: &WorkerMsg) {
        let mut frame = bytes::BytesMut::new();
        self.codec.encode(msg, &mut frame).unwrap();
        self.stream.write_all(&frame).unwrap();
    }

    /// The encrypted channel's handshake with `secret`: the master's answer, and on
    /// success the channel's keys installed.
    fn encrypt(&mut self, secret: &[u8]) -> Option<MasterMsg> {
        let (init, noise) = initiate(&Psk::derive(secret)).unwrap();
        self.send(&WorkerMsg::Handshake { protocol: PROTOCOL_VERSION, noise });
        let answer = self.recv();
        if let Some(MasterMsg::Handshake { noise }) = &answer {
            self.codec.slot().install(init.finish(noise).expect("the master's answer"), None);
        }
        answer
    }

    /// The next message from the master; `None` once it closed the connection.
    fn recv(&mut self) -> Option<MasterMsg> {
        loop {
            if let Some(msg) =
                self.codec.decode(&mut self.buf).expect("the master sends valid frames")
            {
                if msg == MasterMsg::Heartbeat {
                    continue;
                }
                return Some(msg);
            }
            let mut chunk = [0u8; 4096];
            match self.stream.read(&mut chunk) {
                Ok(0) | Err(_) => return None,
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
            }
        }
    }

    /// The rejection reason the master sends before closing.
    fn rejection(&mut self) -> String {
        match self.recv() {
            Some(MasterMsg::Rejected { reason }) => {
                assert_eq!(self.recv(), None, "closed after the rejection");
                reason
            }
            other => panic!("expected Rejected, got {other:?}"),
        }
    }

    /// The encrypted handshake, Hello and Auth with `secret`; returns the Welcome.
    fn join(&mut self, secret: &[u8]) -> MasterMsg {
        assert!(matches!(self.encrypt(secret), Some(MasterMsg::Handshake { .. })));
        self.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "raw".into(), cores: 1 });
        let Some(MasterMsg::Challenge { nonce, auth_required }) = self.recv() else {
            panic!("no challenge")
        };
        assert!(auth_required);
        // The channel authenticates results: they carry no tag.
        self.key = Some(ResultKey::Channel);
        self.send(&WorkerMsg::Auth { mac: Some(gridlight_actors::auth::mac(secret, &nonce)) });
        self.recv().expect("an answer to Auth")
    }
}

#[test]
fn bad_peers_are_rejected_with_their_reason_and_the_master_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let secret_file = dir.path().join("secret");
    std::fs::write(&secret_file, "open sesame\n").unwrap();
    let master =
        Master::start(dir.path(), "127.0.0.1:0", &["--secret-file", secret_file.to_str().unwrap()]);
    let cache = dir.path().join("cache");
    let good =
        worker(master.addr, &cache, "good", 5, &["--secret-file", secret_file.to_str().unwrap()]);
    master.wait_more_frames(2);

    let mut reasons = BTreeMap::new();
    let mut c = Raw::connect(master.addr);
    c.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION + 1, name: "future".into(), cores: 1 });
    reasons.insert("version", c.rejection());

    let mut c = Raw::connect(master.addr);
    c.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "intruder".into(), cores: 1 });
    reasons.insert("no secret", c.rejection());

    let mut c = Raw::connect(master.addr);
    match c.encrypt(b"guess") {
        Some(MasterMsg::Rejected { reason }) => {
            assert_eq!(c.recv(), None, "closed after the rejection");
            reasons.insert("secret", reason);
        }
        other => panic!("a wrong secret's handshake was answered with {other:?}"),
    }

    let mut c = Raw::connect(master.addr);
    c.stream.write_all(&[0, 0, 0, 6, 0xc1, 0xc1, 0xc1, 0xc1, 0xc1, 0xc1]).unwrap();
    reasons.insert("garbage", c.rejection());

    let mut c = Raw::connect(master.addr);
    c.stream.write_all(&[0xff, 0xff, 0xff, 0xff]).unwrap();
    reasons.insert("oversized", c.rejection());

    let mut c = Raw::connect(master.addr);
    assert!(matches!(c.join(b"open sesame"), MasterMsg::Welcome { .. }));
    // Correctly tagged, so that it is refused for what it claims, not for its tag.
    let key = c.key.clone().expect("joined");
    let radiance = PackedRadiance::Rgb9e5(vec![0; (WIDTH * HEIGHT / SETS) as usize]);
    c.send(&WorkerMsg::Result(key.seal(1, 3, 1, radiance, 1)));
    reasons.insert("unasked result", c.rejection());

    let expect = [
        ("version", "version"),
        ("no secret", "requires a shared secret"),
        ("secret", "wrong shared secret"),
        ("garbage", "bad frame"),
        ("oversized", "exceeds"),
        ("unasked result", "not given"),
    ];
    for (case, needle) in expect {
        let reason = &reasons[case];
        assert!(reason.contains(needle), "{case}: reason `{reason}` does not say `{needle}`");
    }
    // The master and its real worker carry on.
    let before = good.results_sent().len();
    master.wait_more_frames(3);
    assert!(good.results_sent().len() > before);
    assert_eq!(master.stats().last().map(|s| u(s, "workers")), Some(1));
}

#[test]
fn a_worker_with_the_wrong_secret_exits_non_zero_naming_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let secret_file = dir.path().join("secret");
    std::fs::write(&secret_file, "right").unwrap();
    let wrong_file = dir.path().join("wrong");
    std::fs::write(&wrong_file, "wrong").unwrap();
    let master =
        Master::start(dir.path(), "127.0.0.1:0", &["--secret-file", secret_file.to_str().unwrap()]);
    let mut w = worker(
        master.addr,
        &dir.path().join("cache"),
        "w",
        0,
        &["--secret-file", wrong_file.to_str().unwrap()],
    );
    let status = w.wait(PATIENCE).expect("the worker gives up");
    assert!(!status.success());
    assert!(w.stderr().contains("wrong shared secret"), "{}", w.stderr());
}

/// No downgrade, both ways: a worker and a master of which only one has a secret never
/// work together, and both name the cause (the worker exits non-zero, the master logs it).
#[test]
fn a_secret_on_one_side_only_is_refused_by_both_naming_the_cause() {
    let dir = tempfile::tempdir().unwrap();
    let secret_file = dir.path().join("secret");
    std::fs::write(&secret_file, "open sesame").unwrap();
    let secret = ["--secret-file", secret_file.to_str().unwrap()];
    let cases: [(&[&str], &[&str], &str); 2] =
        [(&[], &secret, "does not encrypt"), (&secret, &[], "requires a shared secret")];
    for (i, (master_args, worker_args, cause)) in cases.into_iter().enumerate() {
        let master = Master::start(&dir.path().join(format!("m{i}")), "127.0.0.1:0", master_args);
        let cache = dir.path().join(format!("cache{i}"));
        let mut w = worker(master.addr, &cache, "w", 0, worker_args);
        let status = w.wait(PATIENCE).expect("the worker gives up");
        assert!(!status.success(), "{cause}: the worker went on");
        assert!(w.stderr().contains(cause), "worker, {cause}: {}", w.stderr());
        eventually("the master names the cause", || {
            master.proc.stderr().contains(cause).then_some(())
        });
        assert_eq!(master.shown(), 0, "{cause}: a frame was shown");
    }
}

#[test]
fn ctrl_c_stops_master_and_worker_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let mut master = Master::start(dir.path(), "127.0.0.1:0", &[]);
    assert!(
        master.proc.stderr().contains("any host on the network may join"),
        "an open master says so: {}",
        master.proc.stderr()
    );
    let mut w = worker(master.addr, &dir.path().join("cache"), "w", 5, &[]);
    master.wait_more_frames(2);
    w.signal(libc::SIGINT);
    let status = w.wait(PATIENCE).expect("the worker stops on Ctrl-C");
    assert!(status.success(), "worker: {status:?}\n{}", w.stderr());
    master.proc.signal(libc::SIGINT);
    let status = master.proc.wait(PATIENCE).expect("the master stops on Ctrl-C");
    assert!(status.success(), "master: {status:?}\n{}", master.proc.stderr());
    assert!(dir.path().join("frames/summary.json").is_file(), "summary written on Ctrl-C");
}

/// Processes whose command line mentions `needle`.
fn processes_mentioning(needle: &str) -> Vec<u32> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        let Ok(cmdline) = std::fs::read(entry.path().join("cmdline")) else { continue };
        if String::from_utf8_lossy(&cmdline).contains(needle) {
            found.push(pid);
        }
    }
    found
}

/// A floor lit by a quad light at 48×32, one sample per pixel: quick to render.
fn small_box_scene(dir: &std::path::Path) -> std::path::PathBuf {
    let scene = dir.join("box.toml");
    std::fs::write(
        &scene,
        r#"
[camera]
position = [0.0, 0.0, 3.9]
look_at = [0.0, 0.0, 0.0]
vfov = 40.0

[resolution]
width = 48
height = 32

[render]
max_depth = 3
spp = 1

[[materials]]
name = "white"
base_color = [0.8, 0.8, 0.8]

[[materials]]
name = "light"
base_color = [0.8, 0.8, 0.8]
emission = [10.0, 10.0, 10.0]

[[objects]]
name = "floor"
shape = "quad"
material = "white"
transform = { translation = [0.0, -1.0, 0.0], scale = 2.0 }

[[objects]]
name = "light"
shape = "quad"
material = "light"
transform = { translation = [0.0, 0.99, 0.0], rotation = [180.0, 0.0, 0.0], scale = 0.5 }
"#,
    )
    .unwrap();
    scene
}

/// Also checks `--resolution` and `--scale`: the frames have the command line's size (80×48
/// scaled by 0.5), not the file's 48×32.
#[test]
fn the_demo_renders_with_child_worker_processes_and_leaves_none_behind() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_box_scene(dir.path());
    let out = dir.path().join("demo-out");
    let mut demo = Proc::spawn(
        &[
            "demo",
            scene.to_str().unwrap(),
            "--workers",
            "2",
            "--frames",
            "3",
            "--sets",
            "8",
            "--resolution",
            "80x48",
            "--scale",
            "0.5",
            "--out",
            out.to_str().unwrap(),
        ],
        &[("DISPLAY", ""), ("WAYLAND_DISPLAY", "")],
    );
    let status = demo.wait(PATIENCE).expect("the demo ends by itself");
    assert!(status.success(), "demo failed: {}", demo.stderr());
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    let lines: Vec<Value> = stats.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 3);
    assert!(lines.iter().all(|s| u(s, "jobs_back") > 0), "path-traced results arrived: {stats}");
    for s in &lines {
        let png = out.join(format!("frame-{:06}.png", u(s, "frame")));
        let img = image::open(&png).unwrap_or_else(|e| panic!("{}: {e}", png.display())).to_rgb8();
        assert_eq!(
            img.dimensions(),
            (40, 24),
            "--resolution 80x48 --scale 0.5 overrides the file's 48x32"
        );
        assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "{} is black", png.display());
    }
    assert!(
        processes_mentioning(out.to_str().unwrap()).is_empty(),
        "worker processes outlived the demo"
    );
}

/// A live resolution change (what a resized window under `--resolution window` sends, here
/// from an interaction script through the same scene holder): every frame after it has the
/// new size, the master's pixel sets follow and the worker processes render them, and a
/// size with fewer pixels than S is refused without stopping the run.
#[test]
fn a_resolution_edit_resizes_the_frames_and_the_workers_follow() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_box_scene(dir.path());
    let script = dir.path().join("resize.toml");
    std::fs::write(
        &script,
        "[[edit]]\nat = 1.0\nresolution = { width = 4, height = 1 }\n\n\
         [[edit]]\nat = 1.0\nresolution = { width = 72, height = 40 }\n",
    )
    .unwrap();
    let out = dir.path().join("demo-out");
    let mut demo = Proc::spawn(
        &[
            "demo",
            scene.to_str().unwrap(),
            "--workers",
            "2",
            "--frames",
            "60",
            "--sets",
            "8",
            "--fps",
            "20",
            "--script",
            script.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[("DISPLAY", ""), ("WAYLAND_DISPLAY", "")],
    );
    let status = demo.wait(PATIENCE).expect("the demo ends by itself");
    assert!(status.success(), "demo failed: {}", demo.stderr());
    assert!(
        demo.stderr().contains("cannot render 4x1") && demo.stderr().contains("8 sets"),
        "the 4x1 edit (4 pixels, 8 sets) is refused with its reason: {}",
        demo.stderr()
    );
    let stats = std::fs::read_to_string(out.join("stats.jsonl")).unwrap();
    let lines: Vec<Value> = stats.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    let sizes: Vec<(u32, u32, u64)> = lines
        .iter()
        .map(|s| {
            let png = out.join(format!("frame-{:06}.png", u(s, "frame")));
            let img = image::open(&png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
            let lit = img.to_rgb8().pixels().filter(|p| p.0 != [0, 0, 0]).count() as u64;
            (img.width(), img.height(), lit)
        })
        .collect();
    let first_new = sizes.iter().position(|s| (s.0, s.1) == (72, 40));
    let Some(first_new) = first_new else { panic!("no frame of the new size: {sizes:?}") };
    assert!(first_new > 0, "frames before the edit have the file's size: {sizes:?}");
    assert!(
        sizes[..first_new].iter().all(|s| (s.0, s.1) == (48, 32))
            && sizes[first_new..].iter().all(|s| (s.0, s.1) == (72, 40)),
        "one size before the edit, the new one after it: {sizes:?}"
    );
    // Frames of the new size hold the workers' path-traced results, not holes.
    let late = &lines[lines.len() - 5..];
    assert!(late.iter().all(|s| u(s, "jobs_back") > 0), "results at the new size: {stats}");
    // As much of the picture is lit as before (the floor and the light, about a tenth).
    let lit = |s: &(u32, u32, u64)| s.2 as f64 / f64::from(s.0 * s.1);
    let before = lit(&sizes[first_new - 1]);
    assert!(before > 0.02, "the frames before the edit are lit: {sizes:?}");
    assert!(sizes[sizes.len() - 5..].iter().all(|s| lit(s) > before / 2.0), "lit: {sizes:?}");
}

/// A worker with an empty cache renders a glTF scene (`master lit.gltf`: JSON, `.bin` and
/// a PNG beside it) with no set-up: it fetches the three files by hash through the
/// manifest and renders the textured, lit quad for real.
#[test]
fn a_worker_with_an_empty_cache_fetches_and_renders_a_gltf_scene() {
    use gridlight::scene::gltf::fixture::{lit_scene, Bin};
    use sha2::{Digest, Sha256};

    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("model");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let mut f = lit_scene(serde_json::json!({ "name": "orange", "pbrMetallicRoughness": {
        "baseColorTexture": { "index": 0 }, "metallicFactor": 0.0 } }));
    let (image, png) = f.png(2, 2, &[[255, 100, 0]; 4], Some("orange.png"));
    f.texture(image);
    std::fs::write(scene_dir.join("orange.png"), &png).unwrap();
    f.write_gltf(&scene_dir, "lit", Bin::File);

    let out = dir.path().join("out");
    let args = ["--frames", "3", "--resolution", "32x24"];
    let mut master = Master::start_file(&out, &scene_dir.join("lit.gltf"), "127.0.0.1:0", &args);
    let cache = dir.path().join("cache");
    let addr = master.addr.to_string();
    let w = Proc::spawn(
        &["worker", "--master", &addr, "--threads", "1", "--name", "g", "--priority", "normal"]
            .into_iter()
            .chain(["--cache-dir", cache.to_str().unwrap()])
            .collect::<Vec<_>>(),
        &[("RUST_LOG", "info")],
    );
    let status = master.proc.wait(PATIENCE).expect("master stops after 3 frames");
    assert!(status.success(), "master failed: {}", master.proc.stderr());
    drop(w);
    for name in ["lit.gltf", "lit.bin", "orange.png"] {
        let bytes = std::fs::read(scene_dir.join(name)).unwrap();
        let blob = cache.join("blobs").join(hex::encode(Sha256::digest(&bytes)));
        assert!(blob.is_file(), "{name} is not in the worker's cache");
    }
    // The worker's radiance shows the orange texture under the light.
    let mut orange = 0;
    for line in master.stats() {
        let frame = u(&line, "frame");
        let path = master.dir.join("frames").join(format!("frame-{frame:06}.current.exr"));
        let img = image::open(path).unwrap().to_rgb32f();
        orange += img.pixels().filter(|p| p[0] > 0.05 && p[0] > 3.0 * p[2]).count();
    }
    assert!(orange > 0, "no orange pixel in the worker's radiance");
}
