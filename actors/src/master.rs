//! The master's public entry point: [`start`] wires the actors on their own thread
//! (the window owns the main thread) and returns a [`MasterHandle`] to edit the
//! scene, watch statistics, inject faults and stop.
//!
//! ```text
//! SceneHolder ─StateChanged─▶ Scheduler ─FrameScheduled/FrameStarted/FramesOutdated─▶ Assembler
//! Listener ─▶ Connection* ─WorkerReady/JobAnswered─▶ Scheduler        ▲       │
//!                  │ ─ResultArrived───────────────────────────────────┘       │ FrameShown/
//!                  ▲ JobsAssigned (to the address in WorkerReady)              ▼ FrameSkipped
//!   Scheduler ◀─FrameDisplayed (to the address in FrameScheduled)─ Assembler  Presenter ─▶ sink thread
//! ```
//!
//! The actors are made in one direction, each from the addresses of those it sends to
//! (presenter, assembler, scheduler, scene holder, listener: only its context is made
//! first, so that its connections' links lead back to it, their supervisor); a reply
//! goes to the address its request carries, as connections get their jobs.

use std::net::SocketAddr;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use actix::prelude::*;

use crate::assembler::{Assembler, AssemblerConfig, AssemblerLinks};
use crate::connection::{ConnectionConfig, ConnectionLinks};
use crate::discovery::announcer::{AnnounceConfig, Announcer};
use crate::discovery::Announcement;
use crate::listener::Listener;
use crate::messages::{
    ApplyEdit, CurrentState, EditMade, KillConnection, ListConnections, PacingChanged,
    PanicConnection, PlayScript, SetPacing, Shutdown,
};
use crate::presenter::sink::FrameSink;
use crate::presenter::{Presenter, PresenterConfig, Report, ReportState};
use crate::scene::asset_store::AssetStore;
use crate::scene::edit::{Edit, EditError};
use crate::scene::state::{SceneState, StateVersion};
use crate::scene_holder::SceneHolder;
use crate::scheduler::{Scheduler, SchedulerConfig, SchedulerLinks};
use crate::shared::counters::Counters;
use crate::shared::holdings::HeldJobs;
use crate::shared::sets::SetTables;
use crate::shared::workers::{WorkerCounts, WorkerTable};
use crate::supervision::{
    InjectPanic, PanicInjection, PanicPlan, PeerPolicy, RestartPolicy, Supervised, Supervision,
};
use crate::wire::protocol::ConnId;
use crate::wire::protocol::{SetsConfig, HEARTBEAT_INTERVAL, PEER_TIMEOUT, PROTOCOL_VERSION};

pub use crate::presenter::sink::{ShownFrame, SinkError};
pub use crate::presenter::stats::FrameStats;
pub use crate::presenter::ReportState as MasterReport;
pub use crate::shared::pacing::{Heuristic, Pacing, PacingError};
pub use crate::supervision::ActorKind;

/// Default number of jobs a worker may hold (docs/design.md, decision 7).
pub const DEFAULT_PIPELINE: u32 = 2;
/// Default cap on simultaneous connections.
pub const DEFAULT_MAX_CONNECTIONS: usize = 256;
/// I_t's denominator before any frame was shown.
pub const DEFAULT_INITIAL_FRAME_TIME: Duration = Duration::from_millis(250);

