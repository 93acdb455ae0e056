//! `gridlight bench owner-impact`: does a worker slow its desk's owner down?
//!
//! The owner's program is a CPU-bound loop (`busy_loop`, its own process at normal
//! priority, `busy_threads` threads). It runs alone, and beside a real worker process
//! (`gridlight worker`, default settings but `--threads`: render threads at the lowest
//! priority) that is rendering the scene for a real master on loopback; its throughput
//! beside the worker divided by its throughput alone is the ratio (goal ≥ 0.95). Runs
//! alternate, alone-then-beside and beside-then-alone in turn, so that drift in the
//! machine's load falls on both sides; the median ratio is reported.
//!
//! The master stands for another machine: it runs in this process, with a sink that only
//! counts, and its threads run at idle priority too, so that only the worker's impact is
//! measured. Before each "beside" run the worker must have returned results (it is warm
//! and rendering); the results it returns while the owner's loop runs are reported too.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{self, MasterHandle};
use serde::Serialize;

use super::busy_loop::BusyLoop;
use super::master::CountingSink;
use crate::children::Children;
use crate::master::launch::{self, MasterOptions};
use crate::scene::SceneSource;
use crate::worker::priority::{self, Priority};

/// How long a worker may take to return its first results.
const WARMUP_TIMEOUT: Duration = Duration::from_secs(120);

/// Options of one benchmark.
#[derive(Debug, Clone)]
pub struct OwnerImpactOptions {
    pub scene: PathBuf,
    pub asset_dirs: Vec<PathBuf>,
    /// Pairs of runs (alone, beside).
    pub runs: u32,
    /// Seconds of each run of the owner's loop.
    pub seconds: f64,
    /// Threads of the owner's loop.
    pub busy_threads: u32,
    /// Render threads of the worker.
    pub worker_threads: u32,
    /// The worker's `--priority`.
    pub priority: Priority,
}

/// The benchmark's one JSON object.
#[derive(Debug, Clone, Serialize)]
pub struct OwnerImpact {
    pub scene: String,
    pub cpus: usize,
    pub runs: u32,
    pub seconds: f64,
    pub busy_threads: u32,
    pub worker_threads: u32,
    pub priority: String,
    /// The owner's loop alone, iterations per second, run by run.
    pub alone_iterations_per_second: Vec<f64>,
    /// The owner's loop beside the rendering worker.
    pub beside_iterations_per_second: Vec<f64>,
    /// beside / alone, pair by pair.
    pub ratios: Vec<f64>,
    pub median_ratio: f64,
    /// Results the worker returned per second while the owner's loop ran beside it.
    pub worker_jobs_per_second_beside: Vec<f64>,
}

/// Runs the benchmark.
pub fn run(opts: &OwnerImpactOptions) -> anyhow::Result<OwnerImpact> {
    let exe = std::env::current_exe().context("finding the gridlight executable")?;
    let cache = std::env::temp_dir().join(format!("gridlight-owner-impact-{}", std::process::id()));
    let master = start_master(opts)?;
    let outcome = measure(&exe, &cache, &master, opts);
    let _ = std::fs::remove_dir_all(&cache);
    master.stop().context("stopping the master")?;
    outcome
}

fn measure(
    exe: &Path,
    cache: &Path,
    master: &MasterHandle,
    opts: &OwnerImpactOptions,
) -> anyhow::Result<OwnerImpact> {
    let (mut alone, mut beside, mut jobs) = (Vec::new(), Vec::new(), Vec::new());
    for run in 0..opts.runs {
        let alone_first = run % 2 == 0;
        if alone_first {
            alone.push(busy_loop(exe, opts)?.iterations_per_second);
        }
        let (loop_beside, jobs_per_second) = beside_worker(exe, cache, master, opts)?;
        beside.push(loop_beside.iterations_per_second);
        jobs.push(jobs_per_second);
        if !alone_first {
            alone.push(busy_loop(exe, opts)?.iterations_per_second);
        }
        tracing::info!(run, alone = alone[run as usize], beside = beside[run as usize], "run done");
    }
    let ratios: Vec<f64> = beside.iter().zip(&alone).map(|(b, a)| b / a).collect();
    Ok(OwnerImpact {
        scene: opts.scene.display().to_string(),
        cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
        runs: opts.runs,
        seconds: opts.seconds,
        busy_threads: opts.busy_threads,
        worker_threads: opts.worker_threads,
        priority: format!("{:?}", opts.priority).to_lowercase(),
        alone_iterations_per_second: alone,
        beside_iterations_per_second: beside,
        median_ratio: median(&ratios),
        ratios,
        worker_jobs_per_second_beside: jobs,
    })
}

