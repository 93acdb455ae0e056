//! The frame assembler actor: a frame's whole life, from its scheduling to its display
//! (paper §4.1, §4.3).
//!
//! It keeps the frames in flight and the results that fill them ([`FrameTable`]), decides
//! when the oldest is shown or skipped ([`Pacer`]: the wait heuristic, its deadlines and
//! the rule around edits) and, once it is, pushes it one way to the presenter
//! ([`FrameShown`], [`FrameSkipped`]) and tells the scheduler ([`FrameDisplayed`]). Results
//! come from connections already checked there; here they are judged only by time
//! (late, or for a frame lost in a restart). The sink's back-pressure is a count of the
//! frames handed over and not yet freed ([`SinkFreed`]): no frame is decided while the
//! sink holds its most.

pub mod accumulation;
pub mod frame_table;
pub mod new_view;
pub mod pacer;
pub mod wait_heuristic;

use std::sync::Arc;
use std::time::{Duration, Instant};

use actix::prelude::*;

use crate::assembler::accumulation::Accumulation;
use crate::assembler::frame_table::{Admission, FrameTable};
use crate::assembler::pacer::{Judgement, Pacer};
use crate::assembler::wait_heuristic::Decision;
use crate::messages::{
    FrameDisplayed, FrameScheduled, FrameShown, FrameSkipped, FrameStarted, FramesAbandoned,
    FramesOutdated, PrepareState, ResultArrived, SetPacing, SinkFreed,
};
use crate::shared::counters::Counters;
use crate::shared::pacing::{Pacing, PacingError};
use crate::shared::sets::SetTables;
use crate::shared::workers::WorkerTable;
use crate::supervision::{
    ActorKind, Guard, GuardedTimers, InjectPanic, RestartPolicy, Supervised, Supervision,
};
use crate::wire::protocol::{FrameNo, JobResult};

/// How the assembler paces and how far ahead of the sink it may be.
#[derive(Clone, Copy, Debug)]
pub struct AssemblerConfig {
    pub pacing: Pacing,
    /// I_t's denominator before the first frame was displayed.
    pub initial_frame_time: Duration,
    /// Frames handed to the sink and not yet shown, at most (at least 1).
    pub sink_in_flight: usize,
    pub policy: RestartPolicy,
}

/// Where displayed frames go.
pub struct AssemblerLinks {
    pub shown_to: Recipient<FrameShown>,
    pub skipped_to: Recipient<FrameSkipped>,
    /// Every new scene state at once (the sink computes its G-buffer ahead).
    pub prepare_to: Recipient<PrepareState>,
}

/// The frames in flight, their pacing and where they go.
pub struct Assembler {
    table: FrameTable,
    pacer: Pacer,
    /// Shown frames per scene state, decided here once for the stats and the sink.
    accumulation: Accumulation,
    /// The wait heuristic's next deadline.
    timer: Option<SpawnHandle>,
    sink_in_flight: usize,
    max_sink_in_flight: usize,
    links: AssemblerLinks,
    /// The scheduler, as its last [`FrameScheduled`] named it.
    displayed_to: Option<Recipient<FrameDisplayed>>,
    counters: Arc<Counters>,
    /// Late results are counted per worker too (the status panel).
    workers: Arc<WorkerTable>,
    supervision: Supervision,
}

impl Assembler {
    pub fn new(
        sets: Arc<SetTables>,
        config: AssemblerConfig,
        links: AssemblerLinks,
        counters: Arc<Counters>,
        workers: Arc<WorkerTable>,
    ) -> Self {
        Self {
            table: FrameTable::new(sets),
            pacer: Pacer::new(config.pacing, config.initial_frame_time, Instant::now()),
            accumulation: Accumulation::default(),
            timer: None,
            sink_in_flight: 0,
            max_sink_in_flight: config.sink_in_flight.max(1),
            links,
            displayed_to: None,
            supervision: Supervision::restarting(
                ActorKind::Assembler,
                config.policy,
                counters.clone(),
            ),
            counters,
            workers,
        }
    }
}

impl Actor for Assembler {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.start_guarded(ctx);
    }
}

impl Supervised for Assembler {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    /// Decides on the oldest frame (after a restart: the frames the fresh table lost are
    /// skipped).
    fn on_start(&mut self, ctx: &mut Context<Self>) {
        self.evaluate(ctx);
    }

    /// A fresh table: frames in flight are lost, displayed frames stay refused. The lost
    /// frames can take no result: they are skipped at once and left out of the frame
    /// time, as frames whose jobs a scheduler restart lost are. Judged like any other,
    /// each would wait I_max times the frame time, and each skip would stretch the next
    /// one's wait (the soak's longest blank screens, 2–4.6 s, began at this restart).
    fn restart(&mut self, _: &mut Context<Self>) {
        self.table = self.table.restarted();
        if let Some(newest) = self.table.newest() {
            self.pacer.abandoned(newest + 1);
        }
    }
}