/// Everything [`start`] needs besides the scene, its assets and the sink.
#[derive(Clone, Debug)]
pub struct MasterConfig {
    pub listen: SocketAddr,
    pub sets: SetsConfig,
    /// k: jobs one worker may hold at once.
    pub pipeline: u32,
    pub max_connections: usize,
    /// Shared secret workers must prove (HMAC over a nonce); `None`: no authentication.
    pub secret: Option<Vec<u8>>,
    pub pacing: Pacing,
    /// Job-queue threshold; `None` means 2 × S.
    pub queue_threshold: Option<usize>,
    /// Stop after this many shown frames.
    pub max_frames: Option<u64>,
    pub heartbeat: Duration,
    pub peer_timeout: Duration,
    pub initial_frame_time: Duration,
    /// Each core actor's restart intensity and back-off.
    pub restart: RestartPolicy,
    /// When a worker whose connections keep failing is refused, and for how long.
    pub peer_backoff: PeerPolicy,
    /// Panics injected by the guard (a test hook: `gridlight master --inject-panic`).
    pub inject_panics: Vec<PanicInjection>,
    /// Announce this master on the LAN (`discovery`); `None`: stay quiet.
    pub announce: Option<AnnounceConfig>,
    /// Frames the assembler hands to the sink ahead of it (1 for the least latency, 2 to
    /// keep a fast sink busy: [`crate::presenter::DEFAULT_SINK_IN_FLIGHT`]).
    pub sink_in_flight: usize,
    /// A state change discards the queued jobs of older versions and the assembler does
    /// not wait for their held ones (default); `false` only to measure what that gains.
    pub discard_stale_jobs: bool,
    /// The master's inbound link in bytes per second (`--link-mbps`), when known: the
    /// scheduler never asks the grid for more result bytes per second than it carries
    /// (`scheduler::job_size`).
    pub link_bytes_per_second: Option<f64>,
}

impl MasterConfig {
    /// Defaults everywhere but the address and the sets.
    pub fn new(listen: SocketAddr, sets: SetsConfig) -> Self {
        Self {
            listen,
            sets,
            pipeline: DEFAULT_PIPELINE,
            max_connections: DEFAULT_MAX_CONNECTIONS,
            secret: None,
            pacing: Pacing::default(),
            queue_threshold: None,
            max_frames: None,
            heartbeat: HEARTBEAT_INTERVAL,
            peer_timeout: PEER_TIMEOUT,
            initial_frame_time: DEFAULT_INITIAL_FRAME_TIME,
            restart: RestartPolicy::default(),
            peer_backoff: PeerPolicy::default(),
            inject_panics: Vec::new(),
            announce: None,
            discard_stale_jobs: true,
            link_bytes_per_second: None,
            sink_in_flight: crate::presenter::DEFAULT_SINK_IN_FLIGHT,
        }
    }
}

