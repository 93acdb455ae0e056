//! `gridlight bench`: performance measurements printed as text or JSON lines.
//!
//! `bench trace [SCENE...]` (`--gpu`: on the GPU path tracer) renders each scene at 640×480, max depth 5, 4 spp on
//! one thread. Without scenes it runs the built-in Cornell box and, when their
//! assets are found on the search path, the bunny and Sponza scenes.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;

use super::resolution::ResolutionArg;
use super::GlobalArgs;
use crate::assets::Assets;
use crate::render::isa::IsaLevel;
use crate::render::testscenes;
use crate::scene::{self, SceneSource};
use crate::tools::bench::compose::ComposeSettings as ComposeBench;
use crate::tools::bench::reconstruct::BenchSettings as ReconBench;
use crate::tools::bench::trace::{bench_scene, TraceReport, TraceSettings};
use crate::tools::bench::trace_gpu::{bench_scene_gpu, GpuTraceReport};
use gridlight_actors::state::SceneState;

/// Arguments of `gridlight bench`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// What to measure.
#[derive(Debug, Clone, clap::Subcommand)]
pub enum What {
    /// Single-thread path-tracing throughput (samples and rays per second per core).
    Trace(TraceArgs),
    /// The master alone: null-render workers on loopback, 640×480, S = 64.
    Master(super::bench_master::MasterArgs),
    /// Across hosts: network namespaces behind rate-limited links (needs root).
    Lan(super::bench_lan::LanArgs),
    /// The useful fraction of returned results with null-render workers that take
    /// `--job-ms` per job, at each grid size.
    Waste(super::bench_waste::WasteArgs),
    /// Milliseconds per 640×480 frame of the full reconstruction pipeline, CPU and GPU.
    Reconstruct(ReconstructArgs),
    /// The master's compose per shown frame (G-buffer, reconstruction, hand-over to the
    /// display), camera moving and view resting, at each resolution: one JSON line each.
    Compose(ComposeArgs),
    /// A desk owner's CPU-bound program beside a rendering worker, against alone.
    OwnerImpact(super::bench_owner::OwnerImpactArgs),
    /// The owner's program of `owner-impact`: spin threads and count iterations.
    #[command(hide = true)]
    BusyLoop(super::bench_owner::BusyLoopArgs),
}

/// Arguments of `gridlight bench reconstruct`.
#[derive(Debug, Clone, clap::Args)]
pub struct ReconstructArgs {
    /// Print one JSON object (the only format).
    #[arg(long)]
    pub json: bool,
    /// Timed frames per implementation; the median is reported.
    #[arg(long, default_value_t = ReconBench::default().frames)]
    pub frames: u32,
    /// Fraction of pixels without a result in each frame.
    #[arg(long, default_value_t = ReconBench::default().loss)]
    pub loss: f32,
    #[arg(long, default_value_t = ReconBench::default().width)]
    pub width: u32,
    #[arg(long, default_value_t = ReconBench::default().height)]
    pub height: u32,
    /// Skip the GPU (or the CPU) measurement.
    #[arg(long)]
    pub no_gpu: bool,
    #[arg(long)]
    pub no_cpu: bool,
}

/// Arguments of `gridlight bench compose`.
#[derive(Debug, Clone, clap::Args)]
pub struct ComposeArgs {
    /// Print JSON lines (the only format).
    #[arg(long)]
    pub json: bool,
    /// Timed frames per case; the median is reported.
    #[arg(long, default_value_t = ComposeBench::default().frames)]
    pub frames: u32,
    /// Fraction of pixels without a result in each frame.
    #[arg(long, default_value_t = ComposeBench::default().loss)]
    pub loss: f32,
    #[arg(long, default_value_t = 640, conflicts_with = "resolutions")]
    pub width: u32,
    #[arg(long, default_value_t = 480, conflicts_with = "resolutions")]
    pub height: u32,
    /// Several sizes, one line each (e.g. `640x480,1920x1080,3840x2160`).
    #[arg(long, value_delimiter = ',')]
    pub resolutions: Vec<ResolutionArg>,
    /// Skip the hardware adapter's measurement.
    #[arg(long)]
    pub no_gpu: bool,
}

