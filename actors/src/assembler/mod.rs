//! The frame assembler actor: frames in flight and the results that fill them (§4.1).
//!
//! It accepts a result only for a frame not yet displayed and a (frame, set) handed out
//! to that connection and not yet answered; everything else is dropped and counted.
//! It reports each frame's progress (Q_t's numerator) to the display: when it is scheduled,
//! when its first job is handed out (the start of the frame's computation, from which the
//! paper's heuristic measures its time) and with every result; and hands a frame over,
//! once, when the display closes it.

pub mod accumulate;
pub mod frame_table;
pub mod packed_frame;
pub mod wait_heuristic;

use std::sync::Arc;

use actix::prelude::*;

use crate::assembler::frame_table::{Admission, ClosedFrame, FrameTable};
use crate::connection::workers::WorkerTable;
use crate::presenter::stats::Counters;
use crate::presenter::FrameProgress;
use crate::scene::state::SceneState;
use crate::scheduler::sets::SetTable;
use crate::supervision::{ActorKind, Guard, InjectPanic, RestartPolicy, Supervised, Supervision};
use crate::wire::protocol::ConnId;
use crate::wire::protocol::{FrameNo, JobResult, SetNo};

/// To the assembler: these (frame, set) pairs were handed to `conn`.
#[derive(Message)]
#[rtype(result = "()")]
pub struct JobsHandedOut {
    pub conn: ConnId,
    pub jobs: Vec<(FrameNo, SetNo)>,
}

/// To the assembler: all sets of `frame` were queued with `state`.
#[derive(Message, Clone)]
#[rtype(result = "()")]
pub struct FrameScheduled {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
}

/// A connection received a well-formed result (pixel count already checked).
#[derive(Message)]
#[rtype(result = "()")]
pub struct ResultArrived {
    pub conn: ConnId,
    pub result: JobResult,
}

/// The display takes `frame` out; it and earlier frames are displayed from now on.
#[derive(Message)]
#[rtype(result = "Option<ClosedFrame>")]
pub struct CloseFrame {
    pub frame: FrameNo,
}

/// The frame table and where progress goes.
pub struct Assembler {
    table: FrameTable,
    progress_to: Recipient<FrameProgress>,
    counters: Arc<Counters>,
    /// Late results are counted per worker too (the status panel).
    workers: Arc<WorkerTable>,
    supervision: Supervision,
}

impl Assembler {
    pub fn new(
        sets: Arc<SetTable>,
        progress_to: Recipient<FrameProgress>,
        counters: Arc<Counters>,
        workers: Arc<WorkerTable>,
        policy: RestartPolicy,
    ) -> Self {
        Self {
            table: FrameTable::new(sets),
            progress_to,
            supervision: Supervision::restarting(ActorKind::Assembler, policy, counters.clone()),
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

    /// A fresh table: frames in flight are lost (and will be skipped), displayed
    /// frames stay refused.
    fn restart(&mut self, _: &mut Context<Self>) {
        self.table = self.table.restarted();
    }
}

impl Handler<FrameScheduled> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: FrameScheduled, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, _| {
            a.table.open(msg.frame, msg.state);
            a.report_progress(msg.frame);
        });
    }
}

impl Handler<JobsHandedOut> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: JobsHandedOut, ctx: &mut Context<Self>) {
        self.guarded(ctx, |a, _| {
            for (frame, set) in msg.jobs {
                let first = !a.table.started(frame);
                if a.table.handed_out(frame, set, msg.conn) {
                    tracing::error!(frame, set, "a job was handed out twice");
                    Counters::add(&a.counters.jobs_handed_twice, 1);
                }
                if first {
                    a.report_progress(frame);
                }
            }
        });
    }
}

impl Handler<ResultArrived> for Assembler {
    type Result = ();
    fn handle(&mut self, msg: ResultArrived, ctx: &mut Context<Self>) {
        self.guarded(ctx, move |a, _| {
            let JobResult { frame, set, state_version, radiance, .. } = msg.result;
            let admission = a.table.accept(msg.conn, frame, set, state_version, radiance);
            let c = &a.counters;
            match admission {
                Admission::Accepted { back, total } => {
                    Counters::add(&c.results_accepted, 1);
                    let started = true;
                    a.progress_to.do_send(FrameProgress {
                        frame,
                        state_version,
                        back,
                        total,
                        started,
                    });
                }
                Admission::Late => {
                    Counters::add(&c.dropped_late, 1);
                    a.workers.late(msg.conn);
                }
                Admission::Duplicate => Counters::add(&c.dropped_duplicate, 1),
                Admission::Unknown => Counters::add(&c.dropped_unknown, 1),
            }
            if !matches!(admission, Admission::Accepted { .. }) {
                tracing::debug!(conn = msg.conn, frame, set, ?admission, "result dropped");
            }
        });
    }
}

impl Handler<CloseFrame> for Assembler {
    type Result = Option<ClosedFrame>;
    fn handle(&mut self, msg: CloseFrame, ctx: &mut Context<Self>) -> Option<ClosedFrame> {
        self.guarded(ctx, |a, _| a.table.close(msg.frame)).flatten()
    }
}

impl Handler<InjectPanic> for Assembler {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the frame assembler"));
    }
}

impl Assembler {
    /// Tells the display how far an open frame is.
    fn report_progress(&self, frame: FrameNo) {
        if let (Some((back, total)), Some(state_version)) =
            (self.table.progress(frame), self.table.version(frame))
        {
            let started = self.table.started(frame);
            self.progress_to.do_send(FrameProgress { frame, state_version, back, total, started });
        }
    }
}
