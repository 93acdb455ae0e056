//! `gridlight bench master`: how many frames per second the master assembles, and at
//! what CPU cost per job, when workers cost nothing.
//!
//! The master runs in this process with a sink that only counts; the workers are one
//! child `gridlight worker --null-render` process holding `connections` connections on
//! loopback, so the process's CPU time (getrusage) is the master's alone. Frames are
//! paced to be shown only when complete (Q_min = Q_max = 1), so frames per second are
//! whole assembled frames. Each configuration warms up for a few frames, then is
//! measured over a fixed interval; one JSON object per line. Before the workers start,
//! a scripted worker joins [`HANDSHAKES`] times (connect to `Welcome`, the encrypted
//! channel's handshake included with a secret): the median is `handshake_ms`. Each
//! resolution (`--resolution`, the paper's 640×480 by default) is measured with each
//! connection count; `bytes_in_per_frame` is what one whole frame costs the master's
//! inbound link (the figure `--link-mbps` budgets against).

use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use glam::Vec3;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{self, Heuristic, MasterConfig, Pacing, ShownFrame, SinkError};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sink::FrameSink;
use gridlight_actors::state::{Camera, Resolution, SceneState};
use serde::Serialize;

use crate::children::Children;
use crate::tools::bench::join;

/// Connection counts measured by default (issue 3).
pub const DEFAULT_CONNECTIONS: [u32; 4] = [1, 8, 32, 64];
/// Image size of the benchmark by default (the paper's).
pub const RESOLUTION: Resolution = Resolution { width: 640, height: 480 };
/// Sets per frame.
pub const SETS: u32 = 64;
/// Frames shown before measuring.
pub const WARMUP_FRAMES: u64 = 5;
/// Longest wait for the warm-up.
pub const WARMUP_TIMEOUT: Duration = Duration::from_secs(30);
/// Joins timed for `handshake_ms`.
pub const HANDSHAKES: usize = 15;

/// One line of the benchmark's output.
#[derive(Debug, Clone, Serialize)]
pub struct MasterBench {
    pub connections: u32,
    pub frames_per_second: f64,
    pub master_cpu_us_per_job: f64,
    /// Bytes on the wire (both directions, framing included) per pixel delivered.
    pub bytes_per_pixel: f64,
    /// Result bytes (worker → master) per pixel delivered.
    pub bytes_in_per_pixel: f64,
    /// Bytes into the master per whole frame shown (results, credits, heartbeats).
    pub bytes_in_per_frame: f64,
    /// Bytes both ways per whole frame shown.
    pub bytes_per_frame: f64,
    /// Bytes on the wire (both directions) per result accepted: the result, its credit
    /// and its job, with framing (and records and tags when encrypted).
    pub bytes_per_result: f64,
    /// Microseconds the master spent in the channel's cipher per result accepted
    /// (opening results and credits, sealing jobs); 0 without a secret.
    pub master_cipher_us_per_result: f64,
    /// Median milliseconds from connecting to `Welcome` for one worker connection.
    pub handshake_ms: f64,
    /// Whether workers authenticated with a shared secret (`--secret`).
    pub authenticated: bool,
    /// Whether the connections were encrypted (they are exactly when there is a secret).
    pub encrypted: bool,
    pub jobs_per_second: f64,
    pub frames: u64,
    pub seconds: f64,
    pub width: u32,
    pub height: u32,
    pub sets: u32,
}

/// Options of one benchmark run.
#[derive(Debug, Clone)]
pub struct BenchOptions {
    pub connections: Vec<u32>,
    /// Image sizes, each measured with every connection count.
    pub resolutions: Vec<Resolution>,
    pub seconds: f64,
    /// Jobs a worker holds (k).
    pub pipeline: u32,
    /// Workers prove a random shared secret (results carry MACs, not checksums).
    pub secret: bool,
}

