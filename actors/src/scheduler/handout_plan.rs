//! Which frame a worker's next job comes from (docs/design.md, decision 8): pure logic behind
//! the scheduler.
//!
//! A result is used only if it arrives before its frame is displayed; a late one was
//! rendered for nothing. With S = 64, k = 2, the wait heuristic and null workers that take
//! 200 ms per job, only 0.67 of the returned results were used with 8 workers, 0.50 with 32
//! and 0.30 with 128 (`gridlight bench waste`): the queue handed out every set of every
//! frame, in order, to whoever asked. Two rules now keep results from being late:
//!
//! - **Quota.** The wait heuristic shows a frame as soon as Q_max of its jobs are back, so
//!   every job handed out beyond ⌈Q_max·S⌉ of one frame is late by construction (the
//!   counts above are N·k/S jobs in flight past that point). The queue takes only
//!   [`HandOutPlan::quota`] sets of each frame (other sets in the next frame: the queue
//!   rotates where frames start). At a fixed rate any result in time is used: the quota is S.
//! - **Deadline.** Each connection's job time is measured: the time from the later of a
//!   job's hand-out and the connection's previous result to its result (a worker renders its
//!   jobs in order), smoothed. A job handed out now is predicted to arrive at
//!   max(now, the predicted arrival of the connection's last held job) + its job time, and
//!   goes to the oldest open frame whose display is forecast later than that; else to a
//!   later frame. At a fixed rate frame f is shown at t_d + (f − d)·period after frame d
//!   was displayed at t_d. Under the heuristic a frame can be shown, if Q_min of it is
//!   back, I_min times the last frame's time after its first hand-out, so that is its
//!   deadline. The frame window grows with the grid so that every credit can be served.
//!
//! Job times are measured whatever the job's samples per pixel (`job_size`): when the job
//! size changes, the smoothed estimate follows within a few results; the size changes
//! in steps, rarely, so forecasts are off only briefly.
//!
//! A connection that holds nothing always gets a job (of the newest open frame when none
//! fits), so a worker that once looked slow keeps being measured. Nothing here redoes a
//! job: the plan only chooses among sets not handed out yet.
//!
//! The plan owns no job. Which jobs a connection holds, and since when, is read from the
//! master's one record of it ([`Holdings`]), passed in with each question: a job its
//! worker dropped (`Superseded`) or lost leaves the record, and so every forecast, at once.

use std::collections::{BTreeMap, HashMap};
use std::time::{Duration, Instant};

use crate::shared::holdings::{HeldJob, Holdings};
use crate::shared::pacing::Pacing;
use crate::wire::protocol::{ConnId, FrameNo};

/// Weight of a new job-time sample in the running estimate.
const JOB_TIME_GAIN: f64 = 0.25;

/// What is known of one connection's speed.
#[derive(Debug, Default)]
struct ConnClock {
    /// Smoothed time one job takes; `None` until its first result.
    job_time: Option<Duration>,
    last_result: Option<Instant>,
}

/// The last frame the assembler showed or skipped.
#[derive(Clone, Copy, Debug)]
struct Displayed {
    frame: FrameNo,
    at: Instant,
    /// From its first hand-out to its display (`None` when none of it was handed out).
    took: Option<Duration>,
}

/// Per-connection job times, first hand-outs and display times: where a job is useful.
#[derive(Debug)]
pub struct HandOutPlan {
    pacing: Pacing,
    conns: HashMap<ConnId, ConnClock>,
    /// First hand-out of every frame not yet displayed.
    started: BTreeMap<FrameNo, Instant>,
    last: Option<Displayed>,
}

impl HandOutPlan {
    pub fn new(pacing: Pacing) -> Self {
        Self { pacing, conns: HashMap::new(), started: BTreeMap::new(), last: None }
    }

    /// The display paces frames this way from now on.
    pub fn set_pacing(&mut self, pacing: Pacing) {
        self.pacing = pacing;
    }

    /// Jobs of one frame worth handing out when a frame has `sets` sets.
    pub fn quota(&self, sets: u32) -> u32 {
        match self.pacing {
            Pacing::Heuristic(h) => ((h.q_max * f64::from(sets)).ceil() as u32).clamp(1, sets),
            Pacing::FixedFps(_) => sets,
        }
        .max(1)
    }

    /// The frame, among `open` (frames with sets left, oldest first), that `conn`'s next
    /// job should come from at `now`, `conn` holding `held`; `None` when it should wait
    /// for a later frame.
    pub fn choose(
        &self,
        conn: ConnId,
        held: &[HeldJob],
        open: &[FrameNo],
        now: Instant,
    ) -> Option<FrameNo> {
        match open.iter().find(|f| self.fits(conn, held, **f, now)) {
            Some(&f) => Some(f),
            None if held.is_empty() => open.last().copied(),
            None => None,
        }
    }

