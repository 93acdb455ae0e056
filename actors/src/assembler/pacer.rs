//! When the oldest frame in flight is shown, skipped or waited for: the [`wait_heuristic`]
//! (paper §4.3) with the clock it needs and the rule around edits ([`NewView`]), as pure
//! logic behind the frame assembler actor.
//!
//! The heuristic times a frame from the start of its computation (its first hand-out),
//! so frames that were computed side by side and complete together are not judged by the
//! instant between their displays (a frame after such a burst would be skipped at once,
//! its results all late). A fixed rate, and a frame not started yet, count from the later
//! of its scheduling and the previous display. Frames the scheduler abandoned (its
//! restart) and frames decided by the rule around an edit are judged as if their time
//! were up and left out of the frame time: their time is not the workers'.
//!
//! [`wait_heuristic`]: crate::assembler::wait_heuristic

use std::time::{Duration, Instant};

use crate::assembler::frame_table::Progress;
use crate::assembler::new_view::NewView;
use crate::assembler::wait_heuristic::{decide, interaction, quality, Decision};
use crate::shared::pacing::Pacing;
use crate::wire::protocol::FrameNo;

/// The decision about one frame and what it was based on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Judgement {
    pub decision: Decision,
    /// Time on the frame so far.
    pub elapsed: Duration,
    /// Decided for a reason other than the workers' speed (scheduler restart, an edit):
    /// its time does not become the last frame's time.
    pub abandoned: bool,
    /// Q_t and I_t when decided.
    pub q: f64,
    pub i: f64,
}

/// The pacing and the clock of the frames shown so far.
#[derive(Debug)]
pub struct Pacer {
    pacing: Pacing,
    /// Time the last displayed frame took (I_t's denominator).
    last_frame_time: Duration,
    last_close_at: Instant,
    /// Frames below this one lost their queued jobs (a scheduler restart): decided at once
    /// and left out of the frame time, so lost work cannot stretch I_max (each skip at
    /// I_max would otherwise multiply the next frame's wait by I_max).
    abandoned_before: FrameNo,
    /// Frames below this one have an outdated scene state ([`NewView`]).
    outdated_before: FrameNo,
    /// The last frame shown ([`NewView`]).
    last_shown: Option<FrameNo>,
}

impl Pacer {
    /// A pacer whose first frame is judged against `initial_frame_time`.
    pub fn new(pacing: Pacing, initial_frame_time: Duration, now: Instant) -> Self {
        Self {
            pacing,
            last_frame_time: initial_frame_time,
            last_close_at: now,
            abandoned_before: 0,
            outdated_before: 0,
            last_shown: None,
        }
    }

    /// Frames are paced this way from now on (validated by the caller).
    pub fn set_pacing(&mut self, pacing: Pacing) {
        self.pacing = pacing;
    }

    /// Frames before `before` lost their queued jobs.
    pub fn abandoned(&mut self, before: FrameNo) {
        self.abandoned_before = self.abandoned_before.max(before);
    }

    /// Frames before `before` have an outdated scene state.
    pub fn outdated(&mut self, before: FrameNo) {
        self.outdated_before = self.outdated_before.max(before);
    }

    /// Judges `frame`, the oldest not displayed, at `now`; `later_has_results`: a frame
    /// after it has results.
    pub fn judge(
        &self,
        frame: FrameNo,
        p: &Progress,
        later_has_results: bool,
        now: Instant,
    ) -> Judgement {
        let queued = p.scheduled_at.max(self.last_close_at);
        let start = match (self.pacing, p.started_at) {
            (Pacing::Heuristic(_), Some(started)) => started,
            _ => queued,
        };
        let elapsed = now.saturating_duration_since(start);
        let view = NewView { outdated_before: self.outdated_before, last_shown: self.last_shown };
        let around_edit = match self.pacing {
            Pacing::FixedFps(_) => view.decide_fixed_rate(frame, p.back, later_has_results),
            Pacing::Heuristic(_) => view.decide(frame, p.back, later_has_results),
        };
        let abandoned = frame < self.abandoned_before || around_edit.is_some();
        let judged_at = if abandoned { Duration::MAX } else { elapsed };
        let heuristic = decide(&self.pacing, p.back, p.total, judged_at, self.last_frame_time);
        Judgement {
            decision: around_edit.unwrap_or(heuristic),
            elapsed,
            abandoned,
            q: quality(p.back, p.total),
            i: interaction(elapsed, self.last_frame_time),
        }
    }

