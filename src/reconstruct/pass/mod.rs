//! The reconstruction passes (paper §4.3.1), one module per pass: its CPU kernel and its GPU
//! binding (the pass's bindings, in WGSL order); its WGSL is `shaders/reconstruct/<pass>.wgsl`,
//! compiled in (every shader lives under the top-level `shaders/`, laid out like this code).
//!
//! Per shown frame, in this order (the only numbering of the steps; the WGSL and the
//! kernels name their pass instead):
//! 1. [`accumulate`] this frame's samples into the running average (restarted when the
//!    scene state changes, so an unchanged state refines progressively);
//! 2. [`fill`] pixels without samples from calculated neighbours, weighted by D (k = 1);
//! 3. while interacting, [`temporal`]: blend with the previous frames' filled radiance;
//! 4. while interacting, [`gaussian`]: the edge-aware Gaussian;
//! 5. [`remodulate`] the albedo, add directly seen emission, tonemap for display.
//!
//! Every CPU kernel computes what its WGSL twin computes, each tap with the same f32
//! expressions in the same order (D, the weights, the products and the final division), so
//! that the parity test can hold the two to a tight tolerance; the fill adds its taps
//! [`WIDTH`](crate::render::lanes::WIDTH) at a time, which changes its sums by rounding
//! only. The kernels work on planes with a border (`super::planes`): taps need no bounds
//! checks and one vector load fetches WIDTH neighbours. Rows are processed in parallel
//! bands (`super::rows`).
//!
//! What every pass shares lives here: [`PassConsts`] (derived once per frame) and its GPU
//! mirror [`Uniforms`] (the `Params` block of `common.wgsl`, prefixed to every pass).

use bytemuck::{Pod, Zeroable};

use super::discontinuity::Thresholds;
use super::params::{ReconstructParams, MAX_GAUSS_WIDTH, MAX_HISTORY};

pub mod accumulate;
pub mod fill;
pub mod gaussian;
pub mod remodulate;
pub mod temporal;

pub use accumulate::accumulate;
pub use fill::{fill, FillInputs};
pub use gaussian::gaussian;
pub use remodulate::{remodulate, Outputs};
pub use temporal::{temporal, PastFrame};

/// Shared WGSL: the `Params` uniform and D. WGSL has no `#include`: every pass is prefixed
/// with it ([`with_common`]).
pub const COMMON_WGSL: &str = include_str!("../../../shaders/reconstruct/common.wgsl");

/// Every pass's WGSL by file name, in pipeline order (for the naga validation test).
pub const WGSL: [(&str, &str); 5] = [
    ("accumulate.wgsl", accumulate::WGSL),
    ("fill.wgsl", fill::WGSL),
    ("temporal.wgsl", temporal::WGSL),
    ("gaussian.wgsl", gaussian::WGSL),
    ("remodulate.wgsl", remodulate::WGSL),
];

/// A pass's complete module source: the common block, then the pass.
pub fn with_common(pass: &str) -> String {
    format!("{COMMON_WGSL}\n{pass}")
}

/// Entries of the 1-D Gaussian table (radius 0..=MAX_GAUSS_WIDTH/2).
pub const GAUSS_TABLE: usize = (MAX_GAUSS_WIDTH as usize / 2) + 1;

/// The numbers every pass needs, derived once per frame from the parameters and the scene
/// scale (the GPU uniform is built from this very value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassConsts {
    pub width: u32,
    pub height: u32,
    /// α and β (β in scene units) of the discontinuity function.
    pub d: Thresholds,
    pub radius: i32,
    pub gauss_radius: i32,
    /// Exposure in stops.
    pub exposure: f32,
    /// exp(−d²/2σ²) for d = 0, 1, …; the 2-D weight is the product of two entries.
    pub gauss: [f32; GAUSS_TABLE],
}

impl PassConsts {
    pub fn new(width: u32, height: u32, params: &ReconstructParams, scene_scale: f32) -> Self {
        let mut gauss = [0.0; GAUSS_TABLE];
        for (d, g) in gauss.iter_mut().enumerate() {
            let d = d as f32;
            *g = (-(d * d) / (2.0 * params.sigma * params.sigma)).exp();
        }
        Self {
            width,
            height,
            d: Thresholds::new(params.alpha, params.beta * scene_scale),
            radius: params.radius as i32,
            gauss_radius: params.gauss_radius(),
            exposure: params.exposure,
            gauss,
        }
    }
}

/// Mirror of `Params` in `common.wgsl` (std140-compatible: 96 bytes), built from the very
/// [`PassConsts`] the CPU kernels use.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Uniforms {
    pub width: u32,
    pub height: u32,
    pub radius: i32,
    pub gauss_radius: i32,
    pub alpha: f32,
    pub inv_one_minus_alpha: f32,
    pub inv_beta2: f32,
    pub exposure: f32,
    pub reset: u32,
    pub pad: [u32; 3],
    pub history_weight: [f32; 4],
    pub gauss: [f32; 8],
}
const _: () = assert!(std::mem::size_of::<Uniforms>() == 96);

impl Uniforms {
    pub fn new(c: &PassConsts, reset: bool, history_weight: [f32; MAX_HISTORY as usize]) -> Self {
        Self {
            width: c.width,
            height: c.height,
            radius: c.radius,
            gauss_radius: c.gauss_radius,
            alpha: c.d.alpha,
            inv_one_minus_alpha: c.d.inv_one_minus_alpha,
            inv_beta2: c.d.inv_beta2,
            exposure: super::tonemap::exposure_scale(c.exposure),
            reset: reset as u32,
            pad: [0; 3],
            history_weight,
            gauss: c.gauss,
        }
    }
}

/// Helpers of the passes' unit tests: planes and guides from one vector per pixel.
#[cfg(test)]
pub(crate) mod testing {
    use glam::Vec3;

    use super::PassConsts;
    use crate::reconstruct::params::ReconstructParams;
    use crate::reconstruct::planes::{at, split, GuidePlanes, Layout, Planes3};

    pub fn consts(w: u32, h: u32) -> PassConsts {
        PassConsts::new(w, h, &ReconstructParams::default(), 1.0)
    }

    /// A layout for `c` and the guide in it.
    pub fn setup(normal: &[Vec3], position: &[Vec3], c: &PassConsts) -> (Layout, GuidePlanes) {
        let layout = Layout::new(c.width, c.height, c.radius.max(c.gauss_radius) as usize);
        let mut guide = GuidePlanes::new(&layout);
        guide.split(normal, position, &layout);
        (layout, guide)
    }

    pub fn planes(v: &[Vec3], layout: &Layout) -> Planes3 {
        let mut p = layout.zeroed3();
        split(v, layout, 0.0, &mut p);
        p
    }

    pub fn image(p: &Planes3, layout: &Layout) -> Vec<Vec3> {
        let w = layout.width;
        (0..w * layout.height).map(|i| at(p, layout.index(i % w, i / w))).collect()
    }

    pub fn flat(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        (vec![Vec3::Z; n], (0..n).map(|i| Vec3::new(i as f32 * 1e-3, 0.0, 0.0)).collect())
    }
}
