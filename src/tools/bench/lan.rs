//! `gridlight bench lan`: the grid across separate network hosts, each behind a link of a
//! given rate, against the bound that bandwidth alone sets.
//!
//! For every (link rate, worker hosts) pair a [`Testbed`] is built: the master runs in this
//! process on a thread inside the master host's namespace, and each worker host runs one
//! `gridlight worker --null-render` process (`ip netns exec`) whose connections answer
//! every job after a modelled render time. As in `bench master`, frames are shown only when
//! complete, 640×480 in 64 sets. Bytes are the master link's interface counters (Ethernet
//! frames: results, jobs, TCP/IP headers and acknowledgements). The bandwidth bound is the
//! link rate over the bytes per frame of the busier direction (into the master); the
//! compute bound is what the workers' modelled render time allows. One JSON object per
//! configuration, with per-host results and per-link rates so that a test can check that
//! frames came from every host and that no link carried more than its rate.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{self, MasterHandle};
use serde::Serialize;

use super::master::{
    bench_state, complete_frames_config, CountingSink, RESOLUTION, SETS, WARMUP_FRAMES,
    WARMUP_TIMEOUT,
};
use crate::children::Children;
use crate::tools::lan::{netns, Host, LinkCounters, Testbed, TestbedSpec};

/// Link rates measured by default, Mbit/s.
pub const DEFAULT_LINKS_MBIT: [u32; 2] = [100, 1000];
/// Worker host counts measured by default.
pub const DEFAULT_HOSTS: [usize; 2] = [2, 8];
/// Render threads (connections) per worker host by default.
pub const DEFAULT_THREADS: u32 = 4;
/// Modelled render time of one job by default: 4 800 pixels at 4 spp on one core of a
/// current desktop, about 2 M samples per second.
pub const DEFAULT_RENDER_MS: u32 = 10;

/// Options of one benchmark run.
#[derive(Clone, Debug)]
pub struct LanOptions {
    pub links_mbit: Vec<u32>,
    pub hosts: Vec<usize>,
    pub threads: u32,
    pub render_ms: u32,
    pub pipeline: u32,
    /// Seconds measured per configuration, after the warm-up.
    pub seconds: f64,
}

/// One line of the benchmark's output.
#[derive(Clone, Debug, Serialize)]
pub struct LanBench {
    pub link_mbit: u32,
    pub hosts: usize,
    pub frames_per_second: f64,
    /// Bytes on the master's link per frame (S accepted results), both directions.
    pub bytes_per_frame: f64,
    /// Of those, into the master (results).
    pub bytes_in_per_frame: f64,
    /// Frames per second the link rate allows at `bytes_in_per_frame`.
    pub bandwidth_bound_fps: f64,
    /// Frames per second the workers' modelled render time allows.
    pub compute_bound_fps: f64,
    pub threads_per_host: u32,
    pub render_ms: u32,
    /// Connections the master counted as workers at the end of the measurement.
    pub workers: u64,
    /// Results accepted from each worker host since it joined, by host.
    pub results_by_host: BTreeMap<String, u64>,
    /// Each host's link over the measurement, the master's first.
    pub links: Vec<LinkReport>,
    /// The limit of every link, each direction, and the token bucket's depth.
    pub link_limit_bytes_per_second: f64,
    pub burst_bytes: u64,
    pub frames: u64,
    pub seconds: f64,
    pub width: u32,
    pub height: u32,
    pub sets: u32,
}

/// Traffic of one link over the measured interval.
#[derive(Clone, Debug, Serialize)]
pub struct LinkReport {
    pub host: String,
    pub rx_bytes: u64,
    pub tx_bytes: u64,
    /// Between the two counter readings (each bracketed by the time it took; midpoints).
    pub seconds: f64,
    /// The longest the readings can be apart: a link within its rate carried at most
    /// `rate × max_seconds + burst` bytes.
    pub max_seconds: f64,
    pub rx_bytes_per_second: f64,
    pub tx_bytes_per_second: f64,
}

