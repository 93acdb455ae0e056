//! `gridlight bench reconstruct`: milliseconds per frame of the full pipeline, CPU
//! reference and GPU passes, on 640×480 analytic inputs with a fraction of pixels lost.
//!
//! Every timed frame starts a new scene state, so each runs the whole interacting
//! pipeline (accumulate, fill, temporal with a full history, Gaussian, remodulate). CPU
//! time is wall-clock time of `CpuReconstructor::reconstruct_into`, with the output
//! buffers reused from frame to frame as a frame loop would; GPU time comes from
//! timestamps written at the start of the first pass and the end of the last (uploads and
//! readback excluded; they are in `gpu_wall_ms`). `gpu_on_device_ms` is the windowed
//! master's one-device path: uploads and passes, no readback, until the queue is done.
//!
//! The G-buffer is timed on the built-in Cornell box at the same size, a new scene-state
//! version per frame: `gbuffer_ms` for the raster pass, `gbuffer_cpu_ms` for the CPU path
//! (wall-clock, readback and the environment lookup of escaping rays included).

use std::time::Instant;

use serde::Serialize;

use crate::gbuffer::{GBuffer, GBufferSource, GpuGBuffer};
use crate::gpu::{Backend, GpuContext};
use crate::reconstruct::synthetic::{self, SyntheticView};
use crate::reconstruct::{CpuReconstructor, FrameInputs, GpuReconstructor, ReconstructParams};
use crate::render::testscenes;

/// What to measure.
#[derive(Clone, Copy, Debug)]
pub struct BenchSettings {
    pub width: u32,
    pub height: u32,
    /// Fraction of pixels without a result in each frame.
    pub loss: f32,
    /// Timed frames per implementation (after warm-up frames that fill the history).
    pub frames: u32,
    pub params: ReconstructParams,
    pub cpu: bool,
    pub gpu: bool,
}

impl Default for BenchSettings {
    fn default() -> Self {
        Self {
            width: 640,
            height: 480,
            loss: 0.25,
            frames: 20,
            params: ReconstructParams::default(),
            cpu: true,
            gpu: true,
        }
    }
}

/// One benchmark result (one JSON line).
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub width: u32,
    pub height: u32,
    pub loss: f32,
    pub frames: u32,
    /// Median CPU milliseconds per frame; `None` when not measured.
    pub cpu_ms: Option<f64>,
    pub cpu_threads: usize,
    /// Median GPU milliseconds per frame from timestamps; `None` without an adapter or
    /// timestamp support.
    pub gpu_ms: Option<f64>,
    /// Median wall milliseconds per GPU frame including upload and readback.
    pub gpu_wall_ms: Option<f64>,
    /// Median wall milliseconds per GPU frame left on the device (upload, passes, waiting
    /// for the queue; no readback): what a window on the same device waits for.
    pub gpu_on_device_ms: Option<f64>,
    /// Median wall milliseconds of the GPU G-buffer (raster pass and readback).
    pub gbuffer_ms: Option<f64>,
    /// Median wall milliseconds of the CPU G-buffer (one primary ray per pixel).
    pub gbuffer_cpu_ms: Option<f64>,
    /// The adapter's name, or why there is none.
    pub gpu_adapter: String,
}

struct Inputs {
    gbuffer: GBuffer,
    samples: Samples,
}

/// A frame's worth of noisy radiance over a G-buffer and the masks of the results that
/// arrived, one per frame in turn (the benchmarks' frames differ only in their mask).
pub(crate) struct Samples {
    pub radiance: Vec<Vec3>,
    pub masks: Vec<Vec<bool>>,
}

impl Samples {
    /// Noisy radiance over `gbuffer`'s analytic clean image, with `loss` of the pixels lost.
    pub fn new(gbuffer: &GBuffer, loss: f32) -> Self {
        let clean = synthetic::clean_radiance(gbuffer);
        let radiance = synthetic::noisy_radiance(&clean, 0.8, 1, 1);
        let masks =
            (0..4).map(|k| synthetic::random_mask(gbuffer.len(), 1.0 - loss, 3, k)).collect();
        Self { radiance, masks }
    }

    /// The mask of frame `k`.
    pub fn mask(&self, k: u64) -> &[bool] {
        &self.masks[k as usize % self.masks.len()]
    }
}

use glam::Vec3;

