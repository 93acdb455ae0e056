//! How many samples per pixel a job takes: jobs sized to the live grid (docs/design.md,
//! decision 13): pure logic behind the scheduler.
//!
//! The paper's job is one set at the scene's samples per pixel (`render.spp`, the *base*).
//! On today's cores such a job of a small frame takes a couple of milliseconds, and a
//! large grid then returns more results per second than the master can take in (each
//! costs its actor thread a fixed amount: decoding, the integrity check, the frame table)
//! or than its inbound link carries (about 4 bytes a pixel): results queue, come late and
//! are wasted (`eval fig10` on this machine's cores: 0.36 of the grid used at 128 workers).
//! A frame needs its quota of results however large the grid is, so the grid's surplus is
//! better spent inside each job: more samples per pixel, as many results (paper §6.2).
//!
//! The rule. Each connection's render time per job and sample per pixel is measured from
//! the `render_us` of its results (the worker's own time, not the round trip: a saturated
//! master makes the round trip long, and must not make the grid look slow). `G`, the sum
//! of the connections' rates, is how many one-sample jobs the grid renders per second; at
//! `spp` samples a job it returns `G / spp` results per second. The master affords
//! `R = min(R_master, R_link)` results per second:
//!
//! - `R_master = MASTER_SHARE / c`, `c` the seconds the master's actor thread was busy
//!   per result received, running or waiting for a core (on a machine whose cores other
//!   work shares it gets through fewer results a second than its CPU time says),
//!   measured over each review period ([`JobSize::observe_master`]);
//! - `R_link = LINK_SHARE · link / b`, `link` the inbound link's bytes per second
//!   (`--link-mbps`) and `b` the bytes per result, measured the same way (the set's
//!   packed pixels until then).
//!
//! A job takes the smallest multiple of the base with `G / spp <= R`, at most
//! [`MAX_FACTOR`] times the base; while nothing is measured, or jobs are long enough
//! (the paper's 56 ms jobs on 256 workers), that is the base itself. It grows as soon as
//! the grid outruns `R`, and shrinks only when one step less would stay under
//! [`LOWER`]` · R`, so that noise in the measurements does not make it flap. Every job of
//! a frame takes the samples per pixel in force when the frame was opened, so its results
//! are alike; which frames took which is kept ([`JobSize::spp_of`]) to turn a result's
//! render time back into a rate.
//!
//! S, the sets per frame, stays the run's: workers derive pixel lists from the sets
//! configuration of their `Welcome`. A job's size changes what a result is worth, never
//! its bytes; the frame rate stays what the master and the link allow, and each frame
//! holds more samples.

use std::collections::{HashMap, VecDeque};
use std::time::Duration;

use crate::wire::protocol::{ConnId, FrameNo};

/// Share of its time the master's actor thread may be busy with results: the rest is
/// headroom for bursts and for what does not come with results.
pub const MASTER_SHARE: f64 = 0.7;
/// Share of the inbound link results may fill (the rest: TCP/IP headers, heartbeats).
pub const LINK_SHARE: f64 = 0.9;
/// A job never takes more than this many times the base samples per pixel.
pub const MAX_FACTOR: u32 = 64;
/// Fewer samples per job only when one step less keeps the results under this share of
/// what the master affords.
pub const LOWER: f64 = 0.8;
/// How often the scheduler reviews the job size.
pub const REVIEW_PERIOD: Duration = Duration::from_millis(250);
/// Bytes a result costs beyond its packed pixels (frame header, MessagePack fields, tag).
pub const RESULT_OVERHEAD: u64 = 64;
/// Results a review period must have seen to measure the master's cost per result.
const MIN_RESULTS: u64 = 32;
/// Weight of a new sample in the running estimates.
const GAIN: f64 = 0.25;
/// Changes of the job size remembered ([`JobSize::spp_of`]).
const STEPS_KEPT: usize = 32;

/// What the master's actor thread did over one review period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MasterSample {
    /// Seconds the actor thread ran or waited for a core (NaN without a thread clock).
    pub busy_seconds: f64,
    /// Results received.
    pub results: u64,
    /// Bytes received, results and everything else.
    pub bytes: u64,
}

/// The job size in force and what it is decided from.
#[derive(Debug)]
pub struct JobSize {
    /// The scene's samples per pixel: the paper's job.
    base: u32,
    /// The inbound link's bytes per second, if known.
    link: Option<f64>,
    /// Smoothed render seconds per job per sample per pixel, by connection.
    unit: HashMap<ConnId, f64>,
    /// Smoothed busy seconds of the actor thread per result received.
    cost: Option<f64>,
    /// Smoothed bytes per result received; the set's packed size until measured.
    bytes_per_result: f64,
    /// (first frame, samples per pixel) of each job size in force, oldest first.
    steps: VecDeque<(FrameNo, u32)>,
}