    /// `frame` was displayed at `now` as judged (`shown`, or skipped). A skipped frame's
    /// time becomes the last frame's time too, so that when workers slow down I_max grows
    /// until frames complete again (otherwise a fast past would make every frame skip
    /// forever).
    pub fn displayed(&mut self, frame: FrameNo, shown: bool, j: &Judgement, now: Instant) {
        self.last_close_at = now;
        if shown {
            self.last_shown = Some(frame);
        }
        if !j.abandoned {
            self.last_frame_time = j.elapsed;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shared::pacing::Heuristic;

    const LAST: Duration = Duration::from_millis(100);

    fn progress(back: u32, at: Instant, started: Option<Instant>) -> Progress {
        Progress { version: 1, back, total: 10, scheduled_at: at, started_at: started }
    }

    fn ms(n: u64) -> Duration {
        Duration::from_millis(n)
    }

    #[test]
    fn the_heuristic_times_a_frame_from_its_first_hand_out() {
        let t0 = Instant::now();
        let p = Pacer::new(Pacing::Heuristic(Heuristic::default()), LAST, t0);
        let started = progress(3, t0, Some(t0 + ms(100)));
        let j = p.judge(0, &started, false, t0 + ms(250));
        assert_eq!(j.elapsed, ms(150));
        assert_eq!(j.decision, Decision::Wait { recheck_at: ms(200) });
        let j = p.judge(0, &started, false, t0 + ms(300));
        assert_eq!(j.decision, Decision::Show, "Q_min <= Q once I_min passed");
        assert!((j.q - 0.3).abs() < 1e-9 && (j.i - 2.0).abs() < 1e-9);
    }

    #[test]
    fn a_frame_not_started_counts_from_the_later_of_its_scheduling_and_the_last_display() {
        let t0 = Instant::now();
        let mut p = Pacer::new(Pacing::Heuristic(Heuristic::default()), LAST, t0);
        let j = p.judge(0, &progress(5, t0, None), false, t0 + ms(50));
        p.displayed(0, true, &j, t0 + ms(50));
        assert_eq!(p.judge(1, &progress(0, t0, None), false, t0 + ms(60)).elapsed, ms(10));
    }

    #[test]
    fn skipped_frames_set_the_frame_time_and_abandoned_ones_do_not() {
        let t0 = Instant::now();
        let mut p = Pacer::new(Pacing::Heuristic(Heuristic::default()), LAST, t0);
        let j = p.judge(0, &progress(0, t0, Some(t0)), false, t0 + ms(400));
        assert_eq!(j.decision, Decision::Skip, "Q < Q_min at I_max");
        p.displayed(0, false, &j, t0 + ms(400));
        let j = p.judge(1, &progress(0, t0, Some(t0)), false, t0 + ms(500));
        assert_eq!(j.decision, Decision::Wait { recheck_at: ms(800) }, "I_min × 400 ms");
        p.abandoned(5);
        let j = p.judge(2, &progress(0, t0, Some(t0)), false, t0 + ms(501));
        assert!(j.abandoned && j.decision == Decision::Skip, "judged as if its time were up");
        p.displayed(2, false, &j, t0 + ms(501));
        let j = p.judge(6, &progress(0, t0 + ms(501), None), false, t0 + ms(502));
        assert_eq!(j.decision, Decision::Wait { recheck_at: ms(800) }, "frame time kept");
    }

    #[test]
    fn after_an_edit_the_new_views_first_result_is_shown_at_once() {
        let t0 = Instant::now();
        let mut p = Pacer::new(Pacing::Heuristic(Heuristic::default()), LAST, t0);
        p.outdated(4);
        let old = p.judge(3, &progress(2, t0, Some(t0)), true, t0);
        assert_eq!(
            (old.decision, old.abandoned),
            (Decision::Skip, true),
            "a newer frame has results"
        );
        let new = p.judge(4, &progress(1, t0, Some(t0)), false, t0 + ms(1));
        assert_eq!((new.decision, new.abandoned), (Decision::Show, true));
        p.displayed(4, true, &new, t0 + ms(1));
        let next = p.judge(5, &progress(1, t0, Some(t0)), false, t0 + ms(2));
        assert!(matches!(next.decision, Decision::Wait { .. }), "the heuristic decides again");
    }

    #[test]
    fn a_fixed_rate_shows_every_period_whatever_came_back() {
        let t0 = Instant::now();
        let p = Pacer::new(Pacing::FixedFps(10.0), LAST, t0);
        let j = p.judge(0, &progress(0, t0, Some(t0 + ms(90))), false, t0 + ms(100));
        assert_eq!(j.decision, Decision::Show, "a fixed rate counts from the scheduling");
    }
}
