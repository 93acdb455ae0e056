//! `gridlight worker`: render jobs for a master; each thread is one independent worker.

use std::path::PathBuf;

use super::GlobalArgs;
use crate::worker::{self, RendererKind, WorkerConfig, WorkerError};

/// Arguments of `gridlight worker`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The master's address, `HOST:PORT`.
    #[arg(long, value_name = "HOST:PORT")]
    pub master: String,
    /// Render threads, each its own connection (default: the idle cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// File holding the shared secret the master requires (its bytes, trailing newline
    /// removed).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// Asset cache directory (default: `gridlight` under the user's cache directory).
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Name shown in the master's logs (default: host name and process id).
    #[arg(long)]
    pub name: Option<String>,
    /// Jobs held per connection (pipelining; 1 is the paper's strict request/response).
    #[arg(long, default_value_t = worker::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// Answer every job with constant radiance at no cost (for `gridlight bench master`).
    #[arg(long, hide = true)]
    pub null_render: bool,
    /// With `--null-render`: sleep this long per job, as if rendering (fault-injection tests).
    #[arg(long, hide = true, default_value_t = 0)]
    pub null_render_delay_ms: u32,
}

/// Runs `gridlight worker` until Ctrl-C or a fatal error.
pub fn run(args: Args, _global: &GlobalArgs) -> anyhow::Result<()> {
    let secret = match &args.secret_file {
        Some(path) => Some(gridlight_actors::auth::read_secret_file(path)?),
        None => None,
    };
    let config = WorkerConfig {
        master: args.master,
        threads: args.threads.unwrap_or_else(worker::idle_cores).max(1),
        secret,
        cache_dir: args.cache_dir.unwrap_or_else(worker::cache::AssetCache::default_dir),
        name: args.name.unwrap_or_else(worker::default_name),
        pipeline: args.pipeline.max(1),
        renderer: if args.null_render {
            RendererKind::Null { delay_ms: args.null_render_delay_ms }
        } else {
            RendererKind::PathTracer
        },
    };
    match worker::run(config) {
        Ok(()) => Ok(()),
        Err(err @ WorkerError::Rejected { .. }) | Err(err @ WorkerError::NeedSecret) => {
            // Said plainly on stderr whatever RUST_LOG is: this is why the worker stops.
            eprintln!("gridlight worker: {err}");
            Err(err.into())
        }
        Err(err) => Err(err.into()),
    }
}
