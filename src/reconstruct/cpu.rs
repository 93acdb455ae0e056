//! The CPU reference reconstructor: the whole pipeline with rayon, for tests and for
//! headless masters without an adapter.
//!
//! The passes work on planes with a border (`super::planes`). The G-buffer is split into
//! planes once per frame and shared by every filter; the history ring keeps each past
//! frame's planes, and a frame enters the ring by swapping buffers with the slot it
//! replaces (whose buffers become the next frame's), so nothing is copied.

use bytemuck::Zeroable;
use glam::Vec4;

use super::history::HistoryRing;
use super::pass::{self, FillInputs, Outputs, PassConsts, PastFrame};
use super::planes::{GuidePlanes, Layout, Planes3};
use super::{FrameInputs, Mode, ReconstructError, ReconstructParams, Reconstructed};
use gridlight_actors::state::StateVersion;

/// One previous frame kept for the temporal filter.
#[derive(Debug)]
struct Past {
    /// Filled radiance.
    radiance: Planes3,
    guide: Guide,
}

/// G-buffer planes and the scene-state version they were split from: a frame of the same
/// version has the same normals and positions (its G-buffer goes with its state), so
/// while the view rests the split is skipped.
#[derive(Debug)]
struct Guide {
    planes: GuidePlanes,
    version: Option<StateVersion>,
}

impl Guide {
    fn new(layout: &Layout) -> Self {
        Self { planes: GuidePlanes::new(layout), version: None }
    }

    /// The planes of `inputs`' G-buffer, split unless they already hold its version.
    fn update(&mut self, inputs: &FrameInputs, layout: &Layout) -> &GuidePlanes {
        if self.version != Some(inputs.state_version) {
            let g = inputs.gbuffer;
            self.planes.split(&g.normal, &g.position, layout);
            self.version = Some(inputs.state_version);
        }
        &self.planes
    }
}

/// Reconstructs frames of one size on the CPU, keeping accumulation and history between
/// calls.
#[derive(Debug)]
pub struct CpuReconstructor {
    width: u32,
    height: u32,
    params: ReconstructParams,
    layout: Layout,
    /// rgb: sum of samples since the last state change; w: their number.
    accum: Vec<Vec4>,
    ring: HistoryRing,
    past: Vec<Past>,
    /// This frame's G-buffer.
    guide: Guide,
    fill_inputs: FillInputs,
    filled: Planes3,
    blended: Planes3,
    filtered: Planes3,
}

impl CpuReconstructor {
    pub fn new(
        width: u32,
        height: u32,
        params: ReconstructParams,
    ) -> Result<Self, ReconstructError> {
        params.validate()?;
        let n = width as usize * height as usize;
        let pad = params.radius.max(params.gauss_radius() as u32) as usize;
        let layout = Layout::new(width, height, pad);
        let ring = HistoryRing::new(params.history);
        let past = (0..ring.capacity())
            .map(|_| Past { radiance: layout.zeroed3(), guide: Guide::new(&layout) })
            .collect();
        Ok(Self {
            width,
            height,
            params,
            layout,
            accum: vec![Vec4::ZERO; n],
            ring,
            past,
            guide: Guide::new(&layout),
            fill_inputs: FillInputs::new(&layout),
            filled: layout.zeroed3(),
            blended: layout.zeroed3(),
            filtered: layout.zeroed3(),
        })
    }

    pub fn params(&self) -> &ReconstructParams {
        &self.params
    }

