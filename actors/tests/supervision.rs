//! The supervision tree on every axis, over real loopback TCP: a panic in `started`, in
//! a timer and in a handler of each actor that has one restarts it (or, for a
//! connection, ends it and serves the reconnection) while the master keeps showing
//! frames; past the restart intensity the master stops naming the actor; a worker
//! whose connections keep failing is backed off and told why; a panicking
//! connection's jobs are lost, counted and never handed out again.
//!
//! The scheduler, the presenter and the listener run no timer
//! (`every_timer_and_start_is_guarded` checks that no actor starts one outside the
//! guard), so they have no timer axis.

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

use common::*;
use glam::Vec3;
use gridlight_actors::announcer::AnnounceConfig;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::discovery::Announcement;
use gridlight_actors::edit::{CameraEdit, Edit};
use gridlight_actors::master::{start, MasterConfig, MasterHandle};
use gridlight_actors::protocol::*;
use gridlight_actors::supervision::{PanicInjection, PeerPolicy};

/// A master with these `--inject-panic` values (and announcing to `announce_to`).
fn master_with(inject: &[&str], announce_to: Option<SocketAddr>) -> MasterHandle {
    let mut c = config();
    c.inject_panics =
        inject.iter().map(|s| s.parse::<PanicInjection>().expect("injection")).collect();
    c.announce = announce_to.map(|to| AnnounceConfig {
        to,
        name: "test".into(),
        scene: "box".into(),
        interval: Duration::from_millis(50),
    });
    start_with(c)
}

fn start_with(c: MasterConfig) -> MasterHandle {
    let (sink, rx) = collect_sink();
    // Shown frames are counted by the report; the sink's copies are not needed.
    thread::spawn(move || while rx.recv().is_ok() {});
    start(c, scene(), AssetStore::new(), sink).expect("start")
}

/// A worker that answers every job and reconnects whenever its connection ends.
fn worker(addr: SocketAddr, name: &'static str, stop: Arc<AtomicBool>) -> thread::JoinHandle<()> {
    thread::spawn(move || {
        let table = table();
        while !stop.load(Ordering::Relaxed) {
            let mut p = Peer::connect(addr);
            if p.handshake_as(name, None).is_err() {
                thread::sleep(Duration::from_millis(20));
                continue;
            }
            p.send(&WorkerMsg::Ready { credits: 2 });
            while !stop.load(Ordering::Relaxed) {
                let Ok((frame, set, version, _)) = p.next_job() else { break };
                if !p.answer(&table, frame, set, version, frame_value(frame))
                    || !p.try_send(&WorkerMsg::Ready { credits: 1 })
                {
                    break;
                }
            }
        }
    })
}

/// Runs `check` against a master serving one worker, then stops both.
fn serving(m: MasterHandle, check: impl FnOnce(&MasterHandle)) {
    let stop = Arc::new(AtomicBool::new(false));
    let w = worker(m.local_addr(), "steady", stop.clone());
    check(&m);
    stop.store(true, Ordering::Relaxed);
    drop(m);
    w.join().expect("worker thread");
}

/// Frames keep being shown, with no error, and `panics` panics were contained.
fn keeps_serving(m: &MasterHandle, what: &str, panics: u64) {
    let seen = m.report().shown;
    assert!(m.wait_for_frames(seen + 3, Duration::from_secs(20)), "{what}: frames stopped");
    assert_eq!(m.report().error, None, "{what}");
    let contained = Counters::get(&m.counters().panics_contained);
    assert_eq!(contained, panics, "{what}: panics contained");
}

fn eventually(what: &str, f: impl Fn() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while !f() {
        assert!(Instant::now() < deadline, "never: {what}");
        thread::sleep(Duration::from_millis(10));
    }
}

/// A UDP socket the announcer sends to, and a count of what arrives.
fn announcements() -> (SocketAddr, impl Fn(Duration) -> usize) {
    let socket = UdpSocket::bind("127.0.0.1:0").expect("udp");
    let addr = socket.local_addr().expect("addr");
    let count = move |during: Duration| {
        let end = Instant::now() + during;
        let mut n = 0;
        let mut buf = [0u8; 2048];
        while let Some(left) = end.checked_duration_since(Instant::now()) {
            socket.set_read_timeout(Some(left.max(Duration::from_millis(1)))).expect("timeout");
            if let Ok(len) = socket.recv(&mut buf) {
                assert!(Announcement::decode(&buf[..len]).is_ok(), "a broken announcement");
                n += 1;
            }
        }
        n
    };
    (addr, count)
}

#[test]
fn a_panic_in_started_restarts_each_actor_and_the_master_keeps_serving() {
    for actor in ["scheduler", "assembler", "presenter", "scene-holder", "listener", "connection"] {
        let m = master_with(&[&format!("{actor}:started:1")], None);
        serving(m, |m| keeps_serving(m, actor, 1));
    }
    let (to, heard) = announcements();
    let m = master_with(&["announcer:started:1"], Some(to));
    serving(m, |m| {
        assert!(heard(Duration::from_millis(500)) >= 3, "the restarted announcer is quiet");
        keeps_serving(m, "announcer", 1);
    });
}

