//! The scheduler actor: the only place that hands out jobs (paper §4.2).
//!
//! It keeps the [`JobQueue`] topped up with whole frames of the latest scene state,
//! serves workers' credits in arrival order, tells the frame assembler about every new
//! frame and every hand-out *before* the job leaves (so a result can never overtake
//! its bookkeeping), and drops queued jobs of frames the display has passed. When the
//! scene state changes it discards the queued jobs of older versions at once and tells
//! the display not to wait for the jobs of those frames still held by workers
//! ([`FramesOutdated`]), so that the first frame of the new state is not queued behind
//! a view the user has left (the edit-to-display latency).

use std::collections::VecDeque;
use std::sync::Arc;

use actix::prelude::*;

use crate::frame_table::ConnId;
use crate::job_queue::{Job, JobQueue};
use crate::protocol::{FrameNo, SetNo};
use crate::state::SceneState;
use crate::stats::Counters;
use crate::supervisor::{after_panic, contain, InjectPanic, RestartPolicy, RestartTracker};

/// The scene state changed: new frames use it.
#[derive(Message, Clone)]
#[rtype(result = "()")]
pub struct StateChanged(pub Arc<SceneState>);

/// A connection's worker can take `credits` more jobs; send them to `jobs_to`.
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerReady {
    pub conn: ConnId,
    pub credits: u32,
    pub jobs_to: Recipient<JobsAssigned>,
}

/// A connection ended or its worker paused; its unserved credits are void (its held
/// jobs are not redone).
#[derive(Message)]
#[rtype(result = "()")]
pub struct WorkerLeft {
    pub conn: ConnId,
}

/// The display shown or skipped `frame`: jobs of it and earlier frames are discarded.
#[derive(Message, Clone, Copy)]
#[rtype(result = "()")]
pub struct FrameDisplayed {
    pub frame: FrameNo,
}

/// To a connection: jobs handed to it.
#[derive(Message)]
#[rtype(result = "()")]
pub struct JobsAssigned(pub Vec<Job>);

/// To the assembler: all sets of `frame` were queued with `state`.
#[derive(Message, Clone)]
#[rtype(result = "()")]
pub struct FrameScheduled {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
}

/// To the assembler: these (frame, set) pairs were handed to `conn`.
#[derive(Message)]
#[rtype(result = "()")]
pub struct JobsHandedOut {
    pub conn: ConnId,
    pub jobs: Vec<(FrameNo, SetNo)>,
}

/// Where the scheduler's events go.
pub struct SchedulerLinks {
    pub frames_to: Recipient<FrameScheduled>,
    pub handouts_to: Recipient<JobsHandedOut>,
    pub abandoned_to: Recipient<FramesAbandoned>,
    pub outdated_to: Recipient<FramesOutdated>,
}

/// To the display: frames before `before` lost their queued jobs (the scheduler
/// restarted) and will get no results beyond those already handed out. Waiting for them
/// says nothing about the workers' speed, so the display decides on them at once.
#[derive(Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct FramesAbandoned {
    pub before: FrameNo,
}

/// To the display: frames before `before` were made with an outdated scene state; their
/// queued jobs were discarded, so only results already held by workers can still come.
/// The display shows such a frame at once with what it has (or skips it when empty)
/// instead of waiting for them.
#[derive(Message, Debug, Clone, Copy)]
#[rtype(result = "()")]
pub struct FramesOutdated {
    pub before: FrameNo,
}

/// The job queue and the workers waiting for jobs.
pub struct Scheduler {
    /// S, queue threshold: what a restart rebuilds the queue from.
    sets: u32,
    threshold: usize,
    queue: JobQueue,
    /// Connections with unserved credits, served front first.
    demand: VecDeque<(ConnId, u32, Recipient<JobsAssigned>)>,
    links: SchedulerLinks,
    counters: Arc<Counters>,
    restarts: RestartTracker,
    /// Discard queued jobs of outdated state versions on a state change (the default;
    /// off only to measure what it gains).
    discard_stale: bool,
}