    /// Runs the pipeline on one frame (see the module doc of `reconstruct`).
    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        let mut out = Reconstructed::empty(inputs.frame);
        self.reconstruct_into(inputs, &mut out)?;
        Ok(out)
    }

    /// [`Self::reconstruct`] into `out`, reusing its buffers: a caller that keeps one
    /// `Reconstructed` from frame to frame allocates nothing per frame. On an error `out` is
    /// unchanged.
    pub fn reconstruct_into(
        &mut self,
        inputs: &FrameInputs,
        out: &mut Reconstructed,
    ) -> Result<(), ReconstructError> {
        inputs.validate(self.width, self.height)?;
        let g = inputs.gbuffer;
        let c = PassConsts::new(self.width, self.height, &self.params, g.scene_scale);
        let layout = &self.layout;
        let mode = Mode::of(inputs.accumulated_frames);
        let reset = mode == Mode::Interacting;

        let guide = self.guide.update(inputs, layout);
        pass::accumulate(reset, inputs.radiance, inputs.mask, &mut self.accum, self.width);
        pass::fill(&self.accum, guide, &c, layout, &mut self.fill_inputs, &mut self.filled);
        let result = if mode == Mode::Interacting {
            let weights = self.ring.weights(inputs.frame);
            let past: Vec<PastFrame> = self
                .past
                .iter()
                .zip(weights)
                .filter(|(_, w)| *w > 0.0)
                .map(|(p, weight)| PastFrame {
                    weight,
                    radiance: &p.radiance,
                    guide: &p.guide.planes,
                })
                .collect();
            pass::temporal(&self.filled, guide, &past, &c, layout, &mut self.blended);
            pass::gaussian(&self.blended, guide, &c, layout, &mut self.filtered);
            &self.filtered
        } else {
            &self.filled
        };

        (out.frame, out.mode) = (inputs.frame, mode);
        let n = g.len();
        let outputs = Outputs {
            radiance: sized(&mut out.radiance, n),
            colour: sized(&mut out.colour, n),
            display: sized(&mut out.display, n),
        };
        pass::remodulate(result, layout, &g.albedo, &g.emission, &c, outputs);

        if let Some(slot) = self.ring.push(inputs.frame) {
            let p = &mut self.past[slot];
            std::mem::swap(&mut p.radiance, &mut self.filled);
            std::mem::swap(&mut p.guide, &mut self.guide);
        }
        Ok(())
    }
}

/// `v` with `n` entries to be overwritten: as it is when it has them, else new zeroed
/// memory (which the OS maps lazily, so the threads that write it fault it in, in parallel).
fn sized<T: Zeroable>(v: &mut Vec<T>, n: usize) -> &mut [T] {
    if v.len() != n {
        *v = bytemuck::zeroed_vec(n);
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::synthetic::{self, SyntheticView};

    #[test]
    fn reconstruct_into_reuses_its_buffers_and_matches_reconstruct() {
        let (w, h) = (24, 16);
        let g = synthetic::gbuffer(w, h, SyntheticView::default());
        let radiance = synthetic::noisy_radiance(&synthetic::clean_radiance(&g), 0.5, 1, 1);
        let masks: Vec<_> = (0..5).map(|k| synthetic::random_mask(g.len(), 0.7, 1, k)).collect();
        let inputs = |frame: u64| FrameInputs {
            frame,
            state_version: frame / 2,
            accumulated_frames: frame as u32 % 2 + 1,
            radiance: &radiance,
            mask: &masks[frame as usize],
            gbuffer: &g,
            scene: None,
        };
        let params = ReconstructParams::default();
        let (mut into, mut fresh) = (CpuReconstructor::new(w, h, params).expect("valid"), None);
        let mut out = into.reconstruct(&inputs(0)).expect("frame 0");
        let buffer = out.radiance.as_ptr();
        for frame in 1..5 {
            let reference = fresh.get_or_insert_with(|| {
                let mut r = CpuReconstructor::new(w, h, params).expect("valid");
                r.reconstruct(&inputs(0)).expect("frame 0");
                r
            });
            let want = reference.reconstruct(&inputs(frame)).expect("frame");
            into.reconstruct_into(&inputs(frame), &mut out).expect("frame");
            assert_eq!((out.frame, out.mode), (want.frame, want.mode));
            assert_eq!((&out.radiance, &out.colour), (&want.radiance, &want.colour));
            assert_eq!(out.display, want.display);
            assert_eq!(out.radiance.as_ptr(), buffer, "the buffer is reused");
        }
        let short = FrameInputs { frame: 5, mask: &masks[0][1..], ..inputs(4) };
        into.reconstruct_into(&short, &mut out).expect_err("a short mask");
        assert_eq!(out.frame, 4, "an error leaves the output as it was");
    }
}
