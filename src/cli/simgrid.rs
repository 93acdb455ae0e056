//! `gridlight simgrid`: one process of a simulated grid (see `crate::simgrid`). Started by
//! `gridlight eval` with a frame cache it prepared; runnable by hand against any master
//! serving the cached scene.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use tokio_util::sync::CancellationToken;

use super::GlobalArgs;
use crate::simgrid::process::{self, ProcessOptions};
use crate::simgrid::{availability::PAPER_PERIOD, Availability, Curve, FrameCache, SimGrid};

/// Arguments of `gridlight simgrid`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The master's `HOST:PORT`.
    #[arg(long, value_name = "HOST:PORT")]
    pub master: String,
    /// The frame cache and cost model (written by `gridlight eval`).
    #[arg(long, value_name = "FILE")]
    pub cache: PathBuf,
    /// Workers of the whole grid (N of the availability curve).
    #[arg(long)]
    pub grid: u32,
    /// How many of them are available per frame.
    #[arg(long, value_enum, default_value_t = Curve::Constant)]
    pub availability: Curve,
    /// Period of the availability curve, in frames.
    #[arg(long, default_value_t = PAPER_PERIOD)]
    pub period: u32,
    /// This process's first worker (grid-wide number).
    #[arg(long, default_value_t = 0)]
    pub first: u32,
    /// This process's number of workers (default: all of the grid's peak from `--first`).
    #[arg(long)]
    pub count: Option<u32>,
    /// Jobs each worker holds (k).
    #[arg(long, default_value_t = crate::worker::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// The master's fixed frame rate: the curve's frame i is the one due i/FPS seconds
    /// after start (default: the newest frame a job named).
    #[arg(long)]
    pub fps: Option<f32>,
}

/// Runs `gridlight simgrid` until Ctrl-C or a fatal error.
pub fn run(args: Args, _global: &GlobalArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.grid > 0, "--grid must be at least 1");
    let cache = FrameCache::load(&args.cache)?;
    anyhow::ensure!(!cache.is_empty(), "{} holds no frames", args.cache.display());
    let availability = Availability { curve: args.availability, n: args.grid, period: args.period };
    let count = args.count.unwrap_or_else(|| availability.peak().saturating_sub(args.first));
    let opts = ProcessOptions {
        master: args.master,
        availability,
        first: args.first,
        count,
        pipeline: args.pipeline.max(1),
        frame_rate: args.fps.filter(|f| *f > 0.0),
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("simgrid")
        .enable_all()
        .build()
        .context("starting the runtime")?;
    let outcome = runtime.block_on(async move {
        let cancel = CancellationToken::new();
        let ctrl_c = cancel.clone();
        tokio::spawn(async move {
            let _ = tokio::signal::ctrl_c().await;
            ctrl_c.cancel();
        });
        process::run_until(opts, Arc::new(SimGrid::new(cache)), cancel).await
    });
    Ok(outcome?)
}