/// Arguments of `gridlight bench trace`.
#[derive(Debug, Clone, clap::Args)]
pub struct TraceArgs {
    /// Scene files (TOML, or glTF `.gltf`/`.glb`); default: the Cornell box, plus bunny
    /// and Sponza when their assets are found.
    pub scenes: Vec<PathBuf>,
    /// Print one JSON object per scene and line.
    #[arg(long)]
    pub json: bool,
    /// Timed full-frame renders per scene; the median is reported.
    #[arg(long, default_value_t = TraceSettings::default().runs)]
    pub runs: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = TraceSettings::default().spp)]
    pub spp: u32,
    /// Maximum path length in segments (5 = camera ray plus four bounces).
    #[arg(long, default_value_t = TraceSettings::default().max_depth)]
    pub max_depth: u32,
    /// Benchmark the GPU path tracer on the default adapter (samples and rays per second
    /// of the device, with the adapter's name) instead of one CPU core.
    #[arg(long)]
    pub gpu: bool,
    /// The instruction-set level whose kernel build runs (default: the fastest this CPU
    /// has). `baseline` is what workers without AVX2 run; every build gives the same
    /// pixels.
    #[arg(long, value_enum, conflicts_with = "gpu")]
    pub build: Option<IsaArg>,
}

/// `--build` of `bench trace`: an [`IsaLevel`].
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum IsaArg {
    /// x86-64-v4: paths in AVX-512 lanes (CPUs with x86-64-v3 and AVX-512 F, VL, BW, DQ
    /// and CD).
    V4,
    /// x86-64-v3: paths in AVX2 lanes (CPUs with AVX2, BMI1/2, LZCNT and FMA).
    V3,
    /// Baseline x86-64: paths in SSE2 lanes (every x86-64 CPU).
    Baseline,
}

/// The built-in scenes of the default benchmark, relative to the `scenes/` folder.
const DEFAULT_SCENES: [&str; 3] = ["cornell-box.toml", "bunny.toml", "sponza.toml"];

/// Runs `gridlight bench`.
pub fn run(args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    match args.what {
        What::Trace(args) => trace(args, global),
        What::Reconstruct(args) => {
            let settings = ReconBench {
                width: args.width,
                height: args.height,
                loss: args.loss,
                frames: args.frames,
                cpu: !args.no_cpu,
                gpu: !args.no_gpu,
                ..ReconBench::default()
            };
            let report = crate::tools::bench::reconstruct::run(&settings)?;
            println!("{}", serde_json::to_string(&report)?);
            Ok(())
        }
        What::Compose(args) => compose(args),
        What::Master(args) => super::bench_master::run(args, global),
        What::Lan(args) => super::bench_lan::run(args, global),
        What::OwnerImpact(args) => super::bench_owner::run_owner_impact(args, global),
        What::BusyLoop(args) => super::bench_owner::run_busy_loop(args),
        What::Waste(args) => super::bench_waste::run(args, global),
    }
}

fn compose(args: ComposeArgs) -> anyhow::Result<()> {
    let resolutions = if args.resolutions.is_empty() {
        let size = format!("{}x{}", args.width, args.height);
        vec![size.parse::<ResolutionArg>().with_context(|| format!("--width/--height {size}"))?]
    } else {
        args.resolutions
    };
    let settings = ComposeBench {
        resolutions: resolutions.into_iter().map(|r| r.0).collect(),
        frames: args.frames,
        loss: args.loss,
        gpu: !args.no_gpu,
        ..ComposeBench::default()
    };
    crate::tools::bench::compose::run(&settings, |line| {
        println!("{}", serde_json::to_string(line)?);
        Ok(())
    })
}

fn trace(args: TraceArgs, global: &GlobalArgs) -> anyhow::Result<()> {
    let isa = match args.build {
        None => IsaLevel::best(),
        Some(IsaArg::V4) => IsaLevel::V4,
        Some(IsaArg::V3) => IsaLevel::V3,
        Some(IsaArg::Baseline) => IsaLevel::Baseline,
    };
    if !isa.available() {
        anyhow::bail!(
            "bench trace: this CPU cannot run the {} build (v3 needs AVX2, BMI1/2, LZCNT and \
             FMA; v4 also AVX-512 F, VL, BW, DQ and CD); the fastest it runs is {}",
            isa.name(),
            IsaLevel::best().name()
        );
    }
    let settings = TraceSettings {
        spp: args.spp,
        max_depth: args.max_depth,
        runs: args.runs,
        isa,
        ..TraceSettings::default()
    };
    if args.gpu {
        return trace_gpu(&args, global, settings);
    }
    let bench = |name: &str, assets, state: &SceneState| {
        bench_scene(name, assets, state, settings).map_err(anyhow::Error::from)
    };
    let reports: Vec<TraceReport> = scenes_of(&args, global, settings, &bench)?;
    for r in reports {
        if args.json {
            println!("{}", serde_json::to_string(&r)?);
        } else {
            println!(
                "{}: {:.3} M samples/s/core, {:.2} M rays/s/core, {} triangles ({}x{}, {} spp, max depth {}, {:.2} s, {} build)",
                r.scene,
                r.samples_per_second_per_core / 1e6,
                r.rays_per_second_per_core / 1e6,
                r.triangles,
                r.width,
                r.height,
                r.spp,
                r.max_depth,
                r.seconds,
                r.build
            );
        }
    }
    Ok(())
}

