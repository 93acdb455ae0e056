//! The CPU reference reconstructor: the whole pipeline with rayon, for tests and for
//! headless masters without an adapter.

use glam::{Vec3, Vec4};

use super::history::{Accumulation, HistoryRing};
use super::passes::{self, Guide, PassConsts, PastFrame};
use super::{FrameInputs, Mode, ReconstructError, ReconstructParams, Reconstructed};

/// One previous frame kept for the temporal filter.
#[derive(Clone, Debug, Default)]
struct Past {
    radiance: Vec<Vec3>,
    normal: Vec<Vec3>,
    position: Vec<Vec3>,
}

/// Reconstructs frames of one size on the CPU, keeping accumulation and history between
/// calls.
#[derive(Debug)]
pub struct CpuReconstructor {
    width: u32,
    height: u32,
    params: ReconstructParams,
    accumulation: Accumulation,
    /// rgb: sum of samples since the last state change; w: their number.
    accum: Vec<Vec4>,
    ring: HistoryRing,
    past: Vec<Past>,
    filled: Vec<Vec3>,
    blended: Vec<Vec3>,
    filtered: Vec<Vec3>,
}

impl CpuReconstructor {
    pub fn new(
        width: u32,
        height: u32,
        params: ReconstructParams,
    ) -> Result<Self, ReconstructError> {
        params.validate()?;
        let n = width as usize * height as usize;
        let ring = HistoryRing::new(params.history);
        Ok(Self {
            width,
            height,
            params,
            accumulation: Accumulation::default(),
            accum: vec![Vec4::ZERO; n],
            past: vec![Past::default(); ring.capacity()],
            ring,
            filled: vec![Vec3::ZERO; n],
            blended: vec![Vec3::ZERO; n],
            filtered: vec![Vec3::ZERO; n],
        })
    }

    pub fn params(&self) -> &ReconstructParams {
        &self.params
    }

    /// Runs the pipeline on one frame (see the module doc of `reconstruct`).
    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        inputs.validate(self.width, self.height)?;
        let g = inputs.gbuffer;
        let c = PassConsts::new(self.width, self.height, &self.params, g.scene_scale);
        let guide = Guide { normal: &g.normal, position: &g.position };
        let (reset, mode) = self.accumulation.begin(inputs.state_version);

        passes::accumulate(reset, inputs.radiance, inputs.mask, &mut self.accum, self.width);
        passes::fill(&self.accum, guide, &c, &mut self.filled);
        let result = if mode == Mode::Interacting {
            let weights = self.ring.weights(inputs.frame);
            let past: Vec<PastFrame> = self
                .past
                .iter()
                .zip(weights)
                .filter(|(p, w)| *w > 0.0 && !p.radiance.is_empty())
                .map(|(p, weight)| PastFrame {
                    weight,
                    radiance: &p.radiance,
                    guide: Guide { normal: &p.normal, position: &p.position },
                })
                .collect();
            passes::temporal(&self.filled, guide, &past, &c, &mut self.blended);
            passes::gaussian(&self.blended, guide, &c, &mut self.filtered);
            &self.filtered
        } else {
            &self.filled
        };

        let n = result.len();
        let mut out = Reconstructed {
            frame: inputs.frame,
            mode,
            radiance: result.clone(),
            colour: vec![Vec3::ZERO; n],
            display: vec![[0; 4]; n],
        };
        passes::remodulate(
            &out.radiance,
            &g.albedo,
            &g.emission,
            &c,
            &mut out.colour,
            &mut out.display,
        );

        if let Some(slot) = self.ring.push(inputs.frame) {
            let p = &mut self.past[slot];
            p.radiance.clone_from(&self.filled);
            p.normal.clone_from(&g.normal);
            p.position.clone_from(&g.position);
        }
        Ok(out)
    }
}
