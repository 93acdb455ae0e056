//! The presenter actor: where a displayed frame ends up.
//!
//! The frame assembler decides when a frame is shown or skipped and pushes it here one
//! way. The presenter hands a shown frame to the sink thread (still packed), publishes
//! its statistics (the report the master's handle reads, `--stats`), counts skipped
//! frames, and stops the master after `max_frames` shown frames. When the sink is done
//! with a frame it frees its place at the assembler (the address came with the frame).

pub mod edit_latency;
pub mod sink;
pub mod stats;

use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use actix::prelude::*;

use crate::messages::{EditApplied, FrameShown, FrameSkipped, PrepareState, Shutdown, SinkFreed};
use crate::presenter::edit_latency::EditLog;
use crate::presenter::sink::{spawn_sink, FrameSink, PackedShownFrame, Preparer, SinkOutcome};
use crate::presenter::stats::{useful_fraction, FrameStats};
use crate::shared::counters::Counters;
use crate::shared::workers::WorkerTable;
use crate::supervision::{ActorKind, Guard, InjectPanic, RestartPolicy, Supervised, Supervision};

/// Frames handed to the sink thread and not yet shown, at most, by default: two keep a
/// fast sink busy. An interactive master uses one (`MasterConfig::sink_in_flight`): a
/// frame waiting behind another in the sink is a frame decided one compose time before
/// it is shown, so it shows an older view than the one decided when the sink is free.
pub const DEFAULT_SINK_IN_FLIGHT: usize = 2;

/// The sink finished one frame (or failed).
#[derive(Message)]
#[rtype(result = "()")]
pub struct SinkDone(pub SinkOutcome);

/// What the master's handle can see of the presenter, shared with it.
#[derive(Debug, Default)]
pub struct Report {
    pub state: Mutex<ReportState>,
    pub changed: Condvar,
}

impl Report {
    /// Marks the run finished (keeping the first error) and wakes every waiter.
    pub fn finish(&self, error: Option<String>) {
        {
            let mut r = self.state.lock().unwrap_or_else(|p| p.into_inner());
            r.finished = true;
            if r.error.is_none() {
                r.error = error;
            }
        }
        self.changed.notify_all();
    }
}

#[derive(Debug, Default, Clone)]
pub struct ReportState {
    pub shown: u64,
    pub skipped: u64,
    pub last: Option<FrameStats>,
    /// The display stopped (frame limit reached, shutdown or sink failure).
    pub finished: bool,
    /// Why the master stopped on its own, if it failed.
    pub error: Option<String>,
}

/// The sink thread, the report and the counts of shown and skipped frames.
pub struct Presenter {
    skipped_since_show: u64,
    shown: u64,
    max_frames: Option<u64>,
    sink: Option<Box<dyn FrameSink>>,
    /// Frames the sink channel holds (the assembler never hands over more).
    sink_capacity: usize,
    /// The sink's, told every new scene state at once (G-buffers computed ahead).
    prepare: Option<Preparer>,
    sink_tx: Option<SyncSender<PackedShownFrame>>,
    sink_thread: Option<JoinHandle<()>>,
    /// Where the sink's finished frames are freed (the assembler, named by its frames).
    freed_to: Option<Recipient<SinkFreed>>,
    counters: Arc<Counters>,
    /// The connected workers: the paused ones are listed in each frame's statistics.
    workers: Arc<WorkerTable>,
    report: Arc<Report>,
    /// Edits applied and not yet shown.
    edits: EditLog,
    supervision: Supervision,
    finished: bool,
    /// When the presenter was made (the master's start), for `shown_at_ms`.
    started: Instant,
}

/// Construction parameters of the presenter.
pub struct PresenterConfig {
    pub max_frames: Option<u64>,
    pub policy: RestartPolicy,
    /// Frames handed to the sink and not yet shown, at most (the assembler's bound).
    pub sink_in_flight: usize,
}

impl Presenter {
    pub fn new(
        config: PresenterConfig,
        sink: Box<dyn FrameSink>,
        counters: Arc<Counters>,
        workers: Arc<WorkerTable>,
        report: Arc<Report>,
    ) -> Self {
        let supervision =
            Supervision::restarting(ActorKind::Presenter, config.policy, counters.clone());
        Self {
            skipped_since_show: 0,
            shown: 0,
            max_frames: config.max_frames,
            sink: Some(sink),
            sink_capacity: config.sink_in_flight.max(1),
            prepare: None,
            sink_tx: None,
            sink_thread: None,
            freed_to: None,
            counters,
            workers,
            report,
            edits: EditLog::default(),
            supervision,
            finished: false,
            started: Instant::now(),
        }
    }
}

impl Actor for Presenter {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }
}

impl Supervised for Presenter {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    /// Starts the sink thread (once).
    fn on_start(&mut self, ctx: &mut Context<Self>) {
        let Some(mut sink) = self.sink.take() else { return };
        self.prepare = sink.preparer();
        let me = ctx.address();
        match spawn_sink(sink, self.sink_capacity, move |outcome| me.do_send(SinkDone(outcome))) {
            Ok((tx, thread)) => {
                self.sink_tx = Some(tx);
                self.sink_thread = Some(thread);
            }
            Err(e) => self.fail(format!("cannot start the frame sink thread: {e}")),
        }
    }

    /// Nothing to replace: the frame it was showing is lost, the next one is shown.
    fn restart(&mut self, _: &mut Context<Self>) {}
}

