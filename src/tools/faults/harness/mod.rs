//! The fault harness: a master (the actor system in-process, via `master::start`) and N
//! real `gridlight worker` processes on 127.0.0.1, with every fault of issue 6 at hand.
//!
//! Workers run the null renderer (radiance names its frame), so the [`Checker`] sees at
//! once a pixel that came from the wrong frame. Every other worker connects through a
//! [`Proxy`], so link faults hit some workers while the others keep the grid alive; the
//! checker's gap clock only counts while a worker with a healthy link is alive.
//!
//! Files: this one (the harness's life: start, tick, report), `workers.rs` (the worker
//! processes), `fault.rs` (the faults and how each is injected).

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::Vec3;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{start, MasterConfig, MasterHandle};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::state::{Camera, Geometry, Material, Object, Resolution, SceneState};
use thiserror::Error;

use super::invariants::{lock, Checker, CheckingSink, Gap, Limits, QSummary, SharedChecker};
use super::proxy::{LinkMode, Proxy};
use crate::worker::render::null_radiance;

mod fault;
mod workers;

pub use fault::Fault;
use workers::{signal, ScratchDir, WorkerProc};

/// Errors setting up or driving the harness.
#[derive(Debug, Error)]
pub enum HarnessError {
    #[error("cannot start the master: {0}")]
    Master(std::io::Error),
    #[error("cannot start the proxy: {0}")]
    Proxy(std::io::Error),
    #[error("cannot start worker process {binary}: {source}")]
    Spawn { binary: PathBuf, source: std::io::Error },
    #[error("harness files: {0}")]
    Files(std::io::Error),
}

/// Longest time without a shown frame while a worker with a healthy link is alive: the
/// soak's limit (issue 42: the screen was blank up to 4.6 s after an assembler restart).
pub const MAX_GAP: Duration = Duration::from_secs(2);

/// How the harness runs.
#[derive(Clone, Debug)]
pub struct HarnessConfig {
    /// The `gridlight` executable whose `worker` subcommand is started.
    pub binary: PathBuf,
    /// Worker processes at the start (one render thread each).
    pub workers: usize,
    pub secret: Option<Vec<u8>>,
    pub width: u32,
    pub height: u32,
    pub sets: u32,
    /// Simulated render time per job of the null renderer.
    pub render_delay_ms: u32,
    pub heartbeat: Duration,
    pub peer_timeout: Duration,
    /// Longest acceptable gap between shown frames while a healthy worker is alive.
    pub max_gap: Duration,
    /// Put a fault proxy in front of every other worker.
    pub proxy: bool,
}

impl HarnessConfig {
    /// Small and fast: 64×48 pixels, S = 16, 2 s silence timeout.
    pub fn new(binary: PathBuf, workers: usize) -> Self {
        Self {
            binary,
            workers,
            secret: None,
            width: 64,
            height: 48,
            sets: 16,
            render_delay_ms: 2,
            heartbeat: Duration::from_millis(500),
            peer_timeout: Duration::from_secs(2),
            max_gap: MAX_GAP,
            proxy: true,
        }
    }
}

/// What a run did and saw (the soak's JSON).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct HarnessReport {
    pub faults: BTreeMap<String, u64>,
    pub frames_shown: u64,
    pub longest_gap_ms: u64,
    /// The longest gaps (over a second), with the faults and live counts around them.
    pub long_gaps: Vec<Gap>,
    pub dropped: BTreeMap<String, u64>,
    pub rejected: BTreeMap<String, u64>,
    pub master_exits: u64,
    pub master_restarts: u64,
    pub worker_exits: u64,
    pub invariant_violations: u64,
    pub violations: Vec<String>,
    pub results_accepted: u64,
    pub jobs_handed_out: u64,
    /// (frame, set) pairs handed out a second time; the no-redundancy invariant wants 0.
    pub jobs_handed_twice: u64,
    pub panics_contained: u64,
    /// Frames shown and their mean Q_t by connected workers (the resource curve).
    pub q_by_workers: BTreeMap<u64, QSummary>,
}

