//! `gridlight bench trace --gpu`: throughput of the GPU path tracer (`render::gpu`).
//!
//! Renders every pixel of a scene at the benchmark settings in one dispatch, several
//! times, and reports the median run's camera paths ("samples") and rays (closest-hit
//! plus shadow rays, counted by the shader) per second, with the adapter's name. The
//! scene upload and the pass's compilation (one untimed warm-up render) are not timed;
//! the pixel upload and the read-back are, as a worker pays them for every batch.

use std::sync::Arc;
use std::time::Instant;

use gridlight_actors::state::SceneState;
use serde::Serialize;

use super::trace::{median_run, TraceSettings};
use crate::assets::Assets;
use crate::render::gpu::{GpuTracer, PixelBatch};
use crate::render::{RenderScene, Strategy};

/// One line of `bench trace --gpu --json`.
#[derive(Clone, Debug, Serialize)]
pub struct GpuTraceReport {
    pub scene: String,
    pub adapter: String,
    /// Whether the adapter is a software one (Mesa's lavapipe): its figures are CPU ones.
    pub software_adapter: bool,
    pub samples_per_second: f64,
    pub rays_per_second: f64,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Median wall-clock seconds of one full-frame render.
    pub seconds: f64,
    pub samples: u64,
    pub rays: u64,
    pub runs: u32,
}

/// Benchmarks one scene on `tracer`; the state's resolution and render settings are
/// replaced by `settings`.
pub fn bench_scene_gpu(
    tracer: &GpuTracer,
    name: &str,
    assets: Arc<Assets>,
    state: &SceneState,
    settings: TraceSettings,
) -> anyhow::Result<GpuTraceReport> {
    let state = settings.applied_to(state);
    let scene = RenderScene::new(assets, &state)?;
    let uploaded = tracer.upload(&scene)?;
    let pixels: Vec<u32> = (0..state.resolution.pixels() as u32).collect();
    let mut out = Vec::with_capacity(pixels.len());
    let warm = [PixelBatch { frame: u64::MAX, pixels: &pixels[..pixels.len().min(64)] }];
    tracer.render(&uploaded, &warm, Strategy::NeeMis, &mut out)?;
    let mut runs = Vec::new();
    for run in 0..settings.runs.max(1) {
        let batch = [PixelBatch { frame: run as u64, pixels: &pixels }];
        let start = Instant::now();
        let stats = tracer.render(&uploaded, &batch, Strategy::NeeMis, &mut out)?;
        runs.push((start.elapsed().as_secs_f64(), stats));
    }
    let (seconds, stats) = median_run(&mut runs);
    Ok(GpuTraceReport {
        scene: name.to_string(),
        adapter: tracer.adapter().to_string(),
        software_adapter: tracer.is_software(),
        samples_per_second: stats.samples as f64 / seconds,
        rays_per_second: stats.rays as f64 / seconds,
        triangles: scene.triangle_count(),
        width: settings.width,
        height: settings.height,
        spp: settings.spp,
        max_depth: settings.max_depth,
        seconds,
        samples: stats.samples,
        rays: stats.rays,
        runs: settings.runs.max(1),
    })
}