impl Handler<FrameShown> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: FrameShown, ctx: &mut Context<Self>) {
        let freed_to = msg.freed_to.clone();
        self.freed_to = Some(msg.freed_to.clone());
        if self.finished {
            return freed_to.do_send(SinkFreed);
        }
        // Not handed to the sink (or lost in a panic): its place is free at once.
        if self.guarded(ctx, |p, _| p.show(msg)) != Some(true) {
            freed_to.do_send(SinkFreed);
        }
    }
}

impl Handler<FrameSkipped> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: FrameSkipped, ctx: &mut Context<Self>) {
        self.guarded(ctx, |p, _| {
            Counters::add(&p.counters.results_unused, u64::from(msg.back));
            p.skipped_since_show += 1;
            p.report.state.lock().unwrap_or_else(|p| p.into_inner()).skipped += 1;
            p.report.changed.notify_all();
        });
    }
}

impl Handler<PrepareState> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: PrepareState, ctx: &mut Context<Self>) {
        self.guarded(ctx, |p, _| {
            if let Some(prepare) = &p.prepare {
                prepare(msg.0);
            }
        });
    }
}

impl Handler<SinkDone> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: SinkDone, ctx: &mut Context<Self>) {
        self.guarded(ctx, |p, _| {
            if let Some(to) = &p.freed_to {
                to.do_send(SinkFreed);
            }
            if let Err(e) = msg.0 {
                p.fail(e.to_string());
            }
        });
    }
}

impl Handler<Shutdown> for Presenter {
    type Result = ();
    fn handle(&mut self, _: Shutdown, ctx: &mut Context<Self>) {
        self.guarded(ctx, |p, _| p.finish(None));
    }
}

impl Handler<EditApplied> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: EditApplied, ctx: &mut Context<Self>) {
        self.guarded(ctx, |p, _| p.edits.applied(msg.version, msg.at));
    }
}

impl Handler<InjectPanic> for Presenter {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the presenter"));
    }
}

impl Presenter {
    /// Sends a shown frame to the sink and publishes its statistics; false when the
    /// sink did not take it.
    fn show(&mut self, msg: FrameShown) -> bool {
        let FrameShown { closed, q, i, wait, accumulated_frames, .. } = msg;
        let version = closed.state.version;
        self.shown += 1;
        let c = &self.counters;
        let workers = self.workers.counts();
        Counters::add(&c.results_used, u64::from(closed.back));
        let (used, accepted, late) = (
            Counters::get(&c.results_used),
            Counters::get(&c.results_accepted),
            Counters::get(&c.dropped_late),
        );
        let mut stats = FrameStats {
            frame: closed.frame,
            state_version: version,
            jobs_back: closed.back,
            spp: closed.spp,
            jobs_total: closed.total,
            q,
            i,
            wait_ms: wait.as_secs_f64() * 1e3,
            shown_at_ms: self.started.elapsed().as_secs_f64() * 1e3,
            skipped: std::mem::take(&mut self.skipped_since_show),
            dropped_late: late,
            dropped_duplicate: Counters::get(&c.dropped_duplicate),
            dropped_unknown: Counters::get(&c.dropped_unknown),
            workers: workers.live,
            paused_workers: workers.paused,
            paused: if workers.paused > 0 { self.workers.paused_list() } else { Vec::new() },
            bytes_in: Counters::get(&c.bytes_in),
            bytes_out: Counters::get(&c.bytes_out),
            shown: self.shown,
            accumulated_frames,
            edits_at: self.edits.shown(version),
            edit_latency_ms: Vec::new(),
            results_used: used,
            results_returned: accepted + late,
            useful_fraction: useful_fraction(used, accepted, late),
            jobs_discarded_stale: Counters::get(&c.jobs_discarded_stale),
            jobs_superseded: Counters::get(&c.jobs_superseded),
        };
        stats.stamp_edit_latency(Instant::now());
        let frame = PackedShownFrame {
            frame: closed.frame,
            state: closed.state,
            results: closed.results,
            owners: closed.owners,
            stats: stats.clone(),
        };
        let taken = match &self.sink_tx {
            Some(tx) => match tx.try_send(frame) {
                Ok(()) => true,
                // Cannot happen while the assembler bounds the frames in flight; never block.
                Err(TrySendError::Full(_)) => {
                    tracing::warn!(frame = stats.frame, "sink full; frame not shown");
                    false
                }
                Err(TrySendError::Disconnected(_)) => {
                    tracing::warn!("sink thread gone");
                    false
                }
            },
            None => false,
        };
        {
            let mut r = self.report.state.lock().unwrap_or_else(|p| p.into_inner());
            r.shown = self.shown;
            r.last = Some(stats);
        }
        self.report.changed.notify_all();
        if self.max_frames.is_some_and(|m| self.shown >= m) {
            self.finish(None);
        }
        taken
    }

    /// Lets the sink finish, publishes the end and stops the actor system.
    fn finish(&mut self, error: Option<String>) {
        if self.finished {
            return;
        }
        self.finished = true;
        self.sink_tx = None; // the sink thread drains what it has, then calls finish
        if let Some(t) = self.sink_thread.take() {
            if t.join().is_err() {
                tracing::error!("frame sink thread panicked");
            }
        }
        self.report.finish(error);
        System::current().stop();
    }

    fn fail(&mut self, error: String) {
        tracing::error!(cause = %error, "stopping the master");
        self.finish(Some(error));
    }
}
