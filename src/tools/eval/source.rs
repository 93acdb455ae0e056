//! Where evaluation frames come from: a [`FrameSource`] renders complete frames of a
//! sequence of views.

use std::sync::Arc;

use glam::Vec3;

use super::FrameData;
use crate::reconstruct::synthetic::{self, SyntheticView};

/// Renders complete frames. `view` picks a camera of the interaction sequence (0 is the
/// start view; each step moves the camera a little); `frame` seeds the samples, so
/// different frames of one view have independent noise.
pub trait FrameSource {
    fn width(&self) -> u32;
    fn height(&self) -> u32;
    /// A complete frame of `view` with the source's samples per pixel.
    fn frame(&mut self, view: usize, frame: u64) -> anyhow::Result<FrameData>;
    /// A converged image (linear colour) of `view`, the gold standard.
    fn gold(&mut self, view: usize) -> anyhow::Result<Vec<Vec3>>;
    /// Exposure for display, in stops.
    fn exposure(&self) -> f32 {
        0.0
    }
}

/// The analytic scene with multiplicative per-frame noise standing in for path tracing.
#[derive(Debug, Clone)]
pub struct SyntheticSource {
    pub width: u32,
    pub height: u32,
    /// Relative noise amplitude of one frame's samples.
    pub noise: f32,
    /// Camera displacement per view step (scene units).
    pub step: Vec3,
}

impl SyntheticSource {
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, noise: 0.8, step: Vec3::new(0.02, 0.01, 0.0) }
    }

    fn view(&self, view: usize) -> SyntheticView {
        SyntheticView { eye: SyntheticView::default().eye + self.step * view as f32 }
    }
}

impl FrameSource for SyntheticSource {
    fn width(&self) -> u32 {
        self.width
    }

    fn height(&self) -> u32 {
        self.height
    }

    fn frame(&mut self, view: usize, frame: u64) -> anyhow::Result<FrameData> {
        let g = Arc::new(synthetic::gbuffer(self.width, self.height, self.view(view)));
        let clean = synthetic::clean_radiance(&g);
        Ok(FrameData {
            radiance: synthetic::noisy_radiance(&clean, self.noise, 11, frame),
            gbuffer: g,
        })
    }

    fn gold(&mut self, view: usize) -> anyhow::Result<Vec<Vec3>> {
        let g = synthetic::gbuffer(self.width, self.height, self.view(view));
        Ok(super::remodulate(&synthetic::clean_radiance(&g), &g))
    }
}
