//! Plain data for the status panel — frame rate, the last frame's statistics, the
//! workers — and the frame-rate meter. Filled from the master's statistics, drawn by
//! [`super::panel`]; nothing here knows about egui or actors.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// One row of the worker list.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WorkerRow {
    /// Its connection, which also picks its colour in the workers view.
    pub id: u64,
    pub name: String,
    /// The host it connects from.
    pub host: String,
    pub cores: u32,
    pub jobs_per_second: f32,
    /// Results accepted since it joined.
    pub jobs: u64,
    /// Results that came back after their frame was shown.
    pub late: u64,
    /// Mean render time per job, milliseconds.
    pub mean_job_ms: f32,
    /// Seconds since the master last heard from it.
    pub last_seen_s: f32,
    /// Why it paused (its desk's owner is active); `None` while it takes jobs.
    pub paused: Option<String>,
}

/// What the status panel shows about the last shown frame and the grid.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StatusView {
    /// Frames drawn per second in the window.
    pub fps: f32,
    pub frame: u64,
    pub state_version: u64,
    /// Q_t of the last frame: jobs back / jobs of the frame.
    pub q: f32,
    /// I_t of the last frame: its time / the previous frame's.
    pub i: f32,
    pub jobs_back: u64,
    pub jobs_total: u64,
    pub frames_skipped: u64,
    pub dropped_late: u64,
    pub bytes_in: u64,
    pub bytes_out: u64,
    /// Frames the window never drew because a newer one came first.
    pub frames_replaced: u64,
    pub workers: Vec<WorkerRow>,
    /// The reconstructor and the window's graphics adapter, for the curious.
    pub reconstructor: String,
    pub adapter: String,
    /// Frames the compose thread read back from the GPU reconstruction so far (none when
    /// it runs on the window's device and the final view is shown).
    pub frames_read_back: u64,
    /// Pictures the window uploaded so far (the CPU path and the diagnostic views).
    pub picture_uploads: u64,
    /// Frames the window drew from the reconstruction's textures so far.
    pub device_frames: u64,
    /// When the edits this frame shows first were made, those of frames replaced before
    /// the window took one included (the window stamps the latency when it presents the
    /// frame).
    pub edits_at: Vec<Instant>,
    /// Edit-to-display latency: the last edit's, and the median and 95th percentile of
    /// recent ones, milliseconds (`None` before the first edit was shown).
    pub edit_latency_ms: Option<LatencySummary>,
}

/// The edit-to-display latencies the panel shows.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatencySummary {
    pub last: f32,
    pub median: f32,
    pub p95: f32,
}

/// Recent edit-to-display latencies (the last [`LatencyMeter::KEEP`]).
#[derive(Clone, Debug, Default)]
pub struct LatencyMeter {
    recent: VecDeque<f32>,
}

impl LatencyMeter {
    /// Latencies kept for the median and percentile.
    pub const KEEP: usize = 200;

    /// Records one latency in milliseconds.
    pub fn record(&mut self, ms: f32) {
        if self.recent.len() == Self::KEEP {
            self.recent.pop_front();
        }
        self.recent.push_back(ms);
    }

    /// Last, median and 95th percentile (nearest rank); `None` before any.
    pub fn summary(&self) -> Option<LatencySummary> {
        let last = *self.recent.back()?;
        let mut sorted: Vec<f32> = self.recent.iter().copied().collect();
        sorted.sort_by(f32::total_cmp);
        Some(LatencySummary {
            last,
            median: percentile(&sorted, 50.0),
            p95: percentile(&sorted, 95.0),
        })
    }
}

/// The `p`-th percentile of sorted, non-empty `values` by nearest rank.
pub fn percentile(sorted: &[f32], p: f32) -> f32 {
    let rank = ((p / 100.0) * sorted.len() as f32).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

/// Frames per second over a sliding window of recent frame times.
#[derive(Clone, Debug)]
pub struct FpsMeter {
    span: Duration,
    stamps: VecDeque<Instant>,
}

impl FpsMeter {
    /// A meter averaging over the last `span`.
    pub fn new(span: Duration) -> Self {
        Self { span, stamps: VecDeque::new() }
    }

    /// Records a frame at `now`.
    pub fn tick(&mut self, now: Instant) {
        self.stamps.push_back(now);
        while self.stamps.len() > 2 && now.duration_since(self.stamps[0]) > self.span {
            self.stamps.pop_front();
        }
    }

    /// Frames per second between the oldest and newest recorded frame; 0 with fewer than two.
    pub fn fps(&self) -> f32 {
        match (self.stamps.front(), self.stamps.back()) {
            (Some(first), Some(last)) if self.stamps.len() >= 2 => {
                let secs = last.duration_since(*first).as_secs_f32();
                if secs > 0.0 {
                    (self.stamps.len() - 1) as f32 / secs
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }
}

/// Human-readable byte count (KiB, MiB, GiB).
pub fn human_bytes(bytes: u64) -> String {
    const UNITS: [&str; 4] = ["B", "KiB", "MiB", "GiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", UNITS[unit])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fps_counts_intervals_over_the_span() {
        let start = Instant::now();
        let mut meter = FpsMeter::new(Duration::from_secs(1));
        assert_eq!(meter.fps(), 0.0);
        for i in 0..=10 {
            meter.tick(start + Duration::from_millis(100 * i));
        }
        assert!((meter.fps() - 10.0).abs() < 1e-3, "{}", meter.fps());
        // Much later frames push the old ones out of the span.
        meter.tick(start + Duration::from_secs(10));
        meter.tick(start + Duration::from_millis(10_500));
        assert!((meter.fps() - 2.0).abs() < 1e-3, "{}", meter.fps());
    }

    #[test]
    fn latency_summary_is_the_last_the_median_and_the_95th_percentile() {
        let mut m = LatencyMeter::default();
        assert_eq!(m.summary(), None);
        for ms in (1..=100).rev() {
            m.record(ms as f32);
        }
        let s = m.summary().unwrap();
        assert_eq!((s.last, s.median, s.p95), (1.0, 50.0, 95.0));
        // Only the most recent ones count.
        for _ in 0..LatencyMeter::KEEP {
            m.record(7.0);
        }
        assert_eq!(m.summary().unwrap().p95, 7.0);
    }

    #[test]
    fn bytes_read_naturally() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(5 * 1024 * 1024), "5.0 MiB");
    }
}