/// The scene's master on loopback, its threads at idle priority (it stands for another
/// machine), frames counted and dropped.
fn start_master(opts: &OwnerImpactOptions) -> anyhow::Result<MasterHandle> {
    let options = MasterOptions {
        scene: SceneSource::find_with_assets(&opts.scene, &opts.asset_dirs)?.0,
        asset_dirs: opts.asset_dirs.clone(),
        listen: ([127, 0, 0, 1], 0).into(),
        sets: gridlight_actors::protocol::SetsConfig {
            sets: crate::cli::master::DEFAULT_SETS,
            partition: gridlight_actors::protocol::Partition::QuasiRandom,
        },
        pacing: Default::default(),
        display: Default::default(),
        pipeline: master::DEFAULT_PIPELINE,
        link_mbps: None,
        secret: None,
        announce: Default::default(),
        script: None,
        frames: None,
        keep_stale_jobs: false,
        sink_in_flight: gridlight_actors::presenter::DEFAULT_SINK_IN_FLIGHT,
        inject_panics: Vec::new(),
        headless: Default::default(),
    };
    let prepared = launch::prepare(&options)?;
    // Threads inherit their creator's policy: the master's thread is made by this one.
    std::thread::spawn(move || {
        if let Err(e) = priority::apply_to_current_thread(Priority::Idle) {
            tracing::warn!(cause = %e, "the master runs at normal priority");
        }
        master::start(prepared.config, prepared.state, prepared.store, Box::new(CountingSink))
    })
    .join()
    .map_err(|_| anyhow::anyhow!("the master's starter thread panicked"))?
    .context("starting the master")
}

/// The owner's loop, in its own process.
fn busy_loop(exe: &Path, opts: &OwnerImpactOptions) -> anyhow::Result<BusyLoop> {
    let out = Command::new(exe)
        .args(["bench", "busy-loop", "--json", "--threads"])
        .arg(opts.busy_threads.to_string())
        .arg("--seconds")
        .arg(opts.seconds.to_string())
        .stdin(Stdio::null())
        .stderr(Stdio::inherit())
        .output()
        .context("running the busy loop")?;
    if !out.status.success() {
        bail!("the busy loop failed: {}", out.status);
    }
    serde_json::from_slice(&out.stdout).context("reading the busy loop's JSON")
}

/// The owner's loop beside a worker that renders, and the worker's results per second.
fn beside_worker(
    exe: &Path,
    cache: &Path,
    master: &MasterHandle,
    opts: &OwnerImpactOptions,
) -> anyhow::Result<(BusyLoop, f64)> {
    let results = || Counters::get(&master.counters().results_accepted);
    let before_start = results();
    let mut worker = Children::new();
    let mut cmd = Command::new(exe);
    cmd.args(["worker", "--name", "owner-impact", "--master"])
        .arg(master.local_addr().to_string())
        .arg("--threads")
        .arg(opts.worker_threads.to_string())
        .arg("--priority")
        .arg(format!("{:?}", opts.priority).to_lowercase())
        .arg("--cache-dir")
        .arg(cache)
        .env("RUST_LOG", "warn")
        .stdin(Stdio::null())
        .stdout(Stdio::null());
    worker.spawn(cmd).context("starting the worker")?;
    let warm = u64::from(opts.worker_threads) * 2;
    let deadline = Instant::now() + WARMUP_TIMEOUT;
    while results() < before_start + warm {
        if Instant::now() > deadline {
            bail!("the worker returned fewer than {warm} results in {WARMUP_TIMEOUT:?}");
        }
        if !worker.reap_exited().is_empty() {
            bail!("the worker exited before rendering");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let before = (results(), Instant::now());
    let owner = busy_loop(exe, opts)?;
    let jobs_per_second = (results() - before.0) as f64 / before.1.elapsed().as_secs_f64();
    drop(worker);
    Ok((owner, jobs_per_second))
}

/// The median (mean of the middle two for an even count); NaN when empty.
fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn the_median_of_odd_and_even_counts() {
        assert_eq!(median(&[0.9, 1.0, 0.97]), 0.97);
        assert_eq!(median(&[1.0, 0.5, 0.9, 0.7]), 0.8);
        assert!(median(&[]).is_nan());
    }
}
