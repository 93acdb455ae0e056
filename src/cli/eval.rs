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
use crate::reconstruct::{Method, ReconstructParams};
use crate::render::testscenes;
use crate::scene::{self, AssetSearchPath, SceneSource};
use crate::tools::eval::motion::Script;
use crate::tools::eval::oidn::Oidn;
use crate::tools::eval::{loss, motion as motion_eval, sequence};
use crate::tools::eval::{FrameSource, RenderSource, SyntheticSource};

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
    /// Issue 41: paper vs SVGF reconstruction through an orbit and edits, against
    /// converged images of each view (FLIP per frame, stability, milliseconds).
    Motion(MotionArgs),
}

/// Arguments of `gridlight eval motion`.
#[derive(Debug, Clone, clap::Args)]
pub struct MotionArgs {
    /// Scenes (built-in names, `scenes/NAME.toml` or files); those whose assets are
    /// missing are skipped with a note. Each is reconstructed with its own
    /// `[render.reconstruction]`, the method taken from `--methods`.
    #[arg(long, value_delimiter = ',', default_values_t = vec!["cornell-box".to_string(), "bunny".to_string(), "sponza".to_string()])]
    pub scenes: Vec<String>,
    /// Methods compared.
    #[arg(long, value_delimiter = ',', default_values_t = vec![Method::Paper, Method::Svgf])]
    pub methods: Vec<Method>,
    /// Reduced script (6 orbit views, 64-spp references, 320×240): minutes on 2 cores.
    #[arg(long)]
    pub quick: bool,
    /// Image size (default 640×480, or 320×240 with --quick).
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel of the references (default 512, or 64 with --quick).
    #[arg(long)]
    pub gold_spp: Option<u32>,
    /// One JSON line per scene and method (otherwise a short text summary).
    #[arg(long)]
    pub json: bool,
    /// Intel Open Image Denoise as the external anchor (method `oidn`: complete frames
    /// denoised by `scripts/oidn-anchor.py`): `auto` runs it when the interpreter has
    /// `pyoidn` (`pip install pyoidn`), `on` fails without it.
    #[arg(long, value_enum, default_value_t = AnchorChoice::Auto)]
    pub oidn: AnchorChoice,
    /// Samples per pixel of the anchor's complete input frames.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4096))]
    pub oidn_spp: u32,
    /// OIDN's threads (0: every core).
    #[arg(long, default_value_t = 0)]
    pub oidn_threads: u32,
    /// The Python interpreter for the anchor.
    #[arg(long, default_value = "python3")]
    pub python: String,
}

/// Whether `eval motion` runs its external anchor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AnchorChoice {
    Auto,
    On,
    Off,
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
        EvalCommand::Motion(a) => motion(a, global),
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

fn motion(args: MotionArgs, global: &GlobalArgs) -> anyhow::Result<()> {
    let mut script = if args.quick { Script::quick() } else { Script::full() };
    if let Some(spp) = args.gold_spp {
        script.gold_spp = spp;
    }
    let (w, h) = if args.quick { (320, 240) } else { (640, 480) };
    let res = Resolution { width: args.width.unwrap_or(w), height: args.height.unwrap_or(h) };
    let oidn = Oidn { python: args.python.clone(), threads: args.oidn_threads };
    let anchor = match (args.oidn, oidn.check()) {
        (AnchorChoice::Off, _) => None,
        (_, Ok(())) => Some(motion_eval::Anchor { oidn, spp: args.oidn_spp }),
        (AnchorChoice::Auto, Err(err)) => {
            eprintln!("eval motion: no OIDN anchor: {err:#}");
            None
        }
        (AnchorChoice::On, Err(err)) => return Err(err.context("--oidn on")),
    };
    for name in &args.scenes {
        let source = SceneSource::find(std::path::Path::new(name), &[scenes_dir()])
            .with_context(|| format!("finding scene `{name}`"))?;
        let search = source.search_path(&global.assets);
        let loaded = match scene::load_source(&source, &search) {
            Ok(loaded) => loaded,
            Err(err) if err.to_string().contains("not found") => {
                eprintln!("eval motion: skipping `{name}`: {err}");
                continue;
            }
            Err(err) => return Err(err).with_context(|| format!("loading scene `{name}`")),
        };
        let mut state = loaded.state;
        state.resolution = res;
        let (assets, params) = (Arc::new(loaded.assets), loaded.reconstruction);
        let results =
            motion_eval::run(assets, &state, &script, &args.methods, params, anchor.as_ref())?;
        for r in results {
            if args.json {
                println!(
                    "{}",
                    json!({
                        "scene": name, "method": r.method,
                        "first_frame_flip": r.first_frame_flip,
                        "orbit_mean_flip": r.orbit_mean_flip, "stability": r.stability,
                        "cpu_ms": r.cpu_ms, "material_edit_flip": r.material_edit_flip,
                        "light_edit_flip": r.light_edit_flip, "orbit_flip": r.orbit_flip,
                        "width": res.width, "height": res.height, "script": script,
                        "oidn_spp": (r.method == "oidn").then_some(args.oidn_spp),
                    })
                );
            } else {
                let method = match r.method {
                    "oidn" => format!("oidn (complete {}-spp frames)", args.oidn_spp),
                    m => m.to_string(),
                };
                println!(
                    "{name} {method}: first frame FLIP {:.4}, orbit mean {:.4}, material edit {:.4}, light edit {:.4}, stability {:.4}, {:.1} ms/frame",
                    r.first_frame_flip, r.orbit_mean_flip, r.material_edit_flip,
                    r.light_edit_flip, r.stability, r.cpu_ms
                );
            }
        }
    }
    Ok(())
}