/// Errors of the handle's requests.
#[derive(Debug, thiserror::Error)]
pub enum MasterError {
    #[error("the master has stopped")]
    Stopped,
    #[error("pacing: {0}")]
    Pacing(#[from] PacingError),
    #[error(transparent)]
    Edit(#[from] EditError),
}

/// A running master.
pub struct MasterHandle {
    local_addr: SocketAddr,
    system: System,
    thread: Option<JoinHandle<std::io::Result<()>>>,
    scene: Addr<SceneHolder>,
    listener: Addr<Listener>,
    scheduler: Addr<Scheduler>,
    assembler: Addr<Assembler>,
    presenter: Addr<Presenter>,
    /// When the master announces itself.
    announcer: Option<Addr<Announcer>>,
    report: Arc<Report>,
    counters: Arc<Counters>,
    /// The connected workers (`workers()`).
    workers: Arc<WorkerTable>,
}

/// Starts a master listening on `config.listen`; returns once it accepts connections.
pub fn start(
    config: MasterConfig,
    state: SceneState,
    assets: AssetStore,
    sink: Box<dyn FrameSink>,
) -> std::io::Result<MasterHandle> {
    let invalid = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, m);
    config.pacing.validate().map_err(|e| invalid(e.to_string()))?;
    if config.pipeline == 0 || config.max_connections == 0 {
        return Err(invalid("pipeline (k) and max_connections must be at least 1".into()));
    }
    let sets = Arc::new(
        SetTables::new(state.resolution, config.sets).map_err(|e| invalid(e.to_string()))?,
    );
    let socket = std::net::TcpListener::bind(config.listen)?;
    socket.set_nonblocking(true)?;
    let local_addr = socket.local_addr()?;
    if config.secret.is_none() {
        tracing::warn!(
            listen = %local_addr,
            "no shared secret: any host that can reach this address may join and contribute pixels"
        );
    } else {
        tracing::info!(listen = %local_addr, "workers must prove the shared secret");
    }
    let counters = Arc::new(Counters::default());
    let faults = Arc::new(PanicPlan::new(&config.inject_panics));
    let announcer = match &config.announce {
        Some(a) => {
            let what = Announcement::new(
                PROTOCOL_VERSION,
                local_addr,
                &a.name,
                &a.scene,
                config.secret.is_some(),
            );
            let supervision =
                Supervision::restarting(ActorKind::Announcer, config.restart, counters.clone());
            let secret = config.secret.as_deref();
            Some(Announcer::new(a, &what, secret, supervision)?.with_faults(faults.clone()))
        }
        None => None,
    };
    let report = Arc::new(Report::default());
    let workers = Arc::new(WorkerTable::default());
    let (tx, rx) = std::sync::mpsc::channel();
    let (r, c, w) = (report.clone(), counters.clone(), workers.clone());
    let (r_end, c_end) = (report.clone(), counters.clone());
    let thread = std::thread::Builder::new().name("gridlight-master".into()).spawn(move || {
        let system = System::new();
        let wired = system.block_on(async move {
            let mut actors = wire(config, state, assets, sink, sets, socket, r, c, w, faults);
            if let (Ok(actors), Some(a)) = (&mut actors, announcer) {
                actors.announcer = Some(a.start());
            }
            actors
        });
        let ok = wired.is_ok();
        let _ = tx.send(wired.map(|a| (System::current(), a)));
        if !ok {
            return Ok(());
        }
        let ran = system.run();
        // Escalation stops the system without the presenter's finish: whoever waits for
        // the report (the headless master) must still see the end, and why.
        let escalation = c_end.escalation.lock().unwrap_or_else(|p| p.into_inner()).clone();
        r_end.finish(escalation.clone());
        match escalation {
            Some(why) => Err(std::io::Error::other(why)),
            None => ran,
        }
    })?;
    let (system, actors) = match rx.recv() {
        Ok(Ok(v)) => v,
        Ok(Err(e)) => return Err(e),
        Err(_) => return Err(std::io::Error::other("the master thread ended while starting")),
    };
    let Actors { scene, listener, scheduler, assembler, presenter, announcer } = actors;
    Ok(MasterHandle {
        local_addr,
        system,
        thread: Some(thread),
        scene,
        listener,
        scheduler,
        assembler,
        presenter,
        announcer,
        report,
        counters,
        workers,
    })
}

struct Actors {
    scene: Addr<SceneHolder>,
    listener: Addr<Listener>,
    scheduler: Addr<Scheduler>,
    assembler: Addr<Assembler>,
    presenter: Addr<Presenter>,
    announcer: Option<Addr<Announcer>>,
}

/// Creates every actor inside the running system, each after those it sends to.
#[allow(clippy::too_many_arguments)]
fn wire(
    config: MasterConfig,
    state: SceneState,
    assets: AssetStore,
    sink: Box<dyn FrameSink>,
    sets: Arc<SetTables>,
    socket: std::net::TcpListener,
    report: Arc<Report>,
    counters: Arc<Counters>,
    workers: Arc<WorkerTable>,
    faults: Arc<PanicPlan>,
) -> std::io::Result<Actors> {
    let socket = tokio::net::TcpListener::from_std(socket)?;
    let state = Arc::new(state);
    let threshold = config.queue_threshold.unwrap_or(2 * config.sets.sets as usize);

    let presenter_config = PresenterConfig {
        max_frames: config.max_frames,
        policy: config.restart,
        sink_in_flight: config.sink_in_flight,
    };
    let presenter =
        Presenter::new(presenter_config, sink, counters.clone(), workers.clone(), report)
            .with_faults(faults.clone())
            .start();
    let assembler_config = AssemblerConfig {
        pacing: config.pacing,
        initial_frame_time: config.initial_frame_time,
        sink_in_flight: config.sink_in_flight,
        policy: config.restart,
    };
    let links = AssemblerLinks {
        shown_to: presenter.clone().recipient(),
        skipped_to: presenter.clone().recipient(),
        prepare_to: presenter.clone().recipient(),
    };
    let assembler =
        Assembler::new(sets.clone(), assembler_config, links, counters.clone(), workers.clone())
            .with_faults(faults.clone())
            .start();
    let links = SchedulerLinks {
        frames_to: assembler.clone().recipient(),
        started_to: assembler.clone().recipient(),
        abandoned_to: assembler.clone().recipient(),
        outdated_to: assembler.clone().recipient(),
    };
    let scheduler_config = SchedulerConfig {
        sets: config.sets.sets,
        threshold,
        pacing: config.pacing,
        policy: config.restart,
        link_bytes_per_second: config.link_bytes_per_second,
    };
    // Who holds which job: one record, written where a job changes hands.
    let held = Arc::new(HeldJobs::default());
    let scheduler =
        Scheduler::new(scheduler_config, state.clone(), links, counters.clone(), held.clone())
            .with_stale_discard(config.discard_stale_jobs)
            .with_faults(faults.clone())
            .start();
    let (changes_to, edits_to) = (scheduler.clone().recipient(), presenter.clone().recipient());
    let scene = SceneHolder::new(state, changes_to, edits_to, counters.clone(), config.restart)
        .with_sets(sets.clone())
        .with_faults(faults.clone())
        .start();

    let conn_config = Arc::new(ConnectionConfig {
        secret: config.secret,
        sets,
        assets: Arc::new(assets),
        pipeline: config.pipeline,
        heartbeat: config.heartbeat,
        peer_timeout: config.peer_timeout,
        workers,
        held,
        refusal_lines: Default::default(),
    });
    // Connections report their end to the listener, their supervisor.
    let listener_ctx = Context::<Listener>::new();
    let listener_addr = listener_ctx.address();
    let links = ConnectionLinks {
        ready_to: scheduler.clone().recipient(),
        left_to: scheduler.clone().recipient(),
        answered_to: scheduler.clone().recipient(),
        results_to: assembler.clone().recipient(),
        ended_to: listener_addr.clone().recipient(),
        authenticated_to: listener_addr.clone().recipient(),
    };
    let policy = (config.restart, config.peer_backoff);
    let listener =
        Listener::new(socket, config.max_connections, conn_config, links, counters, policy);
    listener_ctx.run(listener.with_faults(faults));
    let listener = listener_addr;
    Ok(Actors { scene, listener, scheduler, assembler, presenter, announcer: None })
}

impl MasterHandle {
    /// The address workers connect to (the real port when `listen` used port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Applies an edit to the scene state; answers the new version.
    pub fn edit(&self, edit: Edit) -> Result<StateVersion, MasterError> {
        Ok(block_on(self.scene.send(ApplyEdit(edit)))??)
    }

