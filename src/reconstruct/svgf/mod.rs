//! SVGF-class reconstruction (issue 41): the accumulated history follows the view, and a
//! variance-guided à-trous filter replaces the paper's temporal blend and Gaussian.
//!
//! Per shown frame, on demodulated radiance guided by the frame's G-buffer:
//! 1. on a new scene state, [`reproject`] the history (demodulated sample sums, counts
//!    and luminance moments) from the previous state's pixels through the known camera
//!    and object motion, rejecting what the previous G-buffer shows as another surface
//!    (disocclusions); after an edit of the lighting or a moved object, where the frame's
//!    new samples show that the light changed, the history is rescaled ([`gradient`]);
//!    then the frame's samples are added. An unchanged state keeps
//!    accumulating without a cap, so a resting view converges to the unbiased mean as
//!    the paper's accumulation does;
//! 2. the paper's fill (`pass::fill`) for pixels still without samples (lost jobs,
//!    disocclusions);
//! 3. [`variance`] of each pixel's estimate, from its moments (spatially where short);
//! 4. [`atrous`] iterations with edge-stopping on normals, planes and luminance;
//! 5. the paper's remodulation (`pass::remodulate`).
//!
//! The edge-stopping weights are `edges.rs`; the parameters and the method switch
//! `params.rs`; the temporal gradient `gradient.rs`. The CPU kernels run in rows over every
//! core (`reconstruct::rows`); `gpu.rs` runs the same steps in WGSL inside the GPU pipeline.

use glam::Vec4;
use gridlight_actors::state::{SceneState, StateVersion};
use rayon::prelude::*;

pub mod atrous;
pub mod edges;
pub mod gpu;
pub mod gradient;
pub mod params;
pub mod reproject;
pub mod variance;

pub use params::{Method, SvgfParams};

use self::edges::Edges;
use self::gradient::Gradient;
use self::reproject::{Moments, Motion, PreviousGuide};
use self::variance::MomentPlanes;
use super::pass::{self, FillInputs, Outputs, PassConsts};
use super::planes::{GuidePlanes, Layout, Plane, Planes3};
use super::{FrameInputs, Mode, ReconstructError, ReconstructParams, Reconstructed};
use crate::gbuffer::NO_OBJECT;

/// The state the history was last carried to, which decides what a new state does to it:
/// the one decision both pipelines (this CPU one and the GPU's, `gpu.rs`) take.
#[derive(Debug, Default)]
pub struct Follower {
    /// Its version, and its scene state when the caller gave one.
    previous: Option<(StateVersion, Option<SceneState>)>,
}

/// What a frame's new scene state does to the history.
#[derive(Debug)]
pub enum Carry {
    /// Nothing to carry it through (the first frame, an unknown motion): start empty.
    Drop,
    /// Reproject it through `motion`, each pixel counting for at most `cap` samples;
    /// `gradient`: where the frame's samples disagree with it, rescale it ([`gradient`]).
    Reproject { motion: Motion, cap: f32, gradient: bool },
}

impl Follower {
    /// `None` while the state is the last one; else what to do, and the new state is kept.
    pub fn follow(&mut self, inputs: &FrameInputs, sp: &SvgfParams) -> Option<Carry> {
        if self.previous.as_ref().is_some_and(|(v, _)| *v == inputs.state_version) {
            return None;
        }
        let motion = match (&self.previous, inputs.scene) {
            (None, _) => None,
            (Some((_, Some(prev))), Some(cur)) => Motion::between(prev, cur),
            (Some(_), _) => {
                let objects = inputs.gbuffer.object.iter().filter(|&&o| o != NO_OBJECT).max();
                Some(Motion::still(objects.map_or(0, |&m| m as usize + 1)))
            }
        };
        self.previous = Some((inputs.state_version, inputs.scene.cloned()));
        Some(match motion {
            Some(motion) => {
                let cap = if motion.lighting_changed { sp.edit_samples } else { sp.motion_samples };
                Carry::Reproject { gradient: motion.relights(), motion, cap }
            }
            None => Carry::Drop,
        })
    }
}

/// Reconstructs frames of one size with reprojected history and à-trous filtering, on
/// the CPU.
#[derive(Debug)]
pub struct SvgfReconstructor {
    width: u32,
    height: u32,
    params: ReconstructParams,
    layout: Layout,
    /// Per pixel: the samples since the history began, reprojected across states.
    history: Vec<Moments>,
    /// The reprojection's output, swapped with `history`.
    spare: Vec<Moments>,
    /// The history's sums as the fill reads them.
    accum: Vec<Vec4>,
    follower: Follower,
    /// The last state's G-buffer planes, which its successor reprojects from.
    previous: PreviousGuide,
    gradient: Gradient,
    guide: GuidePlanes,
    fill_inputs: FillInputs,
    moments: MomentPlanes,
    colour: [Planes3; 2],
    variance: [Plane; 2],
}

