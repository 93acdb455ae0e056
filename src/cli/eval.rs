//! `gridlight eval reconstruction`: reproduces the paper's reconstruction findings on a
//! scene and prints one JSON object per result line.
//!
//! Per loss level (Figure 3): a complete frame loses that fraction of its jobs under the
//! quasi-random and the tile partition; each is reconstructed and compared with the
//! complete frame (FLIP, RMSE, SSIM); images go to `--out`. With `--sequences`, also an
//! interaction sequence (Figure 9) and a static view converging (Figure 8).

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::Context;
use serde_json::json;

use super::eval_paper::Experiment;
use super::GlobalArgs;
use crate::actors::state::Resolution;
use crate::image_io;
use crate::reconstruct::ReconstructParams;
use crate::render::testscenes;
use crate::scene::{self, AssetSearchPath};
use crate::tools::eval::{loss, sequence, FrameSource, RenderSource, SyntheticSource};

/// The evaluations.
#[derive(Debug, clap::Subcommand)]
pub enum EvalCommand {
    /// Reconstruction quality: quasi-random vs tiles under job loss, and sequences.
    Reconstruction(ReconstructionArgs),
    /// The paper's section 6: every experiment, a report with plots (`--quick`: reduced).
    Paper(super::eval_paper::Common),
    /// Figure 3: quasi-random sets vs tiles under job loss, with images.
    Fig3(super::eval_paper::Fig3Args),
    /// Figure 5: Q_t at a fixed frame rate while the simulated grid varies.
    Fig5(super::eval_paper::Fig5Args),
    /// Table 1 / Figure 7: fps and mean Q_t per scene and grid size.
    Table1(super::eval_paper::Table1Args),
    /// Figure 8: a static view converging on simulated grids.
    Fig8(super::eval_paper::Fig8Args),
    /// Figure 9: spatio-temporal vs spatial-only reconstruction per frame.
    Fig9(super::eval_paper::Fig9Args),
    /// Figure 10: speed-up and efficiency for 1 to 256 simulated workers.
    Fig10(super::eval_paper::Fig10Args),
    /// Beyond the paper: the runs across 100 Mbit/s and 1 Gbit/s links (root).
    Lan(super::eval_paper::LanArgs),
}

/// Arguments of `gridlight eval reconstruction`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReconstructionArgs {
    /// Scene file to render with the path tracer (default: the Cornell box).
    pub scene: Option<PathBuf>,
    /// Use the analytic test scene (smooth shading with synthetic per-frame noise)
    /// instead of path-traced frames.
    #[arg(long, conflicts_with = "scene")]
    pub synthetic: bool,
    /// Samples per pixel of the converged image (gold standard of the sequences).
    #[arg(long, default_value_t = 64)]
    pub gold_spp: u32,
    /// Fractions of the frame's jobs that are lost.
    #[arg(long, value_delimiter = ',', default_values_t = vec![0.25, 0.5])]
    pub loss: Vec<f64>,
    /// Number of pixel sets S (jobs per frame).
    #[arg(long, default_value_t = 64)]
    pub sets: u32,
    /// Image width and height (override the scene's resolution).
    #[arg(long, default_value_t = 640)]
    pub width: u32,
    #[arg(long, default_value_t = 480)]
    pub height: u32,
    /// Directory for the images (created if needed).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print JSON lines (otherwise a short text summary).
    #[arg(long)]
    pub json: bool,
    /// Also run the interaction (Figure 9) and static-view (Figure 8) sequences.
    #[arg(long)]
    pub sequences: bool,
    /// Frames of each sequence.
    #[arg(long, default_value_t = 12)]
    pub frames: usize,
    /// Seed for the choice of lost sets.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Runs `gridlight eval ...`.
pub fn run(cmd: EvalCommand, global: &GlobalArgs) -> anyhow::Result<()> {
    match cmd {
        EvalCommand::Reconstruction(args) => reconstruction(args, global),
        EvalCommand::Paper(c) => super::eval_paper::run(Experiment::All(c), global),
        EvalCommand::Fig3(a) => super::eval_paper::run(Experiment::Fig3(a), global),
        EvalCommand::Fig5(a) => super::eval_paper::run(Experiment::Fig5(a), global),
        EvalCommand::Table1(a) => super::eval_paper::run(Experiment::Table1(a), global),
        EvalCommand::Fig8(a) => super::eval_paper::run(Experiment::Fig8(a), global),
        EvalCommand::Fig9(a) => super::eval_paper::run(Experiment::Fig9(a), global),
        EvalCommand::Fig10(a) => super::eval_paper::run(Experiment::Fig10(a), global),
        EvalCommand::Lan(a) => super::eval_paper::run(Experiment::Lan(a), global),
    }
}

