//! GGX (Trowbridge–Reitz) microfacet distribution, Fresnel terms and frames.
//!
//! All directions here are in a local shading frame with the normal on +z.
//! Sampling uses the distribution of visible normals (Heitz 2018, "Sampling the
//! GGX Distribution of Visible Normals"), whose weights stay bounded by one.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

/// An orthonormal frame around a normal (Duff et al. 2017, branchless).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3,
    pub t: Vec3,
    pub n: Vec3,
}

impl Frame {
    #[inline]
    pub fn new(n: Vec3) -> Self {
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Isotropic GGX with roughness `alpha` (perceptual roughness squared).
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    pub alpha: f32,
}

impl Ggx {
    /// Below this alpha a surface is treated as perfectly smooth (a delta lobe).
    pub const SMOOTH: f32 = 1e-3;

    /// Normal distribution D(m).
    #[inline]
    pub fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let cos2 = m.z * m.z;
        let k = cos2 * (a2 - 1.0) + 1.0;
        a2 / (PI * k * k)
    }

    /// Smith Λ(w).
    #[inline]
    fn lambda(&self, w: Vec3) -> f32 {
        let cos2 = w.z * w.z;
        if cos2 >= 1.0 {
            return 0.0;
        }
        let tan2 = (1.0 - cos2).max(0.0) / cos2;
        ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0) * 0.5
    }

    /// Smith masking G1(w).
    #[inline]
    pub fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking-shadowing G2(wo, wi).
    #[inline]
    pub fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// Density of visible normal `m` seen from `w`: G1(w) max(0, w·m) D(m) / |w.z|.
    #[inline]
    pub fn pdf_visible(&self, w: Vec3, m: Vec3) -> f32 {
        let cos = w.z.abs();
        if cos == 0.0 {
            return 0.0;
        }
        self.g1(w) * w.dot(m).abs() * self.d(m) / cos
    }

    /// Samples a visible normal for direction `w` (flipped to the upper hemisphere).
    #[inline]
    pub fn sample_visible(&self, w: Vec3, u: Vec2) -> Vec3 {
        let w = if w.z < 0.0 { -w } else { w };
        // Stretch to the hemisphere configuration.
        let vh = Vec3::new(self.alpha * w.x, self.alpha * w.y, w.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 =
            if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) * (1.0 / len2.sqrt()) } else { Vec3::X };
        let t2 = vh.cross(t1);
        let r = u.x.sqrt();
        let phi = 2.0 * PI * u.y;
        let (sin, cos) = super::trig::sin_cos(phi);
        let p1 = r * cos;
        let mut p2 = r * sin;
        let s = 0.5 * (1.0 + vh.z);
        p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
        let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        Vec3::new(self.alpha * nh.x, self.alpha * nh.y, nh.z.max(1e-6)).normalize()
    }
}

/// Unpolarised Fresnel reflectance of a dielectric interface; `cos_i` is signed
/// (negative: arriving from inside), `eta` is inside over outside.
#[inline]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let (cos_i, eta) = if cos_i < 0.0 { (-cos_i, 1.0 / eta) } else { (cos_i, eta) };
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_parl * r_parl + r_perp * r_perp)
}

/// Schlick's approximation with a coloured normal-incidence reflectance.
#[inline]
pub fn fresnel_schlick(f0: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

/// Mirror reflection of `w` about `n`.
#[inline]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
}

/// Refraction of `w` through the interface with normal `n` (on `w`'s side or
/// not) and relative index `eta` (inside over outside); returns the refracted
/// direction and the index ratio it crossed, or `None` on total internal reflection.
#[inline]
pub fn refract(w: Vec3, n: Vec3, eta: f32) -> Option<(Vec3, f32)> {
    let mut cos_i = n.dot(w);
    let (mut n, mut eta) = (n, eta);
    if cos_i < 0.0 {
        eta = 1.0 / eta;
        cos_i = -cos_i;
        n = -n;
    }
    let sin2_i = (1.0 - cos_i * cos_i).max(0.0);
    let sin2_t = sin2_i / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((-w / eta + (cos_i / eta - cos_t) * n, eta))
}

/// A direction through a rough dielectric interface (the `Dielectric` kind and the glass
/// lobe of `Pbr`): a GGX visible normal from `u2`, then reflection or refraction by exact
/// Fresnel against `u0`; `None` when the direction ends on the wrong side.
#[inline(always)]
pub fn sample_rough_dielectric(ggx: Ggx, eta: f32, wo: Vec3, u0: f32, u2: Vec2) -> Option<Vec3> {
    let wm = ggx.sample_visible(wo, u2);
    let fr = fresnel_dielectric(wo.dot(wm), eta);
    if u0 < fr {
        let wi = reflect(wo, wm);
        if wi.z * wo.z <= 0.0 {
            return None;
        }
        Some(wi)
    } else {
        let (wi, _) = refract(wo, wm, eta)?;
        if wi.z * wo.z >= 0.0 {
            return None;
        }
        Some(wi)
    }
}

/// Cosine-weighted direction on the upper hemisphere (concentric disc mapping).
#[inline]
pub fn cosine_hemisphere(u: Vec2) -> Vec3 {
    let a = 2.0 * u - Vec2::ONE;
    let (r, phi) = if a.x == 0.0 && a.y == 0.0 {
        return Vec3::Z;
    } else if a.x.abs() > a.y.abs() {
        (a.x, PI / 4.0 * (a.y / a.x))
    } else {
        (a.y, PI / 2.0 - PI / 4.0 * (a.x / a.y))
    };
    let (s, c) = super::trig::sin_cos(phi);
    let (x, y) = (r * c, r * s);
    Vec3::new(x, y, (1.0 - x * x - y * y).max(0.0).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3::Z, Vec3::NEG_Z, Vec3::new(0.3, -0.5, 0.8).normalize(), Vec3::X] {
            let f = Frame::new(n);
            assert!(f.s.dot(f.t).abs() < 1e-5 && f.s.dot(f.n).abs() < 1e-5);
            assert!((f.s.length() - 1.0).abs() < 1e-5 && (f.t.length() - 1.0).abs() < 1e-5);
            let v = Vec3::new(0.2, 0.4, -0.7);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
        }
    }

    #[test]
    fn ggx_distribution_projects_to_one() {
        // ∫ D(m) cos θm dm = 1 over the hemisphere.
        for alpha in [0.1f32, 0.5, 1.0] {
            let g = Ggx { alpha };
            let n = 400;
            let mut sum = 0.0f64;
            for i in 0..n {
                let theta = (i as f32 + 0.5) / n as f32 * PI / 2.0;
                let m = Vec3::new(theta.sin(), 0.0, theta.cos());
                sum += (g.d(m) * m.z * theta.sin()) as f64 * (PI / 2.0 / n as f32) as f64;
            }
            sum *= 2.0 * PI as f64;
            assert!((sum - 1.0).abs() < 0.02, "alpha {alpha}: {sum}");
        }
    }

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-3);
        assert_eq!(fresnel_dielectric(-0.1, 1.5), 1.0);
        assert!((fresnel_dielectric(0.0001, 1.5) - 1.0).abs() < 0.01);
        let (t, _) = refract(Vec3::Z, Vec3::Z, 1.5).unwrap();
        assert!((t + Vec3::Z).length() < 1e-6);
    }
}