fn inputs(s: &BenchSettings) -> Inputs {
    let gbuffer = synthetic::gbuffer(s.width, s.height, SyntheticView::default());
    let samples = Samples::new(&gbuffer, s.loss);
    Inputs { gbuffer, samples }
}

/// The median of `v`; `None` when it is empty.
pub(crate) fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// Runs the benchmark.
pub fn run(s: &BenchSettings) -> anyhow::Result<BenchReport> {
    let inp = inputs(s);
    let warmup = s.params.history as u64 + 1;
    let frame = |k: u64| FrameInputs {
        frame: k + 1,
        state_version: k + 1,
        accumulated_frames: 1,
        radiance: &inp.samples.radiance,
        mask: inp.samples.mask(k),
        gbuffer: &inp.gbuffer,
        scene: None,
    };
    let mut report = BenchReport {
        width: s.width,
        height: s.height,
        loss: s.loss,
        frames: s.frames,
        cpu_ms: None,
        cpu_threads: rayon::current_num_threads(),
        gpu_ms: None,
        gpu_wall_ms: None,
        gpu_on_device_ms: None,
        gbuffer_ms: None,
        gbuffer_cpu_ms: None,
        gpu_adapter: "not measured".into(),
    };
    if s.cpu {
        let mut r = CpuReconstructor::new(s.width, s.height, s.params)?;
        let mut out = r.reconstruct(&frame(0))?;
        let mut times = Vec::new();
        for k in 1..warmup + s.frames as u64 {
            let t = Instant::now();
            r.reconstruct_into(&frame(k), &mut out)?;
            if k >= warmup {
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        report.cpu_ms = median(times);
        let (assets, state) = testscenes::cornell_box(s.width, s.height);
        let mut source = GBufferSource::new(assets, &state, Backend::Cpu)?;
        report.gbuffer_cpu_ms = time_gbuffers(s.frames, &state, |st| {
            source.get(st)?;
            Ok(())
        })?;
    }
    if s.gpu {
        match GpuContext::new() {
            Err(err) => report.gpu_adapter = format!("none: {err}"),
            Ok(ctx) => {
                report.gpu_adapter =
                    format!("{} ({:?})", ctx.adapter_info.name, ctx.adapter_info.backend);
                let ctx = ctx.shared();
                let (assets, state) = testscenes::cornell_box(s.width, s.height);
                let mut g = GpuGBuffer::new(ctx.clone(), assets, &state)?;
                report.gbuffer_ms = time_gbuffers(s.frames, &state, |st| {
                    g.compute(st)?;
                    Ok(())
                })?;
                let mut r = GpuReconstructor::new(ctx.clone(), s.width, s.height, s.params)?;
                let (mut gpu, mut wall, mut on_device) = (Vec::new(), Vec::new(), Vec::new());
                // Read-back and on-device frames alternate, so that load changes hit both.
                for k in 0..warmup + 2 * s.frames as u64 {
                    let t = Instant::now();
                    if k % 2 == 0 {
                        r.reconstruct(&frame(k))?;
                    } else {
                        drop(r.reconstruct_on_device(&frame(k))?);
                        ctx.device
                            .poll(wgpu::PollType::wait_indefinitely())
                            .map_err(|e| anyhow::anyhow!("waiting for the GPU: {e}"))?;
                    }
                    if k >= warmup {
                        let ms = t.elapsed().as_secs_f64() * 1e3;
                        if k % 2 == 0 {
                            wall.push(ms);
                            gpu.extend(r.last_gpu_ms());
                        } else {
                            on_device.push(ms);
                        }
                    }
                }
                report.gpu_ms = median(gpu);
                report.gpu_wall_ms = median(wall);
                report.gpu_on_device_ms = median(on_device);
            }
        }
    }
    Ok(report)
}

/// Median wall milliseconds of `compute` over `frames` new versions of `state` (after one
/// warm-up that uploads and compiles).
fn time_gbuffers(
    frames: u32,
    state: &gridlight_actors::state::SceneState,
    mut compute: impl FnMut(&gridlight_actors::state::SceneState) -> anyhow::Result<()>,
) -> anyhow::Result<Option<f64>> {
    let mut state = state.clone();
    let mut times = Vec::new();
    for k in 0..=frames {
        state.version += 1;
        let t = Instant::now();
        compute(&state)?;
        if k > 0 {
            times.push(t.elapsed().as_secs_f64() * 1e3);
        }
    }
    Ok(median(times))
}
