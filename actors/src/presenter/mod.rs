//! The display actor: decides when each frame is shown (§4.3) and hands it to the sink.
//!
//! It follows the oldest frame not yet displayed, asks the [`wait_heuristic`] on every
//! progress report and at the heuristic's deadlines, then closes the frame at the
//! assembler (late results are refused from then on), tells the scheduler, counts the
//! frames shown with the same state version (the sink accumulates their pixels) and
//! sends one [`ShownFrame`] per shown frame to the sink thread. Skipped frames only count.
//!
//! [`wait_heuristic`]: crate::assembler::wait_heuristic

pub mod edit_latency;
pub mod new_view;
pub mod sink;
pub mod stats;

use std::collections::BTreeMap;
use std::sync::mpsc::{SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use actix::prelude::*;

use crate::assembler::accumulate::Accumulator;
use crate::assembler::frame_table::ClosedFrame;
use crate::assembler::wait_heuristic::{
    decide, interaction, quality, Decision, Pacing, PacingError,
};
use crate::assembler::CloseFrame;
use crate::connection::workers::WorkerTable;
use crate::presenter::sink::{spawn_sink, FrameSink, PackedShownFrame, Preparer, SinkOutcome};
use crate::presenter::stats::{useful_fraction, Counters, FrameStats};
use crate::scene::state::{SceneState, StateVersion};
use crate::scheduler::FrameDisplayed;
use crate::supervision::{after_panic, contain, InjectPanic, RestartPolicy, RestartTracker};
use crate::wire::protocol::FrameNo;
use new_view::NewView;

/// Frames handed to the sink thread and not yet shown, at most, by default: two keep a
/// fast sink busy. An interactive master uses one ([`PresenterConfig::sink_in_flight`]): a
/// frame waiting behind another in the sink is a frame decided one compose time before
/// it is shown, so it shows an older view than the one decided when the sink is free.
pub const DEFAULT_SINK_IN_FLIGHT: usize = 2;

/// To the display: `back` of `total` jobs of `frame` are in.
#[derive(Message, Clone, Copy, Debug)]
#[rtype(result = "()")]
pub struct FrameProgress {
    pub frame: FrameNo,
    pub state_version: StateVersion,
    pub back: u32,
    pub total: u32,
    /// A job of the frame was handed out: its computation has started.
    pub started: bool,
}

/// To the display: frames before `before` were made with an outdated scene state; their
/// queued jobs were discarded, so only results already held by workers can still come.
/// The display shows such a frame at once with what it has (or skips it when empty)
/// instead of waiting for them.
#[derive(Message, Debug, Clone)]
#[rtype(result = "()")]
pub struct FramesOutdated {
    pub before: FrameNo,
    /// The new state, which the frames from `before` on have.
    pub state: Arc<SceneState>,
}

/// To the display: frames before `before` lost their queued jobs (the scheduler
/// restarted) and will get no results beyond those already handed out. Waiting for them
/// says nothing about the workers' speed, so the display decides on them at once.
#[derive(Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct FramesAbandoned {
    pub before: FrameNo,
}

/// The sink finished one frame (or failed).
#[derive(Message)]
#[rtype(result = "()")]
pub struct SinkDone(pub SinkOutcome);

/// Stop showing frames, let the sink finish, then stop the actor system.
#[derive(Message)]
#[rtype(result = "()")]
pub struct Shutdown;

/// What the master's handle can see of the display, shared with it.
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

/// Progress of a frame not yet displayed.
#[derive(Clone, Copy, Debug)]
struct Pending {
    back: u32,
    total: u32,
    scheduled_at: Instant,
    /// Its first job was handed out: the start of its computation, from which the
    /// heuristic measures the frame's time (paper §4.3).
    started_at: Option<Instant>,
}