impl JobSize {
    /// Jobs of `base` samples per pixel (at least 1) until the grid outruns the master
    /// or `link` (bytes per second, if known); results of `set_pixels` pixels.
    pub fn new(base: u32, link: Option<f64>, set_pixels: usize) -> Self {
        let base = base.max(1);
        Self {
            base,
            link: link.filter(|l| l.is_finite() && *l > 0.0),
            unit: HashMap::new(),
            cost: None,
            bytes_per_result: (set_pixels as u64 * 4 + RESULT_OVERHEAD) as f64,
            steps: VecDeque::from([(0, base)]),
        }
    }

    /// The samples per pixel of frames opened now.
    pub fn spp(&self) -> u32 {
        self.steps.back().map_or(self.base, |s| s.1)
    }

    /// The samples per pixel `frame`'s jobs took (the base for frames older than every
    /// change remembered).
    pub fn spp_of(&self, frame: FrameNo) -> u32 {
        self.steps.iter().rev().find(|(first, _)| *first <= frame).map_or(self.base, |s| s.1)
    }

    /// `conn` answered a job of `frame`, which its worker rendered in `render_us`.
    pub fn answered(&mut self, conn: ConnId, frame: FrameNo, render_us: u64) {
        // A worker reporting no time at all would make the grid look infinitely fast.
        let sample = render_us.max(1) as f64 * 1e-6 / f64::from(self.spp_of(frame));
        let unit = self.unit.entry(conn).or_insert(sample);
        *unit += GAIN * (sample - *unit);
    }

    /// `conn` is gone (or paused): its rate no longer counts.
    pub fn left(&mut self, conn: ConnId) {
        self.unit.remove(&conn);
    }

    /// What the master's actor thread spent over the last review period.
    pub fn observe_master(&mut self, s: MasterSample) {
        if s.results < MIN_RESULTS {
            return; // too few to say what one costs; idle overhead would dominate
        }
        let n = s.results as f64;
        let bytes = s.bytes as f64 / n;
        self.bytes_per_result += GAIN * (bytes - self.bytes_per_result);
        if s.busy_seconds.is_finite() && s.busy_seconds > 0.0 {
            let cost = s.busy_seconds / n;
            self.cost = Some(self.cost.map_or(cost, |c| c + GAIN * (cost - c)));
        }
    }

    /// One-sample jobs the grid renders per second (`G`).
    pub fn grid_rate(&self) -> f64 {
        self.unit.values().map(|u| 1.0 / u).sum()
    }

    /// Results per second the master affords (`R`); `None` while nothing bounds it.
    pub fn affordable(&self) -> Option<f64> {
        let master = self.cost.map(|c| MASTER_SHARE / c);
        let link = self.link.map(|l| LINK_SHARE * l / self.bytes_per_result);
        match (master, link) {
            (Some(m), Some(l)) => Some(m.min(l)),
            (m, l) => m.or(l),
        }
    }

    /// Reviews the job size from what is measured; frames from `next_frame` on take the
    /// returned samples per pixel.
    pub fn review(&mut self, next_frame: FrameNo) -> u32 {
        let current = self.spp();
        let wanted = self.wanted(current);
        if wanted != current {
            // Frames already opened keep theirs; a step at the same frame replaces it.
            if self.steps.back().is_some_and(|s| s.0 >= next_frame) {
                self.steps.pop_back();
            }
            self.steps.push_back((next_frame, wanted));
            while self.steps.len() > STEPS_KEPT {
                self.steps.pop_front();
            }
        }
        wanted
    }

