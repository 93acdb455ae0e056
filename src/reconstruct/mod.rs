//! Spatio-temporal reconstruction of partial, noisy frames (paper §4.3.1).
//!
//! Per shown frame, on demodulated radiance (reflected radiance divided by the G-buffer's
//! albedo; DESIGN.md), guided by the frame's [`GBuffer`], the five passes of [`pass`] run
//! in order: accumulate, fill, and while interacting (the first frame of a scene state)
//! temporal and the edge-aware Gaussian, then remodulate. Each pass keeps its CPU kernel,
//! WGSL and GPU binding together in `pass/`; the pipelines that run them are
//! [`CpuReconstructor`] (the multithreaded reference, `cpu.rs`) and [`GpuReconstructor`]
//! (`gpu.rs`, on the device plumbing of `crate::gpu`); [`Reconstructor`] picks one.
//! The CPU kernels' support is `planes.rs` (bordered planes), `simd.rs` (vectors and ISA
//! dispatch) and `discontinuity.rs` (D); `history.rs` is the temporal history both
//! pipelines share. Whether a frame accumulates is not decided here: it comes with the
//! frame (`FrameInputs::accumulated_frames`).

use glam::Vec3;
use gridlight_actors::protocol::FrameNo;
use gridlight_actors::state::StateVersion;
use rayon::prelude::*;

pub mod cpu;
pub mod discontinuity;
pub mod gpu;
pub mod history;
pub mod params;
pub mod pass;
pub mod planes;
pub mod simd;
pub mod synthetic;
pub mod tonemap;

pub use cpu::CpuReconstructor;
pub use gpu::GpuReconstructor;
pub use params::ReconstructParams;

use crate::gbuffer::{GBuffer, GBufferError};
use crate::gpu::{Backend, GpuContext, GpuError};

