//! The scheduler actor: the only place that hands out jobs (paper §4.2).
//!
//! It keeps the [`JobQueue`] topped up with frames of the latest scene state (each with the
//! quota of sets the frame assembler can use), serves workers' credits in arrival order,
//! each job from the frame the [`HandOutPlan`] says its result will be in time for, tells
//! the frame assembler about every new frame before any of its jobs leaves and about its
//! first hand-out (which times it), and drops queued jobs of frames already displayed.
//! Who holds which job is kept in one record ([`HeldJobs`]): the scheduler enters each
//! job it hands out, the connection that holds it takes it back out (answered, dropped,
//! lost) and checks its results against it, and the plan reads it. The frame window
//! grows with the credits and jobs the grid holds. When the scene state changes it
//! discards the queued jobs of older versions at once and tells the assembler not to
//! wait for the jobs of those frames still held by workers ([`FramesOutdated`]), so that
//! the first frame of the new state is not queued behind a view the user has left (the
//! edit-to-display latency).
//!
//! Jobs are sized to the live grid ([`JobSize`]): every [`job_size::REVIEW_PERIOD`] the
//! scheduler measures what its own thread (the actor thread, which every connection,
//! the assembler and the presenter share) spent (running or waiting for a core) and
//! received per result, and with the
//! workers' render times and the inbound link's rate decides how many samples per pixel
//! the jobs of the frames it opens next take, so that the grid never returns more results
//! per second than the master can take in or its link carries.

pub mod handout_plan;
pub mod job_queue;
pub mod job_size;

use std::collections::VecDeque;
use std::sync::Arc;
use std::time::Instant;

use actix::prelude::*;

use crate::messages::{
    FrameDisplayed, FrameScheduled, FrameStarted, FramesAbandoned, FramesOutdated, JobAnswered,
    JobsAssigned, PacingChanged, StateChanged, WorkerLeft, WorkerReady,
};
use crate::scene::state::SceneState;
use crate::scheduler::handout_plan::HandOutPlan;
use crate::scheduler::job_queue::{JobQueue, NewFrame};
use crate::scheduler::job_size::{JobSize, MasterSample, REVIEW_PERIOD};
use crate::shared::counters::Counters;
use crate::shared::cpu_clock::thread_busy_seconds;
use crate::shared::holdings::{HeldJob, HeldJobs};
use crate::shared::job::Job;
use crate::shared::pacing::Pacing;
use crate::supervision::{
    ActorKind, Guard, GuardedTimers, InjectPanic, RestartPolicy, Supervised, Supervision,
};
use crate::wire::protocol::ConnId;
use crate::wire::protocol::FrameNo;

/// Most frames in flight however large the grid (each holds a frame table slot).
const MAX_FRAME_WINDOW: u64 = 64;

/// Where the scheduler's events go.
pub struct SchedulerLinks {
    pub frames_to: Recipient<FrameScheduled>,
    pub started_to: Recipient<FrameStarted>,
    pub abandoned_to: Recipient<FramesAbandoned>,
    pub outdated_to: Recipient<FramesOutdated>,
}

/// The job queue and the workers waiting for jobs.
pub struct Scheduler {
    /// S, queue threshold: what a restart rebuilds the queue from.
    sets: u32,
    threshold: usize,
    queue: JobQueue,
    /// Which frame each job should come from.
    plan: HandOutPlan,
    /// How many samples per pixel the jobs of the next frames take.
    size: JobSize,
    /// Results answered so far, and the actor thread's CPU time, the results and the bytes
    /// received at the last review.
    answered: u64,
    last_review: (f64, u64, u64),
    review_timer: Option<SpawnHandle>,
    /// Who holds which job: the master's one record, shared with the connections.
    held: Arc<HeldJobs>,
    /// Connections with unserved credits, served front first.
    demand: VecDeque<(ConnId, u32, Recipient<JobsAssigned>)>,
    links: SchedulerLinks,
    /// This actor's own address, named in [`FrameScheduled`] for the reply.
    me: Option<Recipient<FrameDisplayed>>,
    counters: Arc<Counters>,
    supervision: Supervision,
    /// Discard queued jobs of outdated state versions on a state change (the default;
    /// off only to measure what it gains).
    discard_stale: bool,
}

/// Construction parameters of the scheduler.
pub struct SchedulerConfig {
    /// S: sets per frame.
    pub sets: u32,
    /// Jobs queued below which a new frame is added.
    pub threshold: usize,
    pub pacing: Pacing,
    pub policy: RestartPolicy,
    /// The master's inbound link, in bytes per second, when known (`--link-mbps`): results
    /// never ask for more ([`JobSize`]).
    pub link_bytes_per_second: Option<f64>,
}

