//! `gridlight bench lan`: the grid across network-namespace hosts behind rate-limited links.

use super::GlobalArgs;
use crate::tools::bench::lan::{
    self as lan_bench, LanOptions, DEFAULT_HOSTS, DEFAULT_LINKS_MBIT, DEFAULT_RENDER_MS,
    DEFAULT_THREADS,
};

/// Arguments of `gridlight bench lan`.
#[derive(Debug, Clone, clap::Args)]
pub struct LanArgs {
    /// Print JSON lines (the only output format; accepted for symmetry with `bench trace`).
    #[arg(long)]
    pub json: bool,
    /// Link rates to measure, Mbit/s per link and direction.
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_LINKS_MBIT)]
    pub links: Vec<u32>,
    /// Worker host counts to measure (the master has a host of its own).
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_HOSTS)]
    pub hosts: Vec<usize>,
    /// Render threads (connections) per worker host.
    #[arg(long, default_value_t = DEFAULT_THREADS)]
    pub threads: u32,
    /// Modelled render time of one job, milliseconds (the null renderer sleeps this long).
    #[arg(long, default_value_t = DEFAULT_RENDER_MS)]
    pub render_ms: u32,
    /// Jobs each worker connection holds (k).
    #[arg(long, default_value_t = gridlight_actors::master::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// Seconds measured per configuration (after a warm-up).
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
}

/// Runs `gridlight bench lan`: one JSON line per (link rate, hosts) pair.
pub fn run(args: LanArgs, _global: &GlobalArgs) -> anyhow::Result<()> {
    let opts = LanOptions {
        links_mbit: args.links,
        hosts: args.hosts,
        threads: args.threads.max(1),
        render_ms: args.render_ms,
        pipeline: args.pipeline.max(1),
        seconds: args.seconds,
    };
    lan_bench::run(&opts, |line| match serde_json::to_string(line) {
        Ok(json) => println!("{json}"),
        Err(err) => tracing::error!(cause = %err, "cannot serialise a result"),
    })
}