/// A master, its workers and the proxy.
pub struct Harness {
    config: HarnessConfig,
    master: Option<MasterHandle>,
    /// The master's address; kept across restarts so workers find it again.
    listen: SocketAddr,
    proxy: Option<Proxy>,
    workers: Vec<WorkerProc>,
    checker: SharedChecker,
    /// Worker caches and the secret file; removed on drop.
    dir: ScratchDir,
    report: HarnessReport,
    /// Counters of masters that were restarted, added up.
    past: Totals,
    spawned: u64,
}

#[derive(Clone, Default)]
struct Totals {
    accepted: u64,
    handed: u64,
    handed_twice: u64,
    panics: u64,
    dropped: BTreeMap<String, u64>,
    rejected: BTreeMap<String, u64>,
}

impl Harness {
    /// Starts the master (and proxy) and `config.workers` worker processes.
    pub fn start(config: HarnessConfig) -> Result<Self, HarnessError> {
        let dir = ScratchDir::new().map_err(HarnessError::Files)?;
        if let Some(secret) = &config.secret {
            std::fs::write(dir.path().join("secret"), secret).map_err(HarnessError::Files)?;
        }
        let limits = Limits { sets: config.sets, max_gap: config.max_gap };
        let checker = Arc::new(Mutex::new(Checker::new(limits, Some(null_radiance))));
        let listen: SocketAddr = ([127, 0, 0, 1], 0).into();
        let mut h = Self {
            config,
            master: None,
            listen,
            proxy: None,
            workers: Vec::new(),
            checker,
            dir,
            report: HarnessReport::default(),
            past: Totals::default(),
            spawned: 0,
        };
        h.start_master()?;
        if h.config.proxy {
            h.proxy = Some(Proxy::start(h.listen).map_err(HarnessError::Proxy)?);
        }
        for _ in 0..h.config.workers {
            h.spawn_worker()?;
        }
        Ok(h)
    }

    fn start_master(&mut self) -> Result<(), HarnessError> {
        let c = &self.config;
        let mut mc = MasterConfig::new(
            self.listen,
            SetsConfig { sets: c.sets, partition: Partition::QuasiRandom },
        );
        mc.secret = c.secret.clone();
        mc.heartbeat = c.heartbeat;
        mc.peer_timeout = c.peer_timeout;
        mc.initial_frame_time = Duration::from_millis(50);
        // Broken links fail a worker's connections on purpose, several in a row: the
        // harness measures recovery, so no worker is backed off for them (the back-off
        // has its own tests in actors/tests/supervision.rs).
        mc.peer_backoff.max_failures = usize::MAX;
        let sink = Box::new(CheckingSink(self.checker.clone()));
        let m = start(mc, null_scene(c.width, c.height), AssetStore::new(), sink)
            .map_err(HarnessError::Master)?;
        self.listen = m.local_addr();
        lock(&self.checker).master_restarted();
        self.master = Some(m);
        Ok(())
    }

    /// The running master.
    pub fn master(&self) -> Option<&MasterHandle> {
        self.master.as_ref()
    }

    pub fn proxy(&self) -> Option<&Proxy> {
        self.proxy.as_ref()
    }

    pub fn checker(&self) -> &SharedChecker {
        &self.checker
    }

    /// Periodic checks: the master still runs, workers that exited, the gap clock.
    pub fn tick(&mut self) {
        let now = Instant::now();
        let mut ck = lock(&self.checker);
        ck.tick(now);
        if let Some(m) = &self.master {
            ck.check_counters(m.counters());
            if m.report().finished {
                self.report.master_exits += 1;
                ck.violate("the master finished on its own".into());
            }
        }
        drop(ck);
        let before = self.workers.len();
        self.workers.retain_mut(|w| !matches!(w.child.try_wait(), Ok(Some(_))));
        let exited = (before - self.workers.len()) as u64;
        if exited > 0 {
            self.report.worker_exits += exited;
            self.note_live();
        }
    }

