//! Stale jobs over real loopback TCP (issue 18): when the scene state changes, the
//! master's queued jobs of the old state are never handed out afterwards, the jobs a
//! worker holds for it are not waited for, and a worker that drops a held job of the old
//! state (`Superseded`) gets its slot back.
//!
//! The master is the real one (every actor, the real display); the workers are scripted
//! protocol peers, so that the test sees every job the master sends.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use common::*;
use glam::Vec3;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::edit::{CameraEdit, Edit};
use gridlight_actors::master::{start, MasterHandle, ShownFrame};
use gridlight_actors::protocol::*;
use gridlight_actors::state::StateVersion;

/// Long enough that a display waiting for a held job (I_max × the last frame time) would
/// outlast the test's patience many times over: a frame shown in time was not waited for.
const LAST_FRAME_TIME: Duration = Duration::from_secs(120);
/// How long the test waits for a frame.
const PATIENCE: Duration = Duration::from_secs(30);

fn master(discard_stale_jobs: bool) -> (MasterHandle, Receiver<ShownFrame>) {
    let mut c = config();
    c.initial_frame_time = LAST_FRAME_TIME;
    c.discard_stale_jobs = discard_stale_jobs;
    let (sink, rx) = collect_sink();
    (start(c, scene(), AssetStore::new(), sink).expect("start"), rx)
}

fn move_camera(m: &MasterHandle) -> StateVersion {
    let moved = Vec3::new(0.0, 2.0, 5.0);
    m.edit(Edit::Camera(CameraEdit { position: Some(moved), ..Default::default() })).expect("edit")
}

/// A peer that answers every job at once, recording the state version each named.
fn answering_worker(
    m: &MasterHandle,
    stop: Arc<AtomicBool>,
    versions: Arc<Mutex<Vec<StateVersion>>>,
) -> thread::JoinHandle<()> {
    let addr = m.local_addr();
    thread::spawn(move || {
        let table = table();
        let mut p = Peer::connect(addr);
        if p.handshake(None).is_err() {
            return;
        }
        p.send(&WorkerMsg::Ready { credits: 2 });
        while !stop.load(Ordering::Relaxed) {
            let Ok((frame, set, version, _)) = p.next_job() else { break };
            versions.lock().unwrap().push(version);
            if !p.answer(&table, frame, set, version, 1.0)
                || !p.try_send(&WorkerMsg::Ready { credits: 1 })
            {
                break;
            }
        }
    })
}

/// The first shown frame of `version` or later, the frames before it passed over.
fn first_frame_of(rx: &Receiver<ShownFrame>, version: StateVersion) -> ShownFrame {
    loop {
        let frame = rx.recv_timeout(PATIENCE).expect("a frame of the new state in time");
        if frame.stats.state_version >= version {
            return frame;
        }
    }
}

/// A scripted worker that asked for two jobs and holds them: (frame, set, version) each.
fn holding_two(m: &MasterHandle) -> (Peer, [(FrameNo, SetNo, StateVersion); 2]) {
    let mut p = Peer::connect(m.local_addr());
    p.handshake(None).expect("handshake");
    p.send(&WorkerMsg::Ready { credits: 2 });
    let (f1, s1, v1, _) = p.next_job().expect("a first job");
    let (f2, s2, v2, _) = p.next_job().expect("a second job");
    (p, [(f1, s1, v1), (f2, s2, v2)])
}

/// One worker holds two jobs of the first state and never answers them; the state
/// changes; a second worker joins and answers every job it gets.
struct HeldThenEdited {
    m: MasterHandle,
    rx: Receiver<ShownFrame>,
    /// Kept open: its two jobs stay held.
    _holder: Peer,
    v2: StateVersion,
    /// The state version of every job the second worker got, in order.
    versions: Arc<Mutex<Vec<StateVersion>>>,
    stop: Arc<AtomicBool>,
    other: Option<thread::JoinHandle<()>>,
}

impl HeldThenEdited {
    fn start(discard: bool) -> Self {
        let (m, rx) = master(discard);
        let (holder, [(_, _, v1), (_, _, also_v1)]) = holding_two(&m);
        assert_eq!(v1, also_v1);
        let v2 = move_camera(&m);
        assert!(v2 > v1);
        let stop = Arc::new(AtomicBool::new(false));
        let versions = Arc::new(Mutex::new(Vec::new()));
        let other = Some(answering_worker(&m, Arc::clone(&stop), Arc::clone(&versions)));
        Self { m, rx, _holder: holder, v2, versions, stop, other }
    }

    /// The versions of the second worker's first `n` jobs.
    fn first_jobs(&self, n: usize) -> Vec<StateVersion> {
        let deadline = std::time::Instant::now() + PATIENCE;
        while self.versions.lock().unwrap().len() < n {
            assert!(std::time::Instant::now() < deadline, "the second worker got no {n} jobs");
            thread::sleep(Duration::from_millis(10));
        }
        self.versions.lock().unwrap()[..n].to_vec()
    }
}

