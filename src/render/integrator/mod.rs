//! The path loop: unidirectional path tracing with next-event estimation,
//! multiple importance sampling (power heuristic) and Russian roulette, plus the
//! G-buffer probe (`primary_hit`) and picking.
//!
//! Depth counts path segments: `max_depth` 5 is the camera ray plus four bounces
//! (Mitsuba's convention), so light is sampled at vertices 1..max_depth-1 and
//! emitters are seen up to segment `max_depth`.
//!
//! Files: `path.rs` the steps of one path (trace, arrive, scatter) shared by every
//! kernel, `nee.rs` next-event estimation and its shadow ray, `builds.rs` the kernel's
//! builds per instruction set and the dispatch to them, `gbuffer.rs` the G-buffer probe,
//! directly seen emission and picking, `reference.rs` (tests only) the one-path kernel
//! the stream kernel is checked against.

use super::isa::IsaLevel;
use super::{PixelSample, RenderScene};

mod builds;
mod gbuffer;
mod nee;
mod path;
#[cfg(test)]
mod reference;

pub use builds::{primary_block_in, render_pixels_in, run_in_build, BuildTask};
#[cfg(target_arch = "x86_64")]
pub(crate) use builds::{v3, v4};
pub use gbuffer::{area_emission, escaped_emission, pick, primary_hit, PRIMARY_TILE};
pub(super) use nee::ShadowRay;
pub use path::offset;
pub(super) use path::{arrive, interpolate_uv, scatter, trace, PathState, Surface, EMPTY_SAMPLE};

/// Paths survive Russian roulette unconditionally up to this many segments.
pub(super) const RR_START_DEPTH: u32 = 3;
/// Smallest albedo divided out by demodulation.
const MIN_ALBEDO: f32 = 1e-3;

/// Work counters of one `render_pixels_counted` call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Camera paths traced.
    pub samples: u64,
    /// Rays cast: closest-hit and shadow rays.
    pub rays: u64,
    /// Times the stream kernel's sixteen-lane vector stage ran, path vertices it shaded,
    /// and vertices shaded by the one-path step in a lane (zero in the one-path test
    /// reference).
    pub vector_stages: u64,
    pub vector_vertices: u64,
    pub lane_vertices: u64,
}

impl RenderStats {
    /// Share of the vector stage's lanes that held a vertex to shade, if it ran.
    pub fn vector_lane_occupancy(&self) -> Option<f64> {
        (self.vector_stages > 0).then(|| {
            self.vector_vertices as f64 / (self.vector_stages * super::lanes::WIDTH as u64) as f64
        })
    }

    /// Share of the stream kernel's path vertices that the vector stage shaded, if that
    /// kernel ran.
    pub fn vector_vertex_share(&self) -> Option<f64> {
        let all = self.vector_vertices + self.lane_vertices;
        (all > 0).then(|| self.vector_vertices as f64 / all as f64)
    }
}

/// How paths gather light: both reference strategies must agree on the mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Strategy {
    /// Next-event estimation and BSDF sampling combined with MIS (the default).
    #[default]
    NeeMis,
    /// BSDF sampling only; light is found by hitting emitters (for validation).
    BsdfOnly,
}

/// Renders the given pixels (index = y*width + x, y = 0 is the top row),
/// state.render.spp samples each, max depth state.render.max_depth;
/// single-threaded; deterministic for (state.seed, frame, pixel, sample index).
/// `out` is cleared and filled in pixel order.
pub fn render_pixels(scene: &RenderScene, frame: u64, pixels: &[u32], out: &mut Vec<PixelSample>) {
    render_pixels_counted(scene, frame, pixels, out, Strategy::NeeMis);
}

/// [`render_pixels`] with a choice of light-gathering strategy, also returning
/// how much work it did (for benchmarks and validation), in the best build this CPU
/// runs ([`IsaLevel::best`]).
pub fn render_pixels_counted(
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    render_pixels_in(IsaLevel::best(), scene, frame, pixels, out, strategy)
}