/// Runs every configuration, calling `emit` with each result as it is measured.
pub fn run(opts: &LanOptions, mut emit: impl FnMut(&LanBench)) -> anyhow::Result<()> {
    if let Some(why) = Testbed::unavailable() {
        bail!("bench lan builds hosts from network namespaces and cannot here: {why}");
    }
    let exe = std::env::current_exe().context("finding the gridlight executable")?;
    let cache = std::env::temp_dir().join(format!("gridlight-bench-lan-{}", std::process::id()));
    let outcome = opts.links_mbit.iter().try_for_each(|&link_mbit| {
        opts.hosts.iter().try_for_each(|&hosts| {
            let spec = TestbedSpec { worker_hosts: hosts, link_mbit };
            measure(&exe, &cache, spec, opts).map(|r| emit(&r))
        })
    });
    let _ = std::fs::remove_dir_all(&cache);
    outcome
}

fn measure(
    exe: &Path,
    cache: &Path,
    spec: TestbedSpec,
    opts: &LanOptions,
) -> anyhow::Result<LanBench> {
    let label = format!("{} Mbit/s, {} hosts", spec.link_mbit, spec.worker_hosts);
    let bed = Testbed::build(spec).with_context(|| format!("{label}: building the testbed"))?;
    let config =
        complete_frames_config(SocketAddr::new(bed.master().address.into(), 0), opts.pipeline);
    let handle = netns::run_in(&bed.master().namespace, || {
        master::start(config, bench_state(), AssetStore::new(), Box::new(CountingSink))
    })?
    .with_context(|| format!("{label}: starting the master"))?;
    let workers = start_workers(exe, cache, &bed, handle.local_addr(), opts)?;

    let connections = spec.worker_hosts as u64 * u64::from(opts.threads);
    wait_for(&handle, connections).with_context(|| label.clone())?;
    let before = Snapshot::take(&bed, &handle)?;
    std::thread::sleep(Duration::from_secs_f64(opts.seconds));
    let after = Snapshot::take(&bed, &handle)?;
    let workers_counted = handle.worker_counts().live;
    let results_by_host = results_by_host(&handle);
    drop(workers);
    handle.stop().with_context(|| format!("{label}: stopping the master"))?;

    let seconds = after.at.duration_since(before.at).as_secs_f64();
    let frames = after.shown - before.shown;
    let links: Vec<LinkReport> = bed
        .hosts()
        .iter()
        .zip(before.links.iter().zip(&after.links))
        .map(|(host, (b, a))| link_report(host, b, a))
        .collect();
    let master_link = &links[0];
    // Per frame from the accepted results (S to a frame), finer-grained than whole frames.
    let frames_of_jobs = (after.jobs - before.jobs).max(1) as f64 / f64::from(SETS);
    let per_frame = |bytes: u64| bytes as f64 / frames_of_jobs;
    let bytes_in_per_frame = per_frame(master_link.rx_bytes);
    let busier = bytes_in_per_frame.max(per_frame(master_link.tx_bytes));
    let jobs_per_second = connections as f64 * 1000.0 / f64::from(opts.render_ms.max(1));
    Ok(LanBench {
        link_mbit: spec.link_mbit,
        hosts: spec.worker_hosts,
        frames_per_second: frames as f64 / seconds,
        bytes_per_frame: per_frame(master_link.rx_bytes + master_link.tx_bytes),
        bytes_in_per_frame,
        bandwidth_bound_fps: bed.link_bytes_per_second() / busier.max(1.0),
        compute_bound_fps: jobs_per_second / f64::from(SETS),
        threads_per_host: opts.threads,
        render_ms: opts.render_ms,
        workers: workers_counted,
        results_by_host,
        links,
        link_limit_bytes_per_second: bed.link_bytes_per_second(),
        burst_bytes: bed.burst_bytes(),
        frames,
        seconds,
        width: RESOLUTION.width,
        height: RESOLUTION.height,
        sets: SETS,
    })
}