/// Why a frame could not be reconstructed.
#[derive(Debug, thiserror::Error)]
pub enum ReconstructError {
    #[error("reconstruction parameter `{name}`: {why}")]
    BadParam { name: &'static str, why: String },
    #[error("{what} has {got} entries, expected one per pixel ({expected})")]
    InputLength { what: &'static str, expected: usize, got: usize },
    #[error("radiance of pixel {pixel} is not finite and non-negative: {value}")]
    BadRadiance { pixel: usize, value: Vec3 },
    #[error(transparent)]
    GBuffer(#[from] GBufferError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

/// Everything one frame's reconstruction reads.
#[derive(Clone, Copy, Debug)]
pub struct FrameInputs<'a> {
    pub frame: FrameNo,
    /// Version of the scene state the frame was rendered with (the G-buffer it goes with).
    pub state_version: StateVersion,
    /// Shown frames of this scene state, this one included: 1 restarts the running
    /// average (filters on), more accumulate ([`Mode::of`]). Decided once, by the frame
    /// assembler (`gridlight_actors::accumulation`), never by the reconstruction.
    pub accumulated_frames: u32,
    /// Demodulated radiance of this frame's results, one per pixel (ignored where `mask` is false).
    pub radiance: &'a [Vec3],
    /// Whether this frame has a result for the pixel.
    pub mask: &'a [bool],
    pub gbuffer: &'a GBuffer,
}

impl FrameInputs<'_> {
    /// Checks sizes and that every calculated radiance is finite and non-negative.
    pub fn validate(&self, width: u32, height: u32) -> Result<(), ReconstructError> {
        self.gbuffer.validate(width, height)?;
        let n = width as usize * height as usize;
        for (what, len) in [("radiance", self.radiance.len()), ("mask", self.mask.len())] {
            if len != n {
                return Err(ReconstructError::InputLength { what, expected: n, got: len });
            }
        }
        // In parallel over blocks of pixels; the first bad pixel of the first block with one.
        const BLOCK: usize = 1 << 14;
        let bad = self
            .radiance
            .par_chunks(BLOCK)
            .zip(self.mask.par_chunks(BLOCK))
            .enumerate()
            .find_map_first(|(b, (radiance, mask))| {
                let bad = |(v, &m): (&Vec3, &bool)| m && !(v.is_finite() && v.min_element() >= 0.0);
                radiance.iter().zip(mask).position(bad).map(|p| b * BLOCK + p)
            });
        match bad {
            Some(pixel) => {
                Err(ReconstructError::BadRadiance { pixel, value: self.radiance[pixel] })
            }
            None => Ok(()),
        }
    }
}

/// How a frame was reconstructed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Mode {
    /// First frame of a scene state: fill, temporal and Gaussian filters.
    Interacting,
    /// The state is unchanged since `frames` frames: their average, filled, no filters.
    Accumulating { frames: u32 },
}

impl Mode {
    /// The mode of a frame that is the `accumulated_frames`-th shown with its scene state.
    pub fn of(accumulated_frames: u32) -> Self {
        match accumulated_frames {
            0 | 1 => Mode::Interacting,
            frames => Mode::Accumulating { frames },
        }
    }
}

/// One reconstructed frame.
#[derive(Clone, Debug)]
pub struct Reconstructed {
    pub frame: FrameNo,
    pub mode: Mode,
    /// Reconstructed demodulated radiance.
    pub radiance: Vec<Vec3>,
    /// Final linear colour: albedo · radiance + emission (for EXR).
    pub colour: Vec<Vec3>,
    /// Tonemapped sRGB, 8-bit RGBA (for display and PNG).
    pub display: Vec<[u8; 4]>,
}

/// A reconstructor a frame sink can call once per shown frame, on the CPU or the GPU.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)] // one per sink, never moved in a hot loop
pub enum Reconstructor {
    Cpu(CpuReconstructor),
    Gpu(Box<GpuReconstructor>),
}

impl Reconstructor {
    /// Makes a reconstructor for `width`×`height` frames on the requested backend; `Auto`
    /// falls back to the CPU (with a log line saying why) when no adapter is usable.
    pub fn new(
        width: u32,
        height: u32,
        params: ReconstructParams,
        backend: Backend,
    ) -> Result<Self, ReconstructError> {
        let gpu = |ctx: Result<GpuContext, GpuError>| -> Result<Self, ReconstructError> {
            Ok(Self::Gpu(Box::new(GpuReconstructor::new(ctx?.into(), width, height, params)?)))
        };
        match backend {
            Backend::Cpu => Ok(Self::Cpu(CpuReconstructor::new(width, height, params)?)),
            Backend::Gpu => gpu(GpuContext::new()),
            Backend::Auto => gpu(GpuContext::new_hardware()).or_else(|err| {
                tracing::info!(cause = %err, "GPU reconstruction unavailable, using the CPU");
                Ok(Self::Cpu(CpuReconstructor::new(width, height, params)?))
            }),
        }
    }

    /// Reconstructs one frame.
    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        match self {
            Self::Cpu(r) => r.reconstruct(inputs),
            Self::Gpu(r) => r.reconstruct(inputs),
        }
    }

    /// "cpu" or the GPU adapter's name.
    pub fn describe(&self) -> String {
        match self {
            Self::Cpu(_) => "cpu".to_string(),
            Self::Gpu(r) => r.adapter_name().to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_the_first_bad_calculated_pixel() {
        let (w, h) = (300, 200);
        let n = (w * h) as usize;
        let g = GBuffer::empty(w, h, 1.0);
        let mut mask = vec![true; n];
        mask[5] = false;
        let check = |radiance: &[Vec3]| {
            let inputs = FrameInputs {
                frame: 1,
                state_version: 1,
                accumulated_frames: 1,
                radiance,
                mask: &mask,
                gbuffer: &g,
            };
            inputs.validate(w, h)
        };
        // A bad value without a result does not count; the first bad one with a result
        // does, whichever block of the parallel check it lies in.
        let mut radiance = vec![Vec3::ONE; n];
        radiance[5] = Vec3::NAN;
        check(&radiance).expect("pixel 5 has no result");
        for (p, v) in [(40_000, Vec3::NEG_ONE), (n - 1, Vec3::INFINITY), (20_000, Vec3::NAN)] {
            radiance[p] = v;
        }
        match check(&radiance) {
            Err(ReconstructError::BadRadiance { pixel, .. }) => assert_eq!(pixel, 20_000),
            other => panic!("{other:?}"),
        }
    }
}