/// `bench trace --gpu`: the same scenes on the GPU path tracer.
fn trace_gpu(args: &TraceArgs, global: &GlobalArgs, settings: TraceSettings) -> anyhow::Result<()> {
    let ctx = crate::gpu::GpuContext::new().context("bench trace --gpu: no GPU adapter")?;
    let tracer = crate::render::gpu::GpuTracer::new(ctx.shared());
    let bench = |name: &str, assets, state: &SceneState| {
        bench_scene_gpu(&tracer, name, assets, state, settings)
    };
    let reports: Vec<GpuTraceReport> = scenes_of(args, global, settings, &bench)?;
    for r in reports {
        if args.json {
            println!("{}", serde_json::to_string(&r)?);
        } else {
            println!(
                "{} on {}: {:.3} M samples/s, {:.2} M rays/s, {} triangles ({}x{}, {} spp, max depth {}, {:.2} s)",
                r.scene,
                r.adapter,
                r.samples_per_second / 1e6,
                r.rays_per_second / 1e6,
                r.triangles,
                r.width,
                r.height,
                r.spp,
                r.max_depth,
                r.seconds
            );
        }
    }
    Ok(())
}

/// A benchmark of one loaded scene (the CPU's or the GPU's).
type BenchFn<'a, R> = dyn Fn(&str, Arc<Assets>, &SceneState) -> anyhow::Result<R> + 'a;

/// The scenes `bench trace` measures: those named, or the default set.
fn scenes_of<R>(
    args: &TraceArgs,
    global: &GlobalArgs,
    settings: TraceSettings,
    bench: &BenchFn<R>,
) -> anyhow::Result<Vec<R>> {
    if args.scenes.is_empty() {
        default_scenes(global, settings, bench)
    } else {
        args.scenes.iter().map(|path| bench_file(path, global, bench)).collect()
    }
}

fn bench_file<R>(path: &Path, global: &GlobalArgs, bench: &BenchFn<R>) -> anyhow::Result<R> {
    // As `render` finds it: a glTF file's own folder is part of its search path.
    let (source, resolver) = SceneSource::find_with_assets(path, &global.assets)?;
    let loaded = scene::load_source(&source, &resolver)?;
    let name = path
        .file_stem()
        .map_or_else(|| path.display().to_string(), |s| s.to_string_lossy().into_owned());
    bench(&name, Arc::new(loaded.assets), &loaded.state)
        .with_context(|| format!("rendering {}", path.display()))
}

/// The Cornell box always (from `scenes/` when present, else built in code), then the
/// asset scenes whose assets are found; skipped ones are reported on stderr.
fn default_scenes<R>(
    global: &GlobalArgs,
    settings: TraceSettings,
    bench: &BenchFn<R>,
) -> anyhow::Result<Vec<R>> {
    let dir = scenes_dir();
    let mut reports = Vec::new();
    for (i, file) in DEFAULT_SCENES.iter().enumerate() {
        let path = dir.join(file);
        if !path.is_file() {
            if i == 0 {
                let (assets, state) = testscenes::cornell_box(settings.width, settings.height);
                reports.push(bench("cornell-box", assets, &state)?);
            } else {
                eprintln!("bench trace: skipping {}: not found", path.display());
            }
            continue;
        }
        match bench_file(&path, global, bench) {
            Ok(r) => reports.push(r),
            // Asset scenes are optional: their assets may be absent on this machine.
            Err(err) if i > 0 => eprintln!("bench trace: skipping {}: {err:#}", path.display()),
            Err(err) => return Err(err),
        }
    }
    Ok(reports)
}

/// `scenes/` in the current directory, else the one of the source tree.
fn scenes_dir() -> PathBuf {
    let local = PathBuf::from("scenes");
    if local.is_dir() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
    }
}
