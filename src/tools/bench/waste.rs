//! `gridlight bench waste`: the share of the grid's returned work that reaches an image, at
//! each grid size (issue 15; docs/design.md, decision 8).
//!
//! The master runs in this process with the benchmark's counting sink and the master's own
//! defaults (S = 64, k = 2, the wait heuristic unless `--fps`); the workers are one child
//! `gridlight worker --null-render` process holding `workers` connections on loopback, each
//! answering after `--job-ms` of simulated render time (a sleep on its render thread, so
//! 256 of them cost this machine nothing). After a warm-up (every worker connected and a
//! few frames shown) the counters are sampled over a fixed interval: results used in shown
//! frames against results judged in it (used, accepted into skipped frames, or dropped as
//! late).

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{self, MasterConfig, Pacing};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::stats::useful_fraction;
use serde::Serialize;

use super::master::{bench_state, spawn_null_workers, CountingSink, NullWorkers};

/// Grid sizes measured by default.
pub const DEFAULT_WORKERS: [u32; 4] = [8, 32, 128, 256];
/// Simulated render time per job by default.
pub const DEFAULT_JOB_MS: u32 = 200;
/// Frames shown before measuring, once every worker is connected.
const WARMUP_FRAMES: u64 = 5;
/// Longest wait for the warm-up.
const WARMUP_TIMEOUT: Duration = Duration::from_secs(60);

/// Options of one run.
#[derive(Debug, Clone)]
pub struct WasteOptions {
    pub workers: Vec<u32>,
    pub job_ms: u32,
    pub seconds: f64,
    pub sets: u32,
    /// Jobs a worker holds (k).
    pub pipeline: u32,
    /// `None`: the wait heuristic with the paper's values; `Some(fps)`: a fixed rate.
    pub fps: Option<f32>,
}

/// One line of the benchmark's output.
#[derive(Debug, Clone, Serialize)]
pub struct WasteBench {
    pub workers: u32,
    pub job_ms: u32,
    pub sets: u32,
    pub pipeline: u32,
    /// "heuristic" or "fps=F".
    pub pacing: String,
    /// Results used in shown frames ÷ results returned (accepted or late).
    pub useful_fraction: f64,
    pub results_used: u64,
    pub results_returned: u64,
    pub dropped_late: u64,
    /// Accepted into frames that were then skipped.
    pub unused_accepted: u64,
    /// Accepted into frames not yet displayed when the interval ended (not judged).
    pub pending_accepted: i64,
    /// Useful results per second ÷ what the grid can render per second (workers / job time):
    /// the share of the grid's capacity that reached an image.
    pub useful_per_capacity: f64,
    pub frames_per_second: f64,
    pub frames_skipped: u64,
    /// Mean Q_t of the frames shown in the interval.
    pub mean_q: f64,
    pub seconds: f64,
}

/// Runs every grid size, calling `emit` with each result as it is measured.
pub fn run(opts: &WasteOptions, mut emit: impl FnMut(&WasteBench)) -> anyhow::Result<()> {
    if opts.job_ms == 0 {
        bail!("--job-ms must be at least 1 (the waste comes from jobs taking time)");
    }
    let exe = std::env::current_exe().context("finding the gridlight executable")?;
    let cache = std::env::temp_dir().join(format!("gridlight-bench-waste-{}", std::process::id()));
    let outcome =
        opts.workers.iter().try_for_each(|&n| measure(&exe, &cache, n, opts).map(|r| emit(&r)));
    let _ = std::fs::remove_dir_all(&cache);
    outcome
}

fn measure(
    exe: &std::path::Path,
    cache: &std::path::Path,
    workers: u32,
    opts: &WasteOptions,
) -> anyhow::Result<WasteBench> {
    let mut config = MasterConfig::new(
        SocketAddr::from(([127, 0, 0, 1], 0)),
        SetsConfig { sets: opts.sets, partition: Partition::QuasiRandom },
    );
    config.pipeline = opts.pipeline.max(1);
    if let Some(fps) = opts.fps {
        config.pacing = Pacing::FixedFps(fps);
    }
    config.max_connections = config.max_connections.max(workers as usize);
    let handle = master::start(config, bench_state(), AssetStore::new(), Box::new(CountingSink))
        .context("starting the master")?;
    let spec = NullWorkers {
        connections: workers,
        pipeline: opts.pipeline,
        delay_ms: opts.job_ms,
        secret_file: None,
    };
    let children = spawn_null_workers(exe, handle.local_addr(), cache, &spec)?;

    let deadline = Instant::now() + WARMUP_TIMEOUT;
    while handle.worker_counts().live < u64::from(workers) {
        if Instant::now() >= deadline {
            bail!("{workers} workers: only {} connected in {WARMUP_TIMEOUT:?}", {
                handle.worker_counts().live
            });
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let seen = handle.report().shown;
    if !handle.wait_for_frames(seen + WARMUP_FRAMES, WARMUP_TIMEOUT) {
        bail!("{workers} workers: fewer than {WARMUP_FRAMES} frames in {WARMUP_TIMEOUT:?}");
    }
    let before = Sample::take(&handle);
    std::thread::sleep(Duration::from_secs_f64(opts.seconds));
    let after = Sample::take(&handle);
    drop(children);
    handle.stop().context("stopping the master")?;

    let seconds = after.at.duration_since(before.at).as_secs_f64();
    let used = after.used - before.used;
    let accepted = after.accepted - before.accepted;
    let late = after.late - before.late;
    let unused = after.unused - before.unused;
    let frames = after.shown - before.shown;
    let capacity = f64::from(workers) * 1e3 / f64::from(opts.job_ms) * seconds;
    Ok(WasteBench {
        workers,
        job_ms: opts.job_ms,
        sets: opts.sets,
        pipeline: opts.pipeline,
        pacing: opts.fps.map_or_else(|| "heuristic".into(), |f| format!("fps={f}")),
        // Judged results only: those in frames still open at either end of the interval are
        // neither used nor wasted yet (at 8 workers a frame takes a second).
        useful_fraction: useful_fraction(used, used + unused, late).unwrap_or(0.0),
        results_used: used,
        results_returned: used + unused + late,
        dropped_late: late,
        unused_accepted: unused,
        pending_accepted: accepted as i64 - (used + unused) as i64,
        useful_per_capacity: used as f64 / capacity,
        frames_per_second: frames as f64 / seconds,
        frames_skipped: after.skipped - before.skipped,
        mean_q: if frames == 0 { 0.0 } else { used as f64 / (frames * opts.sets as u64) as f64 },
        seconds,
    })
}

/// Counters at one instant.
struct Sample {
    at: Instant,
    shown: u64,
    skipped: u64,
    used: u64,
    unused: u64,
    accepted: u64,
    late: u64,
}

impl Sample {
    fn take(handle: &master::MasterHandle) -> Self {
        let c = handle.counters();
        let report = handle.report();
        Self {
            at: Instant::now(),
            shown: report.shown,
            skipped: report.skipped,
            used: Counters::get(&c.results_used),
            unused: Counters::get(&c.results_unused),
            accepted: Counters::get(&c.results_accepted),
            late: Counters::get(&c.dropped_late),
        }
    }
}