impl Scheduler {
    pub fn new(
        sets: u32,
        threshold: usize,
        state: Arc<SceneState>,
        links: SchedulerLinks,
        counters: Arc<Counters>,
        policy: RestartPolicy,
    ) -> Self {
        Self {
            discard_stale: true,
            sets,
            threshold,
            queue: JobQueue::new(sets, threshold, state, 0),
            demand: VecDeque::new(),
            links,
            counters,
            restarts: RestartTracker::new(policy),
        }
    }
}

impl Scheduler {
    /// Whether a state change discards the queued jobs of older versions (default: yes).
    pub fn with_stale_discard(mut self, discard: bool) -> Self {
        self.discard_stale = discard;
        self
    }
}

impl Actor for Scheduler {
    type Context = Context<Self>;

    fn started(&mut self, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| s.dispatch());
    }
}

impl Handler<StateChanged> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: StateChanged, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| {
            s.queue.set_state(msg.0);
            if !s.discard_stale {
                return;
            }
            let discarded = s.queue.discard_outdated();
            Counters::add(&s.counters.jobs_discarded_stale, discarded as u64);
            // Every frame scheduled so far is of an older version.
            s.links.outdated_to.do_send(FramesOutdated { before: s.queue.next_frame() });
            tracing::debug!(discarded, "queued jobs of an outdated state discarded");
            s.dispatch();
        });
    }
}

impl Handler<WorkerReady> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: WorkerReady, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| {
            match s.demand.iter_mut().find(|(c, _, _)| *c == msg.conn) {
                Some(entry) => entry.1 += msg.credits,
                None => s.demand.push_back((msg.conn, msg.credits, msg.jobs_to)),
            }
            s.dispatch();
        });
    }
}

impl Handler<WorkerLeft> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: WorkerLeft, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| s.demand.retain(|(c, _, _)| *c != msg.conn));
    }
}

impl Handler<FrameDisplayed> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: FrameDisplayed, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| {
            s.queue.frame_displayed(msg.frame);
            s.dispatch();
        });
    }
}

impl Handler<InjectPanic> for Scheduler {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_| panic!("injected panic in the scheduler"));
    }
}

impl Scheduler {
    /// Tops the queue up and serves waiting credits until one of them runs out.
    fn dispatch(&mut self) {
        loop {
            for f in self.queue.top_up() {
                self.links.frames_to.do_send(FrameScheduled { frame: f.frame, state: f.state });
            }
            let Some((conn, credits, to)) = self.demand.pop_front() else { return };
            let jobs = self.queue.take(credits as usize);
            if jobs.is_empty() {
                self.demand.push_front((conn, credits, to));
                return;
            }
            let left = credits - jobs.len() as u32;
            Counters::add(&self.counters.jobs_handed_out, jobs.len() as u64);
            let pairs = jobs.iter().map(|j| (j.frame, j.set)).collect();
            // Bookkeeping first: the assembler must know before the result can exist.
            self.links.handouts_to.do_send(JobsHandedOut { conn, jobs: pairs });
            to.do_send(JobsAssigned(jobs));
            if left > 0 {
                // Round robin: a worker with credits left waits behind the others.
                self.demand.push_back((conn, left, to));
            }
        }
    }

    /// Runs a handler body; a panic restarts the queue (frame numbers continue, the
    /// jobs it held are lost, never redone) after the policy's back-off.
    fn guarded(&mut self, ctx: &mut Context<Self>, f: impl FnOnce(&mut Self)) {
        if let Err(msg) = contain(|| f(self)) {
            let counters = self.counters.clone();
            if after_panic("scheduler", &msg, &mut self.restarts, &counters, ctx) {
                let state = self.queue.state().clone();
                let first = self.queue.next_frame();
                self.queue = JobQueue::new(self.sets, self.threshold, state, first);
                self.links.abandoned_to.do_send(FramesAbandoned { before: first });
                ctx.notify(Restarted);
            }
        }
    }
}

/// Internal: resume dispatching once the restart back-off is over.
#[derive(Message)]
#[rtype(result = "()")]
struct Restarted;

impl Handler<Restarted> for Scheduler {
    type Result = ();
    fn handle(&mut self, _: Restarted, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s| s.dispatch());
    }
}