/// Runs every configuration, calling `emit` with each result as it is measured.
pub fn run(opts: &BenchOptions, mut emit: impl FnMut(&MasterBench)) -> anyhow::Result<()> {
    let exe = std::env::current_exe().context("finding the gridlight executable")?;
    // The scene has no assets, so the cache stays empty; it still must not be the user's.
    let cache = std::env::temp_dir().join(format!("gridlight-bench-master-{}", std::process::id()));
    let secret_file = cache.with_extension("secret");
    let outcome = write_secret(opts.secret, &secret_file).and_then(|secret| {
        let secret = secret.as_ref().map(|s| (secret_file.as_path(), s.as_slice()));
        opts.resolutions.iter().try_for_each(|&resolution| {
            opts.connections.iter().try_for_each(|&connections| {
                measure(&exe, &cache, secret, connections, resolution, opts).map(|r| emit(&r))
            })
        })
    });
    let _ = std::fs::remove_dir_all(&cache);
    let _ = std::fs::remove_file(&secret_file);
    outcome
}

/// With `--secret`, a fresh random secret written to `path` for the workers: the hex of a
/// nonce, printable in a file as a user would write one.
fn write_secret(wanted: bool, path: &std::path::Path) -> anyhow::Result<Option<Vec<u8>>> {
    if !wanted {
        return Ok(None);
    }
    let secret: String =
        gridlight_actors::auth::nonce().iter().map(|b| format!("{b:02x}")).collect();
    std::fs::write(path, &secret).with_context(|| format!("writing {}", path.display()))?;
    Ok(Some(secret.into_bytes()))
}

fn measure(
    exe: &std::path::Path,
    cache: &std::path::Path,
    secret: Option<(&std::path::Path, &[u8])>,
    connections: u32,
    resolution: Resolution,
    opts: &BenchOptions,
) -> anyhow::Result<MasterBench> {
    let mut config = complete_frames_config(SocketAddr::from(([127, 0, 0, 1], 0)), opts.pipeline);
    config.secret = secret.map(|(_, bytes)| bytes.to_vec());
    let state = SceneState { resolution, ..bench_state() };
    let handle = master::start(config, state, AssetStore::new(), Box::new(CountingSink))
        .context("starting the master")?;
    let mut joins = (0..HANDSHAKES)
        .map(|i| join::time_join(handle.local_addr(), secret.map(|(_, s)| s), i))
        .collect::<anyhow::Result<Vec<f64>>>()?;
    joins.sort_by(f64::total_cmp);
    let spec = NullWorkers {
        connections,
        pipeline: opts.pipeline,
        delay_ms: 0,
        secret_file: secret.map(|(file, _)| file.to_path_buf()),
    };
    let workers = spawn_null_workers(exe, handle.local_addr(), cache, &spec)?;

    if !handle.wait_for_frames(WARMUP_FRAMES, WARMUP_TIMEOUT) {
        bail!("{connections} connections: fewer than {WARMUP_FRAMES} frames in {WARMUP_TIMEOUT:?}");
    }
    let before = Sample::take(&handle);
    std::thread::sleep(Duration::from_secs_f64(opts.seconds));
    let after = Sample::take(&handle);
    drop(workers);
    handle.stop().context("stopping the master")?;

    let seconds = after.at.duration_since(before.at).as_secs_f64();
    let frames = after.shown - before.shown;
    let jobs = (after.jobs - before.jobs).max(1);
    let pixels = jobs as f64 * resolution.pixels() as f64 / SETS as f64;
    let (bytes_in, bytes_out) =
        (after.bytes_in - before.bytes_in, after.bytes_out - before.bytes_out);
    let per_frame = |bytes: u64| if frames > 0 { bytes as f64 / frames as f64 } else { f64::NAN };
    Ok(MasterBench {
        connections,
        frames_per_second: frames as f64 / seconds,
        master_cpu_us_per_job: (after.cpu_us - before.cpu_us) / jobs as f64,
        bytes_per_pixel: ((after.bytes_in - before.bytes_in) + (after.bytes_out - before.bytes_out))
            as f64
            / pixels,
        bytes_in_per_pixel: (after.bytes_in - before.bytes_in) as f64 / pixels,
        bytes_in_per_frame: per_frame(bytes_in),
        bytes_per_frame: per_frame(bytes_in + bytes_out),
        bytes_per_result: ((after.bytes_in - before.bytes_in)
            + (after.bytes_out - before.bytes_out)) as f64
            / jobs as f64,
        master_cipher_us_per_result: (after.cipher_ns - before.cipher_ns) as f64
            / 1e3
            / jobs as f64,
        handshake_ms: joins[joins.len() / 2],
        authenticated: opts.secret,
        encrypted: opts.secret,
        jobs_per_second: jobs as f64 / seconds,
        frames,
        seconds,
        width: resolution.width,
        height: resolution.height,
        sets: SETS,
    })
}

