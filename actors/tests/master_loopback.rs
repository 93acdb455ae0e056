//! The master over real loopback TCP with scripted protocol peers: handshake
//! rejections, bad frames, result validation, late/duplicate results, supervision.

mod common;

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::Duration;

use common::*;
use glam::Vec3;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::edit::{CameraEdit, Edit};
use gridlight_actors::master::{start, ActorKind, MasterHandle};
use gridlight_actors::protocol::*;
use gridlight_actors::workers::WorkerCounts;

fn master() -> (MasterHandle, std::sync::mpsc::Receiver<gridlight_actors::master::ShownFrame>) {
    let (sink, rx) = collect_sink();
    (start(config(), scene(), AssetStore::new(), sink).expect("start"), rx)
}

/// A peer thread answering every job with its frame's value until `stop` is set.
fn null_worker(
    addr: std::net::SocketAddr,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<Vec<(FrameNo, SetNo)>> {
    thread::spawn(move || {
        let table = table();
        let mut p = Peer::connect(addr);
        let mut done = Vec::new();
        if let Err(e) = p.handshake(None) {
            // The test may have seen its frames and stopped the master before this
            // worker finished its handshake; any other failure is a defect.
            assert!(stop.load(Ordering::Relaxed), "handshake: {e:?}");
            return done;
        }
        p.send(&WorkerMsg::Ready { credits: 2 });
        while !stop.load(Ordering::Relaxed) {
            let Ok((frame, set, version, _)) = p.next_job() else { break };
            done.push((frame, set));
            if !p.answer(&table, frame, set, version, frame_value(frame))
                || !p.try_send(&WorkerMsg::Ready { credits: 1 })
            {
                break;
            }
        }
        done
    })
}

#[test]
fn wrong_protocol_version_is_rejected_with_both_versions() {
    let (m, _rx) = master();
    let mut p = Peer::connect(m.local_addr());
    p.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION + 1, name: "old".into(), cores: 1 });
    let reason = p.expect_rejected();
    assert!(
        reason.contains("protocol version") && reason.contains(&PROTOCOL_VERSION.to_string()),
        "{reason}"
    );
    assert!(p.recv().is_err(), "connection stayed open");
}

#[test]
fn wrong_or_missing_secret_is_rejected_and_the_right_one_welcomed() {
    let (sink, _rx) = collect_sink();
    let mut c = config();
    c.secret = Some(b"s3cret".to_vec());
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    let reason = Peer::connect(m.local_addr()).handshake(Some(b"wrong")).unwrap_err();
    assert!(reason.contains("wrong shared secret"), "{reason}");
    let reason = Peer::connect(m.local_addr()).handshake(None).unwrap_err();
    assert!(reason.contains("requires a shared secret"), "{reason}");
    assert!(Peer::connect(m.local_addr()).handshake(Some(b"s3cret")).is_ok());
}

#[test]
fn garbage_and_oversized_frames_are_rejected_and_the_master_goes_on() {
    let (m, _rx) = master();
    let mut p = Peer::connect(m.local_addr());
    p.send_raw(&[0, 0, 0, 4, 0xc1, 0xc1, 0xc1, 0xc1]);
    let reason = p.expect_rejected();
    assert!(reason.contains("bad frame"), "{reason}");

    let mut p = Peer::connect(m.local_addr());
    p.send_raw(&(MAX_FRAME_LEN as u32 + 1).to_be_bytes());
    let reason = p.expect_rejected();
    assert!(reason.contains("exceeds"), "{reason}");

    let mut p = Peer::connect(m.local_addr());
    p.send(&WorkerMsg::Ready { credits: 1 });
    let reason = p.expect_rejected();
    assert!(reason.contains("unexpected Ready"), "{reason}");

    assert!(Peer::connect(m.local_addr()).handshake(None).is_ok(), "master stopped serving");
}