/// Pacing, the frames being waited on, accumulation and the sink.
pub struct Presenter {
    pacing: Pacing,
    /// Time the last shown frame took (I_t's denominator).
    last_frame_time: Duration,
    pending: BTreeMap<FrameNo, Pending>,
    /// Frames up to this one were displayed.
    last_closed: Option<FrameNo>,
    /// Frames below this one lost their queued jobs (a scheduler restart): decided at once
    /// and left out of the frame time, so lost work cannot stretch I_max (each skip at
    /// I_max would otherwise multiply the next frame's wait by I_max).
    abandoned_before: FrameNo,
    /// The last frame shown (the rule around edits, [`NewView`]).
    last_shown: Option<FrameNo>,
    /// Frames below this one have an outdated scene state: shown at once with what they
    /// have (skipped when empty), never waited for, and left out of the frame time.
    outdated_before: FrameNo,
    last_close_at: Instant,
    /// A CloseFrame is on its way to the assembler.
    closing: bool,
    skipped_since_show: u64,
    shown: u64,
    max_frames: Option<u64>,
    accum: Accumulator,
    /// Heuristic deadline timer.
    timer: Option<SpawnHandle>,
    sink: Option<Box<dyn FrameSink>>,
    /// The sink's, told every new scene state at once (G-buffers computed ahead).
    prepare: Option<Preparer>,
    sink_tx: Option<SyncSender<PackedShownFrame>>,
    sink_thread: Option<JoinHandle<()>>,
    sink_in_flight: usize,
    /// The most frames handed to the sink and not yet shown.
    max_sink_in_flight: usize,
    close_to: Recipient<CloseFrame>,
    displayed_to: Recipient<FrameDisplayed>,
    counters: Arc<Counters>,
    /// The connected workers: the paused ones are listed in each frame's statistics.
    workers: Arc<WorkerTable>,
    report: Arc<Report>,
    restarts: RestartTracker,
    finished: bool,
    /// When the display was made (the master's start), for `shown_at_ms`.
    started: Instant,
}

/// Construction parameters of the display.
pub struct PresenterConfig {
    pub pacing: Pacing,
    /// I_t's denominator before the first frame was shown.
    pub initial_frame_time: Duration,
    pub max_frames: Option<u64>,
    pub policy: RestartPolicy,
    /// Frames handed to the sink and not yet shown, at most (at least 1).
    pub sink_in_flight: usize,
}

impl Presenter {
    pub fn new(
        config: PresenterConfig,
        sink: Box<dyn FrameSink>,
        close_to: Recipient<CloseFrame>,
        displayed_to: Recipient<FrameDisplayed>,
        counters: Arc<Counters>,
        workers: Arc<WorkerTable>,
        report: Arc<Report>,
    ) -> Self {
        Self {
            pacing: config.pacing,
            last_frame_time: config.initial_frame_time,
            pending: BTreeMap::new(),
            last_closed: None,
            abandoned_before: 0,
            outdated_before: 0,
            last_shown: None,
            last_close_at: Instant::now(),
            closing: false,
            skipped_since_show: 0,
            shown: 0,
            max_frames: config.max_frames,
            accum: Accumulator::default(),
            timer: None,
            sink: Some(sink),
            prepare: None,
            sink_tx: None,
            sink_thread: None,
            sink_in_flight: 0,
            max_sink_in_flight: config.sink_in_flight.max(1),
            close_to,
            displayed_to,
            counters,
            workers,
            report,
            restarts: RestartTracker::new(config.policy),
            finished: false,
            started: Instant::now(),
        }
    }
}

impl Actor for Presenter {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        let Some(mut sink) = self.sink.take() else { return };
        self.prepare = sink.preparer();
        let me = ctx.address();
        let capacity = self.max_sink_in_flight;
        match spawn_sink(sink, capacity, move |outcome| me.do_send(SinkDone(outcome))) {
            Ok((tx, thread)) => {
                self.sink_tx = Some(tx);
                self.sink_thread = Some(thread);
            }
            Err(e) => self.fail(format!("cannot start the frame sink thread: {e}")),
        }
    }
}

impl Handler<FrameProgress> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: FrameProgress, ctx: &mut Context<Self>) {
        if self.last_closed.is_some_and(|c| msg.frame <= c) {
            return;
        }
        let now = Instant::now();
        let p = self.pending.entry(msg.frame).or_insert(Pending {
            back: 0,
            total: msg.total,
            scheduled_at: now,
            started_at: None,
        });
        if msg.started && p.started_at.is_none() {
            p.started_at = Some(now);
        }
        p.back = p.back.max(msg.back);
        p.total = msg.total;
        self.evaluate(ctx);
    }
}

impl Handler<SinkDone> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: SinkDone, ctx: &mut Context<Self>) {
        self.sink_in_flight = self.sink_in_flight.saturating_sub(1);
        match msg.0 {
            Ok(()) => self.evaluate(ctx),
            Err(e) => self.fail(e.to_string()),
        }
    }
}

