//! `gridlight master`: serve a scene to workers and show the frames in a window, or
//! write them (`--headless`, or when no display exists).

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::bail;
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::supervision::PanicInjection;

use super::resolution::{ScaleArg, SizeArg};
use super::GlobalArgs;
use crate::gpu::Backend;
use crate::master::headless::HeadlessOptions;
use crate::master::launch::{self, AnnounceOptions, MasterOptions, DEFAULT_LISTEN};
use crate::master::view::View;
use crate::reconstruct::ReconstructParams;
use crate::scene::{PacingOverrides, SceneSource};

/// Sets per frame when `--sets` is not given (docs/design.md, decision 1).
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

/// `--link-mbps`: the master's inbound link in Mbit/s, positive and finite.
pub fn parse_link_mbps(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(v) => Err(format!("the link's rate must be positive and finite, got {v}")),
        Err(_) => Err(format!("`{s}` is not a rate in Mbit/s (e.g. 1000)")),
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
    /// What the command line says; the scene file and the paper fill in the rest.
    pub fn overrides(&self) -> PacingOverrides {
        PacingOverrides {
            fps: self.fps,
            q_min: self.qmin,
            q_max: self.qmax,
            i_min: self.imin,
            i_max: self.imax,
        }
    }
}

/// What the master shows or writes, and how it reconstructs (each flag overrides the
/// scene's `[render.reconstruction]`, which overrides the paper's values).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct DisplayArgs {
    /// Image size, overriding the scene file's `[resolution]` (each side 1..=16384); `window`:
    /// the window's picture area in physical pixels, following every resize.
    #[arg(long, value_name = "WxH|window")]
    pub resolution: Option<SizeArg>,
    /// Multiplies the image size (the scene file's, `--resolution`'s, or the window's) by F
    /// on each side, rounded (0.5: a quarter of the pixels).
    #[arg(long, value_name = "F")]
    pub scale: Option<ScaleArg>,
    /// The view shown in the window or written as PNG.
    #[arg(long, value_enum, default_value_t = View::Final)]
    pub view: View,
    /// Reconstruction on the GPU, the CPU, or the GPU when an adapter exists.
    #[arg(long, value_enum, default_value_t = Backend::Auto)]
    pub reconstruct: Backend,
    /// The reconstruction: the paper's filter, or reprojected history with variance-guided
    /// à-trous filtering (svgf).
    #[arg(long, value_enum)]
    pub reconstruction: Option<crate::reconstruct::Method>,
    /// Discontinuity threshold α on the cosine between normals.
    #[arg(long)]
    pub alpha: Option<f32>,
    /// Discontinuity threshold β on positions, in units of the scene's half-extent.
    #[arg(long)]
    pub beta: Option<f32>,
    /// Fill radius in pixels.
    #[arg(long)]
    pub radius: Option<u32>,
    /// Width of the edge-aware Gaussian (odd).
    #[arg(long)]
    pub gauss_width: Option<u32>,
    /// σ of the edge-aware Gaussian in pixels.
    #[arg(long)]
    pub sigma: Option<f32>,
    /// Previous frames blended while interacting (0: spatial only).
    #[arg(long)]
    pub history: Option<u32>,
    /// Exposure in stops before the filmic tonemap.
    #[arg(long)]
    pub exposure: Option<f32>,
    /// Compute each new scene state's G-buffer on a thread of its own as soon as the
    /// scene changes, while the workers render it. For a master with cores to spare (its
    /// workers on other machines); beside local workers on few cores it only competes
    /// with the reconstruction (docs/performance.md, edit-to-display latency).
    #[arg(long)]
    pub gbuffer_ahead: bool,
}

impl DisplayArgs {
    /// `--resolution window`'s scale (render pixels per window pixel: `--scale`, or 1).
    pub fn follow_window(&self) -> Option<f32> {
        (self.resolution == Some(SizeArg::Window)).then(|| self.scale.map_or(1.0, |s| s.0))
    }

    /// Refuses `--resolution window` where no window will show (headless, no display).
    pub fn check_windowless(&self) -> anyhow::Result<()> {
        if self.follow_window().is_some() {
            anyhow::bail!(
                "--resolution window needs a window, and this run has none (--headless, or no \
                 display): give the size as --resolution WxH"
            );
        }
        Ok(())
    }

    /// `base` (the scene's parameters) with this command line's overrides.
    pub fn params(&self, base: ReconstructParams) -> ReconstructParams {
        ReconstructParams {
            alpha: self.alpha.unwrap_or(base.alpha),
            beta: self.beta.unwrap_or(base.beta),
            radius: self.radius.unwrap_or(base.radius),
            gauss_width: self.gauss_width.unwrap_or(base.gauss_width),
            sigma: self.sigma.unwrap_or(base.sigma),
            history: self.history.unwrap_or(base.history),
            exposure: self.exposure.unwrap_or(base.exposure),
            method: self.reconstruction.unwrap_or(base.method),
            svgf: base.svgf,
        }
    }
}