#[test]
fn a_panic_in_a_timer_restarts_each_actor_that_has_one() {
    // The frame assembler's heuristic deadline: at a fixed rate every frame waits on it.
    let mut c = config();
    c.pacing = gridlight_actors::pacing::Pacing::FixedFps(50.0);
    c.inject_panics = vec!["assembler:timer:1".parse().expect("injection")];
    serving(start_with(c), |m| keeps_serving(m, "frame assembler", 1));

    // A connection's keep-alive tick: it ends, the worker's reconnection is served.
    let mut c = config();
    c.heartbeat = Duration::from_millis(40);
    c.inject_panics = vec!["connection:timer:1".parse().expect("injection")];
    serving(start_with(c), |m| {
        eventually("the tick panicked", || Counters::get(&m.counters().panics_contained) == 1);
        keeps_serving(m, "connection", 1);
    });

    // The scene holder's script timer: the edit it was applying is lost, the next applies.
    let m = master_with(&["scene-holder:timer:1"], None);
    serving(m, |m| {
        let before = m.state().expect("state").version;
        let to = |x| {
            Edit::Camera(CameraEdit {
                position: Some(Vec3::new(x, 1.0, 4.0)),
                ..Default::default()
            })
        };
        m.play_script(vec![
            (Duration::from_millis(10), to(0.5)),
            (Duration::from_millis(100), to(1.0)),
        ]);
        eventually("the second edit applied", || m.state().expect("state").version == before + 1);
        keeps_serving(m, "scene holder", 1);
    });

    // The announcer's interval: announcements go on.
    let (to, heard) = announcements();
    let m = master_with(&["announcer:timer:1"], Some(to));
    serving(m, |m| {
        assert!(heard(Duration::from_millis(600)) >= 5, "the restarted announcer is quiet");
        keeps_serving(m, "announcer", 1);
    });
}

#[test]
fn panics_in_started_past_the_intensity_stop_the_master_naming_actor_and_site() {
    let m = master_with(&["assembler:started"], None);
    assert!(m.wait_finished(Duration::from_secs(20)), "the master did not stop");
    let error = m.report().error.expect("an escalation is an error");
    assert!(error.contains("frame assembler panicked 6 times"), "{error}");
    assert!(error.contains("in its started: injected panic"), "{error}");
    assert!(m.stop().is_err(), "an escalated master stops with an error");
}

#[test]
fn a_worker_whose_connections_keep_failing_is_backed_off_and_told_why() {
    let mut c = config();
    c.peer_backoff = PeerPolicy {
        max_failures: 2,
        window: Duration::from_secs(30),
        backoff: Duration::from_secs(30),
    };
    let m = start_with(c);
    // Each connection of "looping" ends on an error: garbage after its handshake.
    for _ in 0..3 {
        let mut p = Peer::connect(m.local_addr());
        p.handshake_as("looping", None).expect("served while under the limit");
        p.send_raw(&[0, 0, 0, 3, 0xc1, 0xc1, 0xc1]);
        assert!(p.expect_rejected().starts_with("bad frame"));
    }
    // The listener records the failures as the connections end: a little later.
    eventually("looping is backed off", || {
        let mut p = Peer::connect(m.local_addr());
        match p.handshake_as("looping", None) {
            Err(reason) => {
                assert!(reason.contains("worker looping: 3 failed connections"), "{reason}");
                assert!(reason.contains("retry in"), "{reason}");
                true
            }
            Ok(_) => false,
        }
    });
    assert!(m.counters().rejections().get("backed_off").is_some_and(|n| *n >= 1));
    // Another worker from the same address is served, and refusals do not count as failures.
    let mut other = Peer::connect(m.local_addr());
    other.handshake_as("steady", None).expect("another worker is served");
    assert_eq!(m.report().error, None);
}

#[test]
fn a_panicking_connections_held_jobs_are_lost_counted_and_never_handed_out_again() {
    let m = start_with(config());
    let mut victim = Peer::connect(m.local_addr());
    let id = victim.handshake_as("victim", None).expect("handshake");
    victim.send(&WorkerMsg::Ready { credits: 2 });
    let held = [victim.next_job().expect("job"), victim.next_job().expect("job")];
    assert!(m.panic_connection(id).expect("master alive"));
    assert!(victim.expect_rejected().contains("internal error"));
    eventually("its jobs counted lost", || Counters::get(&m.counters().jobs_lost) == 2);
    // A second worker serves frames from here on and never gets the lost jobs.
    let mut p = Peer::connect(m.local_addr());
    p.handshake_as("second", None).expect("served");
    p.send(&WorkerMsg::Ready { credits: 2 });
    let table = table();
    for _ in 0..4 * S {
        let (frame, set, version, _) = p.next_job().expect("job");
        assert!(
            !held.iter().any(|(f, s, _, _)| (*f, *s) == (frame, set)),
            "lost job ({frame}, {set}) handed out again"
        );
        assert!(p.answer(&table, frame, set, version, frame_value(frame)));
        p.send(&WorkerMsg::Ready { credits: 1 });
    }
    assert_eq!(Counters::get(&m.counters().jobs_handed_twice), 0);
}

/// Every timer and every `started` of the actors runs under the guard: no actor
/// file starts a timer with actix's bare `run_later`/`run_interval`, and each
/// `started` only hands over to the guard.
#[test]
fn every_timer_and_start_is_guarded() {
    let mut files = Vec::new();
    let mut dirs = vec![std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/src"))];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).expect("read src").flatten() {
            let path = entry.path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    assert!(files.len() > 20, "the sources were not found: {files:?}");
    let mut starts = 0;
    for path in files.iter().filter(|p| !p.ends_with("supervision/guard.rs")) {
        let text = std::fs::read_to_string(path).expect("source");
        for bare in [".run_later(", ".run_interval(", ".notify_later("] {
            assert!(!text.contains(bare), "{} starts an unguarded timer ({bare})", path.display());
        }
        for (at, _) in text.match_indices("fn started(&mut self") {
            let body: String = text[at..].lines().skip(1).take(1).collect();
            assert_eq!(body.trim(), "self.start_guarded(ctx);", "{}", path.display());
            starts += 1;
        }
    }
    assert_eq!(starts, 7, "one guarded `started` per actor");
}