    /// Whether a job of `frame` handed at `now` to `conn`, holding `held`, is forecast to
    /// come back before the frame is displayed (true when either cannot be forecast yet).
    pub fn fits(&self, conn: ConnId, held: &[HeldJob], frame: FrameNo, now: Instant) -> bool {
        match (self.arrival(conn, held, now), self.deadline(frame, now)) {
            (Some(a), Some(d)) => a <= d,
            _ => true,
        }
    }

    /// `conn` was handed a job of `frame` at `now`. True when it is the frame's first
    /// hand-out: the start of its computation.
    pub fn handed(&mut self, conn: ConnId, frame: FrameNo, now: Instant) -> bool {
        let mut first = false;
        if self.last.is_none_or(|d| frame > d.frame) {
            self.started.entry(frame).or_insert_with(|| {
                first = true;
                now
            });
        }
        self.conns.entry(conn).or_default();
        first
    }

    /// `conn` returned at `now` the result of a job handed out at `handed_at` (in time or
    /// not): a sample of its job time, from the later of the hand-out and its previous
    /// result (a worker renders its jobs in order).
    pub fn answered(&mut self, conn: ConnId, handed_at: Instant, now: Instant) {
        let Some(c) = self.conns.get_mut(&conn) else { return };
        let began = c.last_result.map_or(handed_at, |r| r.max(handed_at));
        let sample = now.saturating_duration_since(began);
        c.job_time = Some(match c.job_time {
            Some(t) => t.mul_f64(1.0 - JOB_TIME_GAIN) + sample.mul_f64(JOB_TIME_GAIN),
            None => sample,
        });
        c.last_result = Some(now);
    }

    /// `conn` is gone (or paused): what was measured of it is forgotten.
    pub fn left(&mut self, conn: ConnId) {
        self.conns.remove(&conn);
    }

    /// The display shown or skipped `frame` (and so every earlier one) at `now`.
    pub fn displayed(&mut self, frame: FrameNo, now: Instant) {
        if self.last.is_some_and(|d| frame <= d.frame) {
            return;
        }
        let took = self.started.get(&frame).map(|s| now.saturating_duration_since(*s));
        self.started.retain(|f, _| *f > frame);
        self.last = Some(Displayed { frame, at: now, took });
    }

    /// At a fixed rate, how many frame periods ahead the slowest connection's next result
    /// arrives, the connections holding `holdings`: the frame window must reach that far
    /// for its job to be in time (0 under the heuristic, which waits for results).
    pub fn frames_ahead(&self, holdings: &Holdings, now: Instant) -> u64 {
        let Pacing::FixedFps(fps) = self.pacing else { return 0 };
        let lead = self
            .conns
            .keys()
            .filter_map(|c| self.arrival(*c, holdings.of(*c), now))
            .map(|a| a.saturating_duration_since(now))
            .max()
            .unwrap_or_default();
        (lead.as_secs_f64() * f64::from(fps)).ceil() as u64
    }

    /// When a job handed at `now` to `conn`, holding `held`, should come back; `None`
    /// before it answered once. Its worker renders what it holds first, in order, each
    /// job from the later of its hand-out and the previous one's forecast result.
    pub fn arrival(&self, conn: ConnId, held: &[HeldJob], now: Instant) -> Option<Instant> {
        let c = self.conns.get(&conn)?;
        let t = c.job_time?;
        let mut free = c.last_result;
        for h in held {
            free = Some(free.map_or(h.handed_at, |f| f.max(h.handed_at)) + t);
        }
        Some(free.map_or(now, |f| f.max(now)) + t)
    }

