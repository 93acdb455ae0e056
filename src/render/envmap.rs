//! Light from infinity: a constant colour or an equirectangular map, with
//! importance sampling by a marginal/conditional CDF over the map's luminance.
//!
//! Mapping: +y is up; texel row 0 is the zenith (θ = 0), column u covers
//! φ = 2π·u measured from +x towards +z. The environment's rotation turns the map
//! about +y. Lookups are nearest-texel so that the sampled pdf is exactly the
//! piecewise-constant density the CDF describes.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{Mat3A, Vec2, Vec3};

use crate::assets::Texture;

/// A 1-D piecewise-constant distribution.
#[derive(Clone, Debug)]
pub(crate) struct Distribution1D {
    /// `cdf[i]` is the mass of bins below `i`; `cdf[n] == 1`.
    pub(crate) cdf: Vec<f32>,
    pub(crate) func: Vec<f32>,
    pub(crate) integral: f32,
}

impl Distribution1D {
    fn new(func: Vec<f32>) -> Self {
        let n = func.len();
        let mut cdf = vec![0.0f32; n + 1];
        let mut acc = 0.0f64;
        for (i, f) in func.iter().enumerate() {
            acc += *f as f64 / n as f64;
            cdf[i + 1] = acc as f32;
        }
        let integral = acc as f32;
        if integral > 0.0 {
            for c in &mut cdf {
                *c /= integral;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n as f32;
            }
        }
        cdf[n] = 1.0;
        Self { cdf, func, integral }
    }

    /// A continuous sample in [0, 1), its density and its bin.
    fn sample(&self, u: f32) -> (f32, f32, usize) {
        let n = self.func.len();
        // Last index whose cdf is <= u.
        let i = self.cdf.partition_point(|&c| c <= u).saturating_sub(1).min(n - 1);
        let width = self.cdf[i + 1] - self.cdf[i];
        let du = if width > 0.0 { (u - self.cdf[i]) / width } else { 0.5 };
        let pdf = if self.integral > 0.0 { self.func[i] / self.integral } else { 1.0 };
        (((i as f32 + du.clamp(0.0, 1.0)) / n as f32).min(1.0 - f32::EPSILON), pdf, i)
    }

    fn pdf(&self, i: usize) -> f32 {
        if self.integral > 0.0 {
            self.func[i] / self.integral
        } else {
            1.0
        }
    }
}

/// The environment of a render scene.
#[derive(Clone, Debug)]
pub enum Environment {
    Constant(Vec3),
    Map(Box<EnvMap>),
}

/// An importance-sampled equirectangular map.
#[derive(Clone, Debug)]
pub struct EnvMap {
    pub(crate) texture: Arc<Texture>,
    pub(crate) scale: Vec3,
    /// World to map space (inverse of the rotation about +y).
    to_map: Mat3A,
    pub(crate) to_world: Mat3A,
    pub(crate) marginal: Distribution1D,
    pub(crate) conditional: Vec<Distribution1D>,
}

impl Environment {
    pub fn constant(radiance: Vec3) -> Self {
        Self::Constant(radiance)
    }

    pub fn map(texture: Arc<Texture>, scale: Vec3, rotation_deg: f32) -> Self {
        let (w, h) = (texture.width as usize, texture.height as usize);
        let mut conditional = Vec::with_capacity(h);
        let mut rows = Vec::with_capacity(h);
        for y in 0..h {
            let sin_theta = ((y as f32 + 0.5) / h as f32 * PI).sin();
            let row: Vec<f32> = (0..w)
                .map(|x| {
                    let c = texture.texels.get(y * w + x) * scale;
                    (c.x + c.y + c.z).max(0.0) * sin_theta
                })
                .collect();
            let d = Distribution1D::new(row);
            rows.push(d.integral);
            conditional.push(d);
        }
        let marginal = Distribution1D::new(rows);
        let to_world = Mat3A::from_rotation_y(rotation_deg.to_radians());
        Self::Map(Box::new(EnvMap {
            texture,
            scale,
            to_map: to_world.transpose(),
            to_world,
            marginal,
            conditional,
        }))
    }

    /// Radiance arriving from direction `dir` (pointing away from the scene).
    #[inline]
    pub fn eval(&self, dir: Vec3) -> Vec3 {
        match self {
            Self::Constant(c) => *c,
            Self::Map(m) => {
                let (x, y) = m.texel_of(m.to_map * dir);
                m.texture.texels.get(y * m.texture.width as usize + x) * m.scale
            }
        }
    }

