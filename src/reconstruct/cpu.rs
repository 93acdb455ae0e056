//! The CPU reference reconstructor: the whole pipeline with rayon, for tests and for
//! headless masters without an adapter.
//!
//! The passes work on planes with a border (`super::planes`). The G-buffer is split into
//! planes once per scene state and shared by every filter; the history ring keeps each
//! past frame's planes, and a frame enters the ring by swapping its radiance buffers with
//! the slot it replaces (whose buffers become the next frame's) and sharing its guide, so
//! nothing is copied, and a resting view, whose frames all have one state, splits its
//! G-buffer once.

use std::sync::Arc;

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
    /// Its G-buffer's planes, shared with the other frames of its scene state.
    guide: Arc<Guide>,
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
}

/// This frame's guide, and planes to split the next state's into.
#[derive(Debug)]
struct Guides {
    current: Arc<Guide>,
    /// The guide the ring let go of last, reused unless a slot still shares it.
    spare: Option<Arc<Guide>>,
}

impl Guides {
    /// The planes of `inputs`' G-buffer, split unless the current guide holds its version;
    /// the planes split into are the current guide's unless a ring slot shares them, else
    /// the spare's, else new ones.
    fn update(&mut self, inputs: &FrameInputs, layout: &Layout) -> &GuidePlanes {
        if self.current.version != Some(inputs.state_version) {
            if Arc::get_mut(&mut self.current).is_none() {
                self.current = match self.spare.take() {
                    Some(spare) if Arc::strong_count(&spare) == 1 => spare,
                    _ => Arc::new(Guide::new(layout)),
                };
            }
            let guide = Arc::get_mut(&mut self.current).expect("not shared");
            let g = inputs.gbuffer;
            guide.planes.split(&g.normal, &g.position, layout);
            guide.version = Some(inputs.state_version);
        }
        &self.current.planes
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
    guides: Guides,
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
            .map(|_| Past { radiance: layout.zeroed3(), guide: Arc::new(Guide::new(&layout)) })
            .collect();
        Ok(Self {
            width,
            height,
            params,
            layout,
            accum: vec![Vec4::ZERO; n],
            ring,
            past,
            guides: Guides { current: Arc::new(Guide::new(&layout)), spare: None },
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

        let mut clock = PassClock::start();
        let guide = self.guides.update(inputs, layout);
        clock.lap("guide");
        pass::accumulate(reset, inputs.radiance, inputs.mask, &mut self.accum, self.width);
        clock.lap("accumulate");
        pass::fill(&self.accum, guide, &c, layout, &mut self.fill_inputs, &mut self.filled);
        clock.lap("fill");
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
            clock.lap("temporal");
            pass::gaussian(&self.blended, guide, &c, layout, &mut self.filtered);
            clock.lap("gaussian");
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
        clock.lap("remodulate");
        clock.report(inputs.frame);

        if let Some(slot) = self.ring.push(inputs.frame) {
            let p = &mut self.past[slot];
            std::mem::swap(&mut p.radiance, &mut self.filled);
            let shared = Arc::clone(&self.guides.current);
            self.guides.spare = Some(std::mem::replace(&mut p.guide, shared));
        }
        Ok(())
    }
}

/// Milliseconds of each pass of one frame, logged at debug level (`RUST_LOG=debug`): where
/// the reconstruction's time goes, without a profiler.
struct PassClock {
    last: std::time::Instant,
    laps: Vec<(&'static str, f64)>,
}

impl PassClock {
    fn start() -> Self {
        Self { last: std::time::Instant::now(), laps: Vec::with_capacity(6) }
    }

    fn lap(&mut self, pass: &'static str) {
        let now = std::time::Instant::now();
        self.laps.push((pass, (now - self.last).as_secs_f64() * 1e3));
        self.last = now;
    }

    fn report(&self, frame: u64) {
        tracing::debug!(frame, passes_ms = ?self.laps, "cpu reconstruction");
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

    #[test]
    fn frames_of_one_state_share_one_split_of_its_gbuffer() {
        let (w, h) = (20, 12);
        let g = synthetic::gbuffer(w, h, SyntheticView::default());
        let radiance = synthetic::clean_radiance(&g);
        let mask = synthetic::random_mask(g.len(), 0.7, 1, 0);
        let mut r = CpuReconstructor::new(w, h, ReconstructParams::default()).expect("valid");
        let frame = |frame: u64, state_version: u64| FrameInputs {
            frame,
            state_version,
            accumulated_frames: 1,
            radiance: &radiance,
            mask: &mask,
            gbuffer: &g,
            scene: None,
        };
        for f in 1..=3 {
            r.reconstruct(&frame(f, f)).expect("moving");
        }
        let moving = r.guides.current.clone();
        assert!(r
            .past
            .iter()
            .all(|p| Arc::ptr_eq(&p.guide, &moving) == (p.guide.version == Some(3))));
        for f in 4..=9 {
            r.reconstruct(&frame(f, 4)).expect("resting");
        }
        let current = &r.guides.current;
        assert_eq!(current.version, Some(4));
        assert!(r.past.iter().all(|p| Arc::ptr_eq(&p.guide, current)), "one split, shared");
    }
}