/// A master on `listen` with the benchmark's sets, showing only complete frames (so that
/// frames per second are whole assembled frames), workers holding `pipeline` jobs each.
pub fn complete_frames_config(listen: SocketAddr, pipeline: u32) -> MasterConfig {
    let mut config =
        MasterConfig::new(listen, SetsConfig { sets: SETS, partition: Partition::QuasiRandom });
    config.pacing =
        Pacing::Heuristic(Heuristic { q_min: 1.0, q_max: 1.0, i_min: 100.0, i_max: 100.0 });
    config.pipeline = pipeline.max(1);
    config
}

/// Counters at one instant.
struct Sample {
    at: Instant,
    shown: u64,
    jobs: u64,
    bytes_in: u64,
    bytes_out: u64,
    cipher_ns: u64,
    cpu_us: f64,
}

impl Sample {
    fn take(handle: &master::MasterHandle) -> Self {
        let c = handle.counters();
        Self {
            at: Instant::now(),
            shown: handle.report().shown,
            jobs: Counters::get(&c.results_accepted),
            bytes_in: Counters::get(&c.bytes_in),
            bytes_out: Counters::get(&c.bytes_out),
            cipher_ns: Counters::get(&c.cipher_ns),
            cpu_us: process_cpu_us(),
        }
    }
}

/// User plus system CPU time of this process (all its threads), in microseconds: NaN
/// off Unix, where `getrusage` does not exist (`master_cpu_us_per_job` is then `null`).
#[cfg(not(unix))]
fn process_cpu_us() -> f64 {
    f64::NAN
}

/// User plus system CPU time of this process (all its threads), in microseconds.
#[cfg(unix)]
fn process_cpu_us() -> f64 {
    // SAFETY: rusage is plain integers, for which all-zero bytes are a valid value.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage writes only the struct it is given, which lives on this stack.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return 0.0;
    }
    let us = |t: libc::timeval| t.tv_sec as f64 * 1e6 + t.tv_usec as f64;
    us(usage.ru_utime) + us(usage.ru_stime)
}

/// What [`spawn_null_workers`] starts.
#[derive(Debug, Clone)]
pub struct NullWorkers {
    /// Connections (each one worker) of the single child process.
    pub connections: u32,
    /// Jobs each connection holds (k).
    pub pipeline: u32,
    /// Simulated render time per job; 0 answers at once on the connection's task.
    pub delay_ms: u32,
    /// The shared secret the workers prove, if any.
    pub secret_file: Option<std::path::PathBuf>,
}

/// Starts one child `gridlight worker --null-render` process with `spec.connections`
/// connections to `master`; it is killed when the returned [`Children`] is dropped.
pub fn spawn_null_workers(
    exe: &std::path::Path,
    master: SocketAddr,
    cache: &std::path::Path,
    spec: &NullWorkers,
) -> anyhow::Result<Children> {
    let mut workers = Children::new();
    let mut cmd = Command::new(exe);
    cmd.args(["worker", "--null-render", "--master"])
        .arg(master.to_string())
        .args([
            "--threads",
            &spec.connections.to_string(),
            "--pipeline",
            &spec.pipeline.to_string(),
            "--null-render-delay-ms",
            &spec.delay_ms.to_string(),
            "--name",
            "bench",
            // They stand for other machines: at idle priority the master would starve them.
            "--priority",
            "normal",
        ])
        .arg("--cache-dir")
        .arg(cache)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::null());
    if let Some(file) = &spec.secret_file {
        cmd.arg("--secret-file").arg(file);
    }
    workers.spawn(cmd).context("starting the null-render worker")?;
    Ok(workers)
}

/// A sink that drops frames: the benchmarks measure assembly, not output.
pub struct CountingSink;

impl FrameSink for CountingSink {
    fn show(&mut self, _frame: ShownFrame) -> Result<(), SinkError> {
        Ok(())
    }
}

/// An empty 640×480 scene: the null renderer never looks at it (also a base for tests).
pub fn bench_state() -> SceneState {
    SceneState::empty(RESOLUTION, Camera::pinhole(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 40.0))
}
