//! The `gridlight` binary: parses the command line, starts logging and hands over to the
//! library (`gridlight::cli::run`).

use clap::Parser;
use tracing_subscriber::EnvFilter;

fn main() -> anyhow::Result<()> {
    let cli = gridlight::cli::Cli::parse();
    // RUST_LOG overrides the default level; logs go to stderr so stdout stays for output
    // such as benchmark JSON. Evaluations run masters in-process: their progress bar, not
    // every connection's log line, says what happens.
    let level = match cli.command {
        // Its masters run on loopback for the experiment only: no warning about secrets.
        gridlight::cli::Command::Eval(_) => "warn,gridlight_actors::master=error",
        _ => "info",
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(level)),
        )
        .with_writer(std::io::stderr)
        .init();
    gridlight::cli::run(cli)
}