    /// Waits until `n` more frames were shown; false on timeout.
    pub fn wait_frames(&mut self, n: u64, timeout: Duration) -> bool {
        let target = lock(&self.checker).frames_shown() + n;
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            self.tick();
            if lock(&self.checker).frames_shown() >= target {
                return true;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        false
    }

    /// Everything so far, the current master's counters included.
    pub fn report(&self) -> HarnessReport {
        let mut r = self.report.clone();
        let mut t = self.past.clone();
        if let Some(m) = &self.master {
            add_counters(&mut t, m.counters());
        }
        let ck = lock(&self.checker);
        r.frames_shown = ck.frames_shown();
        r.longest_gap_ms = ck.longest_gap().as_millis() as u64;
        r.long_gaps = ck.long_gaps().to_vec();
        r.invariant_violations = ck.violations();
        r.violations = ck.violation_texts().to_vec();
        r.dropped = t.dropped;
        r.rejected = t.rejected;
        r.results_accepted = t.accepted;
        r.jobs_handed_out = t.handed;
        r.jobs_handed_twice = t.handed_twice;
        r.panics_contained = t.panics;
        r.q_by_workers = ck.q_by_workers();
        r
    }

    /// Stops everything; the final report.
    pub fn finish(mut self) -> HarnessReport {
        for w in &mut self.workers {
            if w.frozen {
                signal(&w.child, libc::SIGCONT);
            }
            let _ = w.child.kill();
            let _ = w.child.wait();
        }
        self.workers.clear();
        let report = self.report();
        if let Some(m) = self.master.take() {
            if let Err(e) = m.stop() {
                tracing::error!(cause = %e, "master stopped with an error");
            }
        }
        report
    }

    fn add_up(&mut self, c: &Counters) {
        add_counters(&mut self.past, c);
    }

    /// Tells the checker how many workers can deliver: running, and not behind a
    /// faulty link.
    fn note_live(&mut self) {
        let healthy_link = self
            .proxy
            .as_ref()
            .is_none_or(|p| matches!(p.mode(), LinkMode::Pass | LinkMode::Delay(_)));
        let live =
            self.workers.iter().filter(|w| !w.frozen && (healthy_link || !w.proxied)).count();
        let live = if self.master.is_some() { live } else { 0 };
        lock(&self.checker).note_live(live, Instant::now());
    }
}

impl Drop for Harness {
    fn drop(&mut self) {
        for w in &mut self.workers {
            signal(&w.child, libc::SIGCONT);
            let _ = w.child.kill();
            let _ = w.child.wait();
        }
    }
}

fn add_counters(t: &mut Totals, c: &Counters) {
    t.accepted += Counters::get(&c.results_accepted);
    t.handed += Counters::get(&c.jobs_handed_out);
    t.handed_twice += Counters::get(&c.jobs_handed_twice);
    t.panics += Counters::get(&c.panics_contained);
    for (k, v) in [
        ("late", &c.dropped_late),
        ("duplicate", &c.dropped_duplicate),
        ("unknown", &c.dropped_unknown),
    ] {
        *t.dropped.entry(k.to_owned()).or_default() += Counters::get(v);
    }
    for (k, v) in c.rejections() {
        *t.rejected.entry(k.to_owned()).or_default() += v;
    }
}

/// A one-cube scene; the null renderer ignores it, the master only needs its size.
pub fn null_scene(width: u32, height: u32) -> SceneState {
    let camera = Camera::pinhole(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 40.0);
    SceneState { seed: 1, ..SceneState::empty(Resolution { width, height }, camera) }.with_object(
        Object::new("cube", Geometry::Cube),
        Material::diffuse("grey", Vec3::splat(0.5)),
    )
}
