//! `gridlight soak`: the fault harness under random faults for a bounded time, one JSON
//! object at the end (issue 6). Loopback only; workers are this binary's `worker`
//! subcommand started as child processes.

use super::GlobalArgs;

/// Arguments of `gridlight soak`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// How long to run, in minutes.
    #[arg(long, default_value_t = 1.0)]
    pub minutes: f64,
    /// Worker processes at the resource curve's mean (it swings ±N/4).
    #[arg(long, default_value_t = 4)]
    pub workers: usize,
    /// Seed of the fault sequence (default: from the clock; printed in the report).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Run without a shared secret (by default the soak uses a random one).
    #[arg(long)]
    pub no_secret: bool,
    /// Print the report as one JSON object (the only output format for now).
    #[arg(long)]
    pub json: bool,
}

/// Runs the soak and prints its report; fails when an invariant was violated.
pub fn run(args: Args, _global: &GlobalArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.minutes > 0.0 && args.minutes <= 24.0 * 60.0,
        "--minutes must be in (0, 1440]"
    );
    anyhow::ensure!((1..=64).contains(&args.workers), "--workers must be 1 to 64");
    soak(args)
}

/// The fault harness stops and continues workers with POSIX signals.
#[cfg(not(unix))]
fn soak(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!(
        "gridlight soak stops and continues its worker processes with POSIX signals \
         (SIGSTOP, SIGCONT), so it runs on Unix (Linux, macOS) only"
    )
}

#[cfg(unix)]
fn soak(args: Args) -> anyhow::Result<()> {
    use crate::tools::faults::{harness::HarnessConfig, soak};
    use anyhow::Context;
    let seed = args.seed.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as u64)
    });
    let binary = std::env::current_exe().context("cannot find this executable to start workers")?;
    let mut config = HarnessConfig::new(binary, args.workers);
    if !args.no_secret {
        let secret: [u8; 32] = rand::random();
        config.secret = Some(secret.to_vec());
    }
    let report = soak::run(config, args.minutes, seed).context("soak harness")?;
    let violations = report.run.invariant_violations;
    println!("{}", serde_json::to_string(&report).context("report")?);
    anyhow::ensure!(violations == 0, "{violations} invariant violations (see `violations`)");
    Ok(())
}