    /// Changes the pacing (wait heuristic bounds or frame rate) from now on; a bad value
    /// is refused with the reason and the pacing stays as it was.
    pub fn set_pacing(&self, pacing: Pacing) -> Result<(), MasterError> {
        block_on(self.assembler.send(SetPacing(pacing)))??;
        self.scheduler.do_send(PacingChanged(pacing));
        Ok(())
    }

    /// The workers connected now, with their rates.
    pub fn workers(&self) -> Vec<crate::shared::workers::WorkerInfo> {
        self.workers.list()
    }

    /// How many connected workers take jobs and how many are paused, now.
    pub fn worker_counts(&self) -> WorkerCounts {
        self.workers.counts()
    }

    /// Applies an edit that happened at `at` (an input event), without waiting: the
    /// window's path. The edit-to-display latency is measured from `at`.
    pub fn edit_made(&self, edit: Edit, at: Instant) {
        self.scene.do_send(EditMade { edit, at });
    }

    /// Plays an interaction script from now on.
    pub fn play_script(&self, script: Vec<(Duration, Edit)>) {
        self.scene.do_send(PlayScript(script));
    }

    /// The current scene state.
    pub fn state(&self) -> Result<Arc<SceneState>, MasterError> {
        block_on(self.scene.send(CurrentState))
    }