fn source(
    args: &ReconstructionArgs,
    global: &GlobalArgs,
) -> anyhow::Result<(String, Box<dyn FrameSource>)> {
    if args.synthetic {
        return Ok(("synthetic".into(), Box::new(SyntheticSource::new(args.width, args.height))));
    }
    let path = args.scene.clone().unwrap_or_else(|| scenes_dir().join(DEFAULT_SCENE));
    let name = path
        .file_stem()
        .map_or_else(|| path.display().to_string(), |s| s.to_string_lossy().into_owned());
    let (assets, mut state) = if args.scene.is_none() && !path.is_file() {
        testscenes::cornell_box(args.width, args.height)
    } else {
        let resolver = AssetSearchPath::from_env(&global.assets, Some(&path));
        let loaded =
            scene::load(&path, &resolver).with_context(|| format!("loading {}", path.display()))?;
        (Arc::new(loaded.assets), loaded.state)
    };
    state.resolution = Resolution { width: args.width, height: args.height };
    Ok((name, Box::new(RenderSource::new(assets, state, args.gold_spp)?)))
}

/// The scene evaluated when none is named.
const DEFAULT_SCENE: &str = "cornell-box.toml";

/// `scenes/` in the current directory, else the one of the source tree.
fn scenes_dir() -> PathBuf {
    let local = PathBuf::from("scenes");
    if local.is_dir() {
        local
    } else {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
    }
}

fn reconstruction(args: ReconstructionArgs, global: &GlobalArgs) -> anyhow::Result<()> {
    for &l in &args.loss {
        anyhow::ensure!((0.0..=1.0).contains(&l), "--loss {l} is not a fraction in [0, 1]");
    }
    let (scene, mut source) = source(&args, global)?;
    let params = ReconstructParams::default();
    let (w, h) = (source.width(), source.height());
    let exposure = source.exposure();
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let frame = source.frame(0, 1)?;
    for &l in &args.loss {
        let out = loss::run(&frame, args.sets, l, params, exposure, args.seed)?;
        let line = json!({
            "experiment": "loss",
            "scene": scene,
            "loss": l,
            "metric": "flip",
            "quasi_random_error": out.quasi_random.flip,
            "tile_error": out.tiles.flip,
            "ratio": out.tiles.flip / out.quasi_random.flip.max(f64::MIN_POSITIVE),
            "quasi_random": out.quasi_random,
            "tiles": out.tiles,
            "sets": out.sets,
            "dropped_sets": out.dropped,
            "width": w,
            "height": h,
        });
        if args.json {
            println!("{line}");
        } else {
            println!(
                "loss {l}: FLIP quasi-random {:.4}, tiles {:.4} (tiles/quasi-random {:.2}); RMSE {:.4} / {:.4}; SSIM {:.4} / {:.4}",
                out.quasi_random.flip, out.tiles.flip, line["ratio"], out.quasi_random.rmse, out.tiles.rmse,
                out.quasi_random.ssim, out.tiles.ssim
            );
        }
        if let Some(dir) = &args.out {
            let pct = (l * 100.0).round() as u32;
            let i = &out.images;
            let files = [
                ("complete.png".to_string(), &i.reference),
                (format!("loss{pct}-quasi-random.png"), &i.quasi_random),
                (format!("loss{pct}-tiles.png"), &i.tiles),
                (format!("loss{pct}-quasi-random-holes.png"), &i.quasi_random_holes),
                (format!("loss{pct}-tiles-holes.png"), &i.tiles_holes),
            ];
            for (name, img) in files {
                image_io::write_png(&dir.join(name), w, h, img, exposure)?;
            }
        }
    }
    if args.sequences {
        let loss_level = args.loss.last().copied().unwrap_or(0.5);
        for p in sequence::interaction(source.as_mut(), args.frames, args.sets, loss_level, params)?
        {
            println!(
                "{}",
                json!({ "experiment": "interaction", "scene": scene, "loss": loss_level, "metric": "flip", "point": p })
            );
        }
        for p in sequence::convergence(source.as_mut(), args.frames, args.sets, loss_level, params)?
        {
            println!(
                "{}",
                json!({ "experiment": "convergence", "scene": scene, "loss": loss_level, "metric": "flip", "point": p })
            );
        }
    }
    Ok(())
}
