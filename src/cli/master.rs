//! `gridlight master`: serve a scene to workers and show (here: write) the frames.

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::bail;
use gridlight_actors::master::{Heuristic, Pacing};
use gridlight_actors::protocol::{Partition, SetsConfig};

use super::GlobalArgs;
use crate::headless::HeadlessOptions;
use crate::master_cmd::{self, MasterOptions, DEFAULT_LISTEN};

/// Sets per frame when `--sets` is not given (DESIGN.md decision 1).
pub const DEFAULT_SETS: u32 = 64;

/// Pixel partition names on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PartitionArg {
    QuasiRandom,
    Tiles,
}

impl From<PartitionArg> for Partition {
    fn from(p: PartitionArg) -> Self {
        match p {
            PartitionArg::QuasiRandom => Partition::QuasiRandom,
            PartitionArg::Tiles => Partition::Tiles,
        }
    }
}

/// How frames are paced: the paper's wait heuristic or a fixed rate.
#[derive(Debug, Clone, clap::Args)]
pub struct PacingArgs {
    /// Fixed frame rate: show a frame every 1/F seconds (replaces the wait heuristic).
    #[arg(long, value_name = "F", conflicts_with_all = ["qmin", "qmax", "imin", "imax"])]
    pub fps: Option<f32>,
    /// Wait heuristic Q_min (fraction of the frame's jobs back).
    #[arg(long)]
    pub qmin: Option<f64>,
    /// Wait heuristic Q_max.
    #[arg(long)]
    pub qmax: Option<f64>,
    /// Wait heuristic I_min (time on this frame / time of the last).
    #[arg(long)]
    pub imin: Option<f64>,
    /// Wait heuristic I_max.
    #[arg(long)]
    pub imax: Option<f64>,
}

impl PacingArgs {
    /// The pacing these options describe (paper defaults for what is not given).
    pub fn pacing(&self) -> anyhow::Result<Pacing> {
        let pacing = match self.fps {
            Some(fps) => Pacing::FixedFps(fps),
            None => {
                let d = Heuristic::default();
                Pacing::Heuristic(Heuristic {
                    q_min: self.qmin.unwrap_or(d.q_min),
                    q_max: self.qmax.unwrap_or(d.q_max),
                    i_min: self.imin.unwrap_or(d.i_min),
                    i_max: self.imax.unwrap_or(d.i_max),
                })
            }
        };
        if let Err(e) = pacing.validate() {
            bail!("pacing: {e}");
        }
        Ok(pacing)
    }
}

/// Arguments of `gridlight master`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Address to listen on; port 0 picks a free port (the chosen address is printed).
    #[arg(long, default_value = DEFAULT_LISTEN)]
    pub listen: SocketAddr,
    /// Pixel sets (jobs) per frame; keep it far above the number of workers.
    #[arg(long, default_value_t = DEFAULT_SETS)]
    pub sets: u32,
    /// How pixels are assigned to sets.
    #[arg(long, value_enum, default_value_t = PartitionArg::QuasiRandom)]
    pub partition: PartitionArg,
    #[command(flatten)]
    pub pacing: PacingArgs,
    /// Jobs a worker may hold at once (k; 1 is the paper's request/response).
    #[arg(long, default_value_t = gridlight_actors::master::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// Interaction script: a TOML file of timed edits.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// No window: write frames and statistics (the only mode until the window lands).
    #[arg(long)]
    pub headless: bool,
    /// Stop after this many shown frames (default: run until Ctrl-C).
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Write every shown frame as PNG into this directory, plus `summary.json`.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Statistics, one JSON line per shown frame.
    #[arg(long, value_name = "FILE.jsonl")]
    pub stats: Option<PathBuf>,
    /// Shared secret workers must prove (HMAC over a nonce; the secret never travels).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    /// Also write each frame's own unfiltered results as EXR (process tests).
    #[arg(long, hide = true)]
    pub dump_current: bool,
}

impl Args {
    /// The run these arguments describe.
    pub fn options(&self, global: &GlobalArgs) -> anyhow::Result<MasterOptions> {
        let secret = match &self.secret_file {
            Some(path) => Some(gridlight_actors::auth::read_secret_file(path)?),
            None => None,
        };
        if self.dump_current && self.out.is_none() {
            bail!("--dump-current needs --out DIR");
        }
        Ok(MasterOptions {
            scene: self.scene.clone(),
            asset_dirs: global.assets.clone(),
            listen: self.listen,
            sets: SetsConfig { sets: self.sets, partition: self.partition.into() },
            pacing: self.pacing.pacing()?,
            pipeline: self.pipeline,
            secret,
            script: self.script.clone(),
            frames: self.frames,
            headless: HeadlessOptions {
                out_dir: self.out.clone(),
                stats: self.stats.clone(),
                verbose: true,
                dump_current: self.dump_current,
            },
        })
    }
}

/// Runs `gridlight master`.
pub fn run(args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    let opts = args.options(global)?;
    if !args.headless {
        tracing::info!("no window yet: running headless");
    }
    let report = master_cmd::run(&opts, |_| Ok(()))?;
    tracing::info!(shown = report.shown, skipped = report.skipped, "master finished");
    Ok(())
}
