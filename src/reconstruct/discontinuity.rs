//! The discontinuity function D of section 4.3.1 and the filter weights built on it.
//!
//! The paper prints `D = max(0, n_i·n_j − α) × max(0, |z_i − z_j|² − β²)`, which would give
//! zero weight to pixels at the same position and positive weight to distant ones — the
//! opposite of its stated purpose (docs/design.md). We implement the intended meaning: positive
//! only when the orientations agree (`n_i·n_j > α`) and the positions are close
//! (`|z_i − z_j| < β`), falling smoothly to zero at each threshold:
//!
//! `D = max(0, (n_i·n_j − α)/(1 − α)) × max(0, 1 − |z_i − z_j|²/β²)`
//!
//! evaluated as `max(0, (n_i·n_j − α)·(1/(1 − α))) × max(0, 1 − |z_i − z_j|²·(1/β²))`
//!
//! so that D = 1 for a pixel against itself. Pixels whose camera ray hit no surface have a
//! zero normal and therefore D = 0 against everything. The WGSL passes
//! (`shaders/reconstruct/common.wgsl`) evaluate exactly these expressions in the same order.

use std::ops::{Add, Mul, Sub};

use glam::Vec3;

use crate::render::isa::Isa;
use crate::render::lanes::F32s;

/// The arithmetic D is made of: `f32`, or [`F32s`] (several pixels at once, lane by lane,
/// with the same roundings).
pub trait Real: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    fn splat(v: f32) -> Self;

    /// max(0, x); NaN gives 0.
    fn positive_part(self) -> Self;
}

impl Real for f32 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }

    #[inline(always)]
    fn positive_part(self) -> Self {
        if self > 0.0 {
            self
        } else {
            0.0
        }
    }
}

impl<I: Isa> Real for F32s<I> {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        F32s::splat(v)
    }

    #[inline(always)]
    fn positive_part(self) -> Self {
        F32s::positive_part(self)
    }
}

/// The thresholds of D in the form every implementation evaluates it (reciprocals
/// precomputed once, so the inner loops multiply instead of dividing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    pub alpha: f32,
    /// 1 / (1 − α).
    pub inv_one_minus_alpha: f32,
    /// 1 / β², β in scene units (already multiplied by the scene scale).
    pub inv_beta2: f32,
}

impl Thresholds {
    pub fn new(alpha: f32, beta: f32) -> Self {
        Self { alpha, inv_one_minus_alpha: 1.0 / (1.0 - alpha), inv_beta2: 1.0 / (beta * beta) }
    }

    /// The orientation factor from a dot product of normals.
    #[inline(always)]
    pub fn orientation<R: Real>(&self, dot: R) -> R {
        ((dot - R::splat(self.alpha)) * R::splat(self.inv_one_minus_alpha)).positive_part()
    }

    /// The position factor from a squared distance.
    #[inline(always)]
    pub fn position<R: Real>(&self, dist2: R) -> R {
        (R::splat(1.0) - dist2 * R::splat(self.inv_beta2)).positive_part()
    }

    /// D between pixels (or frames of one pixel) with normals `n_i`, `n_j` and positions
    /// `z_i`, `z_j`.
    #[inline(always)]
    pub fn d(&self, n_i: Vec3, n_j: Vec3, z_i: Vec3, z_j: Vec3) -> f32 {
        self.d3(n_i.to_array(), n_j.to_array(), z_i.to_array(), z_j.to_array())
    }

    /// [`Self::d`] on components (dot products summed x, y, z, as `Vec3::dot`).
    #[inline(always)]
    pub fn d3<R: Real>(&self, n_i: [R; 3], n_j: [R; 3], z_i: [R; 3], z_j: [R; 3]) -> R {
        let dot = n_i[0] * n_j[0] + n_i[1] * n_j[1] + n_i[2] * n_j[2];
        let dz = [z_i[0] - z_j[0], z_i[1] - z_j[1], z_i[2] - z_j[2]];
        self.orientation(dot) * self.position(dz[0] * dz[0] + dz[1] * dz[1] + dz[2] * dz[2])
    }
}

/// D with thresholds α and β (scene units); see [`Thresholds::d`].
#[inline]
pub fn discontinuity(n_i: Vec3, n_j: Vec3, z_i: Vec3, z_j: Vec3, alpha: f32, beta: f32) -> f32 {
    Thresholds::new(alpha, beta).d(n_i, n_j, z_i, z_j)
}

/// Unnormalised Gaussian weight of an offset (the 1/(2πσ²) of the paper cancels out in
/// the normalised sum).
#[inline]
pub fn gaussian(dx: i32, dy: i32, sigma: f32) -> f32 {
    let r2 = (dx * dx + dy * dy) as f32;
    (-r2 / (2.0 * sigma * sigma)).exp()
}

/// Whether a normal belongs to a surface (escaping rays have a zero normal).
#[inline]
pub fn is_surface(normal: Vec3) -> bool {
    normal.length_squared() > 0.25
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: f32 = 0.75;

    #[test]
    fn same_pixel_has_full_weight() {
        let d = discontinuity(Vec3::Y, Vec3::Y, Vec3::ONE, Vec3::ONE, A, 1.0);
        assert!((d - 1.0).abs() < 1e-6);
    }

    #[test]
    fn far_positions_and_turned_normals_have_zero_weight() {
        assert_eq!(
            discontinuity(Vec3::Y, Vec3::Y, Vec3::ZERO, Vec3::new(0.0, 0.0, 1.5), A, 1.0),
            0.0
        );
        assert_eq!(discontinuity(Vec3::Y, Vec3::X, Vec3::ZERO, Vec3::ZERO, A, 1.0), 0.0);
        assert_eq!(discontinuity(Vec3::ZERO, Vec3::Y, Vec3::ZERO, Vec3::ZERO, A, 1.0), 0.0);
    }

    #[test]
    fn weight_falls_monotonically_with_distance_and_angle() {
        let mut last = f32::INFINITY;
        for k in 0..10 {
            let d = discontinuity(
                Vec3::Y,
                Vec3::Y,
                Vec3::ZERO,
                Vec3::new(k as f32 * 0.1, 0.0, 0.0),
                A,
                1.0,
            );
            assert!(d < last);
            last = d;
        }
        let mut last = f32::INFINITY;
        for k in 0..8 {
            let angle = k as f32 * 0.05;
            let n = Vec3::new(angle.sin(), angle.cos(), 0.0);
            let d = discontinuity(Vec3::Y, n, Vec3::ZERO, Vec3::ZERO, A, 1.0);
            assert!(d < last, "{k}");
            last = d;
        }
    }

    #[test]
    fn gaussian_is_one_at_centre_and_symmetric() {
        assert_eq!(gaussian(0, 0, 1.0), 1.0);
        assert_eq!(gaussian(2, 1, 1.0), gaussian(-1, 2, 1.0));
        assert!((gaussian(1, 0, 1.0) - (-0.5f32).exp()).abs() < 1e-7);
    }
}