/// Whether and how a master announces itself on the LAN (`gridlight worker` without
/// `--master` joins a master it hears).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct AnnounceArgs {
    /// Do not announce this master on the LAN (workers must then name it with --master).
    #[arg(long)]
    pub no_announce: bool,
    /// Where announcements go, `ADDR:PORT` [default: 255.255.255.255:7841, or
    /// 127.255.255.255:7841 for a master listening on loopback]; e.g. a subnet's broadcast
    /// address on a machine with several networks.
    #[arg(long, value_name = "ADDR:PORT", conflicts_with = "no_announce")]
    pub announce_to: Option<SocketAddr>,
    /// Name announced to workers (they choose with --master-name) [default: host name].
    #[arg(long, value_name = "NAME")]
    pub name: Option<String>,
}

impl AnnounceArgs {
    /// What the master is told.
    pub fn options(&self) -> AnnounceOptions {
        AnnounceOptions {
            enabled: !self.no_announce,
            to: self.announce_to,
            name: self.name.clone(),
        }
    }
}

/// Arguments of `gridlight master`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// A scene file (TOML) or the name of a built-in scene (`gridlight scenes` lists them).
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
    #[command(flatten)]
    pub display: DisplayArgs,
    /// Jobs a worker may hold at once (k; 1 is the paper's request/response).
    #[arg(long, default_value_t = gridlight_actors::master::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// The master's inbound link in Mbit/s: the grid is never asked for more result
    /// bytes per second than it carries (jobs take more samples per pixel instead).
    #[arg(long, value_name = "MBIT/S", value_parser = parse_link_mbps)]
    pub link_mbps: Option<f64>,
    /// Interaction script: a TOML file of timed edits.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// No window even when a display exists: write frames and statistics.
    #[arg(long)]
    pub headless: bool,
    /// Stop after this many shown frames (default: run until Ctrl-C).
    #[arg(long, value_name = "N")]
    pub frames: Option<u64>,
    /// Write every shown frame (the `--view`) as PNG into this directory, plus `summary.json`.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// With `--out`, also write the final view's linear colour as EXR.
    #[arg(long, requires = "out")]
    pub exr: bool,
    /// Statistics, one JSON line per shown frame.
    #[arg(long, value_name = "FILE.jsonl")]
    pub stats: Option<PathBuf>,
    /// Shared secret workers must prove (HMAC over a nonce; the secret never travels).
    #[arg(long, value_name = "FILE")]
    pub secret_file: Option<PathBuf>,
    #[command(flatten)]
    pub announce: AnnounceArgs,
    /// Also write each frame's own unfiltered results as EXR (process tests).
    #[arg(long, hide = true)]
    pub dump_current: bool,
    /// Test hook (supervision tests): the guard makes ACTOR (scheduler, assembler,
    /// presenter, scene-holder, listener, connection, announcer) panic at SITE (started,
    /// handler or timer; default started), COUNT times or every time. Repeatable.
    #[arg(long, value_name = "ACTOR[:SITE[:COUNT]]", hide = true)]
    pub inject_panic: Vec<PanicInjection>,
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
            scene: SceneSource::find_with_assets(&self.scene, &global.assets)?.0,
            asset_dirs: global.assets.clone(),
            listen: self.listen,
            sets: SetsConfig { sets: self.sets, partition: self.partition.into() },
            pacing: self.pacing.overrides(),
            display: self.display.clone(),
            pipeline: self.pipeline,
            link_mbps: self.link_mbps,
            secret,
            announce: self.announce.options(),
            script: self.script.clone(),
            frames: self.frames,
            keep_stale_jobs: false,
            sink_in_flight: 1,
            inject_panics: self.inject_panic.clone(),
            headless: HeadlessOptions {
                out_dir: self.out.clone(),
                stats: self.stats.clone(),
                verbose: true,
                view: self.display.view,
                exr: self.exr,
                dump_current: self.dump_current,
            },
        })
    }
}

/// Runs `gridlight master`.
pub fn run(args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    let opts = args.options(global)?;
    if !args.headless && crate::window::display_available() {
        let window = crate::window::WindowOptions {
            title: format!("gridlight master: {}", opts.scene.name()),
            view: args.display.view,
            shot_dir: args.out.clone().unwrap_or_else(|| PathBuf::from(".")),
            follow_window: args.display.follow_window(),
            ..crate::window::WindowOptions::default()
        };
        let report = launch::run_window(&opts, window, |_| Ok(()), None)?;
        tracing::info!(shown = report.shown, skipped = report.skipped, "master finished");
        return Ok(());
    }
    args.display.check_windowless()?;
    let report = launch::run(&opts, |_| Ok(()))?;
    tracing::info!(shown = report.shown, skipped = report.skipped, "master finished");
    Ok(())
}
