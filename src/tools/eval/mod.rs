//! Evaluation of reconstruction against the paper's findings, and its metrics.
//!
//! - [`loss`]: a complete frame with 25 %/50 % of its jobs dropped, quasi-random sets
//!   against tiles (Figure 3);
//! - [`sequence`]: an interaction sequence, spatio-temporal against spatial-only
//!   (Figure 9), and a static view converging as frames accumulate (Figure 8);
//! - [`paper`]: the paper's section 6 as one report (`eval paper`), on simulated grids;
//! - metrics: FLIP ([`flip`]; HDR-FLIP for linear radiance, [`hdr_flip`]), RMSE and SSIM
//!   ([`metrics`]).
//!
//! Frames come from a [`FrameSource`]: the path tracer for real scenes, or the analytic
//! scene of `reconstruct::synthetic` where no renderer is wanted.

use std::sync::Arc;

use glam::Vec3;
use serde::Serialize;

use crate::gbuffer::GBuffer;
use crate::reconstruct::tonemap::tonemap;

pub mod filter;
pub mod flip;
pub mod hdr_flip;
pub mod loss;
pub mod metrics;
pub mod motion;
pub mod oidn;
pub mod paper;
pub mod pfm;
pub mod render_source;
pub mod sequence;
pub mod source;

pub use render_source::RenderSource;
pub use source::{FrameSource, SyntheticSource};

/// One complete frame: every pixel's demodulated radiance and the frame's G-buffer.
#[derive(Clone, Debug)]
pub struct FrameData {
    pub radiance: Vec<Vec3>,
    pub gbuffer: Arc<GBuffer>,
}

impl FrameData {
    /// Final linear colour of the frame as rendered (no reconstruction).
    pub fn colour(&self) -> Vec<Vec3> {
        remodulate(&self.radiance, &self.gbuffer)
    }
}

/// albedo · radiance + emission.
pub fn remodulate(radiance: &[Vec3], g: &GBuffer) -> Vec<Vec3> {
    radiance.iter().zip(&g.albedo).zip(&g.emission).map(|((l, a), e)| *a * *l + *e).collect()
}

/// The errors of one image against a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Errors {
    /// Mean LDR-FLIP of the tonemapped images (0 = identical, 1 = maximal).
    pub flip: f64,
    /// RMSE of the linear colour.
    pub rmse: f64,
    /// Mean SSIM of the tonemapped luma (1 = identical).
    pub ssim: f64,
}

/// Compares linear colour images: FLIP and SSIM on their tonemapped display values
/// (`exposure` in stops), RMSE on the linear values.
pub fn compare(
    reference: &[Vec3],
    test: &[Vec3],
    width: u32,
    height: u32,
    exposure: f32,
) -> Errors {
    let (w, h) = (width as usize, height as usize);
    let display =
        |img: &[Vec3]| -> Vec<Vec3> { img.iter().map(|c| tonemap(*c, exposure)).collect() };
    let (rd, td) = (display(reference), display(test));
    Errors {
        flip: flip::flip(&rd, &td, w, h, flip::DEFAULT_PPD).mean,
        rmse: metrics::rmse(reference, test),
        ssim: metrics::ssim(&rd, &td, w, h),
    }
}