#[test]
fn a_result_for_a_set_not_given_is_rejected_and_counted() {
    let (m, _rx) = master();
    let table = table();
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("handshake");
    p.send(&WorkerMsg::Ready { credits: 1 });
    let (frame, set, version, state) = p.next_job().expect("job");
    assert_eq!(state.expect("state before the first job").version, version);
    let other = (set + 1) % S;
    p.answer(&table, frame, other, version, 1.0);
    let reason = p.expect_rejected();
    assert!(reason.contains("not given"), "{reason}");
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    while Counters::get(&m.counters().dropped_unknown) == 0 && std::time::Instant::now() < deadline
    {
        thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(Counters::get(&m.counters().dropped_unknown), 1);
}

#[test]
fn a_result_with_the_wrong_pixel_count_is_rejected() {
    let (m, _rx) = master();
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("handshake");
    p.send(&WorkerMsg::Ready { credits: 1 });
    let (frame, set, version, _) = p.next_job().expect("job");
    let radiance = gridlight_actors::packing::pack(&[Vec3::ONE; 3]).expect("pack");
    let msg = p.result(frame, set, version, radiance);
    p.send(&msg);
    let reason = p.expect_rejected();
    assert!(reason.contains("pixels"), "{reason}");
}

#[test]
fn frames_hold_only_their_own_results_and_no_set_is_handed_out_twice() {
    let (m, rx) = master();
    let stop = Arc::new(AtomicBool::new(false));
    let workers: Vec<_> = (0..2).map(|_| null_worker(m.local_addr(), stop.clone())).collect();
    let mut shown = Vec::new();
    while shown.len() < 6 {
        shown.push(rx.recv_timeout(Duration::from_secs(30)).expect("a frame"));
    }
    stop.store(true, Ordering::Relaxed);
    drop(m);
    let mut handed: HashMap<FrameNo, HashSet<SetNo>> = HashMap::new();
    for w in workers {
        for (frame, set) in w.join().expect("worker") {
            assert!(
                handed.entry(frame).or_default().insert(set),
                "frame {frame} set {set} handed out twice"
            );
        }
    }
    assert!(handed.values().all(|s| s.len() <= S as usize));
    let mut last = None;
    for f in &shown {
        assert!(last < Some(f.frame), "frames not in increasing order");
        last = Some(f.frame);
        assert!(f.stats.jobs_back > 0 && f.stats.jobs_total == S);
        let v = Vec3::splat(frame_value(f.frame));
        for (px, covered) in f.current.iter().zip(&f.current_mask) {
            if *covered {
                assert_eq!(*px, v, "frame {} holds another frame's pixel", f.frame);
            }
        }
        let covered = f.current_mask.iter().filter(|c| **c).count();
        assert!(covered > 0 && covered <= (W * H) as usize);
    }
}

#[test]
fn late_and_duplicate_results_are_dropped_and_counted_and_the_worker_gets_new_work() {
    let (m, _rx) = master();
    let table = table();
    // The only peer takes one job and sits on it until its frame is skipped (Q = 0).
    let mut slow = Peer::connect(m.local_addr());
    slow.handshake(None).expect("handshake");
    slow.send(&WorkerMsg::Ready { credits: 1 });
    let (frame, set, version, _) = slow.next_job().expect("job");
    let deadline = std::time::Instant::now() + Duration::from_secs(30);
    while m.report().skipped == 0 && std::time::Instant::now() < deadline {
        thread::sleep(Duration::from_millis(5));
    }
    assert!(m.report().skipped >= 1, "the frame was never displayed");
    slow.answer(&table, frame, set, version, 99.0);
    slow.answer(&table, frame, set, version, 99.0);
    slow.send(&WorkerMsg::Ready { credits: 1 });
    let (f2, s2, v2, _) = slow.next_job().expect("new work after a late result");
    assert!(f2 > frame);
    // The next frame waits I_max times the skipped frame's time: ample for two answers.
    slow.answer(&table, f2, s2, v2, frame_value(f2));
    slow.answer(&table, f2, s2, v2, frame_value(f2));
    let c = m.counters();
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    while Counters::get(&c.dropped_duplicate) < 2 && std::time::Instant::now() < deadline {
        thread::sleep(Duration::from_millis(5));
    }
    // A second answer is a duplicate, late or not: the connection that knows it counts it
    // and nothing forwards it.
    assert_eq!(Counters::get(&c.dropped_late), 1, "the answer to the displayed frame is late");
    assert_eq!(Counters::get(&c.dropped_duplicate), 2, "one per second answer");
    assert_eq!(Counters::get(&c.dropped_unknown), 0);
    assert_eq!(Counters::get(&c.results_accepted), 1);
}

#[test]
fn a_killed_or_panicking_connection_ends_alone_and_the_master_goes_on() {
    let (m, rx) = master();
    let stop = Arc::new(AtomicBool::new(false));
    let good = null_worker(m.local_addr(), stop.clone());
    let mut victim = Peer::connect(m.local_addr());
    let id = victim.handshake(None).expect("handshake");
    victim.send(&WorkerMsg::Ready { credits: 2 });
    let _ = victim.next_job().expect("job");
    assert!(m.kill_connection(id).expect("master alive"));
    loop {
        match victim.recv() {
            Err(_) => break,
            Ok(_) => continue,
        }
    }
    let mut other = Peer::connect(m.local_addr());
    let id2 = other.handshake(None).expect("a worker that reconnects is served again");
    assert!(m.panic_connection(id2).expect("master alive"));
    assert!(other.expect_rejected().contains("internal error"));
    m.inject_panic(ActorKind::Scheduler);
    m.inject_panic(ActorKind::Assembler);
    m.inject_panic(ActorKind::Presenter);
    m.inject_panic(ActorKind::SceneHolder);
    let seen = m.report().shown;
    assert!(m.wait_for_frames(seen + 5, Duration::from_secs(20)), "frames stopped after faults");
    assert!(Counters::get(&m.counters().panics_contained) >= 5);
    assert!(!m.connections().expect("alive").contains(&id));
    stop.store(true, Ordering::Relaxed);
    drop(m);
    drop(rx);
    let _ = good.join();
}

#[test]
fn an_edit_sends_the_new_state_before_the_first_job_naming_it() {
    let (m, _rx) = master();
    let table = table();
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("handshake");
    p.send(&WorkerMsg::Ready { credits: 1 });
    let (f, s, v, state) = p.next_job().expect("job");
    assert_eq!(state.map(|s| s.version), Some(v));
    let moved = Vec3::new(0.0, 2.0, 5.0);
    let new_version = m
        .edit(Edit::Camera(CameraEdit { position: Some(moved), ..Default::default() }))
        .expect("edit");
    assert!(new_version > v);
    p.answer(&table, f, s, v, 1.0);
    p.send(&WorkerMsg::Ready { credits: 1 });
    let mut seen_states = HashSet::from([v]);
    for _ in 0..200 {
        let (f, s, v, state) = p.next_job().expect("job");
        if let Some(st) = state {
            assert_eq!(st.version, v);
            assert!(seen_states.insert(v), "state {v} sent twice");
            if v == new_version {
                assert_eq!(st.camera.position, moved);
                return;
            }
        }
        assert!(seen_states.contains(&v), "job names version {v} that was never sent");
        p.answer(&table, f, s, v, 1.0);
        p.send(&WorkerMsg::Ready { credits: 1 });
    }
    panic!("the new state never arrived");
}

/// The edit-to-display latency: an edit made at `at` is counted once, on the first shown
/// frame whose state includes it, from `at` (the scene holder tells the presenter when
/// each edit happened); frames before and after it carry none.
#[test]
fn an_edit_is_timed_once_on_the_first_shown_frame_of_its_state() {
    let (m, rx) = master();
    let stop = Arc::new(AtomicBool::new(false));
    let worker = null_worker(m.local_addr(), stop.clone());
    let before = m.state().expect("state").version;
    let at = std::time::Instant::now() - Duration::from_millis(50);
    let moved = Vec3::new(0.0, 2.0, 5.0);
    m.edit_made(Edit::Camera(CameraEdit { position: Some(moved), ..Default::default() }), at);
    let mut timed = Vec::new();
    let mut after = 0;
    while after < 3 {
        let frame = rx.recv_timeout(Duration::from_secs(30)).expect("frames keep coming");
        let stats = frame.stats;
        if stats.state_version == before {
            assert!(stats.edits_at.is_empty(), "a frame of the old state shows no edit");
        } else if timed.is_empty() {
            timed = stats.edit_latency_ms.clone();
            assert_eq!(stats.edits_at, [at], "the edit's own instant");
        } else {
            assert!(stats.edits_at.is_empty(), "the edit was counted again");
            after += 1;
        }
    }
    assert!(timed.len() == 1 && timed[0] >= 50.0, "{timed:?}");
    stop.store(true, Ordering::Relaxed);
    drop(m);
    worker.join().expect("worker");
}

#[test]
fn assets_are_served_by_manifest_hash_only() {
    let dir = std::env::temp_dir().join(format!("gl-master-assets-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("mesh.obj");
    let data: Vec<u8> = (0..(ASSET_CHUNK_LEN + 10)).map(|i| (i % 251) as u8).collect();
    std::fs::write(&file, &data).expect("write");
    let mut assets = AssetStore::new();
    let hash = assets.add_file("mesh.obj", &file).expect("hash").hash;
    let (sink, _rx) = collect_sink();
    let m = start(config(), scene(), assets, sink).expect("start");
    let mut p = Peer::connect(m.local_addr());
    p.send(&WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "a".into(), cores: 1 });
    let MasterMsg::Challenge { nonce: _, auth_required } =
        p.recv_non_heartbeat().expect("challenge")
    else {
        panic!("no challenge")
    };
    assert!(!auth_required);
    p.send(&WorkerMsg::Auth { mac: None });
    let MasterMsg::Welcome { assets, .. } = p.recv_non_heartbeat().expect("welcome") else {
        panic!("no welcome")
    };
    assert_eq!(assets.len(), 1);
    assert_eq!((assets[0].hash, assets[0].len), (hash, data.len() as u64));
    p.send(&WorkerMsg::AssetRequest { hash });
    let mut got = Vec::new();
    while got.len() < data.len() {
        match p.recv_non_heartbeat().expect("chunk") {
            MasterMsg::AssetChunk { hash: h, offset, len, data: d } => {
                assert_eq!((h, offset, len), (hash, got.len() as u64, data.len() as u64));
                got.extend_from_slice(&d);
            }
            m => panic!("unexpected {m:?}"),
        }
    }
    assert_eq!(got, data);
    p.send(&WorkerMsg::AssetRequest { hash: [7; 32] });
    assert!(p.expect_rejected().contains("not in the manifest"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_master_stops_after_max_frames_and_the_sink_sees_every_frame() {
    let (sink, rx) = collect_sink();
    let mut c = config();
    c.max_frames = Some(3);
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    let stop = Arc::new(AtomicBool::new(false));
    let w = null_worker(m.local_addr(), stop.clone());
    assert!(m.wait_finished(Duration::from_secs(20)), "did not finish");
    let report = m.stop().expect("clean stop");
    assert_eq!(report.shown, 3);
    let frames: Vec<_> = rx.try_iter().collect();
    assert_eq!(frames.len(), 3);
    assert_eq!(frames.last().map(|f| f.stats.shown), Some(3));
    stop.store(true, Ordering::Relaxed);
    let _ = w.join();
}

#[test]
fn connections_over_the_cap_are_refused_with_a_reason() {
    let (sink, _rx) = collect_sink();
    let mut c = config();
    c.max_connections = 1;
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    let mut first = Peer::connect(m.local_addr());
    first.handshake(None).expect("first connection served");
    let mut second = Peer::connect(m.local_addr());
    assert!(second.expect_rejected().contains("full"));
    drop(first);
    // Once the first is gone its place is free again.
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    loop {
        let mut p = Peer::connect(m.local_addr());
        match p.handshake(None) {
            Ok(_) => break,
            Err(e) if std::time::Instant::now() < deadline && e.contains("full") => {
                thread::sleep(Duration::from_millis(20))
            }
            Err(e) => panic!("not served after the first left: {e}"),
        }
    }
}

#[test]
fn a_worker_joining_mid_run_gets_work_and_the_state_first() {
    let (m, rx) = master();
    let stop = Arc::new(AtomicBool::new(false));
    let busy = null_worker(m.local_addr(), stop.clone());
    rx.recv_timeout(Duration::from_secs(30)).expect("frames with one worker");
    let mut late = Peer::connect(m.local_addr());
    late.handshake(None).expect("handshake");
    late.send(&WorkerMsg::Ready { credits: 1 });
    let (_, _, _, state) = late.next_job().expect("a job");
    assert!(state.is_some(), "state not sent before the first job");
    stop.store(true, Ordering::Relaxed);
    drop(m);
    let _ = busy.join();
}

/// Polls `what` until it holds (the master's counters change on its own thread).
fn eventually(what: &str, f: impl Fn() -> bool) {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while !f() {
        assert!(std::time::Instant::now() < deadline, "timed out waiting for {what}");
        thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn a_paused_worker_is_counted_apart_gets_no_jobs_and_comes_back_when_it_resumes() {
    let (m, rx) = master();
    let c = m.counters();
    // Another worker keeps frames coming, so that their statistics can be read.
    let stop = Arc::new(AtomicBool::new(false));
    let other = null_worker(m.local_addr(), stop.clone());
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("welcome");
    p.send(&WorkerMsg::Ready { credits: 2 });
    let (held_frame, held_set, _, _) = p.next_job().expect("a job before pausing");
    eventually("two live workers", || m.worker_counts() == WorkerCounts { live: 2, paused: 0 });

    let reason = PauseReason::OwnerCpu { percent: 87.0, window_s: 10.0 };
    p.send(&WorkerMsg::Paused { reason: reason.clone() });
    eventually("the worker counted as paused", || {
        m.worker_counts() == WorkerCounts { live: 1, paused: 1 }
    });
    let listed = m.workers();
    assert_eq!(listed.len(), 2, "a paused worker stays listed");
    assert_eq!(listed.iter().filter(|w| w.paused == Some(reason.clone())).count(), 1);
    // The frames' statistics name it and say why.
    let paused_in_stats = loop {
        let frame = rx.recv_timeout(Duration::from_secs(20)).expect("frames go on");
        if frame.stats.paused_workers == 1 {
            break frame.stats;
        }
    };
    assert_eq!(paused_in_stats.workers, 1, "a paused worker is not a live one");
    assert_eq!(paused_in_stats.paused[0].kind, "owner_cpu");
    assert!(paused_in_stats.paused[0].reason.contains("87 %"), "{:?}", paused_in_stats.paused);

    // Jobs already on their way when it paused may still arrive; after that, none.
    for _ in 0..8 {
        if p.recv_within(Duration::from_millis(300)).is_none() {
            break;
        }
    }
    let leaked = p.recv_within(Duration::from_millis(1500));
    assert!(leaked.is_none(), "a paused worker was sent {leaked:?}");

    p.send(&WorkerMsg::Resumed);
    p.send(&WorkerMsg::Ready { credits: 1 });
    let (frame, set, _, _) = p.next_job().expect("a job after resuming");
    assert_ne!((frame, set), (held_frame, held_set), "a job held at the pause was redone");
    eventually("the worker live again", || {
        m.worker_counts() == WorkerCounts { live: 2, paused: 0 }
    });
    assert!(m.workers().iter().all(|w| w.paused.is_none()));
    stop.store(true, Ordering::Relaxed);
    drop(p);
    let _ = other.join();
    assert_eq!(Counters::get(&c.jobs_handed_twice), 0);
}

#[test]
fn credits_or_results_while_paused_and_resuming_unpaused_end_the_connection() {
    let (m, _rx) = master();
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("welcome");
    p.send(&WorkerMsg::Paused { reason: PauseReason::OwnerInput { seconds_ago: 2.0 } });
    p.send(&WorkerMsg::Ready { credits: 1 });
    let reason = p.expect_rejected();
    assert!(reason.contains("Ready while the worker is paused"), "{reason}");

    let mut q = Peer::connect(m.local_addr());
    q.handshake(None).expect("welcome");
    q.send(&WorkerMsg::Resumed);
    let reason = q.expect_rejected();
    assert!(reason.contains("Resumed while the worker is not paused"), "{reason}");
    eventually("no worker counted", || m.worker_counts() == WorkerCounts::default());
}

#[test]
fn panics_past_the_restart_intensity_stop_the_master_with_a_message_naming_the_actor() {
    let mut c = config();
    c.restart.max_restarts = 2;
    let (sink, _rx) = collect_sink();
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    for _ in 0..3 {
        m.inject_panic(ActorKind::Scheduler);
    }
    assert!(m.wait_finished(Duration::from_secs(20)), "the master did not stop");
    let error = m.report().error.expect("an escalation is an error");
    assert!(error.contains("scheduler") && error.contains("3 times"), "{error}");
    let stopped = m.stop().expect_err("an escalated master stops with an error");
    assert!(stopped.to_string().contains("scheduler"), "{stopped}");
}
