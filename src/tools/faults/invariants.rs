//! The invariants every fault run checks, fed by the master's shown frames and counters.
//!
//! - Frames keep being shown whenever at least one worker is alive: the gap between two
//!   shown frames (not counting time with no live worker) stays below a bound.
//! - Every covered pixel of a shown frame came from a result of that frame: workers run
//!   the null renderer, whose radiance names its frame, so a pixel of another frame is
//!   seen at once.
//! - No frame holds more results than it has jobs (S), no (frame, set) is ever handed
//!   out twice (so at most S jobs per frame: nothing lost is recomputed), and the master
//!   never accepts more results than it handed out jobs.
//!
//! It also keeps, per number of connected workers, how many frames were shown and their
//! mean Q_t, so a run along the resource curve shows Q_t following the resources; and the
//! longest gaps with what happened around them (the harness's events: faults, undos,
//! live-worker counts), so a long blank screen names its cause.
//!
//! [`CheckingSink`] is the master's frame sink in the harness; the harness tells the
//! checker how many workers are alive ([`Checker::note_live`]).

use std::collections::{BTreeMap, VecDeque};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use glam::Vec3;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{ShownFrame, SinkError};
use gridlight_actors::protocol::FrameNo;
use gridlight_actors::sink::FrameSink;

/// Violations kept verbatim; beyond this only the count grows (bounded memory).
const MAX_KEPT: usize = 32;
/// Gaps at least this long are kept with their events.
const NOTED_GAP: Duration = Duration::from_millis(1000);
/// The longest gaps kept.
const MAX_GAPS: usize = 8;
/// Events kept (older ones are forgotten) and how long before a gap they are shown.
const MAX_EVENTS: usize = 256;
const EVENTS_BEFORE: Duration = Duration::from_secs(3);

/// The bounds a run is checked against.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// S: jobs per frame.
    pub sets: u32,
    /// Longest acceptable time between shown frames while a worker is alive.
    pub max_gap: Duration,
}

/// Radiance a covered pixel of `frame` must have (the null renderer's).
pub type ExpectedRadiance = fn(FrameNo) -> Vec3;

/// Running state of the checks.
#[derive(Debug)]
pub struct Checker {
    limits: Limits,
    expected: Option<ExpectedRadiance>,
    /// Start of the current gap; `None` while no worker is alive.
    gap_start: Option<Instant>,
    gap_reported: bool,
    live: usize,
    longest_gap: Duration,
    frames_shown: u64,
    last_frame: Option<FrameNo>,
    violations: u64,
    kept: Vec<String>,
    /// The current master's `jobs_handed_twice` already reported.
    handed_twice_seen: u64,
    /// Shown frames and the sum of their Q_t, by connected workers (bounded: one entry
    /// per worker count).
    q_by_workers: BTreeMap<u64, (u64, f64)>,
    /// When the checker started (event times are given from it).
    began: Instant,
    /// The harness's latest events.
    events: VecDeque<(Instant, String)>,
    /// The longest gaps seen, longest first.
    gaps: Vec<Gap>,
}

/// A gap between shown frames with a worker alive, and what happened around it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Gap {
    /// Seconds from the start of the run to the start of the gap.
    pub at_s: f64,
    pub ms: u64,
    /// The events from [`EVENTS_BEFORE`] before the gap to its end, `+S.SS s: what`.
    pub events: Vec<String>,
}

/// Frames shown with a given number of workers connected, and their mean Q_t.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct QSummary {
    pub frames: u64,
    pub mean_q: f64,
}

impl Checker {
    pub fn new(limits: Limits, expected: Option<ExpectedRadiance>) -> Self {
        Self {
            limits,
            expected,
            gap_start: None,
            gap_reported: false,
            live: 0,
            longest_gap: Duration::ZERO,
            frames_shown: 0,
            last_frame: None,
            violations: 0,
            kept: Vec::new(),
            handed_twice_seen: 0,
            q_by_workers: BTreeMap::new(),
            began: Instant::now(),
            events: VecDeque::new(),
            gaps: Vec::new(),
        }
    }

    /// Records something the harness did (a fault, an undo), for the gaps' reports.
    pub fn event(&mut self, now: Instant, what: String) {
        if self.events.len() == MAX_EVENTS {
            self.events.pop_front();
        }
        self.events.push_back((now, what));
    }

    /// The longest gaps of at least [`NOTED_GAP`], longest first, with their events.
    pub fn long_gaps(&self) -> &[Gap] {
        &self.gaps
    }

    /// The gap running since `gap_start` ended at `now`: kept if it is among the longest.
    fn gap_ended(&mut self, now: Instant) {
        let Some(start) = self.gap_start else { return };
        let len = now.saturating_duration_since(start);
        if len < NOTED_GAP
            || (self.gaps.len() == MAX_GAPS
                && self.gaps.last().is_some_and(|g| g.ms >= len.as_millis() as u64))
        {
            return;
        }
        let since = |t: Instant| t.saturating_duration_since(self.began).as_secs_f64();
        let events = self
            .events
            .iter()
            .filter(|(t, _)| *t + EVENTS_BEFORE >= start && *t <= now)
            .map(|(t, what)| format!("+{:.2} s: {what}", since(*t)))
            .collect();
        self.gaps.push(Gap { at_s: since(start), ms: len.as_millis() as u64, events });
        self.gaps.sort_by_key(|g| std::cmp::Reverse(g.ms));
        self.gaps.truncate(MAX_GAPS);
    }