impl SvgfReconstructor {
    pub fn new(
        width: u32,
        height: u32,
        params: ReconstructParams,
    ) -> Result<Self, ReconstructError> {
        params.validate()?;
        let n = width as usize * height as usize;
        let pad = (params.radius as usize).max(params.svgf.reach());
        let layout = Layout::new(width, height, pad);
        Ok(Self {
            width,
            height,
            params,
            layout,
            history: vec![Moments::default(); n],
            spare: vec![Moments::default(); n],
            accum: vec![Vec4::ZERO; n],
            follower: Follower::default(),
            previous: PreviousGuide::default(),
            gradient: Gradient::new(width, height),
            guide: GuidePlanes::new(&layout),
            fill_inputs: FillInputs::new(&layout),
            moments: MomentPlanes::new(&layout),
            colour: [layout.zeroed3(), layout.zeroed3()],
            variance: [Plane::zeroed(layout.plane_len()), Plane::zeroed(layout.plane_len())],
        })
    }

    pub fn params(&self) -> &ReconstructParams {
        &self.params
    }

    /// Samples each pixel's history holds (the frame's own included), after the last frame.
    pub fn samples(&self) -> impl Iterator<Item = f32> + '_ {
        self.history.iter().map(|m| m.sum.w)
    }

    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        let mut out = Reconstructed::empty(inputs.frame);
        self.reconstruct_into(inputs, &mut out)?;
        Ok(out)
    }

    /// [`Self::reconstruct`] into `out`, reusing its buffers.
    pub fn reconstruct_into(
        &mut self,
        inputs: &FrameInputs,
        out: &mut Reconstructed,
    ) -> Result<(), ReconstructError> {
        inputs.validate(self.width, self.height)?;
        let g = inputs.gbuffer;
        let c = PassConsts::new(self.width, self.height, &self.params, g.scene_scale);
        let layout = self.layout;
        let sp = self.params.svgf;

        if self.follow(inputs) {
            self.gradient.correct(&mut self.history, inputs.radiance, inputs.mask);
        }
        self.history.par_iter_mut().zip(inputs.radiance).zip(inputs.mask).for_each(
            |((m, &v), &has)| {
                if has {
                    m.add(v);
                }
            },
        );
        self.accum.par_iter_mut().zip(&self.history).for_each(|(a, m)| *a = m.sum);
        self.guide.split(&g.normal, &g.position, &layout);
        let [filled, spare] = &mut self.colour;
        pass::fill(&self.accum, &self.guide, &c, &layout, &mut self.fill_inputs, filled);

        let edges = Edges::new(sp.normal_power, sp.sigma_plane, g.scene_scale);
        self.moments.split(&self.history, &layout);
        let [var, var_spare] = &mut self.variance;
        variance::variance(&self.moments, filled, &self.guide, edges, &layout, var);
        let (mut src, mut dst) = ((filled, var), (spare, var_spare));
        for k in 0..sp.iterations {
            let (colour, var) = (&*src.0, &*src.1);
            let outputs = (&mut *dst.0, &mut *dst.1);
            atrous::iteration(
                colour,
                var,
                &self.guide,
                edges,
                sp.sigma_luminance,
                1 << k,
                &layout,
                outputs,
            );
            std::mem::swap(&mut src, &mut dst);
        }

        (out.frame, out.mode) = (inputs.frame, Mode::of(inputs.accumulated_frames));
        let n = g.len();
        let outputs = Outputs {
            radiance: sized(&mut out.radiance, n),
            colour: sized(&mut out.colour, n),
            display: sized(&mut out.display, n),
        };
        pass::remodulate(src.0, &layout, &g.albedo, &g.emission, &c, outputs);
        Ok(())
    }

    /// On a new scene state, carries the history over from the previous one (or drops it
    /// where the motion is unknown) and keeps this frame's G-buffer for the next; whether
    /// the lighting may have changed (the temporal gradient's turn).
    fn follow(&mut self, inputs: &FrameInputs) -> bool {
        let g = inputs.gbuffer;
        let Some(carry) = self.follower.follow(inputs, &self.params.svgf) else {
            return false;
        };
        let relit = match carry {
            Carry::Reproject { motion, cap, gradient } => {
                let (prev, history) = (&self.previous, &self.history);
                reproject::reproject(&motion, prev, history, g, cap, &mut self.spare);
                std::mem::swap(&mut self.history, &mut self.spare);
                gradient
            }
            Carry::Drop => {
                self.history.fill(Moments::default());
                false
            }
        };
        self.previous.keep(g);
        relit
    }
}

/// `v` with `n` entries to be overwritten.
fn sized<T: bytemuck::Zeroable + Clone>(v: &mut Vec<T>, n: usize) -> &mut [T] {
    if v.len() != n {
        *v = bytemuck::zeroed_vec(n);
    }
    v
}

#[cfg(test)]
mod tests;
