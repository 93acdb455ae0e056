//! `gridlight eval paper` and the experiments one by one (`eval fig3`, `fig5`, `table1`,
//! `fig8`, `fig9`, `fig10`, `lan`): each writes `report.md`, `index.html`, `results.json`, its
//! plots and images into `--out`, with a progress bar on stderr.

use std::path::PathBuf;

use super::GlobalArgs;
use crate::simgrid::Curve;
use crate::tools::eval::paper::{self, Context, Options};

/// What every experiment takes.
#[derive(Debug, Clone, clap::Args)]
pub struct Common {
    /// Directory for the report, plots and images (created if needed).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// The reduced run (under 3 minutes on 2 cores) instead of the full one (about 20).
    #[arg(long)]
    pub quick: bool,
}

/// `gridlight eval fig3`.
#[derive(Debug, Clone, clap::Args)]
pub struct Fig3Args {
    #[command(flatten)]
    pub common: Common,
    /// Fractions of the frame's jobs lost.
    #[arg(long, value_delimiter = ',')]
    pub loss: Option<Vec<f64>>,
}

/// `gridlight eval fig5`.
#[derive(Debug, Clone, clap::Args)]
pub struct Fig5Args {
    #[command(flatten)]
    pub common: Common,
    /// N of the availability curve.
    #[arg(long)]
    pub workers: Option<u32>,
    /// The fixed frame rate.
    #[arg(long)]
    pub fps: Option<f32>,
    #[arg(long, value_enum)]
    pub availability: Option<Curve>,
    /// Period of the curve in frames.
    #[arg(long)]
    pub period: Option<u32>,
    /// The camera path (an interaction script).
    #[arg(long, value_name = "FILE")]
    pub path: Option<PathBuf>,
}

