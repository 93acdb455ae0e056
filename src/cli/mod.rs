//! The command line: one clap-derive [`Cli`] with global options and one subcommand per file.
//!
//! Each subcommand lives in its own module with an `Args` struct and a
//! `run(args, &GlobalArgs) -> anyhow::Result<()>`; adding one means a module, a variant of
//! [`Command`] and an arm in [`run`]. The binary (`src/main.rs`) only parses and calls [`run`],
//! so tests can drive the same code in-process (STYLE.md item 1).

use std::path::PathBuf;

use clap::{Parser, Subcommand};

pub mod bench;
pub mod bench_lan;
pub mod bench_master;
pub mod bench_owner;
pub mod bench_waste;
pub mod demo;
pub mod eval;
pub mod eval_paper;
pub mod master;
pub mod render;
pub mod resolution;
pub mod scenes;
pub mod simgrid;
pub mod soak;
pub mod worker;
pub mod worker_file;
pub mod worker_gpu;

/// Interactive path tracing on a desktop grid.
#[derive(Debug, Parser)]
#[command(name = "gridlight", version, about, propagate_version = true)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// Options every subcommand accepts.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct GlobalArgs {
    /// Directory searched for scene assets (meshes, textures, environment maps); repeatable,
    /// searched in order before `GRIDLIGHT_ASSETS` (colon-separated) and `scenes/assets/`.
    #[arg(long = "assets", value_name = "DIR", global = true)]
    pub assets: Vec<PathBuf>,
}

/// The subcommands (each engineer adds theirs here, in its own module).
#[derive(Debug, Subcommand)]
pub enum Command {
    /// List the built-in scenes and the scene files found on the asset search path.
    Scenes(scenes::Args),
    /// Render a scene file to a PNG (tonemapped sRGB) or EXR (linear) image on all local cores.
    Render(render::Args),
    /// Evaluations that reproduce the paper's findings; JSON lines with `--json`.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// Measure performance (JSON lines with `--json`).
    Bench(bench::Args),
    /// Run a master and worker processes on loopback under random faults; print a JSON report.
    Soak(soak::Args),
    /// Serve a scene to workers and show (write) the frames they render.
    Master(master::Args),
    /// Render jobs for a master; every thread is one independent worker.
    Worker(worker::Args),
    /// A master plus one local worker process per core, on the Cornell box by default.
    Demo(demo::Args),
    /// Simulated workers (modelled render time, cached real pixels) for `gridlight eval`.
    #[command(hide = true)]
    Simgrid(simgrid::Args),
}

/// Runs the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Render(args) => render::run(args, &cli.global),
        Command::Scenes(args) => scenes::run(args, &cli.global),
        Command::Soak(args) => soak::run(args, &cli.global),
        Command::Eval(cmd) => eval::run(cmd, &cli.global),
        Command::Bench(args) => bench::run(args, &cli.global),
        Command::Master(args) => master::run(args, &cli.global),
        Command::Worker(args) => worker::run(args, &cli.global),
        Command::Demo(args) => demo::run(args, &cli.global),
        Command::Simgrid(args) => simgrid::run(args, &cli.global),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn a_subcommand_is_required() {
        assert!(Cli::try_parse_from(["gridlight"]).is_err());
    }

    /// Parses `gridlight <before> render s.toml --out x.png <after>`.
    fn parse(before: &[&str], after: &[&str]) -> Cli {
        let args = ["gridlight"]
            .iter()
            .chain(before)
            .chain(&["render", "s.toml", "--out", "x.png"])
            .chain(after)
            .copied();
        Cli::try_parse_from(args).expect("valid command line")
    }

    #[test]
    fn assets_option_is_repeatable_before_or_after_the_subcommand() {
        let expected = vec![PathBuf::from("a"), PathBuf::from("b")];
        // clap keeps the occurrences of one side only when a global option is given on both.
        assert_eq!(parse(&["--assets", "a", "--assets", "b"], &[]).global.assets, expected);
        assert_eq!(parse(&[], &["--assets", "a", "--assets", "b"]).global.assets, expected);
        assert!(parse(&[], &[]).global.assets.is_empty());
    }
}