/// One null-render worker process per worker host, named after its host.
fn start_workers(
    exe: &Path,
    cache: &Path,
    bed: &Testbed,
    master: SocketAddr,
    opts: &LanOptions,
) -> anyhow::Result<Children> {
    let mut children = Children::new();
    for host in bed.workers() {
        let mut cmd = bed.command(host, exe);
        cmd.args([
            "worker",
            "--null-render",
            "--master",
            &master.to_string(),
            "--name",
            &host.name,
        ])
        .args(["--null-render-delay-ms", &opts.render_ms.to_string()])
        .args(["--threads", &opts.threads.to_string()])
        .args(["--pipeline", &opts.pipeline.to_string()])
        // They stand for other machines: at idle priority this machine's load would starve
        // their modelled renders.
        .args(["--priority", "normal"])
        .arg("--cache-dir")
        .arg(cache.join(&host.name))
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null());
        children.spawn(cmd).with_context(|| format!("starting the worker on {}", host.name))?;
    }
    Ok(children)
}

/// Waits for every connection and then for the warm-up frames.
fn wait_for(handle: &MasterHandle, connections: u64) -> anyhow::Result<()> {
    let deadline = Instant::now() + WARMUP_TIMEOUT;
    while handle.worker_counts().live < connections {
        if Instant::now() > deadline {
            bail!(
                "only {} of {connections} worker connections joined in {WARMUP_TIMEOUT:?}",
                handle.worker_counts().live
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let shown = handle.report().shown;
    if !handle.wait_for_frames(shown + WARMUP_FRAMES, WARMUP_TIMEOUT) {
        bail!("fewer than {WARMUP_FRAMES} frames in {WARMUP_TIMEOUT:?}");
    }
    Ok(())
}

/// Accepted results per worker host: connection `i` of host `NAME` calls itself `NAME#i`.
fn results_by_host(handle: &MasterHandle) -> BTreeMap<String, u64> {
    let mut by_host = BTreeMap::new();
    for worker in handle.workers() {
        let host = worker.name.split('#').next().unwrap_or(&worker.name).to_string();
        *by_host.entry(host).or_insert(0) += worker.jobs;
    }
    by_host
}

/// Frames shown and every link's counters, each reading bracketed by the time it took.
struct Snapshot {
    at: Instant,
    shown: u64,
    jobs: u64,
    links: Vec<(Instant, LinkCounters, Instant)>,
}

impl Snapshot {
    fn take(bed: &Testbed, handle: &MasterHandle) -> anyhow::Result<Self> {
        let at = Instant::now();
        let shown = handle.report().shown;
        let jobs = Counters::get(&handle.counters().results_accepted);
        let links = bed
            .hosts()
            .iter()
            .map(|host| {
                let start = Instant::now();
                let counters = bed.counters(host)?;
                Ok::<_, anyhow::Error>((start, counters, Instant::now()))
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(Self { at, shown, jobs, links })
    }
}

fn link_report(
    host: &Host,
    before: &(Instant, LinkCounters, Instant),
    after: &(Instant, LinkCounters, Instant),
) -> LinkReport {
    // Each reading happened somewhere inside its bracket.
    let max_seconds = after.2.duration_since(before.0).as_secs_f64();
    let min_seconds = after.0.saturating_duration_since(before.2).as_secs_f64();
    let seconds = (max_seconds + min_seconds) / 2.0;
    let rx_bytes = after.1.rx_bytes - before.1.rx_bytes;
    let tx_bytes = after.1.tx_bytes - before.1.tx_bytes;
    LinkReport {
        host: host.name.clone(),
        rx_bytes,
        tx_bytes,
        seconds,
        max_seconds,
        rx_bytes_per_second: rx_bytes as f64 / seconds,
        tx_bytes_per_second: tx_bytes as f64 / seconds,
    }
}