    /// The job size the measurements ask for, `current` in force.
    fn wanted(&self, current: u32) -> u32 {
        let (grid, Some(afford)) = (self.grid_rate(), self.affordable()) else {
            return self.base;
        };
        if grid <= 0.0 {
            return current;
        }
        let base = f64::from(self.base);
        let results = |factor: u32| grid / (base * f64::from(factor));
        let factor = current / self.base;
        let needed = (grid / (base * afford)).ceil().clamp(1.0, f64::from(MAX_FACTOR)) as u32;
        if needed > factor {
            needed * self.base
        } else if factor > 1 && results(factor - 1) <= LOWER * afford {
            // As far down as the margin allows.
            let mut f = factor - 1;
            while f > needed.max(1) && results(f - 1) <= LOWER * afford {
                f -= 1;
            }
            f * self.base
        } else {
            current
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` connections rendering jobs of the base (4 spp) in `job_ms` each.
    fn grid(n: u64, job_ms: f64, link: Option<f64>) -> JobSize {
        let mut s = JobSize::new(4, link, 300);
        for conn in 0..n {
            s.answered(conn, 0, (job_ms * 1e3) as u64);
        }
        s
    }

    /// A review period in which the master spent `cost_us` per result on `results`.
    fn master(s: &mut JobSize, results: u64, cost_us: f64) {
        let busy_seconds = results as f64 * cost_us * 1e-6;
        s.observe_master(MasterSample { busy_seconds, results, bytes: results * 1264 });
    }

    #[test]
    fn long_jobs_keep_the_papers_job_size() {
        // 256 workers with the paper's 56 ms jobs return 4571 results a second; a master
        // busy 20 µs a result affords 0.7 / 20 µs = 35 000.
        let mut s = grid(256, 56.0, None);
        assert_eq!(s.review(1), 4, "nothing measured of the master yet");
        master(&mut s, 4571 / 4, 20.0);
        assert_eq!(s.review(2), 4);
        assert_eq!(s.spp_of(2), 4);
    }

    #[test]
    fn short_jobs_on_a_saturated_master_take_more_samples_each() {
        // 256 workers with 1.7 ms jobs: 150 600 results a second at 4 spp; the master
        // affords 0.7 / 40 µs = 17 500, so a job must take 9 times as many samples.
        let mut s = grid(256, 1.7, None);
        master(&mut s, 3000, 40.0);
        assert_eq!(s.review(10), 36);
        let results = s.grid_rate() / 36.0;
        assert!(results <= s.affordable().unwrap(), "{results} results a second");
        assert!(s.grid_rate() / 32.0 > s.affordable().unwrap(), "not the smallest");
        assert_eq!((s.spp_of(9), s.spp_of(10), s.spp()), (4, 36, 36));
    }

    #[test]
    fn the_render_time_measured_is_per_sample_whatever_the_job_size() {
        let mut s = grid(8, 1.0, None);
        let before = s.grid_rate();
        master(&mut s, 3000, 700.0); // 1000 results a second affordable: 8 times the base
        assert_eq!(s.review(5), 32);
        for conn in 0..8 {
            s.answered(conn, 5, 8000); // 32 spp at the same speed: 8 ms
        }
        assert!((s.grid_rate() / before - 1.0).abs() < 1e-9, "the grid looks as fast");
        assert_eq!(s.review(6), 32, "and the size holds");
    }

    #[test]
    fn the_size_shrinks_when_the_grid_does_but_not_at_the_first_dip() {
        let mut s = grid(64, 4.0, None);
        master(&mut s, 3000, 140.0); // affords 5000 a second; the grid: 64 000 one-sample jobs
        assert_eq!(s.review(1), 16, "3.2 times the base's 16 000 results, rounded up");
        // A grid a little slower: 3 steps of the base would be 5300 > 0.8 × 5000.
        for conn in 0..64 {
            s.answered(conn, 1, 16_400);
        }
        assert_eq!(s.review(2), 16, "no flapping at the margin");
        // Half the grid leaves: 32 000 one-sample jobs a second; two steps (8 spp) give
        // 4000 results a second, at the margin.
        for conn in 32..64 {
            s.left(conn);
        }
        assert_eq!(s.review(3), 8);
        for conn in 2..32 {
            s.left(conn);
        }
        assert_eq!(s.review(4), 4, "back to the paper's jobs");
        assert_eq!((s.spp_of(0), s.spp_of(1), s.spp_of(3), s.spp_of(4)), (4, 16, 8, 4));
    }

    #[test]
    fn the_link_bounds_the_result_bytes_per_second() {
        // A 1 Gbit/s link and results of 300 pixels (1264 bytes): 0.9 × 125e6 / 1264 =
        // 89 000 results a second. 256 workers with 1 ms jobs: 256 000 at 4 spp.
        let link = 125e6;
        let mut s = grid(256, 1.0, Some(link));
        assert_eq!(s.review(1), 12, "the link alone bounds it, before the master is measured");
        let bytes = s.grid_rate() / 12.0 * 1264.0;
        assert!(bytes <= LINK_SHARE * link, "{bytes} B/s");
        // A fast master changes nothing; a slower one than the link takes over.
        master(&mut s, 3000, 1.0);
        assert_eq!(s.review(2), 12);
        for _ in 0..6 {
            master(&mut s, 3000, 100.0);
        }
        assert!(s.review(3) > 12, "the master's cost now bounds it");
    }

    #[test]
    fn measured_bytes_per_result_replace_the_estimate() {
        let mut s = JobSize::new(4, Some(1e6), 300);
        s.answered(1, 0, 100);
        assert_eq!(s.affordable(), Some(0.9e6 / 1264.0));
        s.observe_master(MasterSample { busy_seconds: f64::NAN, results: 1000, bytes: 2_528_000 });
        let r = s.affordable().unwrap();
        assert!(r < 0.9e6 / 1264.0, "bytes per result moved toward the 2528 measured: {r}");
        assert_eq!(s.cost, None, "no thread clock: no cost measured");
        s.observe_master(MasterSample { busy_seconds: 1.0, results: 5, bytes: 0 });
        assert_eq!(s.cost, None, "too few results to measure");
    }

    #[test]
    fn a_worker_reporting_no_time_is_bounded_by_the_largest_job() {
        let mut s = grid(4, 10.0, Some(1e6));
        s.answered(99, 0, 0);
        assert_eq!(s.review(1), 4 * MAX_FACTOR);
        s.left(99);
        assert!(s.review(2) < 4 * MAX_FACTOR);
    }
}
