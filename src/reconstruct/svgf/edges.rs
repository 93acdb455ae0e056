//! The edge-stopping weights of the variance estimate and the à-trous filter, on lanes.
//!
//! Geometry: the normals' agreement, (max(0, n_i·n_j))^k, times the plane test: how far
//! the neighbour lies off the pixel's tangent plane relative to their distance, d/|Δ| with
//! d = n_i·Δ. Points of one flat surface have d = 0 whatever their depth and angle to the
//! camera; a surface behind or in front has d ≈ |Δ|. The weight is (a/(a + d²))² with
//! a = σ²|Δ|², a rational fall-off of (d/σ|Δ|)² that needs no exponential (the WGSL can
//! evaluate the same expressions). Luminance: (1 + |l_i − l_j|/(σ_l·σ_i))⁻⁴, which falls
//! like exp(−x) near 0, with σ_i the standard deviation of the pixel's estimate.
//!
//! Taps on the border (normal 0, position ∞) get weight exactly 0: the normal factor is 0
//! there and the product is selected away rather than multiplied (∞ would give NaN).

use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s};

/// The weights' constants for one frame.
#[derive(Clone, Copy, Debug)]
pub struct Edges {
    /// log2 of the normal exponent.
    pub normal_squarings: u32,
    /// σ² of the plane test.
    pub plane2: f32,
    /// Added to a so that coincident points weigh 1 (scene units squared).
    pub eps2: f32,
}

impl Edges {
    pub fn new(normal_power: u32, sigma_plane: f32, scene_scale: f32) -> Self {
        let eps = 1e-6 * scene_scale;
        Self {
            normal_squarings: normal_power.trailing_zeros(),
            plane2: sigma_plane * sigma_plane,
            eps2: eps * eps,
        }
    }

    /// The geometric weight between pixels i and j (0 where j has no surface).
    #[inline(always)]
    pub fn geometry<I: Isa>(
        &self,
        n_i: Vec3s<I>,
        p_i: Vec3s<I>,
        n_j: Vec3s<I>,
        p_j: Vec3s<I>,
    ) -> F32s<I> {
        let mut w_n = n_i.dot(n_j).positive_part();
        for _ in 0..self.normal_squarings {
            w_n = w_n * w_n;
        }
        let delta = p_j - p_i;
        let d = n_i.dot(delta);
        let a = delta.dot(delta) * F32s::splat(self.plane2) + F32s::splat(self.eps2);
        let w_p = a / (a + d * d);
        let w = w_n * w_p * w_p;
        F32s::select(w_n.gt(F32s::splat(0.0)), w, F32s::splat(0.0))
    }

    /// The luminance weight of a difference `dl` scaled by 1/(σ_l·σ_i) (`inv`).
    #[inline(always)]
    pub fn luminance<I: Isa>(dl: F32s<I>, inv: F32s<I>) -> F32s<I> {
        let t = F32s::splat(1.0) + dl.abs() * inv;
        let t2 = t * t;
        F32s::splat(1.0) / (t2 * t2)
    }
}

/// Rec. 709 luminance of lanes (as `reproject::luminance`).
#[inline(always)]
pub fn luminance<I: Isa>(c: Vec3s<I>) -> F32s<I> {
    c.x * F32s::splat(0.2126) + c.y * F32s::splat(0.7152) + c.z * F32s::splat(0.0722)
}
