//! Turning a shown frame into pixels: the G-buffer of its scene state, reconstruction, and
//! the [`View`] asked for.
//!
//! G-buffers come from the wgpu raster pass on a hardware adapter and from primary rays on
//! the CPU otherwise ([`GBufferSource`]); reconstruction likewise (`--reconstruct`).
//!
//! One composer serves both the headless sink and the window, so that what a headless
//! master writes is exactly what the window shows. Every frame is reconstructed, whatever
//! the view, so that the temporal history and the accumulation stay complete when the user
//! switches back to the final view.

use std::sync::{Arc, RwLock};

use glam::Vec3;
use gridlight_actors::sink::ShownFrame;
use gridlight_actors::state::SceneState;
use thiserror::Error;

use crate::assets::Assets;
use crate::reconstruct::gbuffer::{GBufferError, GBufferSource};
use crate::reconstruct::{
    Backend, FrameInputs, ReconstructError, ReconstructParams, Reconstructor,
};
use crate::view::{self, View, ViewInputs};

/// The G-buffers of a run's frames, shared with whoever picks objects in the shown frame's
/// scene (the window): picking reads the same render scene the G-buffer was made from.
pub type SharedScene = Arc<RwLock<GBufferSource>>;

/// Why a frame could not be composed.
#[derive(Debug, Error)]
pub enum ComposeError {
    #[error(transparent)]
    GBuffer(#[from] GBufferError),
    #[error("reconstruction: {0}")]
    Reconstruct(#[from] ReconstructError),
    #[error("the frame's planes do not match its {width}×{height} resolution")]
    Size { width: u32, height: u32 },
}

/// One composed frame.
#[derive(Clone, Debug)]
pub struct Composed {
    pub width: u32,
    pub height: u32,
    /// The chosen view, display-encoded RGBA (tonemapped sRGB for colour views).
    pub rgba: Vec<[u8; 4]>,
    /// Final linear colour (albedo · radiance + emission), only for the final view.
    pub linear: Option<Vec<Vec3>>,
}

/// G-buffer, reconstruction and views for a run's shown frames.
pub struct Composer {
    gbuffers: SharedScene,
    params: ReconstructParams,
    backend: Backend,
    reconstructor: Option<Reconstructor>,
}

impl Composer {
    /// A composer for frames of scenes over `assets`, starting from `state`.
    pub fn new(
        assets: Arc<Assets>,
        state: &SceneState,
        params: ReconstructParams,
        backend: Backend,
    ) -> Result<Self, ComposeError> {
        params.validate()?;
        let source = GBufferSource::new(assets, state, backend)?;
        Ok(Self { gbuffers: Arc::new(RwLock::new(source)), params, backend, reconstructor: None })
    }

    /// The G-buffer source, whose render scene is the last composed frame's (for picking).
    pub fn scene(&self) -> SharedScene {
        Arc::clone(&self.gbuffers)
    }

    /// "cpu" or the GPU adapter's name, once the first frame chose.
    pub fn reconstructor(&self) -> Option<String> {
        self.reconstructor.as_ref().map(Reconstructor::describe)
    }

    /// Reconstructs `frame` and makes `view` of it.
    pub fn compose(&mut self, frame: &ShownFrame, view: View) -> Result<Composed, ComposeError> {
        let res = frame.state.resolution;
        let (width, height) = (res.width, res.height);
        let reconstructor = match &mut self.reconstructor {
            Some(r) => r,
            empty => empty.insert(Reconstructor::new(width, height, self.params, self.backend)?),
        };
        let g = self.gbuffers.write().unwrap_or_else(|p| p.into_inner()).get(&frame.state)?;
        let inputs = FrameInputs {
            frame: frame.frame,
            state_version: frame.state.version,
            radiance: &frame.current,
            mask: &frame.current_mask,
            gbuffer: &g,
        };
        let out = reconstructor.reconstruct(&inputs)?;
        if view == View::Final {
            return Ok(Composed { width, height, rgba: out.display, linear: Some(out.colour) });
        }
        let owner = if view == View::Workers {
            frame.owners.per_pixel(frame.current.len())
        } else {
            Vec::new()
        };
        let planes = ViewInputs {
            width,
            height,
            radiance: &frame.current,
            mask: &frame.current_mask,
            albedo: &g.albedo,
            emission: &g.emission,
            normal: &g.normal,
            owner: &owner,
        };
        let exposure = self.params.exposure;
        let rgba =
            view::diagnostic(view, &planes, |c| crate::reconstruct::tonemap::to_rgba8(c, exposure))
                .ok_or(ComposeError::Size { width, height })?;
        Ok(Composed { width, height, rgba, linear: None })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::master::FrameStats;

    fn cornell() -> (Arc<Assets>, SceneState) {
        crate::render::testscenes::cornell_box(16, 12)
    }

    fn frame(state: &SceneState, covered: impl Fn(usize) -> bool) -> ShownFrame {
        let n = state.resolution.pixels();
        let mask: Vec<bool> = (0..n).map(covered).collect();
        let radiance: Vec<Vec3> =
            mask.iter().map(|&m| if m { Vec3::splat(0.5) } else { Vec3::ZERO }).collect();
        ShownFrame {
            frame: 1,
            state: Arc::new(state.clone()),
            current: radiance.clone(),
            current_mask: mask.clone(),
            owners: Default::default(),
            stats: FrameStats { frame: 1, ..FrameStats::default() },
        }
    }

    #[test]
    fn the_final_view_fills_holes_that_the_partial_view_shows() {
        let (assets, state) = cornell();
        let mut c =
            Composer::new(assets, &state, ReconstructParams::default(), Backend::Cpu).unwrap();
        // Every other pixel lost: the final view must cover them from their neighbours.
        let f = frame(&state, |i| i % 2 == 0);
        let g = c.gbuffers.write().unwrap().get(&state).unwrap();
        let partial = c.compose(&f, View::Partial).unwrap();
        let last = c.compose(&f, View::Final).unwrap();
        assert!(last.linear.is_some() && partial.linear.is_none());
        let hit_holes: Vec<usize> = (0..g.len())
            .filter(|&i| i % 2 == 1 && g.object[i] != crate::reconstruct::NO_OBJECT)
            .collect();
        assert!(hit_holes.len() > 50, "the box's surfaces cover most holes");
        for &i in &hit_holes {
            assert_eq!(partial.rgba[i], [0, 0, 0, 255], "pixel {i}: a hole in the partial view");
            assert_ne!(last.rgba[i], [0, 0, 0, 255], "pixel {i}: filled in the final view");
        }
    }

    #[test]
    fn bad_parameters_are_refused_before_any_frame() {
        let (assets, state) = cornell();
        let params = ReconstructParams { radius: 999, ..ReconstructParams::default() };
        let err = Composer::new(assets, &state, params, Backend::Cpu)
            .err()
            .expect("radius 999 is refused");
        assert!(err.to_string().contains("radius"), "{err}");
    }
}
