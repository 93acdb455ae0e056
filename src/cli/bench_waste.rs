//! `gridlight bench waste`: the useful fraction of returned results at each grid size.

use super::GlobalArgs;
use crate::tools::bench::waste::{self, WasteOptions, DEFAULT_JOB_MS, DEFAULT_WORKERS};

/// Arguments of `gridlight bench waste`.
#[derive(Debug, Clone, clap::Args)]
pub struct WasteArgs {
    /// Print JSON lines (the only output format; accepted for symmetry with `bench trace`).
    #[arg(long)]
    pub json: bool,
    /// Grid sizes (worker connections, all in one null-render child process).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_WORKERS)]
    pub workers: Vec<u32>,
    /// Simulated render time of every job, milliseconds.
    #[arg(long, default_value_t = DEFAULT_JOB_MS)]
    pub job_ms: u32,
    /// Seconds measured per grid size (after a warm-up).
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// Pixel sets per frame (S).
    #[arg(long, default_value_t = 64)]
    pub sets: u32,
    /// Jobs each worker connection holds (k).
    #[arg(long, default_value_t = gridlight_actors::master::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// A fixed frame rate instead of the wait heuristic.
    #[arg(long)]
    pub fps: Option<f32>,
}

/// Runs `gridlight bench waste`: one JSON line per grid size.
pub fn run(args: WasteArgs, _global: &GlobalArgs) -> anyhow::Result<()> {
    let opts = WasteOptions {
        workers: args.workers,
        job_ms: args.job_ms,
        seconds: args.seconds,
        sets: args.sets,
        pipeline: args.pipeline,
        fps: args.fps,
    };
    waste::run(&opts, |line| match serde_json::to_string(line) {
        Ok(json) => println!("{json}"),
        Err(err) => tracing::error!(cause = %err, "cannot serialise a result"),
    })
}