    /// The number of live workers changed; the gap clock only runs while it is ≥ 1.
    pub fn note_live(&mut self, live: usize, now: Instant) {
        self.tick(now);
        if live != self.live {
            self.event(now, format!("{live} workers live"));
        }
        if live == 0 {
            self.gap_ended(now);
            self.gap_start = None;
        } else if self.live == 0 || self.gap_start.is_none() {
            self.gap_start = Some(now);
            self.gap_reported = false;
        }
        self.live = live;
    }

    /// A new master numbers its frames from the start again.
    pub fn master_restarted(&mut self) {
        self.last_frame = None;
        self.handed_twice_seen = 0;
    }

    /// Checks the gap so far (call now and then: a stopped display shows nothing).
    pub fn tick(&mut self, now: Instant) {
        let Some(start) = self.gap_start else { return };
        let gap = now.saturating_duration_since(start);
        self.longest_gap = self.longest_gap.max(gap);
        if gap > self.limits.max_gap && !self.gap_reported {
            self.gap_reported = true;
            let (ms, max) = (gap.as_millis(), self.limits.max_gap.as_millis());
            self.violate(format!("no frame shown for {ms} ms with a worker alive (max {max} ms)"));
        }
    }

    /// Checks one shown frame.
    pub fn on_frame(&mut self, f: &ShownFrame, now: Instant) {
        self.tick(now);
        if self.live > 0 {
            self.gap_ended(now);
            self.gap_start = Some(now);
            self.gap_reported = false;
        }
        self.frames_shown += 1;
        if let Some(last) = self.last_frame {
            if f.frame <= last {
                self.violate(format!("frame {} shown after frame {last}", f.frame));
            }
        }
        self.last_frame = Some(f.frame);
        let q = self.q_by_workers.entry(f.stats.workers).or_default();
        q.0 += 1;
        q.1 += f.stats.q;
        if f.stats.jobs_back > self.limits.sets {
            let (n, s) = (f.stats.jobs_back, self.limits.sets);
            self.violate(format!("frame {} holds {n} results, S = {s}", f.frame));
        }
        if let Some(expected) = self.expected {
            let want = expected(f.frame);
            let foreign = f
                .current
                .iter()
                .zip(&f.current_mask)
                .filter(|(v, covered)| **covered && (**v - want).abs().max_element() > 1e-3)
                .count();
            if foreign > 0 {
                self.violate(format!(
                    "frame {}: {foreign} pixels hold radiance of another frame",
                    f.frame
                ));
            }
        }
    }

    /// Checks the master's counters.
    pub fn check_counters(&mut self, c: &Counters) {
        let accepted = Counters::get(&c.results_accepted);
        let handed = Counters::get(&c.jobs_handed_out);
        if accepted > handed {
            self.violate(format!("{accepted} results accepted but only {handed} jobs handed out"));
        }
        let twice = Counters::get(&c.jobs_handed_twice);
        if twice > self.handed_twice_seen {
            let new = twice - self.handed_twice_seen;
            self.handed_twice_seen = twice;
            self.violate(format!("{new} jobs handed out a second time (more than S per frame)"));
        }
    }

    /// Frames shown and their mean Q_t, by the number of workers connected then.
    pub fn q_by_workers(&self) -> BTreeMap<u64, QSummary> {
        self.q_by_workers
            .iter()
            .map(|(&w, &(frames, sum))| (w, QSummary { frames, mean_q: sum / frames as f64 }))
            .collect()
    }

    /// Records a violation found elsewhere (the master exited, a worker was not served).
    pub fn violate(&mut self, what: String) {
        tracing::error!(violation = %what, "invariant violated");
        self.violations += 1;
        if self.kept.len() < MAX_KEPT {
            self.kept.push(what);
        }
    }

    pub fn frames_shown(&self) -> u64 {
        self.frames_shown
    }

    pub fn longest_gap(&self) -> Duration {
        self.longest_gap
    }

    pub fn violations(&self) -> u64 {
        self.violations
    }

    /// The first violations, verbatim.
    pub fn violation_texts(&self) -> &[String] {
        &self.kept
    }
}

/// A checker shared between the master's sink thread and the harness.
pub type SharedChecker = Arc<Mutex<Checker>>;

/// Locks a shared checker (a poisoned lock still holds valid counts).
pub fn lock(c: &SharedChecker) -> MutexGuard<'_, Checker> {
    c.lock().unwrap_or_else(|p| p.into_inner())
}

/// The master's frame sink in the harness: checks every shown frame.
pub struct CheckingSink(pub SharedChecker);

