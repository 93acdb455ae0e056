//! `gridlight bench compose`: milliseconds per shown frame of the master's compose, stage
//! by stage, at each resolution asked for, while the camera moves and while the view rests.
//!
//! The master's own [`Composer`] composes frames of the built-in Cornell box, as a frame
//! sink does: each frame's samples are noisy radiance with a fraction of the pixels lost
//! (the same inputs as `bench reconstruct`, over the box's G-buffer). *Moving*: every frame
//! is a new scene state, the camera a step further along an orbit of the look-at point
//! (as `scenes/scripts/orbit.toml` drags it), so every frame computes its G-buffer and
//! runs the interacting pipeline. *Resting*: one state, frames accumulating (the
//! G-buffer is cached; its area-mean emission is made once, in the warm-up frame).
//!
//! Stages, per frame: `gbuffer_ms` (getting the state's G-buffer), `reconstruct_ms`
//! (demodulation and reconstruction, the display's tonemap included), `handover_ms` (the
//! window sink's hand-over of the composed frame: [`FrameImage::from_composed`]), and
//! `total_ms` (the whole compose and the hand-over). Each is the median over the timed
//! frames, taken on its own (the stages' medians need not add up to the total's).

use std::sync::Arc;
use std::time::Instant;

use glam::{Quat, Vec3};
use gridlight_actors::master::FrameStats;
use gridlight_actors::sink::ShownFrame;
use gridlight_actors::state::{Resolution, SceneState};
use serde::Serialize;

use super::reconstruct::{median, Samples};
use crate::gpu::{Backend, GpuContext};
use crate::master::compose::Composer;
use crate::master::view::View;
use crate::reconstruct::ReconstructParams;
use crate::render::testscenes;
use crate::window::picture::FrameImage;

/// What to measure.
#[derive(Clone, Debug)]
pub struct ComposeSettings {
    pub resolutions: Vec<Resolution>,
    /// Timed frames per case (after warm-up frames that fill the history).
    pub frames: u32,
    /// Fraction of pixels without a result in each frame.
    pub loss: f32,
    pub params: ReconstructParams,
    /// Also measure on a hardware adapter, when there is one.
    pub gpu: bool,
}

impl Default for ComposeSettings {
    fn default() -> Self {
        Self {
            resolutions: vec![Resolution { width: 640, height: 480 }],
            frames: 10,
            loss: 0.25,
            params: ReconstructParams::default(),
            gpu: true,
        }
    }
}

/// Median milliseconds of each stage of one case.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Stages {
    pub gbuffer_ms: f64,
    pub reconstruct_ms: f64,
    pub handover_ms: f64,
    pub total_ms: f64,
}

/// Both cases on one backend.
#[derive(Clone, Debug, Serialize)]
pub struct Cases {
    /// "cpu", or the adapter's name.
    pub backend: String,
    /// A new scene state every frame.
    pub moving: Stages,
    /// One scene state, accumulating.
    pub resting: Stages,
}

/// One resolution's results (one JSON line).
#[derive(Clone, Debug, Serialize)]
pub struct ComposeReport {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub loss: f32,
    pub cpu_threads: usize,
    pub cpu: Cases,
    /// On a hardware adapter (G-buffer raster pass and GPU reconstruction, read back as a
    /// headless master does); `None` without one or when not asked for.
    pub gpu: Option<Cases>,
    /// The adapter's name, or why there is none.
    pub gpu_adapter: String,
}

/// Runs the benchmark at every resolution, calling `report` with each line as it is done.
pub fn run(
    s: &ComposeSettings,
    mut report: impl FnMut(&ComposeReport) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let adapter = if s.gpu {
        GpuContext::new_hardware().map(|ctx| ctx.adapter_info.name.clone())
    } else {
        Err(crate::gpu::GpuError::NoAdapter("not asked for".into()))
    };
    for &res in &s.resolutions {
        let cpu = cases(s, res, Backend::Cpu, "cpu")?;
        let gpu = match &adapter {
            Ok(name) => Some(cases(s, res, Backend::Gpu, name)?),
            Err(_) => None,
        };
        report(&ComposeReport {
            width: res.width,
            height: res.height,
            frames: s.frames,
            loss: s.loss,
            cpu_threads: rayon::current_num_threads(),
            cpu,
            gpu,
            gpu_adapter: match &adapter {
                Ok(name) => name.clone(),
                Err(err) => format!("none: {err}"),
            },
        })?;
    }
    Ok(())
}

