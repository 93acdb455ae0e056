//! `gridlight render`: renders one scene file to an image on all local cores.
//!
//! This is also how gold-standard images are made. One std thread per core pulls blocks of
//! pixels and renders all samples of a block before taking the next; each sample is one
//! `render_pixels` call with one sample per pixel and the sample number as the frame, so
//! the image does not depend on the thread count. The colour is `reflected + emission`
//! (what workers send, plus what the master adds), never remodulated. Colours accumulate in f64. The output format follows the
//! extension: `.png` is tonemapped sRGB, `.exr` is linear radiance.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use anyhow::{bail, Context};
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};

use super::resolution::{self, ResolutionArg, ScaleArg};
use super::GlobalArgs;
use crate::image_io::{self, ClaimedOutput};
use crate::render::{render_pixels, PixelSample, RenderScene};
use crate::scene::{self, SceneSource};

/// Samples per pixel when `--spp` is not given.
pub const DEFAULT_SPP: u32 = 64;
/// Pixels per block handed to a render thread.
pub const BLOCK_PIXELS: usize = 256;

/// Arguments of `gridlight render`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// A scene file (TOML) or the name of a built-in scene (`gridlight scenes` lists them).
    pub scene: PathBuf,
    /// Samples per pixel.
    #[arg(long, default_value_t = DEFAULT_SPP)]
    pub spp: u32,
    /// Output image: `.png` (tonemapped sRGB) or `.exr` (linear).
    #[arg(long)]
    pub out: PathBuf,
    /// Render threads (default: one per local core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Exposure in stops applied before tonemapping (PNG only).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Image size, overriding the scene file's `[resolution]` (each side 1..=16384).
    #[arg(long, value_name = "WxH")]
    pub resolution: Option<ResolutionArg>,
    /// Multiplies the image size (the scene file's, or `--resolution`'s) by F on each side,
    /// rounded (0.5: a quarter of the pixels).
    #[arg(long, value_name = "F")]
    pub scale: Option<ScaleArg>,
    /// Hide the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `gridlight render`.
pub fn run(args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    // Check the cheap things before loading anything, the output file first.
    let out = ClaimedOutput::claim(&args.out)?;
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    let threads = match args.threads {
        Some(0) => bail!("--threads must be at least 1"),
        Some(t) => t,
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
    };
    let (source, search) = SceneSource::find_with_assets(&args.scene, &global.assets)?;
    let started = Instant::now();
    let loaded = scene::load_source(&source, &search)?;
    let mut state = loaded.state;
    state.render.spp = 1;
    resolution::apply(&mut state.resolution, args.resolution, args.scale)?;
    let render_scene = RenderScene::new(Arc::new(loaded.assets), &state)
        .with_context(|| format!("cannot render `{source}`"))?;
    tracing::info!(
        scene = %source,
        width = state.resolution.width,
        height = state.resolution.height,
        spp = args.spp,
        threads,
        load_s = started.elapsed().as_secs_f32(),
        "rendering"
    );
    let progress = progress_bar(state.resolution.pixels() as u64 * args.spp as u64, args.quiet);
    let started = Instant::now();
    let pixels = render_image(&render_scene, args.spp, threads, &progress);
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let samples = state.resolution.pixels() as f64 * args.spp as f64;
    image_io::write_image(
        &args.out,
        state.resolution.width,
        state.resolution.height,
        &pixels,
        args.exposure,
    )?;
    out.keep();
    tracing::info!(
        out = %args.out.display(),
        seconds,
        samples_per_second = samples / seconds,
        "written"
    );
    Ok(())
}

fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::new(total);
    let style = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {percent}% {human_pos}/{human_len} samples, {per_sec}, ETA {eta}",
    )
    .expect("valid progress template")
    .progress_chars("=> ");
    bar.set_style(style);
    bar
}

/// Renders every pixel of `scene` with `spp` samples on `threads` threads and returns the
/// mean colour (`reflected + emission`) per pixel, row-major, top row first.
/// `scene`'s state must have `render.spp == 1`; sample `s` is rendered as frame `s`.
pub fn render_image(
    scene: &RenderScene,
    spp: u32,
    threads: usize,
    progress: &ProgressBar,
) -> Vec<Vec3> {
    let count = scene.state().resolution.pixels();
    let blocks = count.div_ceil(BLOCK_PIXELS);
    let next = AtomicUsize::new(0);
    let image = Mutex::new(vec![Vec3::ZERO; count]);
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| {
                let mut samples: Vec<PixelSample> = Vec::with_capacity(BLOCK_PIXELS);
                let mut sum = vec![DVec3::ZERO; BLOCK_PIXELS];
                loop {
                    let block = next.fetch_add(1, Ordering::Relaxed);
                    if block >= blocks {
                        break;
                    }
                    let start = block * BLOCK_PIXELS;
                    let end = (start + BLOCK_PIXELS).min(count);
                    let pixels: Vec<u32> = (start as u32..end as u32).collect();
                    sum[..pixels.len()].fill(DVec3::ZERO);
                    for sample in 0..spp {
                        render_pixels(scene, sample as u64, &pixels, &mut samples);
                        for (acc, p) in sum.iter_mut().zip(&samples) {
                            *acc += (p.reflected + p.emission).as_dvec3();
                        }
                        progress.inc(pixels.len() as u64);
                    }
                    let mut image = image.lock().unwrap_or_else(|e| e.into_inner());
                    for (dst, acc) in image[start..end].iter_mut().zip(&sum) {
                        *dst = (*acc / spp as f64).as_vec3();
                    }
                }
            });
        }
    });
    image.into_inner().unwrap_or_else(|e| e.into_inner())
}