impl Handler<FrameScheduled> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: FrameScheduled, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, ctx| {
            a.displayed_to = Some(msg.displayed_to);
            a.table.open(msg.frame, msg.state, msg.spp, Instant::now());
            a.evaluate(ctx);
        });
    }
}

impl Handler<FrameStarted> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: FrameStarted, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, ctx| {
            a.table.start(msg.frame, Instant::now());
            a.evaluate(ctx);
        });
    }
}

impl Handler<ResultArrived> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: ResultArrived, ctx: &mut Context<Self>) {
        self.guarded(ctx, move |a, ctx| {
            let JobResult { frame, set, radiance, .. } = msg.result;
            let admission = a.table.accept(msg.conn, frame, set, radiance);
            let c = &a.counters;
            match admission {
                Admission::Accepted { .. } => {
                    Counters::add(&c.results_accepted, 1);
                    a.evaluate(ctx);
                }
                Admission::Late => {
                    Counters::add(&c.dropped_late, 1);
                    a.workers.late(msg.conn);
                }
                Admission::Unknown => Counters::add(&c.dropped_unknown, 1),
                Admission::HandedTwice => {
                    tracing::error!(frame, set, "a job was handed out twice");
                    Counters::add(&c.jobs_handed_twice, 1);
                }
            }
            if !matches!(admission, Admission::Accepted { .. }) {
                tracing::debug!(conn = msg.conn, frame, set, ?admission, "result dropped");
            }
        });
    }
}

impl Handler<FramesOutdated> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: FramesOutdated, ctx: &mut Context<Self>) {
        self.links.prepare_to.do_send(PrepareState(msg.state));
        self.guarded(ctx, |a, ctx| {
            a.pacer.outdated(msg.before);
            a.evaluate(ctx);
        });
    }
}

impl Handler<FramesAbandoned> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: FramesAbandoned, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, ctx| {
            a.pacer.abandoned(msg.before);
            a.evaluate(ctx);
        });
    }
}

impl Handler<SetPacing> for Assembler {
    type Result = Result<(), PacingError>;
    fn handle(&mut self, msg: SetPacing, ctx: &mut Context<Self>) -> Self::Result {
        msg.0.validate()?;
        // A looser bound may show the waiting frame at once; a tighter one re-arms the timer.
        self.guarded(ctx, |a, ctx| {
            a.pacer.set_pacing(msg.0);
            a.evaluate(ctx);
        });
        Ok(())
    }
}

impl Handler<SinkFreed> for Assembler {
    type Result = ();
    fn handle(&mut self, _: SinkFreed, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, ctx| {
            a.sink_in_flight = a.sink_in_flight.saturating_sub(1);
            a.evaluate(ctx);
        });
    }
}

impl Handler<InjectPanic> for Assembler {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the frame assembler"));
    }
}

impl Assembler {
    /// Decides about the oldest frame not yet displayed, and the next ones while they
    /// are decided at once; else arms the timer for the heuristic's next deadline.
    fn evaluate(&mut self, ctx: &mut Context<Self>) {
        if let Some(t) = self.timer.take() {
            ctx.cancel_future(t);
        }
        while self.sink_in_flight < self.max_sink_in_flight {
            let Some((frame, progress)) = self.table.oldest() else { return };
            let later = self.table.later_has_results(frame);
            let now = Instant::now();
            let j = self.pacer.judge(frame, &progress, later, now);
            tracing::trace!(frame, back = progress.back, total = progress.total,
                elapsed = ?j.elapsed, decision = ?j.decision, "display decision");
            match j.decision {
                Decision::Wait { recheck_at } => {
                    let wait = recheck_at.saturating_sub(j.elapsed).max(Duration::from_micros(100));
                    self.timer = Some(ctx.run_later_guarded(wait, |a, ctx| {
                        a.timer = None;
                        a.evaluate(ctx);
                    }));
                    return;
                }
                Decision::Show => self.display(frame, true, &j, now, ctx),
                Decision::Skip => self.display(frame, false, &j, now, ctx),
            }
        }
    }

    /// Takes `frame` out of the table, pushes it to the presenter (shown or skipped) and
    /// tells the scheduler.
    fn display(
        &mut self,
        frame: FrameNo,
        show: bool,
        j: &Judgement,
        now: Instant,
        ctx: &mut Context<Self>,
    ) {
        let Some(closed) = self.table.close(frame) else { return };
        self.pacer.displayed(frame, show, j, now);
        if let Some(to) = &self.displayed_to {
            to.do_send(FrameDisplayed { frame });
        }
        if show {
            let accumulated_frames = self.accumulation.add(closed.state.version);
            self.sink_in_flight += 1;
            self.links.shown_to.do_send(FrameShown {
                closed,
                q: j.q,
                i: j.i,
                wait: j.elapsed,
                accumulated_frames,
                freed_to: ctx.address().recipient(),
            });
        } else {
            let (back, total) = (closed.back, closed.total);
            tracing::debug!(frame, back, total, "frame skipped");
            self.links.skipped_to.do_send(FrameSkipped { frame, back });
        }
    }
}
