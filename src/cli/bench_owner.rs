//! `gridlight bench owner-impact` and its hidden helper `gridlight bench busy-loop`.

use std::path::PathBuf;

use super::GlobalArgs;
use crate::tools::bench::owner_impact::{self, OwnerImpactOptions};
use crate::worker::Priority;

/// Arguments of `gridlight bench owner-impact`.
#[derive(Debug, Clone, clap::Args)]
pub struct OwnerImpactArgs {
    /// Print one JSON object (the only format; accepted for symmetry).
    #[arg(long)]
    pub json: bool,
    /// The scene the worker renders.
    #[arg(long, default_value = "scenes/cornell-box.toml")]
    pub scene: PathBuf,
    /// Pairs of runs (owner's program alone, beside the worker), alternating.
    #[arg(long, default_value_t = 5)]
    pub runs: u32,
    /// Seconds per run of the owner's program.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Threads of the owner's program.
    #[arg(long, default_value_t = 2)]
    pub busy_threads: u32,
    /// Render threads of the worker.
    #[arg(long, default_value_t = 2)]
    pub worker_threads: u32,
    /// The worker's render-thread priority (normal shows what the default prevents).
    #[arg(long, value_enum, default_value_t = Priority::Idle)]
    pub priority: Priority,
}

/// Arguments of `gridlight bench busy-loop`.
#[derive(Debug, Clone, clap::Args)]
pub struct BusyLoopArgs {
    /// Print one JSON object (the only format).
    #[arg(long)]
    pub json: bool,
    #[arg(long, default_value_t = 2)]
    pub threads: u32,
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
}

/// Runs the benchmark and prints its JSON object.
pub fn run_owner_impact(args: OwnerImpactArgs, global: &GlobalArgs) -> anyhow::Result<()> {
    if args.runs == 0 || args.seconds.is_nan() || args.seconds <= 0.0 {
        anyhow::bail!("--runs and --seconds must be positive");
    }
    let report = owner_impact::run(&OwnerImpactOptions {
        scene: args.scene,
        asset_dirs: global.assets.clone(),
        runs: args.runs,
        seconds: args.seconds,
        busy_threads: args.busy_threads,
        worker_threads: args.worker_threads,
        priority: args.priority,
    })?;
    println!("{}", serde_json::to_string(&report)?);
    Ok(())
}

/// Spins and prints what it did as JSON.
pub fn run_busy_loop(args: BusyLoopArgs) -> anyhow::Result<()> {
    let r = crate::tools::bench::busy_loop::run(args.threads, args.seconds);
    println!("{}", serde_json::to_string(&r)?);
    Ok(())
}
