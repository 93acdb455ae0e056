//! The pause/resume decision: plain data in, [`Activity`] out, no clock and no I/O, so
//! that tests replay recorded samples.
//!
//! The owner is **active** when either
//! - (a) other processes used more than `cpu_percent` % of all CPUs over the last
//!   `cpu_window`: the machine's busy time minus this process's own, both from
//!   [`CpuTimes`], between the newest sample and the newest one at least `cpu_window`
//!   older (or the oldest, until the window has filled); or
//! - (b) the keyboard or mouse was used less than `input_idle` ago, where the platform
//!   tells ([`InputIdle::Known`]). Unknown input is no evidence either way: the CPU
//!   decides alone, and logs say so.
//!
//! A working worker pauses at the first active sample. A paused one resumes only after
//! the owner has been inactive for `resume_after` without a break, so that a short pause
//! in the owner's typing does not bring the renderer back at once.

use std::collections::VecDeque;
use std::time::Duration;

use gridlight_actors::protocol::PauseReason;

use super::cpu::CpuTimes;
use super::input::InputIdle;

/// When a worker counts its desk's owner as active, and how long it waits to resume.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdlePolicy {
    /// (a): the other processes' share of all CPUs above which the owner is active, in %.
    pub cpu_percent: f32,
    /// (a): over how long that share is measured.
    pub cpu_window: Duration,
    /// (b): input more recent than this means the owner is active.
    pub input_idle: Duration,
    /// Inactivity needed, without a break, before a paused worker resumes.
    pub resume_after: Duration,
    /// Time between two samples.
    pub sample_every: Duration,
}

impl Default for IdlePolicy {
    fn default() -> Self {
        Self {
            cpu_percent: 25.0,
            cpu_window: Duration::from_secs(10),
            input_idle: Duration::from_secs(300),
            resume_after: Duration::from_secs(30),
            sample_every: Duration::from_secs(1),
        }
    }
}

impl IdlePolicy {
    /// Checks the values a user gave; the message names the offending setting.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.cpu_percent > 0.0 && self.cpu_percent <= 100.0) {
            return Err(format!("idle CPU percent must be in (0, 100], got {}", self.cpu_percent));
        }
        if self.sample_every.is_zero() || self.cpu_window < self.sample_every {
            return Err(format!(
                "the CPU window ({:?}) must be at least one sample interval ({:?}), which must be positive",
                self.cpu_window, self.sample_every
            ));
        }
        Ok(())
    }
}

/// One observation of the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// When it was taken, on any monotonic clock.
    pub at: Duration,
    /// CPU times, where the platform has them.
    pub cpu: Option<CpuTimes>,
    pub input: InputIdle,
}

/// Whether the worker takes jobs.
#[derive(Clone, Debug, PartialEq)]
pub enum Activity {
    Working,
    Paused(PauseReason),
}

/// The decision over a stream of samples.
#[derive(Debug)]
pub struct Decider {
    policy: IdlePolicy,
    /// CPU samples, oldest first, spanning at least the window once it has filled.
    history: VecDeque<(Duration, CpuTimes)>,
    state: Activity,
    /// While paused: since when the owner has been inactive.
    quiet_since: Option<Duration>,
}

impl Decider {
    /// Starts working; the first active sample pauses.
    pub fn new(policy: IdlePolicy) -> Self {
        Self { policy, history: VecDeque::new(), state: Activity::Working, quiet_since: None }
    }

    /// The decision after `sample`.
    pub fn observe(&mut self, sample: Sample) -> &Activity {
        let active = self.owner_activity(&sample);
        match (&self.state, active) {
            (_, Some(reason)) => {
                self.quiet_since = None;
                self.state = Activity::Paused(reason);
            }
            (Activity::Paused(_), None) => {
                let since = *self.quiet_since.get_or_insert(sample.at);
                if sample.at.saturating_sub(since) >= self.policy.resume_after {
                    self.quiet_since = None;
                    self.state = Activity::Working;
                }
            }
            (Activity::Working, None) => {}
        }
        &self.state
    }

    /// The current decision.
    pub fn activity(&self) -> &Activity {
        &self.state
    }