/// `gridlight eval table1`.
#[derive(Debug, Clone, clap::Args)]
pub struct Table1Args {
    #[command(flatten)]
    pub common: Common,
    #[arg(long, value_delimiter = ',')]
    pub scenes: Option<Vec<String>>,
    #[arg(long, value_delimiter = ',')]
    pub workers: Option<Vec<u32>>,
    /// Seconds measured per cell.
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// `gridlight eval fig8`.
#[derive(Debug, Clone, clap::Args)]
pub struct Fig8Args {
    #[command(flatten)]
    pub common: Common,
    #[arg(long, value_delimiter = ',')]
    pub workers: Option<Vec<u32>>,
    /// Seconds each grid converges.
    #[arg(long)]
    pub seconds: Option<f64>,
    /// Mean FLIP below which two images are taken to look the same.
    #[arg(long)]
    pub threshold: Option<f64>,
}

/// `gridlight eval fig9`.
#[derive(Debug, Clone, clap::Args)]
pub struct Fig9Args {
    #[command(flatten)]
    pub common: Common,
    #[arg(long)]
    pub frames: Option<usize>,
    /// Fraction of each frame's jobs lost.
    #[arg(long)]
    pub loss: Option<f64>,
}

/// `gridlight eval fig10`.
#[derive(Debug, Clone, clap::Args)]
pub struct Fig10Args {
    #[command(flatten)]
    pub common: Common,
    #[arg(long, value_delimiter = ',')]
    pub workers: Option<Vec<u32>>,
    /// Seconds measured per grid size.
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// `gridlight eval lan`.
#[derive(Debug, Clone, clap::Args)]
pub struct LanArgs {
    #[command(flatten)]
    pub common: Common,
    #[arg(long, value_delimiter = ',')]
    pub workers: Option<Vec<u32>>,
    /// Link rates in Mbit/s (each direction of every link).
    #[arg(long, value_delimiter = ',')]
    pub links: Option<Vec<u32>>,
    /// Seconds measured per run.
    #[arg(long)]
    pub seconds: Option<f64>,
}

/// One experiment by name with its flags applied over the quick or full defaults.
#[derive(Debug, Clone)]
pub enum Experiment {
    All(Common),
    Fig3(Fig3Args),
    Fig5(Fig5Args),
    Table1(Table1Args),
    Fig8(Fig8Args),
    Fig9(Fig9Args),
    Fig10(Fig10Args),
    Lan(LanArgs),
}

/// Runs `eval paper` or one experiment.
pub fn run(experiment: Experiment, global: &GlobalArgs) -> anyhow::Result<()> {
    let common = match &experiment {
        Experiment::All(c) => c.clone(),
        Experiment::Fig3(a) => a.common.clone(),
        Experiment::Fig5(a) => a.common.clone(),
        Experiment::Table1(a) => a.common.clone(),
        Experiment::Fig8(a) => a.common.clone(),
        Experiment::Fig9(a) => a.common.clone(),
        Experiment::Fig10(a) => a.common.clone(),
        Experiment::Lan(a) => a.common.clone(),
    };
    let mut opts = Options::new(common.quick);
    let only = apply(&experiment, &mut opts)?;
    let steps = if only.is_some() { 1 } else { paper::EXPERIMENTS.len() as u64 };
    let mut ctx = Context::new(opts, &common.out, global.assets.clone(), steps)?;
    let sections = match only {
        None => paper::run_all(&mut ctx)?,
        Some(id) => {
            let section = paper::run_one(&mut ctx, id)?;
            paper::report::write(&ctx, std::slice::from_ref(&section))?;
            vec![section]
        }
    };
    ctx.progress.finish_and_clear();
    println!("report: {}", common.out.join("report.md").display());
    for s in &sections {
        for c in &s.claims {
            println!("{}: {} {}", s.id, if c.holds { "holds" } else { "does not hold" }, c.text);
        }
    }
    Ok(())
}

/// Applies the experiment's flags; returns its id (`None` for all of them).
fn apply(e: &Experiment, o: &mut Options) -> anyhow::Result<Option<&'static str>> {
    Ok(match e {
        Experiment::All(_) => None,
        Experiment::Fig3(a) => {
            if let Some(l) = &a.loss {
                anyhow::ensure!(
                    l.iter().all(|x| (0.0..1.0).contains(x)),
                    "--loss takes fractions in [0, 1)"
                );
                o.fig3.losses = l.clone();
            }
            Some("fig3")
        }
        Experiment::Fig5(a) => {
            set(&mut o.fig5.workers, a.workers);
            set(&mut o.fig5.fps, a.fps);
            set(&mut o.fig5.curve, a.availability);
            set(&mut o.fig5.period, a.period);
            set(&mut o.fig5.path, a.path.clone());
            anyhow::ensure!(
                o.fig5.fps > 0.0 && o.fig5.workers > 0,
                "--fps and --workers must be positive"
            );
            Some("fig5")
        }
        Experiment::Table1(a) => {
            set(&mut o.table1.scenes, a.scenes.clone());
            set(&mut o.table1.workers, a.workers.clone());
            set(&mut o.table1.seconds, a.seconds);
            Some("table1")
        }
        Experiment::Fig8(a) => {
            set(&mut o.fig8.workers, a.workers.clone());
            set(&mut o.fig8.seconds, a.seconds);
            set(&mut o.fig8.threshold, a.threshold);
            Some("fig8")
        }
        Experiment::Fig9(a) => {
            set(&mut o.fig9.frames, a.frames);
            set(&mut o.fig9.loss, a.loss);
            Some("fig9")
        }
        Experiment::Fig10(a) => {
            if let Some(w) = &a.workers {
                anyhow::ensure!(w.iter().all(|&n| n > 0), "--workers must be positive");
            }
            set(&mut o.fig10.workers, a.workers.clone());
            set(&mut o.fig10.seconds, a.seconds);
            Some("fig10")
        }
        Experiment::Lan(a) => {
            anyhow::ensure!(
                a.workers.iter().flatten().chain(a.links.iter().flatten()).all(|&n| n > 0),
                "--workers and --links must be positive"
            );
            set(&mut o.lan.workers, a.workers.clone());
            set(&mut o.lan.links_mbit, a.links.clone());
            set(&mut o.lan.seconds, a.seconds);
            Some("lan")
        }
    })
}

fn set<T>(slot: &mut T, value: Option<T>) {
    if let Some(v) = value {
        *slot = v;
    }
}
