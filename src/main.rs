//! The `gridlight` binary: parses the command line, starts logging and hands over to the
//! library (`gridlight::cli::run`).

use clap::Parser;
use tracing_subscriber::EnvFilter;

fn main() -> anyhow::Result<()> {
    // RUST_LOG overrides the default level; logs go to stderr so stdout stays for output
    // such as benchmark JSON.
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info")),
        )
        .with_writer(std::io::stderr)
        .init();
    gridlight::cli::run(gridlight::cli::Cli::parse())
}