    /// Frames shown and skipped so far and the last frame's statistics.
    pub fn report(&self) -> MasterReport {
        self.report.state.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// The last shown frame's statistics.
    pub fn stats(&self) -> Option<FrameStats> {
        self.report().last
    }

    /// The run's counters (bytes, workers, dropped results, ...).
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// Ids (`worker_id`s) of the live connections.
    pub fn connections(&self) -> Result<Vec<ConnId>, MasterError> {
        block_on(self.listener.send(ListConnections))
    }

    /// Fault injection: ends connection `id` abruptly. False when it does not exist.
    pub fn kill_connection(&self, id: ConnId) -> Result<bool, MasterError> {
        block_on(self.listener.send(KillConnection(id)))
    }

    /// Fault injection: a panic inside one of connection `id`'s handlers.
    pub fn panic_connection(&self, id: ConnId) -> Result<bool, MasterError> {
        block_on(self.listener.send(PanicConnection(id)))
    }

    /// Fault injection: a panic inside a handler of `actor` (of every live connection
    /// for [`ActorKind::Connection`]; nothing for the announcer of a quiet master).
    pub fn inject_panic(&self, actor: ActorKind) {
        match actor {
            ActorKind::Scheduler => self.scheduler.do_send(InjectPanic),
            ActorKind::Assembler => self.assembler.do_send(InjectPanic),
            ActorKind::Presenter => self.presenter.do_send(InjectPanic),
            ActorKind::SceneHolder => self.scene.do_send(InjectPanic),
            ActorKind::Listener => self.listener.do_send(InjectPanic),
            ActorKind::Announcer => {
                if let Some(a) = &self.announcer {
                    a.do_send(InjectPanic);
                }
            }
            ActorKind::Connection => {
                for id in self.connections().unwrap_or_default() {
                    self.listener.do_send(PanicConnection(id));
                }
            }
        }
    }

    /// Waits until `n` frames were shown in total; false on timeout or when the master
    /// finished before.
    pub fn wait_for_frames(&self, n: u64, timeout: Duration) -> bool {
        self.wait_until(timeout, |r| r.shown >= n || r.finished).shown >= n
    }

    /// Waits until the master finished on its own (frame limit or failure).
    pub fn wait_finished(&self, timeout: Duration) -> bool {
        self.wait_until(timeout, |r| r.finished).finished
    }

    fn wait_until(&self, timeout: Duration, done: impl Fn(&ReportState) -> bool) -> ReportState {
        let deadline = Instant::now() + timeout;
        let mut r = self.report.state.lock().unwrap_or_else(|p| p.into_inner());
        while !done(&r) {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            r = self.report.changed.wait_timeout(r, left).unwrap_or_else(|p| p.into_inner()).0;
        }
        r.clone()
    }

    /// Stops cleanly: the sink gets its last frames and `finish`, the threads end.
    pub fn stop(mut self) -> std::io::Result<MasterReport> {
        self.shutdown()?;
        Ok(self.report())
    }

    fn shutdown(&mut self) -> std::io::Result<()> {
        let Some(thread) = self.thread.take() else { return Ok(()) };
        if self.presenter.try_send(Shutdown).is_err() {
            self.system.stop();
        }
        match thread.join() {
            Ok(r) => r,
            Err(_) => Err(std::io::Error::other("the master thread panicked")),
        }
    }
}

impl Drop for MasterHandle {
    fn drop(&mut self) {
        if let Err(e) = self.shutdown() {
            tracing::warn!(cause = %e, "master stopped with an error");
        }
    }
}

/// Waits for an actor's answer from outside the actor system.
fn block_on<T>(
    req: impl std::future::Future<Output = Result<T, MailboxError>>,
) -> Result<T, MasterError> {
    futures::executor::block_on(req).map_err(|_| MasterError::Stopped)
}
