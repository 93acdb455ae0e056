//! Spatio-temporal reconstruction of partial, noisy frames (paper §4.3.1).
//!
//! Per shown frame, on demodulated radiance (reflected radiance divided by the G-buffer's
//! albedo; docs/design.md), guided by the frame's [`GBuffer`], the five passes of [`pass`] run
//! in order: accumulate, fill, and while interacting (the first frame of a scene state)
//! temporal and the edge-aware Gaussian, then remodulate. Each pass keeps its CPU kernel,
//! WGSL and GPU binding together in `pass/`; the pipelines that run them are
//! [`CpuReconstructor`] (the multithreaded reference, `cpu.rs`) and [`GpuReconstructor`]
//! (`gpu.rs`, on the device plumbing of `crate::gpu`); [`Reconstructor`] picks one. The
//! GPU pipeline writes each frame's outputs to a target of its own (`display_target.rs`)
//! and can leave them there for a window on its device ([`DeviceImage`]).
//! The CPU kernels' support is `planes.rs` (bordered planes), `rows.rs` (row kernels run
//! in parallel bands, in the renderer's instruction-set builds, on its lane types
//! `crate::render::lanes`) and `discontinuity.rs` (D); `history.rs` is the temporal history both
//! pipelines share. Whether a frame accumulates is not decided here: it comes with the
//! frame (`FrameInputs::accumulated_frames`).

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::protocol::FrameNo;
use gridlight_actors::state::{SceneState, StateVersion};
use rayon::prelude::*;

pub mod cpu;
pub mod device_image;
pub mod discontinuity;
pub mod display_target;
pub mod gpu;
pub mod history;
pub mod params;
pub mod pass;
pub mod planes;
pub mod rows;
pub mod svgf;
pub mod synthetic;
pub mod tonemap;

pub use cpu::CpuReconstructor;
pub use device_image::DeviceImage;
pub use gpu::GpuReconstructor;
pub use params::ReconstructParams;
pub use svgf::{Method, SvgfReconstructor};

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
    /// The frame's scene state, when the caller knows it: SVGF reprojects its history
    /// through the camera and object motion between states (without it, nothing moved).
    pub scene: Option<&'a SceneState>,
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

impl Reconstructed {
    /// A frame with no planes yet, for `reconstruct_into` to fill.
    pub fn empty(frame: FrameNo) -> Self {
        Self {
            frame,
            mode: Mode::Interacting,
            radiance: Vec::new(),
            colour: Vec::new(),
            display: Vec::new(),
        }
    }
}

/// A reconstructor a frame sink can call once per shown frame, on the CPU or the GPU.
#[derive(Debug)]
#[allow(clippy::large_enum_variant)] // one per sink, never moved in a hot loop
pub enum Reconstructor {
    Cpu(CpuReconstructor),
    Gpu(Box<GpuReconstructor>),
    /// SVGF (`params.method`) on the CPU; on the GPU it is a [`GpuReconstructor`]'s.
    Svgf(Box<SvgfReconstructor>),
}

/// A reconstructed frame as [`Reconstructor::reconstruct_for_display`] gives it.
#[derive(Clone, Debug)]
pub enum ForDisplay {
    /// Read back (or made on the CPU).
    Host(Reconstructed),
    /// Left on the GPU reconstructor's device.
    Device(DeviceImage),
}

impl Reconstructor {
    /// Makes a reconstructor for `width`×`height` frames on the requested backend, on
    /// `device` when one is given (the window's) and on a device of its own otherwise;
    /// `Auto` takes the CPU (with a log line saying why) unless a hardware adapter is
    /// usable ([`GpuContext::new_hardware`]).
    pub fn new(
        width: u32,
        height: u32,
        params: ReconstructParams,
        backend: Backend,
        device: Option<Arc<GpuContext>>,
    ) -> Result<Self, ReconstructError> {
        let gpu = |ctx: Result<Arc<GpuContext>, GpuError>| -> Result<Self, ReconstructError> {
            Ok(Self::Gpu(Box::new(GpuReconstructor::new(ctx?, width, height, params)?)))
        };
        let hardware = |ctx: Arc<GpuContext>| {
            if ctx.is_software() {
                Err(ctx.software())
            } else {
                Ok(ctx)
            }
        };
        let cpu = || -> Result<Self, ReconstructError> {
            Ok(match params.method {
                Method::Paper => Self::Cpu(CpuReconstructor::new(width, height, params)?),
                Method::Svgf => {
                    Self::Svgf(Box::new(SvgfReconstructor::new(width, height, params)?))
                }
            })
        };
        match (backend, device) {
            (Backend::Cpu, _) => cpu(),
            (Backend::Gpu, Some(ctx)) => gpu(Ok(ctx)),
            (Backend::Gpu, None) => gpu(GpuContext::new().map(Arc::new)),
            (Backend::Auto, device) => {
                let ctx = match device {
                    Some(ctx) => hardware(ctx),
                    None => GpuContext::new_hardware().map(Arc::new),
                };
                gpu(ctx).or_else(|err| {
                    tracing::info!(cause = %err, "GPU reconstruction unavailable, using the CPU");
                    cpu()
                })
            }
        }
    }

    /// Reconstructs one frame.
    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        match self {
            Self::Cpu(r) => r.reconstruct(inputs),
            Self::Gpu(r) => r.reconstruct(inputs),
            Self::Svgf(r) => r.reconstruct(inputs),
        }
    }

    /// [`Self::reconstruct`] into `out`, reusing the buffers it still has (a GPU
    /// reconstructor's read-back replaces them).
    pub fn reconstruct_into(
        &mut self,
        inputs: &FrameInputs,
        out: &mut Reconstructed,
    ) -> Result<(), ReconstructError> {
        match self {
            Self::Cpu(r) => r.reconstruct_into(inputs, out),
            Self::Gpu(r) => r.reconstruct(inputs).map(|frame| *out = frame),
            Self::Svgf(r) => r.reconstruct_into(inputs, out),
        }
    }

    /// Reconstructs one frame for a display on `device`: a GPU reconstructor on that
    /// device leaves it there; otherwise it comes to the CPU.
    pub fn reconstruct_for_display(
        &mut self,
        inputs: &FrameInputs,
        device: &wgpu::Device,
    ) -> Result<ForDisplay, ReconstructError> {
        match self {
            Self::Gpu(r) if &r.context().device == device => {
                r.reconstruct_on_device(inputs).map(ForDisplay::Device)
            }
            other => other.reconstruct(inputs).map(ForDisplay::Host),
        }
    }

    /// Frames read back from the GPU so far (none on the CPU).
    pub fn read_backs(&self) -> u64 {
        match self {
            Self::Cpu(_) | Self::Svgf(_) => 0,
            Self::Gpu(r) => r.read_backs(),
        }
    }

    /// "cpu" or the GPU adapter's name.
    pub fn describe(&self) -> String {
        match self {
            Self::Cpu(_) => "cpu".to_string(),
            Self::Svgf(_) => "cpu (svgf)".to_string(),
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
                scene: None,
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
