//! `gridlight demo`: a master and one local worker process per core, on the Cornell box.
//!
//! The workers are child processes of this executable (`gridlight worker`), not
//! threads, so they behave exactly like remote ones (own connection, handshake, asset
//! fetch into a cache); they are killed when the demo ends, however it ends. With a
//! display the frames appear in the window until it is closed; without one (no
//! `DISPLAY`/`WAYLAND_DISPLAY`) or with `--headless` the demo writes frames and
//! statistics for a bounded number of frames, so it terminates.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};

use anyhow::Context;
use gridlight_actors::protocol::{Partition, SetsConfig};
use tracing::info;

use super::master::{DisplayArgs, PacingArgs, DEFAULT_SETS};
use super::GlobalArgs;
use crate::children::Children;
use crate::master::headless::HeadlessOptions;
use crate::master::launch::{self, AnnounceOptions, MasterOptions};
use crate::scene::SceneSource;

/// Where a headless demo writes when `--out` is not given.
pub const DEFAULT_OUT: &str = "gridlight-demo";
/// Frames a headless demo shows before it ends.
pub const DEFAULT_FRAMES: u64 = 30;

/// Arguments of `gridlight demo`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// A scene file or the name of a built-in scene (default: the built-in Cornell box).
    pub scene: Option<PathBuf>,
    /// Local worker processes (default: one per core).
    #[arg(long)]
    pub workers: Option<usize>,
    /// Frames to show before stopping (headless default: 30; the window runs until closed).
    #[arg(long)]
    pub frames: Option<u64>,
    /// No window even when a display exists.
    #[arg(long)]
    pub headless: bool,
    /// Interaction script: a TOML file of timed edits, played from the start.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Output directory for frames, `stats.jsonl` and `summary.json`.
    #[arg(long, default_value = DEFAULT_OUT)]
    pub out: PathBuf,
    /// Pixel sets per frame.
    #[arg(long, default_value_t = DEFAULT_SETS)]
    pub sets: u32,
    /// The master's inbound link in Mbit/s: the grid is never asked for more result
    /// bytes per second than it carries (jobs take more samples per pixel instead).
    #[arg(long, value_name = "MBIT/S", value_parser = super::master::parse_link_mbps)]
    pub link_mbps: Option<f64>,
    /// Keep queued jobs of outdated scene states when the scene changes (the old
    /// scheduler; to measure the edit-to-display latency without the discard).
    #[arg(long, hide = true)]
    pub keep_stale_jobs: bool,
    /// Frames handed to the frame sink ahead of it (1: least latency; 2 was the default
    /// before; to measure the difference).
    #[arg(long, hide = true, default_value_t = 1)]
    pub sink_in_flight: usize,
    #[command(flatten)]
    pub pacing: PacingArgs,
    #[command(flatten)]
    pub display: DisplayArgs,
    /// Do not announce the demo's master (on loopback: other workers of this machine could
    /// join it, with the secret in `OUT/.demo-secret`).
    #[arg(long)]
    pub no_announce: bool,
}

/// Runs `gridlight demo`.
pub fn run(args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    let scene = match &args.scene {
        Some(arg) => SceneSource::find_with_assets(arg, &global.assets)?.0,
        None => SceneSource::default_builtin(),
    };
    let windowed = !args.headless && crate::window::display_available();
    if !windowed {
        args.display.check_windowless()?;
    }
    let workers = args
        .workers
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    let exe = std::env::current_exe().context("finding the gridlight executable")?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Only this machine's workers may join: a fresh random secret, shared through a file.
    let secret: [u8; 32] = rand::random();
    let secret_hex = hex::encode(secret).into_bytes();
    let secret_file = args.out.join(".demo-secret");
    write_private(&secret_file, &secret_hex)?;

    let opts = MasterOptions {
        scene,
        asset_dirs: global.assets.clone(),
        listen: SocketAddr::from(([127, 0, 0, 1], 0)),
        sets: SetsConfig { sets: args.sets, partition: Partition::QuasiRandom },
        pacing: args.pacing.overrides(),
        display: args.display.clone(),
        pipeline: gridlight_actors::master::DEFAULT_PIPELINE,
        link_mbps: args.link_mbps,
        secret: Some(secret_hex),
        announce: AnnounceOptions { enabled: !args.no_announce, to: None, name: None },
        script: args.script.clone(),
        frames: if windowed { args.frames } else { Some(args.frames.unwrap_or(DEFAULT_FRAMES)) },
        keep_stale_jobs: args.keep_stale_jobs,
        sink_in_flight: args.sink_in_flight,
        inject_panics: Vec::new(),
        headless: HeadlessOptions {
            out_dir: Some(args.out.clone()),
            stats: Some(args.out.join("stats.jsonl")),
            verbose: true,
            view: args.display.view,
            ..HeadlessOptions::default()
        },
    };
    let children = Arc::new(Mutex::new(Children::new()));
    let start_workers = {
        let children = Arc::clone(&children);
        let secret_file = secret_file.clone();
        move |addr: SocketAddr| -> anyhow::Result<()> {
            let mut children = children.lock().unwrap_or_else(|p| p.into_inner());
            for i in 0..workers {
                let mut cmd = Command::new(&exe);
                cmd.args(["worker", "--threads", "1", "--master"])
                    .arg(addr.to_string())
                    .arg("--name")
                    .arg(format!("demo-{i}"))
                    .arg("--secret-file")
                    .arg(&secret_file)
                    .stdin(Stdio::null());
                let pid = children.spawn(cmd).context("starting a worker process")?;
                info!(pid, "worker process started");
            }
            Ok(())
        }
    };
    let stop_workers = {
        let children = Arc::clone(&children);
        move || children.lock().unwrap_or_else(|p| p.into_inner()).kill_all()
    };
    let outcome = if windowed {
        let window = crate::window::WindowOptions {
            title: format!("gridlight demo: {}", opts.scene.name()),
            view: args.display.view,
            shot_dir: args.out.clone(),
            follow_window: args.display.follow_window(),
            ..crate::window::WindowOptions::default()
        };
        launch::run_window(&opts, window, start_workers, Some(Box::new(stop_workers.clone())))
    } else {
        launch::run(&opts, start_workers)
    };
    stop_workers();
    let _ = std::fs::remove_file(&secret_file);
    let report = outcome?;
    // The same summary however the demo ended: window closed, Ctrl-C, SIGTERM, frame limit.
    println!(
        "demo: {} frames shown ({} skipped) by {workers} worker processes; {}",
        report.shown,
        report.skipped,
        if windowed {
            format!("screenshots and scripts in {}", args.out.display())
        } else {
            format!("frames and stats in {}", args.out.display())
        }
    );
    Ok(())
}

/// Writes a file only the current user can read (mode 0600 on Unix; elsewhere the
/// file takes its folder's permissions).
fn write_private(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    use std::io::Write;
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut f = options.open(path).with_context(|| format!("writing {}", path.display()))?;
    f.write_all(bytes).with_context(|| format!("writing {}", path.display()))
}