    /// Samples a direction; returns it, its radiance and its solid-angle pdf.
    #[inline]
    pub fn sample(&self, u: Vec2) -> (Vec3, Vec3, f32) {
        match self {
            Self::Constant(c) => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (sin, cos) = super::trig::sin_cos(2.0 * PI * u.y);
                (Vec3::new(r * cos, z, r * sin), *c, 1.0 / (4.0 * PI))
            }
            Self::Map(m) => {
                let (v, pdf_v, row) = m.marginal.sample(u.y);
                let (uu, pdf_u, _) = m.conditional[row].sample(u.x);
                let theta = v * PI;
                let phi = uu * 2.0 * PI;
                let (sin_theta, cos_theta) = super::trig::sin_cos(theta);
                if sin_theta <= 0.0 {
                    return (Vec3::Y, Vec3::ZERO, 0.0);
                }
                let (sin_phi, cos_phi) = super::trig::sin_cos(phi);
                let local = Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi);
                let dir = (m.to_world * local).normalize();
                // The density is pdf_v · pdf_u / (2π² sin θ); evaluating it through
                // `pdf` keeps sample and evaluation identical at texel borders.
                let _ = (pdf_v, pdf_u);
                (dir, self.eval(dir), self.pdf(dir))
            }
        }
    }

    /// Solid-angle pdf with which [`Environment::sample`] picks `dir`.
    #[inline]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        match self {
            Self::Constant(_) => 1.0 / (4.0 * PI),
            Self::Map(m) => {
                let local = m.to_map * dir;
                let (x, y) = m.texel_of(local);
                let sin_theta = (1.0 - local.y * local.y).max(0.0).sqrt();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                m.marginal.pdf(y) * m.conditional[y].pdf(x) / (2.0 * PI * PI * sin_theta)
            }
        }
    }
}

impl EnvMap {
    #[inline]
    fn texel_of(&self, local: Vec3) -> (usize, usize) {
        let (w, h) = (self.texture.width as usize, self.texture.height as usize);
        let theta = local.y.clamp(-1.0, 1.0).acos();
        let phi = local.z.atan2(local.x).rem_euclid(2.0 * PI);
        let x = ((phi / (2.0 * PI) * w as f32) as usize).min(w - 1);
        let y = ((theta / PI * h as f32) as usize).min(h - 1);
        (x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sampler::SampleStream;

    fn test_map() -> Arc<Texture> {
        let (w, h) = (16u32, 8u32);
        let texels = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if x == 3 && y == 2 {
                    Vec3::splat(50.0)
                } else {
                    Vec3::new(0.2 + 0.05 * y as f32, 0.3, 0.1 * (x % 4) as f32)
                }
            })
            .collect();
        Arc::new(Texture::linear(w, h, texels))
    }

    #[test]
    fn sampled_pdf_matches_evaluated_pdf_and_integrates_radiance() {
        let env = Environment::map(test_map(), Vec3::ONE, 30.0);
        let n = 20_000;
        let mut estimate = Vec3::ZERO;
        for i in 0..n {
            let p = SampleStream::new(1, 0, 0, i).next4();
            let (dir, radiance, pdf) = env.sample(Vec2::new(p[0], p[1]));
            assert!((dir.length() - 1.0).abs() < 1e-4);
            let eval_pdf = env.pdf(dir);
            assert!((eval_pdf - pdf).abs() <= 1e-3 * pdf.max(1.0), "pdf {pdf} vs {eval_pdf}");
            assert_eq!(radiance, env.eval(dir));
            estimate += radiance / pdf;
        }
        estimate /= n as f32;
        // Reference: ∫ L dω by uniform quadrature over the sphere.
        let mut reference = Vec3::ZERO;
        let m = 400;
        for i in 0..m {
            for j in 0..m {
                let z = 1.0 - 2.0 * (i as f32 + 0.5) / m as f32;
                let phi = 2.0 * PI * (j as f32 + 0.5) / m as f32;
                let r = (1.0 - z * z).sqrt();
                reference += env.eval(Vec3::new(r * phi.cos(), z, r * phi.sin()));
            }
        }
        reference *= 4.0 * PI / (m * m) as f32;
        let err = (estimate - reference).abs() / reference;
        assert!(err.max_element() < 0.03, "estimate {estimate} vs {reference}");
    }

    #[test]
    fn rotation_turns_the_map_about_up() {
        let a = Environment::map(test_map(), Vec3::ONE, 0.0);
        let b = Environment::map(test_map(), Vec3::ONE, 90.0);
        let d = Vec3::new(1.0, 0.3, 0.2).normalize();
        let rotated = Mat3A::from_rotation_y(90f32.to_radians()) * d;
        assert_eq!(a.eval(d), b.eval(rotated));
    }
}