    /// Why the owner counts as active in `sample`, if they do (input first).
    fn owner_activity(&mut self, sample: &Sample) -> Option<PauseReason> {
        let cpu = sample.cpu.and_then(|c| self.others_share(sample.at, c));
        if let InputIdle::Known(idle) = sample.input {
            if idle < self.policy.input_idle {
                return Some(PauseReason::OwnerInput { seconds_ago: idle.as_secs_f32() });
            }
        }
        let (percent, span) = cpu?;
        (percent > self.policy.cpu_percent)
            .then_some(PauseReason::OwnerCpu { percent, window_s: span.as_secs_f32() })
    }

    /// Records `cpu` and returns the other processes' share of all CPUs (%) over the
    /// window, with the span it was measured over; `None` before two samples.
    fn others_share(&mut self, at: Duration, cpu: CpuTimes) -> Option<(f32, Duration)> {
        // A counter that went backwards (a new process, a wrapped counter) restarts.
        if self.history.back().is_some_and(|(_, c)| c.total > cpu.total || c.own > cpu.own) {
            self.history.clear();
        }
        self.history.push_back((at, cpu));
        let start = at.saturating_sub(self.policy.cpu_window);
        while self.history.len() > 2 && self.history[1].0 <= start {
            self.history.pop_front();
        }
        let (then_at, then) = *self.history.front()?;
        let total = cpu.total - then.total;
        if self.history.len() < 2 || total == 0 {
            return None;
        }
        let others = (cpu.busy.saturating_sub(then.busy)).saturating_sub(cpu.own - then.own);
        Some((100.0 * others as f32 / total as f32, at - then_at))
    }
}

#[cfg(test)]
mod tests {
    use super::super::cpu::{parse_proc_stat, parse_self_stat};
    use super::*;

    /// A recorded sample: `/proc/stat`'s first line and this process's `/proc/self/stat`
    /// (2 CPUs at 100 ticks per second: 200 ticks of CPU time per second in all).
    fn recorded(at_s: u64, proc_stat: &str, self_stat: &str, input: InputIdle) -> Sample {
        let (total, busy) = parse_proc_stat(proc_stat).unwrap();
        let own = parse_self_stat(self_stat).unwrap();
        Sample { at: Duration::from_secs(at_s), cpu: Some(CpuTimes { total, busy, own }), input }
    }

    /// `/proc/stat` after `user` and `idle` ticks.
    fn stat(user: u64, idle: u64) -> String {
        format!("cpu  {user} 0 300 {idle} 12 0 7 0 0 0\ncpu0 0 0 0 0 0 0 0 0 0 0\n")
    }

    /// `/proc/self/stat` of a worker with `utime` ticks of user time.
    fn own(utime: u64) -> String {
        format!("9001 (gridlight) S 1 9001 9001 0 -1 4194560 5000 0 0 0 {utime} 40 0 0 20 0 7 0")
    }

    fn policy() -> IdlePolicy {
        IdlePolicy {
            cpu_percent: 25.0,
            cpu_window: Duration::from_secs(4),
            input_idle: Duration::from_secs(60),
            resume_after: Duration::from_secs(5),
            sample_every: Duration::from_secs(1),
        }
    }

    const NO_INPUT: InputIdle = InputIdle::Unknown;

    /// A timeline of (user, idle, own utime) per second: the worker renders on both
    /// CPUs (its ticks are most of the busy ones) until the owner starts a build at 6 s,
    /// which takes the CPUs (SCHED_IDLE render threads get almost nothing), and stops
    /// at 12 s; the machine is then quiet.
    fn timeline() -> Vec<(u64, u64, u64)> {
        let mut t = Vec::new();
        let (mut user, mut idle, mut mine) = (50_000u64, 9_000u64, 1_000u64);
        for s in 0..30u64 {
            t.push((user, idle, mine));
            match s {
                0..=5 => (user, idle, mine) = (user + 196, idle + 4, mine + 192),
                6..=11 => (user, idle, mine) = (user + 199, idle + 1, mine + 2),
                _ => (user, idle, mine) = (user + 4, idle + 196, mine),
            }
        }
        t
    }

    fn replay(input: impl Fn(u64) -> InputIdle) -> Vec<Activity> {
        let mut d = Decider::new(policy());
        timeline()
            .into_iter()
            .enumerate()
            .map(|(s, (user, idle, mine))| {
                let s = s as u64;
                d.observe(recorded(s, &stat(user, idle), &own(mine), input(s))).clone()
            })
            .collect()
    }