    /// The latest arrival at which a result of `frame` is still forecast to be used;
    /// `None` when nothing can be forecast yet (no frame displayed).
    pub fn deadline(&self, frame: FrameNo, now: Instant) -> Option<Instant> {
        let last = self.last?;
        if frame <= last.frame {
            return Some(last.at); // displayed already: nothing is in time
        }
        match self.pacing {
            Pacing::FixedFps(fps) => {
                let period = Duration::from_secs_f64(1.0 / f64::from(fps));
                Some(last.at + period.mul_f64((frame - last.frame) as f64))
            }
            Pacing::Heuristic(h) => {
                let start = self.started.get(&frame).copied().unwrap_or(now);
                Some(start + last.took?.mul_f64(h.i_min))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::state::Resolution;
    use crate::shared::pacing::Heuristic;
    use crate::wire::protocol::SetNo;

    const MS: Duration = Duration::from_millis(1);

    fn heuristic_plan() -> HandOutPlan {
        HandOutPlan::new(Pacing::Heuristic(Heuristic::default()))
    }

    /// The plan with the record of held jobs beside it, kept as the scheduler (hand-outs)
    /// and the connections (results, dropped jobs) keep them.
    struct Grid {
        plan: HandOutPlan,
        held: Holdings,
    }

    impl Grid {
        fn new(pacing: Pacing) -> Self {
            Self { plan: HandOutPlan::new(pacing), held: Holdings::default() }
        }

        fn heuristic() -> Self {
            Self { plan: heuristic_plan(), held: Holdings::default() }
        }

        /// The scheduler hands `(frame, set)` to `conn` at `at`; true for the frame's first.
        fn hand(&mut self, conn: ConnId, frame: FrameNo, set: SetNo, at: Instant) -> bool {
            let resolution = Resolution { width: 8, height: 8 };
            self.held.hand(conn, HeldJob { frame, set, version: 1, resolution, handed_at: at });
            self.plan.handed(conn, frame, at)
        }

        /// `conn`'s result for `(frame, set)` comes at `at`.
        fn answer(&mut self, conn: ConnId, frame: FrameNo, set: SetNo, at: Instant) {
            let job = self.held.take(conn, frame, set).expect("a held job");
            self.plan.answered(conn, job.handed_at, at);
        }

        fn choose(&self, conn: ConnId, open: &[FrameNo], now: Instant) -> Option<FrameNo> {
            self.plan.choose(conn, self.held.of(conn), open, now)
        }

        fn fits(&self, conn: ConnId, frame: FrameNo, now: Instant) -> bool {
            self.plan.fits(conn, self.held.of(conn), frame, now)
        }

        fn arrival(&self, conn: ConnId, now: Instant) -> Option<Instant> {
            self.plan.arrival(conn, self.held.of(conn), now)
        }
    }

    /// A connection that answered one job taking `ms`, at `t0 + ms`.
    fn measured(grid: &mut Grid, conn: ConnId, t0: Instant, ms: u32) {
        grid.hand(conn, 0, conn as SetNo, t0);
        grid.answer(conn, 0, conn as SetNo, t0 + MS * ms);
    }

    #[test]
    fn the_heuristic_quota_is_what_shows_a_frame_and_a_fixed_rate_uses_every_set() {
        assert_eq!(heuristic_plan().quota(64), 32, "Q_max = 0.5 of 64 sets");
        assert_eq!(heuristic_plan().quota(5), 3, "rounded up: 2 of 5 would not reach Q_max");
        let complete = Heuristic { q_min: 1.0, q_max: 1.0, ..Heuristic::default() };
        assert_eq!(HandOutPlan::new(Pacing::Heuristic(complete)).quota(64), 64);
        assert_eq!(HandOutPlan::new(Pacing::FixedFps(10.0)).quota(64), 64);
        let none = Heuristic { q_min: 0.0, q_max: 0.0, ..Heuristic::default() };
        assert_eq!(HandOutPlan::new(Pacing::Heuristic(none)).quota(64), 1);
    }

    #[test]
    fn job_time_is_measured_from_the_later_of_hand_out_and_previous_result() {
        let mut p = Grid::heuristic();
        let t0 = Instant::now();
        // Two jobs at once: the second is rendered after the first, so it also took 100 ms.
        assert!(p.hand(1, 0, 0, t0), "the frame's first hand-out starts it");
        assert!(!p.hand(1, 0, 1, t0));
        assert_eq!(p.arrival(1, t0), None, "unmeasured");
        p.answer(1, 0, 0, t0 + MS * 100);
        p.answer(1, 0, 1, t0 + MS * 200);
        assert_eq!(p.arrival(1, t0 + MS * 200), Some(t0 + MS * 300));
        assert!(p.held.of(1).is_empty());
        // Held jobs queue up: the next one comes after them.
        p.hand(1, 1, 0, t0 + MS * 200);
        assert_eq!(p.arrival(1, t0 + MS * 200), Some(t0 + MS * 400));
    }

    #[test]
    fn at_a_fixed_rate_a_job_goes_to_the_first_frame_shown_after_it_arrives() {
        let mut p = Grid::new(Pacing::FixedFps(10.0)); // a frame every 100 ms
        let t0 = Instant::now();
        measured(&mut p, 1, t0, 250);
        let now = t0 + MS * 250;
        p.plan.displayed(4, now);
        // Frames 5, 6, 7 are shown at +100, +200, +300 ms; the job arrives at +250.
        assert_eq!(p.choose(1, &[5, 6, 7, 8], now), Some(7));
        assert_eq!(p.plan.frames_ahead(&p.held, now), 3, "the window must reach frame 4 + 3");
        assert_eq!(p.plan.deadline(4, now), Some(now), "a displayed frame has no future");
    }

    #[test]
    fn a_worker_holding_work_waits_rather_than_render_a_late_result() {
        let mut p = Grid::new(Pacing::FixedFps(10.0));
        let t0 = Instant::now();
        measured(&mut p, 1, t0, 250);
        let now = t0 + MS * 250;
        p.plan.displayed(4, now);
        p.hand(1, 7, 0, now); // arrives at +250: in time for frame 7
        assert_eq!(p.choose(1, &[5, 6, 7], now), None, "its next would arrive at +500");
        assert_eq!(p.choose(1, &[5, 6, 7, 8, 9], now), Some(9));
        // Holding nothing, it gets the newest frame anyway: it must stay measured.
        p.answer(1, 7, 0, now + MS * 250);
        assert_eq!(p.choose(1, &[5, 6], now + MS * 250), Some(6));
        assert!(!p.fits(1, 6, now + MS * 250) && p.fits(1, 9, now + MS * 250));
    }

    #[test]
    fn under_the_heuristic_the_deadline_is_i_min_times_the_last_frame_after_a_frame_starts() {
        let mut p = Grid::heuristic();
        let t0 = Instant::now();
        p.hand(2, 0, 0, t0);
        p.plan.displayed(0, t0 + MS * 100); // frame 0 took 100 ms from its first hand-out
        measured(&mut p, 1, t0 + MS * 100, 50);
        let now = t0 + MS * 150;
        p.hand(2, 1, 0, now - MS * 40);
        // Frame 1 started 40 ms ago: its deadline is in 160 ms; a fresh frame's in 200.
        assert_eq!(p.plan.deadline(1, now), Some(now + MS * 160));
        assert_eq!(p.plan.deadline(2, now), Some(now + MS * 200));
        assert_eq!(p.choose(1, &[1, 2], now), Some(1), "a 50 ms job is in time for frame 1");
        // A worker taking 180 ms is too slow for frame 1 but not for frame 2.
        measured(&mut p, 3, now - MS * 180, 180);
        p.hand(3, 9, 1, now);
        assert_eq!(p.choose(3, &[1, 2], now), None, "held work first: +360 ms");
        p.answer(3, 9, 1, now + MS * 180);
        let later = now + MS * 180;
        assert_eq!(p.plan.deadline(2, later), Some(later + MS * 200));
        assert_eq!(p.choose(3, &[1, 2], later), Some(2));
    }

    #[test]
    fn nothing_is_forecast_before_a_frame_was_displayed() {
        let mut p = Grid::new(Pacing::FixedFps(100.0));
        let t0 = Instant::now();
        measured(&mut p, 1, t0, 5000);
        assert_eq!(p.plan.deadline(3, t0), None);
        assert_eq!(p.choose(1, &[3, 4], t0), Some(3));
    }

    #[test]
    fn a_job_its_worker_dropped_leaves_every_forecast_at_once() {
        // Issue 43: the plan kept its own list of held jobs, which a dropped (superseded)
        // job never left: the worker looked busy for good, its forecasts stayed late, and
        // an idle worker with no frame in time for it got nothing.
        let mut p = Grid::new(Pacing::FixedFps(10.0));
        let t0 = Instant::now();
        measured(&mut p, 1, t0, 250);
        let now = t0 + MS * 250;
        p.plan.displayed(4, now);
        p.hand(1, 7, 0, now);
        assert_eq!(p.arrival(1, now), Some(now + MS * 500), "behind its held job");
        assert_eq!(p.choose(1, &[5, 6], now), None, "busy, and nothing is in time");
        // The worker drops it (a newer state's job came): the connection takes it back.
        assert!(p.held.take(1, 7, 0).is_some());
        assert_eq!(p.arrival(1, now), Some(now + MS * 250));
        assert_eq!(p.choose(1, &[5, 6], now), Some(6), "idle: the newest frame anyway");
        assert_eq!(p.plan.frames_ahead(&p.held, now), 3);
    }

    #[test]
    fn a_connection_that_leaves_is_forgotten() {
        let mut p = Grid::heuristic();
        let t0 = Instant::now();
        measured(&mut p, 1, t0, 100);
        assert!(p.arrival(1, t0).is_some());
        p.plan.left(1);
        assert_eq!(p.arrival(1, t0), None, "measured afresh if it comes back");
        p.plan.answered(1, t0, t0 + MS); // a stray answer after leaving changes nothing
        assert_eq!(p.arrival(1, t0), None);
    }
}