impl FrameSink for CheckingSink {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        lock(&self.0).on_frame(&frame, Instant::now());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::master::FrameStats;
    use gridlight_actors::state::{Camera, Resolution, SceneState};

    fn limits() -> Limits {
        Limits { sets: 4, max_gap: Duration::from_millis(100) }
    }

    fn shown(frame: FrameNo, values: Vec<Vec3>, jobs_back: u32) -> ShownFrame {
        let camera = Camera::pinhole(Vec3::Z, Vec3::ZERO, 40.0);
        let state = SceneState::empty(Resolution { width: values.len() as u32, height: 1 }, camera);
        ShownFrame {
            frame,
            state: Arc::new(state),
            current_mask: values.iter().map(|v| *v != Vec3::ZERO).collect(),
            owners: Default::default(),
            current: values,
            stats: FrameStats { frame, jobs_back, jobs_total: 4, ..Default::default() },
        }
    }

    fn expected(frame: FrameNo) -> Vec3 {
        Vec3::splat(frame as f32)
    }

    #[test]
    fn a_pixel_of_another_frame_and_too_many_results_are_violations() {
        let mut c = Checker::new(limits(), Some(expected));
        let t = Instant::now();
        c.note_live(1, t);
        c.on_frame(&shown(2, vec![Vec3::splat(2.0), Vec3::ZERO], 4), t);
        assert_eq!(c.violations(), 0, "{:?}", c.violation_texts());
        c.on_frame(&shown(3, vec![Vec3::splat(2.0), Vec3::splat(3.0)], 4), t);
        assert_eq!(c.violations(), 1);
        c.on_frame(&shown(4, vec![Vec3::splat(4.0)], 5), t);
        assert_eq!(c.violations(), 2);
        c.on_frame(&shown(4, vec![Vec3::splat(4.0)], 1), t);
        assert_eq!(c.violations(), 3, "a frame shown twice was not noticed");
        assert_eq!(c.frames_shown(), 4);
    }

    #[test]
    fn gaps_count_only_while_a_worker_is_alive() {
        let mut c = Checker::new(limits(), None);
        let t = Instant::now();
        c.note_live(1, t);
        c.tick(t + Duration::from_millis(50));
        assert_eq!(c.violations(), 0);
        c.note_live(0, t + Duration::from_millis(60));
        c.tick(t + Duration::from_secs(10));
        assert_eq!(c.violations(), 0, "a gap without workers was counted");
        c.note_live(2, t + Duration::from_secs(10));
        c.event(t + Duration::from_millis(10_500), "restart_master".into());
        c.tick(t + Duration::from_secs(11));
        c.tick(t + Duration::from_secs(12));
        assert_eq!(c.violations(), 1, "one long gap is one violation");
        assert!(c.longest_gap() >= Duration::from_secs(2));
        c.on_frame(&shown(1, vec![Vec3::ONE], 1), t + Duration::from_secs(12));
        let gaps = c.long_gaps();
        assert_eq!(gaps.len(), 1, "{gaps:?}");
        assert_eq!(gaps[0].ms, 2000);
        assert!(gaps[0].events.iter().any(|e| e.ends_with("restart_master")), "{gaps:?}");
        assert!(gaps[0].events.iter().any(|e| e.ends_with("2 workers live")), "{gaps:?}");
    }

    #[test]
    fn more_results_than_jobs_is_a_violation() {
        let mut c = Checker::new(limits(), None);
        let counters = Counters::default();
        Counters::add(&counters.jobs_handed_out, 3);
        Counters::add(&counters.results_accepted, 3);
        c.check_counters(&counters);
        assert_eq!(c.violations(), 0);
        Counters::add(&counters.results_accepted, 1);
        c.check_counters(&counters);
        assert_eq!(c.violations(), 1);
    }

    #[test]
    fn a_job_handed_out_twice_is_one_violation_per_occurrence() {
        let mut c = Checker::new(limits(), None);
        let counters = Counters::default();
        c.check_counters(&counters);
        Counters::add(&counters.jobs_handed_twice, 1);
        c.check_counters(&counters);
        c.check_counters(&counters);
        assert_eq!(c.violations(), 1, "{:?}", c.violation_texts());
        c.master_restarted();
        let fresh = Counters::default();
        c.check_counters(&fresh);
        assert_eq!(c.violations(), 1, "a new master's counters start at zero");
    }

    #[test]
    fn q_is_summarised_by_connected_workers() {
        let mut c = Checker::new(limits(), None);
        let t = Instant::now();
        for (frame, workers, q) in [(1, 2, 0.5), (2, 2, 1.0), (3, 4, 1.0)] {
            let mut f = shown(frame, vec![Vec3::ONE], 1);
            f.stats.workers = workers;
            f.stats.q = q;
            c.on_frame(&f, t);
        }
        let q = c.q_by_workers();
        assert_eq!(q[&2], QSummary { frames: 2, mean_q: 0.75 });
        assert_eq!(q[&4], QSummary { frames: 1, mean_q: 1.0 });
    }
}