impl Scheduler {
    pub fn new(
        config: SchedulerConfig,
        state: Arc<SceneState>,
        links: SchedulerLinks,
        counters: Arc<Counters>,
        held: Arc<HeldJobs>,
    ) -> Self {
        let SchedulerConfig { sets, threshold, pacing, policy, link_bytes_per_second } = config;
        let plan = HandOutPlan::new(pacing);
        let set_pixels = state.resolution.pixels().div_ceil(sets.max(1) as usize);
        let size = JobSize::new(state.render.spp, link_bytes_per_second, set_pixels);
        let mut queue = JobQueue::new(sets, threshold, state, 0);
        queue.set_quota(plan.quota(sets));
        Self {
            size,
            answered: 0,
            last_review: (f64::NAN, 0, 0),
            review_timer: None,
            discard_stale: true,
            sets,
            threshold,
            queue,
            plan,
            held,
            demand: VecDeque::new(),
            links,
            supervision: Supervision::restarting(ActorKind::Scheduler, policy, counters.clone()),
            me: None,
            counters,
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
        self.start_guarded(ctx);
    }
}

impl Supervised for Scheduler {
    fn supervision(&mut self) -> &mut Supervision {
        &mut self.supervision
    }

    fn on_start(&mut self, ctx: &mut Context<Self>) {
        self.me = Some(ctx.address().recipient());
        if let Some(timer) = self.review_timer.take() {
            ctx.cancel_future(timer); // a restart starts it again
        }
        self.last_review = self.master_now();
        self.review_timer = Some(ctx.run_interval_guarded(REVIEW_PERIOD, |s, _| s.review()));
        self.dispatch();
    }

    /// A fresh queue: frame numbers continue, the jobs it held are lost (never redone)
    /// and the presenter decides on their frames at once.
    fn restart(&mut self, _: &mut Context<Self>) {
        let state = self.queue.state().clone();
        let first = self.queue.next_frame();
        self.queue = JobQueue::new(self.sets, self.threshold, state, first);
        self.queue.set_quota(self.plan.quota(self.sets));
        self.queue.set_spp(self.size.spp());
        self.links.abandoned_to.do_send(FramesAbandoned { before: first });
    }
}

impl Handler<StateChanged> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: StateChanged, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| {
            s.queue.set_state(msg.0);
            if !s.discard_stale {
                return;
            }
            let discarded = s.queue.discard_outdated();
            Counters::add(&s.counters.jobs_discarded_stale, discarded as u64);
            // Every frame scheduled so far is of an older version.
            let (before, state) = (s.queue.next_frame(), Arc::clone(s.queue.state()));
            s.links.outdated_to.do_send(FramesOutdated { before, state });
            tracing::debug!(discarded, "queued jobs of an outdated state discarded");
            s.dispatch();
        });
    }
}

impl Handler<WorkerReady> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: WorkerReady, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| {
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
        self.guarded(ctx, |s, _| {
            s.demand.retain(|(c, _, _)| *c != msg.conn);
            // Its jobs are lost: other sets of those frames make up their quota.
            // Jobs handed out while its end was on the way never reached it: lost too.
            let late = s.held.lock().release(msg.conn);
            for frame in msg.lost.into_iter().chain(late.iter().map(|h| h.frame)) {
                s.queue.queue_more(frame, 1);
            }
            s.plan.left(msg.conn);
            s.size.left(msg.conn);
            s.dispatch();
        });
    }
}

impl Handler<JobAnswered> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: JobAnswered, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| {
            s.plan.answered(msg.conn, msg.handed_at, Instant::now());
            s.size.answered(msg.conn, msg.frame, msg.render_us);
            s.answered += 1;
        });
    }
}

impl Handler<PacingChanged> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: PacingChanged, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| {
            s.plan.set_pacing(msg.0);
            s.queue.set_quota(s.plan.quota(s.sets));
            s.dispatch();
        });
    }
}

impl Handler<FrameDisplayed> for Scheduler {
    type Result = ();
    fn handle(&mut self, msg: FrameDisplayed, ctx: &mut Context<Self>) {
        self.guarded(ctx, |s, _| {
            s.queue.frame_displayed(msg.frame);
            s.plan.displayed(msg.frame, Instant::now());
            s.dispatch();
        });
    }
}