impl Drop for HeldThenEdited {
    fn drop(&mut self) {
        // Not joined: it may be waiting for a job that never comes (the old scheduler
        // waits for the held ones); it ends when the master's socket closes.
        self.stop.store(true, Ordering::Relaxed);
        drop(self.other.take());
    }
}

#[test]
fn after_an_edit_no_queued_job_of_the_old_state_is_handed_out_and_held_ones_are_not_waited_for() {
    let run = HeldThenEdited::start(true);
    // The two held jobs are never answered, and the waiting rule would keep their frame
    // for minutes (LAST_FRAME_TIME): the new view is shown without them.
    let shown = first_frame_of(&run.rx, run.v2);
    assert_eq!(shown.stats.state_version, run.v2);
    let versions = run.versions.lock().unwrap().clone();
    assert!(!versions.is_empty(), "the second worker got jobs");
    assert!(
        versions.iter().all(|&v| v >= run.v2),
        "a queued job of the old state was handed out after the edit: {versions:?}"
    );
    let c = run.m.counters();
    assert!(
        Counters::get(&c.jobs_discarded_stale) > 0,
        "the old state's queue was discarded, not drained"
    );
    assert_eq!(shown.stats.jobs_discarded_stale, Counters::get(&c.jobs_discarded_stale));
    assert_eq!(Counters::get(&c.jobs_handed_twice), 0);
}

#[test]
fn the_old_scheduler_hands_out_the_old_states_queue_so_the_check_above_can_fail() {
    let run = HeldThenEdited::start(false);
    let versions = run.first_jobs(4);
    assert!(
        versions.iter().any(|&v| v < run.v2),
        "without the discard the queued old jobs go out first: {versions:?}"
    );
}

#[test]
fn a_worker_that_drops_its_held_old_jobs_gets_its_slots_back() {
    let (m, _rx) = master(true);
    let table = table();
    let (mut p, [(f1, s1, v1), (f2, s2, _)]) = holding_two(&m);
    let v2 = move_camera(&m);
    // Both held jobs are dropped unrendered, as a worker does when a newer state's job
    // comes; without the master freeing their slots these credits would be clamped to 0
    // (k = 2 held already) and no job would ever come again.
    for (frame, set) in [(f1, s1), (f2, s2)] {
        p.send(&WorkerMsg::Superseded { frame, set });
        p.send(&WorkerMsg::Ready { credits: 1 });
    }
    for _ in 0..2 {
        let (_, _, v, _) = p.next_job().expect("a job for each slot freed");
        assert_eq!(v, v2, "the jobs after the edit are of the new state");
    }
    assert_eq!(Counters::get(&m.counters().jobs_superseded), 2);
    assert_eq!(Counters::get(&m.counters().jobs_handed_twice), 0);
    // A superseded job is lost like any other: the worker no longer holds it, and a
    // result for it afterwards is one for a job it was not given.
    p.answer(&table, f1, s1, v1, 1.0);
    let reason = loop {
        match p.recv_non_heartbeat().expect("the master's answer") {
            MasterMsg::Rejected { reason } => break reason,
            MasterMsg::Job { .. } | MasterMsg::State(_) => continue,
            other => panic!("expected Rejected, got {other:?}"),
        }
    };
    assert!(reason.contains("not given"), "{reason}");
}

/// Issue 43: a worker that dropped every job it held (`Superseded`) holds nothing, so it
/// is idle and must get a job even when none is forecast in time for it. Here its one
/// measured job took longer than the frame window reaches at 100 frames per second (64
/// frames, 640 ms), so no frame fits it: only "an idle worker always gets a job" serves
/// it. A second record of held jobs that kept the dropped one would call it busy, and
/// it would wait for good.
#[test]
fn a_worker_that_dropped_its_held_jobs_is_idle_and_gets_a_job() {
    let mut c = config();
    c.pacing = gridlight_actors::pacing::Pacing::FixedFps(100.0);
    let (sink, _rx) = collect_sink();
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    let table = table();
    let (mut p, [(f1, s1, v1), (f2, s2, _)]) = holding_two(&m);
    // Its job time is measured from this answer: longer than the frame window reaches.
    thread::sleep(Duration::from_millis(1200));
    assert!(p.answer(&table, f1, s1, v1, 1.0));
    move_camera(&m);
    p.send(&WorkerMsg::Superseded { frame: f2, set: s2 });
    p.send(&WorkerMsg::Ready { credits: 1 });
    let job = loop {
        match p.recv_within(Duration::from_secs(5)) {
            Some(MasterMsg::State(_)) => continue,
            other => break other,
        }
    };
    assert!(
        matches!(job, Some(MasterMsg::Job { .. })),
        "the idle worker got no job within 5 s: {job:?}"
    );
    assert_eq!(Counters::get(&m.counters().jobs_superseded), 1);
}
