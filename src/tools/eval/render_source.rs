//! Evaluation frames from the path tracer: complete frames of a scene, with the camera
//! orbiting its look-at point by a small angle per view step (the interaction sequence).

use std::sync::Arc;

use glam::{Quat, Vec3};
use gridlight_actors::state::SceneState;
use rayon::prelude::*;

use super::{FrameData, FrameSource};
use crate::assets::Assets;
use crate::gbuffer::{scene_scale, GBuffer};
use crate::render::{render_pixels, PixelSample, RenderScene};

/// Pixels per parallel render task.
const CHUNK: usize = 4096;

/// Renders frames of one scene with `render_pixels` on all cores.
pub struct RenderSource {
    scene: RenderScene,
    assets: Arc<Assets>,
    base: SceneState,
    scale: f32,
    /// Samples per pixel of the converged image.
    pub gold_spp: u32,
    /// Camera orbit per view step, degrees about the up vector.
    pub step_deg: f32,
}

impl RenderSource {
    /// A source for `state` (its resolution and spp are the frames').
    pub fn new(assets: Arc<Assets>, state: SceneState, gold_spp: u32) -> anyhow::Result<Self> {
        let scene = RenderScene::new(assets.clone(), &state)?;
        let scale = scene_scale(&state, &assets);
        Ok(Self { scene, assets, base: state, scale, gold_spp, step_deg: 0.5 })
    }

    fn state(&self, view: usize, spp: u32) -> SceneState {
        let mut s = self.base.clone();
        let cam = &mut s.camera;
        let rot = Quat::from_axis_angle(
            cam.up.normalize_or(Vec3::Y),
            (self.step_deg * view as f32).to_radians(),
        );
        cam.position = cam.look_at + rot * (cam.position - cam.look_at);
        s.version = view as u64 + 1;
        s.render.spp = spp;
        s
    }

    fn render(&mut self, state: &SceneState, frame: u64) -> anyhow::Result<Vec<PixelSample>> {
        self.scene.set_state(state)?;
        let n = state.resolution.pixels() as u32;
        let pixels: Vec<u32> = (0..n).collect();
        let scene = &self.scene;
        let chunks: Vec<Vec<PixelSample>> = pixels
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut out = Vec::with_capacity(chunk.len());
                render_pixels(scene, frame, chunk, &mut out);
                out
            })
            .collect();
        Ok(chunks.concat())
    }
}

impl FrameSource for RenderSource {
    fn width(&self) -> u32 {
        self.base.resolution.width
    }

    fn height(&self) -> u32 {
        self.base.resolution.height
    }

    fn frame(&mut self, view: usize, frame: u64) -> anyhow::Result<FrameData> {
        let state = self.state(view, self.base.render.spp);
        let samples = self.render(&state, frame)?;
        let g = GBuffer::from_samples(self.width(), self.height(), &samples, self.scale);
        // As the master does: what workers send, demodulated by the G-buffer's albedo, so
        // that remodulating gives each pixel's mean colour back.
        let reflected: Vec<Vec3> = samples.iter().map(|s| s.reflected).collect();
        let mut radiance = Vec::new();
        crate::master::compose::demodulate(&reflected, &g.albedo, &mut radiance);
        Ok(FrameData { radiance, gbuffer: Arc::new(g) })
    }

    fn gold(&mut self, view: usize) -> anyhow::Result<Vec<glam::Vec3>> {
        let state = self.state(view, self.gold_spp);
        // A frame number no evaluation frame uses, so the gold samples are independent.
        let samples = self.render(&state, u64::MAX / 2)?;
        Ok(samples.iter().map(|s| s.reflected + s.emission).collect())
    }
}

impl std::fmt::Debug for RenderSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RenderSource")
            .field("assets", &self.assets.meshes.len())
            .finish_non_exhaustive()
    }
}