/// Changes how frames are paced from now on (the window's sliders).
#[derive(Message)]
#[rtype(result = "Result<(), PacingError>")]
pub struct SetPacing(pub Pacing);

impl Handler<SetPacing> for Presenter {
    type Result = Result<(), PacingError>;
    fn handle(&mut self, msg: SetPacing, ctx: &mut Context<Self>) -> Self::Result {
        msg.0.validate()?;
        self.pacing = msg.0;
        // A looser bound may show the waiting frame at once; a tighter one re-arms the timer.
        self.evaluate(ctx);
        Ok(())
    }
}

impl Handler<Shutdown> for Presenter {
    type Result = ();
    fn handle(&mut self, _: Shutdown, _: &mut Context<Self>) {
        self.finish(None);
    }
}

impl Handler<FramesAbandoned> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: FramesAbandoned, ctx: &mut Context<Self>) {
        self.abandoned_before = self.abandoned_before.max(msg.before);
        self.evaluate(ctx);
    }
}

impl Handler<FramesOutdated> for Presenter {
    type Result = ();
    fn handle(&mut self, msg: FramesOutdated, ctx: &mut Context<Self>) {
        if let Some(prepare) = &self.prepare {
            prepare(msg.state);
        }
        self.outdated_before = self.outdated_before.max(msg.before);
        self.evaluate(ctx);
    }
}

impl Handler<InjectPanic> for Presenter {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        if let Err(msg) = contain(|| panic!("injected panic in the presenter")) {
            self.restart_after(&msg, ctx);
        }
    }
}

impl Presenter {
    /// Decides about the oldest frame not yet displayed.
    fn evaluate(&mut self, ctx: &mut Context<Self>) {
        if self.closing || self.finished || self.sink_in_flight >= self.max_sink_in_flight {
            return;
        }
        let Some((&frame, &p)) = self.pending.iter().next() else { return };
        // The heuristic times a frame from the start of its computation, so frames that
        // were computed side by side and complete together are not judged by the instant
        // between their displays (a frame after such a burst would be skipped at once, its
        // results all late). A fixed rate, and a frame not started yet, count from the
        // later of its scheduling and the previous display.
        let queued = p.scheduled_at.max(self.last_close_at);
        let start = match (self.pacing, p.started_at) {
            (Pacing::Heuristic(_), Some(started)) => started,
            _ => queued,
        };
        let elapsed = start.elapsed();
        // Around an edit the new view comes first ([`NewView`]): frames of an outdated
        // state are never waited for, the new state's first frame is shown with its first
        // result. Those decisions are the edit's, left out of the frame time as abandoned
        // frames are (judged as if their time were up: shown if good enough).
        let later_has_results = self.pending.range(frame + 1..).any(|(_, later)| later.back > 0);
        let view = NewView { outdated_before: self.outdated_before, last_shown: self.last_shown };
        let around_edit = match self.pacing {
            Pacing::FixedFps(_) => view.decide_fixed_rate(frame, p.back, later_has_results),
            Pacing::Heuristic(_) => view.decide(frame, p.back, later_has_results),
        };
        let abandoned = frame < self.abandoned_before || around_edit.is_some();
        let judged_at = if abandoned { Duration::MAX } else { elapsed };
        let decision = match contain(|| {
            decide(&self.pacing, p.back, p.total, judged_at, self.last_frame_time)
        }) {
            Ok(d) => around_edit.unwrap_or(d),
            Err(msg) => return self.restart_after(&msg, ctx),
        };
        if let Some(t) = self.timer.take() {
            ctx.cancel_future(t);
        }
        tracing::trace!(
            frame,
            back = p.back,
            total = p.total,
            ?elapsed,
            ?decision,
            "display decision"
        );
        match decision {
            Decision::Wait { recheck_at } => {
                let wait = recheck_at.saturating_sub(elapsed).max(Duration::from_micros(100));
                self.timer = Some(ctx.run_later(wait, |act, ctx| {
                    act.timer = None;
                    act.evaluate(ctx);
                }));
            }
            Decision::Show => self.close(frame, false, abandoned, elapsed, p, ctx),
            Decision::Skip => self.close(frame, true, abandoned, elapsed, p, ctx),
        }
    }

