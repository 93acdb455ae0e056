//! `gridlight bench master`: the master alone, with null-render workers on loopback.

use super::resolution::ResolutionArg;
use super::GlobalArgs;
use crate::tools::bench::master::{
    self as master_bench, BenchOptions, DEFAULT_CONNECTIONS, RESOLUTION,
};

/// Arguments of `gridlight bench master`.
#[derive(Debug, Clone, clap::Args)]
pub struct MasterArgs {
    /// Print JSON lines (the only output format; accepted for symmetry with `bench trace`).
    #[arg(long)]
    pub json: bool,
    /// Connection counts to measure.
    #[arg(long, value_delimiter = ',', default_values_t = DEFAULT_CONNECTIONS)]
    pub connections: Vec<u32>,
    /// Image sizes to measure, each with every connection count (default 640x480;
    /// for example `640x480,1920x1080,3840x2160`).
    #[arg(long, value_name = "WxH", value_delimiter = ',')]
    pub resolution: Vec<ResolutionArg>,
    /// Seconds measured per connection count (after a warm-up).
    #[arg(long, default_value_t = 3.0)]
    pub seconds: f64,
    /// Jobs each worker connection holds (k).
    #[arg(long, default_value_t = gridlight_actors::master::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// Give master and workers a random shared secret, as `--secret-file` does: every
    /// connection is then encrypted (and results carry no checksum of their own).
    #[arg(long)]
    pub secret: bool,
}

/// Runs `gridlight bench master`: one JSON line per connection count.
pub fn run(args: MasterArgs, _global: &GlobalArgs) -> anyhow::Result<()> {
    let opts = BenchOptions {
        connections: args.connections,
        resolutions: if args.resolution.is_empty() {
            vec![RESOLUTION]
        } else {
            args.resolution.iter().map(|r| r.0).collect()
        },
        seconds: args.seconds,
        pipeline: args.pipeline,
        secret: args.secret,
    };
    master_bench::run(&opts, |line| match serde_json::to_string(line) {
        Ok(json) => println!("{json}"),
        Err(err) => tracing::error!(cause = %err, "cannot serialise a result"),
    })
}