    fn first_pause(a: &[Activity]) -> usize {
        a.iter().position(|x| matches!(x, Activity::Paused(_))).expect("a pause")
    }

    #[test]
    fn the_workers_own_rendering_never_counts_as_the_owners() {
        let a = replay(|_| NO_INPUT);
        assert!(a[..=6].iter().all(|x| *x == Activity::Working), "{a:?}");
    }

    #[test]
    fn the_owners_build_pauses_the_worker_with_its_share_of_the_cpus() {
        let a = replay(|_| NO_INPUT);
        let at = first_pause(&a);
        assert_eq!(at, 7, "the first sample that sees the build pauses: {a:?}");
        let Activity::Paused(PauseReason::OwnerCpu { percent, window_s }) = &a[at] else {
            panic!("{:?}", a[at])
        };
        // A window of 4 s: one second of the build (197 of 200 ticks are others') and
        // three of rendering (4 of 200 each): 209 / 800, about 26 %.
        assert!((25.0..30.0).contains(percent), "{percent}");
        assert_eq!(*window_s, 4.0);
    }

    #[test]
    fn the_worker_resumes_only_after_the_owner_was_quiet_for_resume_after() {
        let a = replay(|_| NO_INPUT);
        // The build ends at 12 s; the window still holds build time until 16 s; then 5 s
        // of quiet are needed.
        let resumed = a.iter().rposition(|x| matches!(x, Activity::Paused(_))).unwrap() + 1;
        assert!(a[..resumed].iter().skip(7).all(|x| matches!(x, Activity::Paused(_))));
        assert_eq!(resumed, 21, "{a:?}");
        assert!(a[resumed..].iter().all(|x| *x == Activity::Working));
    }

    #[test]
    fn recent_input_pauses_and_keeps_the_worker_paused_whatever_the_cpu() {
        // Input at 20 s (the CPUs are quiet by then), reported by a fake source.
        let a = replay(|s| {
            if s < 20 {
                InputIdle::Known(Duration::from_secs(600 + s))
            } else {
                InputIdle::Known(Duration::from_secs(s - 20))
            }
        });
        let last = a.last().unwrap();
        assert_eq!(*last, Activity::Paused(PauseReason::OwnerInput { seconds_ago: 9.0 }));
        assert!(matches!(a[20], Activity::Paused(PauseReason::OwnerInput { .. })), "{:?}", a[20]);
    }

    #[test]
    fn unknown_input_is_no_evidence_and_the_cpu_decides_alone() {
        let unknown = replay(|_| InputIdle::Unknown);
        let long_idle = replay(|_| InputIdle::Known(Duration::from_secs(3600)));
        assert_eq!(unknown, long_idle);
    }

    #[test]
    fn a_paused_worker_waits_again_when_the_owner_comes_back_before_resume_after() {
        let mut d = Decider::new(policy());
        let input = |ago: u64| InputIdle::Known(Duration::from_secs(ago));
        let at = |s: u64, i| Sample { at: Duration::from_secs(s), cpu: None, input: i };
        assert!(matches!(d.observe(at(0, input(0))), Activity::Paused(_)));
        // Inactive (input 60 s ago) at 60 s; input again at 63 s; inactive again at 124 s.
        assert!(matches!(d.observe(at(60, input(60))), Activity::Paused(_)));
        assert!(matches!(d.observe(at(63, input(0))), Activity::Paused(_)));
        assert!(matches!(d.observe(at(124, input(61))), Activity::Paused(_)));
        assert!(matches!(d.observe(at(128, input(65))), Activity::Paused(_)));
        assert_eq!(*d.observe(at(129, input(66))), Activity::Working);
    }

    #[test]
    fn bad_policies_are_refused_with_the_setting_named() {
        let mut p = policy();
        p.cpu_percent = 0.0;
        assert!(p.validate().unwrap_err().contains("percent"));
        let mut p = policy();
        p.cpu_window = Duration::ZERO;
        assert!(p.validate().unwrap_err().contains("window"));
        assert!(policy().validate().is_ok());
    }
}