    /// Takes `frame` from the assembler; shows it (or only counts it when skipped). The
    /// time an abandoned frame took is not the workers' frame time.
    fn close(
        &mut self,
        frame: FrameNo,
        skip: bool,
        abandoned: bool,
        elapsed: Duration,
        p: Pending,
        ctx: &mut Context<Self>,
    ) {
        self.closing = true;
        let i = interaction(elapsed, self.last_frame_time);
        let q = quality(p.back, p.total);
        self.close_to
            .send(CloseFrame { frame })
            .into_actor(self)
            .map(move |res, act, ctx| {
                act.closing = false;
                act.last_closed = Some(frame);
                act.last_close_at = Instant::now();
                act.pending.retain(|f, _| *f > frame);
                act.displayed_to.do_send(FrameDisplayed { frame });
                match res {
                    Ok(Some(closed)) if !skip => {
                        act.last_shown = Some(frame);
                        if !abandoned {
                            act.last_frame_time = elapsed;
                        }
                        if let Err(msg) = contain(|| act.show(closed, q, i, elapsed)) {
                            return act.restart_after(&msg, ctx);
                        }
                    }
                    other => {
                        if let Ok(Some(closed)) = other {
                            Counters::add(&act.counters.results_unused, u64::from(closed.back));
                        }
                        // The skipped frame's time becomes the last frame's time, so that
                        // when workers slow down I_max grows until frames complete again
                        // (otherwise a fast past would make every frame skip forever).
                        if !abandoned {
                            act.last_frame_time = elapsed;
                        }
                        act.skipped_since_show += 1;
                        act.report.state.lock().unwrap_or_else(|p| p.into_inner()).skipped += 1;
                        act.report.changed.notify_all();
                        tracing::debug!(frame, back = p.back, total = p.total, "frame skipped");
                    }
                }
                act.evaluate(ctx);
            })
            .spawn(ctx);
    }

    /// Accumulates a closed frame, sends it to the sink and publishes its statistics.
    fn show(&mut self, closed: ClosedFrame, q: f64, i: f64, elapsed: Duration) {
        let version = closed.state.version;
        self.accum.add(version);
        self.shown += 1;
        let c = &self.counters;
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
            jobs_total: closed.total,
            q,
            i,
            wait_ms: elapsed.as_secs_f64() * 1e3,
            shown_at_ms: self.started.elapsed().as_secs_f64() * 1e3,
            skipped: std::mem::take(&mut self.skipped_since_show),
            dropped_late: late,
            dropped_duplicate: Counters::get(&c.dropped_duplicate),
            dropped_unknown: Counters::get(&c.dropped_unknown),
            workers: Counters::get(&c.workers),
            paused_workers: Counters::get(&c.paused_workers),
            paused: if Counters::get(&c.paused_workers) > 0 {
                self.workers.paused_list()
            } else {
                Vec::new()
            },
            bytes_in: Counters::get(&c.bytes_in),
            bytes_out: Counters::get(&c.bytes_out),
            shown: self.shown,
            accumulated_frames: self.accum.frames(),
            edits_at: c.edits.shown(version),
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
        if let Some(tx) = &self.sink_tx {
            match tx.try_send(frame) {
                Ok(()) => self.sink_in_flight += 1,
                // Cannot happen while sink_in_flight bounds the channel; never block here.
                Err(TrySendError::Full(_)) => {
                    tracing::warn!(frame = stats.frame, "sink full; frame not shown")
                }
                Err(TrySendError::Disconnected(_)) => tracing::warn!("sink thread gone"),
            }
        }
        {
            let mut r = self.report.state.lock().unwrap_or_else(|p| p.into_inner());
            r.shown = self.shown;
            r.last = Some(stats);
        }
        self.report.changed.notify_all();
        if self.max_frames.is_some_and(|m| self.shown >= m) {
            self.finish(None);
        }
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

    /// After a contained panic: drop the accumulation and wait for the next frame.
    fn restart_after(&mut self, msg: &str, ctx: &mut Context<Self>) {
        let counters = self.counters.clone();
        if after_panic("presenter", msg, &mut self.restarts, &counters, ctx) {
            self.accum = Accumulator::default();
            self.closing = false;
            ctx.run_later(Duration::ZERO, |act, ctx| act.evaluate(ctx));
        }
    }
}