impl Handler<InjectPanic> for Scheduler {
    type Result = ();
    fn handle(&mut self, _: InjectPanic, ctx: &mut Context<Self>) {
        self.guarded(ctx, |_, _| panic!("injected panic in the scheduler"));
    }
}

impl Scheduler {
    /// The actor thread's busy time, the results answered and the bytes received so far.
    fn master_now(&self) -> (f64, u64, u64) {
        (thread_busy_seconds(), self.answered, Counters::get(&self.counters.bytes_in))
    }

    /// Measures what the master spent and received per result since the last review and
    /// sizes the jobs of the frames opened from now on.
    fn review(&mut self) {
        let now = self.master_now();
        let (cpu, results, bytes) = self.last_review;
        let sample = MasterSample {
            busy_seconds: now.0 - cpu,
            results: now.1.saturating_sub(results),
            bytes: now.2.saturating_sub(bytes),
        };
        self.size.observe_master(sample);
        self.last_review = now;
        let before = self.queue.spp();
        let spp = self.size.review(self.queue.next_frame());
        if spp != before {
            tracing::info!(
                spp,
                before,
                grid_rate = self.size.grid_rate(),
                affordable = self.size.affordable(),
                "job size changed"
            );
            self.queue.set_spp(spp);
        }
    }

    /// Serves every waiting connection in turn, each job from the frame the plan chooses
    /// for it; a connection that no queued frame suits keeps its credits for later.
    fn dispatch(&mut self) {
        let now = Instant::now();
        let credits: usize = self.demand.iter().map(|(_, n, _)| *n as usize).sum();
        let quota = self.plan.quota(self.sets) as usize;
        // Enough frames in flight for every credit and held job of the grid, plus two, and
        // at a fixed rate as far ahead as the slowest worker's next result.
        let window = {
            let held = self.held.lock();
            (credits + held.total()).div_ceil(quota) as u64 + 2 + self.plan.frames_ahead(&held, now)
        };
        self.queue.set_frame_window(window.min(MAX_FRAME_WINDOW));
        for _ in 0..self.demand.len() {
            let Some((conn, credits, to)) = self.demand.pop_front() else { return };
            let jobs = self.take_for(conn, credits, now);
            let left = credits - jobs.len() as u32;
            if !jobs.is_empty() {
                Counters::add(&self.counters.jobs_handed_out, jobs.len() as u64);
                to.do_send(JobsAssigned(jobs));
            }
            if left > 0 {
                // Round robin: a worker with credits left waits behind the others.
                self.demand.push_back((conn, left, to));
            }
        }
    }

    /// Up to `credits` jobs for `conn`, topping the queue up as it empties, and opening
    /// later frames (as far as the window allows) when no queued one is in time for it.
    fn take_for(&mut self, conn: ConnId, credits: u32, now: Instant) -> Vec<Job> {
        let mut jobs = Vec::new();
        while jobs.len() < credits as usize {
            self.top_up();
            let mut frame = self.choose(conn, now);
            while !frame.is_some_and(|f| self.plan.fits(conn, self.held.lock().of(conn), f, now)) {
                let Some(f) = self.queue.open_frame() else { break };
                self.scheduled(f);
                frame = self.choose(conn, now);
            }
            let Some(job) = frame.and_then(|f| self.queue.take_from(f)) else { break };
            let (frame, set, version) = (job.frame, job.set, job.state.version);
            let resolution = job.state.resolution;
            let held = HeldJob { frame, set, version, resolution, handed_at: now };
            self.held.lock().hand(conn, held);
            if self.plan.handed(conn, job.frame, now) {
                self.links.started_to.do_send(FrameStarted { frame: job.frame });
            }
            jobs.push(job);
        }
        jobs
    }

    /// The frame the plan chooses for `conn`'s next job among the queued ones.
    fn choose(&self, conn: ConnId, now: Instant) -> Option<FrameNo> {
        self.plan.choose(conn, self.held.lock().of(conn), &self.queue.frames(), now)
    }

    /// Adds frames to the queue and tells the assembler about them.
    fn top_up(&mut self) {
        for f in self.queue.top_up() {
            self.scheduled(f);
        }
    }

    /// Tells the assembler about a new frame, before any of its jobs can leave.
    fn scheduled(&self, f: NewFrame) {
        if let Some(me) = &self.me {
            let displayed_to = me.clone();
            let NewFrame { frame, state, spp } = f;
            self.links.frames_to.do_send(FrameScheduled { frame, state, spp, displayed_to });
        }
    }
}