/// The moving and the resting case at `res` on `backend`.
fn cases(
    s: &ComposeSettings,
    res: Resolution,
    backend: Backend,
    name: &str,
) -> anyhow::Result<Cases> {
    let (assets, mut state) = testscenes::cornell_box(res.width, res.height);
    let mut composer = Composer::new(assets, &state, s.params, backend)?;
    let gbuffer = composer.scene().write().unwrap_or_else(|p| p.into_inner()).get(&state)?;
    let samples = Samples::new(&gbuffer, s.loss);
    drop(gbuffer);
    let warmup = s.params.history as u64 + 1;
    let centre = state.camera.position;
    let mut frame_no = 0;
    let mut compose = |state: &SceneState, accumulated: u32| -> anyhow::Result<[f64; 4]> {
        frame_no += 1;
        let mask = samples.mask(frame_no);
        let current = samples
            .radiance
            .iter()
            .zip(mask)
            .map(|(&l, &m)| if m { l } else { Vec3::ZERO })
            .collect();
        let frame = ShownFrame {
            frame: frame_no,
            state: Arc::new(state.clone()),
            current,
            current_mask: mask.to_vec(),
            owners: Default::default(),
            stats: FrameStats {
                frame: frame_no,
                accumulated_frames: accumulated,
                ..FrameStats::default()
            },
        };
        let started = Instant::now();
        let c = composer.compose(&frame, View::Final)?;
        let handing = Instant::now();
        let image = FrameImage::from_composed(c.width, c.height, c.image)
            .ok_or_else(|| anyhow::anyhow!("the composed picture does not match its size"))?;
        let handover_ms = handing.elapsed().as_secs_f64() * 1e3;
        let total_ms = started.elapsed().as_secs_f64() * 1e3;
        drop(image);
        let t = c.timings;
        Ok([t.gbuffer_ms, t.reconstruct_ms, handover_ms, total_ms])
    };
    let mut moving = Vec::new();
    for k in 0..warmup + s.frames as u64 {
        state.version += 1;
        state.camera.position = orbit(centre, state.camera.look_at, k);
        let times = compose(&state, 1)?;
        if k >= warmup {
            moving.push(times);
        }
    }
    let mut resting = Vec::new();
    // The first accumulating frame makes the state's area-mean emission: warm-up.
    for k in 0..=s.frames {
        let times = compose(&state, 2 + k)?;
        if k > 0 {
            resting.push(times);
        }
    }
    Ok(Cases { backend: name.to_string(), moving: stages(moving), resting: stages(resting) })
}

/// The camera position of orbit step `k`: swinging ±20° around `look_at`'s vertical axis,
/// 1.5° a frame (a steady drag).
fn orbit(start: Vec3, look_at: Vec3, k: u64) -> Vec3 {
    let step = (k % 54) as f32;
    let degrees = if step < 27.0 { step * 1.5 - 20.0 } else { 20.0 - (step - 27.0) * 1.5 };
    look_at + Quat::from_rotation_y(degrees.to_radians()) * (start - look_at)
}

/// Each stage's median over the frames.
fn stages(frames: Vec<[f64; 4]>) -> Stages {
    let of = |k: usize| median(frames.iter().map(|f| f[k]).collect()).unwrap_or(f64::NAN);
    Stages { gbuffer_ms: of(0), reconstruct_ms: of(1), handover_ms: of(2), total_ms: of(3) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_stage_is_timed_in_both_cases() {
        let s = ComposeSettings {
            resolutions: vec![Resolution { width: 24, height: 16 }],
            frames: 2,
            gpu: false,
            ..ComposeSettings::default()
        };
        let mut lines = Vec::new();
        run(&s, |r| {
            lines.push(r.clone());
            Ok(())
        })
        .expect("the benchmark runs");
        assert_eq!(lines.len(), 1);
        let r = &lines[0];
        assert_eq!((r.width, r.height, r.cpu.backend.as_str()), (24, 16, "cpu"));
        for c in [r.cpu.moving, r.cpu.resting] {
            for ms in [c.gbuffer_ms, c.reconstruct_ms, c.handover_ms, c.total_ms] {
                assert!(ms.is_finite() && ms >= 0.0, "{c:?}");
            }
            assert!(c.total_ms >= c.reconstruct_ms, "{c:?}");
        }
        assert!(r.gpu.is_none());
    }

    #[test]
    fn the_orbit_keeps_its_distance_and_swings_both_ways() {
        let (start, look_at) = (Vec3::new(0.0, 0.0, 3.9), Vec3::ZERO);
        let xs: Vec<f32> = (0..54).map(|k| orbit(start, look_at, k).x).collect();
        for k in 0..54 {
            assert!((orbit(start, look_at, k).length() - 3.9).abs() < 1e-4);
        }
        assert!(xs.iter().any(|&x| x > 1.0) && xs.iter().any(|&x| x < -1.0));
        assert_ne!(orbit(start, look_at, 3), orbit(start, look_at, 4));
    }
}
