//! The scattering functions of the material kinds, in a local shading frame (glTF's
//! metallic-roughness `Pbr` kind in [`super::pbr`]).
//!
//! A [`Bsdf`] is a small `Copy` value built per hit from the material table and
//! the texture lookup; evaluation and sampling `match` on its kind, so there is no
//! dynamic dispatch per sample. Values returned are `f · |cos θi|` (the cosine is
//! folded in) with the solid-angle pdf; sampled weights are `f · |cos θi| / pdf`.
//!
//! Diffuse, conductor, glossy and opaque `Pbr` surfaces are two-sided: the caller flips
//! the frame so that `wo.z > 0`. Dielectrics and transmissive `Pbr` surfaces keep the
//! outward normal on +z, so `wo.z < 0` means the ray arrives from inside.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};
use gridlight_actors::state::MaterialKind;

use super::microfacet::{
    cosine_hemisphere, fresnel_dielectric, fresnel_schlick, reflect, refract,
    sample_rough_dielectric, Ggx,
};

/// Scattering at one surface point.
#[derive(Clone, Copy, Debug)]
pub struct Bsdf {
    pub kind: MaterialKind,
    /// Albedo / reflectance / transmission tint (textured).
    pub color: Vec3,
    pub ggx: Ggx,
    /// Index of refraction (inside over outside) of dielectrics, glossy coats and `Pbr`.
    pub eta: f32,
    /// `Pbr` only (0 otherwise): the metal's share of the material.
    pub metallic: f32,
    /// `Pbr` only (0 otherwise): the glass's share of the non-metal.
    pub transmission: f32,
}

/// One sampled direction.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wi: Vec3,
    /// `f · |cos θi| / pdf`.
    pub weight: Vec3,
    /// Solid-angle pdf; meaningless when `delta`.
    pub pdf: f32,
    /// A perfectly specular choice (no MIS with light sampling possible).
    pub delta: bool,
}

impl Bsdf {
    /// Roughness of glossy coats is clamped to keep their lobe evaluable.
    const MIN_COAT_ALPHA: f32 = 0.01;

    pub fn new(kind: MaterialKind, color: Vec3, roughness: f32, ior: f32) -> Self {
        let mut alpha = (roughness * roughness).clamp(0.0, 1.0);
        if kind == MaterialKind::Glossy {
            alpha = alpha.max(Self::MIN_COAT_ALPHA);
        }
        let eta = if ior.is_finite() && ior > 0.0 && ior != 1.0 { ior } else { 1.5 };
        Self { kind, color, ggx: Ggx { alpha }, eta, metallic: 0.0, transmission: 0.0 }
    }

    /// A glTF metallic-roughness surface (`MaterialKind::Pbr`); `metallic` and
    /// `transmission` are clamped to [0, 1].
    pub fn pbr(color: Vec3, metallic: f32, roughness: f32, transmission: f32, ior: f32) -> Self {
        let unit = |v: f32| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
        Self {
            metallic: unit(metallic),
            transmission: unit(transmission),
            ..Self::new(MaterialKind::Pbr, color, roughness, ior)
        }
    }

    /// Whether every sampled direction is a delta (light sampling is useless).
    #[inline]
    pub fn is_delta(&self) -> bool {
        match self.kind {
            MaterialKind::Conductor | MaterialKind::Dielectric => self.ggx.alpha < Ggx::SMOOTH,
            MaterialKind::Pbr => self.pbr_is_delta(),
            MaterialKind::Diffuse | MaterialKind::Glossy => false,
        }
    }

    /// Whether the frame is two-sided (flipped so that `wo.z > 0`).
    #[inline]
    pub fn two_sided(&self) -> bool {
        match self.kind {
            MaterialKind::Dielectric => false,
            MaterialKind::Pbr => self.transmission == 0.0,
            _ => true,
        }
    }

    /// `f(wo, wi) · |cos θi|` and the pdf of sampling `wi`.
    #[inline(always)]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if self.is_delta() {
            return (Vec3::ZERO, 0.0);
        }
        match self.kind {
            MaterialKind::Diffuse => {
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    return (Vec3::ZERO, 0.0);
                }
                (self.color * (wi.z * FRAC_1_PI), wi.z * FRAC_1_PI)
            }
            MaterialKind::Conductor => self.eval_conductor(wo, wi),
            MaterialKind::Glossy => self.eval_glossy(wo, wi),
            MaterialKind::Dielectric => self.eval_dielectric(wo, wi),
            MaterialKind::Pbr => self.eval_pbr(wo, wi),
        }
    }

    /// Samples `wi` from three uniform numbers.
    #[inline(always)]
    pub fn sample(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        let u2 = Vec2::new(u[1], u[2]);
        match self.kind {
            MaterialKind::Diffuse => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = cosine_hemisphere(u2);
                Some(BsdfSample { wi, weight: self.color, pdf: wi.z * FRAC_1_PI, delta: false })
            }
            MaterialKind::Conductor => {
                if wo.z <= 0.0 {
                    return None;
                }
                if self.is_delta() {
                    let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                    let weight = fresnel_schlick(self.color, wo.z);
                    return Some(BsdfSample { wi, weight, pdf: 1.0, delta: true });
                }
                let m = self.ggx.sample_visible(wo, u2);
                let wi = reflect(wo, m);
                if wi.z <= 0.0 {
                    return None;
                }
                // With visible-normal sampling the weight reduces to F · G2 / G1.
                let f = fresnel_schlick(self.color, wo.dot(m));
                let weight = f * (self.ggx.g2(wo, wi) / self.ggx.g1(wo));
                let pdf = self.ggx.g1(wo) * self.ggx.d(m) / (4.0 * wo.z);
                Some(BsdfSample { wi, weight, pdf, delta: false })
            }
            MaterialKind::Glossy => {
                if wo.z <= 0.0 {
                    return None;
                }
                let wi = if u[0] < self.coat_probability(wo) {
                    reflect(wo, self.ggx.sample_visible(wo, u2))
                } else {
                    cosine_hemisphere(u2)
                };
                self.weighted(wo, wi)
            }
            MaterialKind::Dielectric => self.sample_dielectric(wo, u),
            MaterialKind::Pbr => self.sample_pbr(wo, u),
        }
    }

    /// A sample whose weight comes from `eval` (for the mixed lobes).
    #[inline]
    pub(super) fn weighted(&self, wo: Vec3, wi: Vec3) -> Option<BsdfSample> {
        let (f, pdf) = self.eval(wo, wi);
        (pdf > 0.0).then(|| BsdfSample { wi, weight: f / pdf, pdf, delta: false })
    }

    fn eval_conductor(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let m = (wo + wi).normalize();
        let d = self.ggx.d(m);
        let f = fresnel_schlick(self.color, wo.dot(m));
        let value = f * (d * self.ggx.g2(wo, wi) / (4.0 * wo.z));
        (value, self.ggx.g1(wo) * d / (4.0 * wo.z))
    }

    /// Probability of sampling the coat rather than the diffuse base: the coat's
    /// share of the lobes' maximal albedo. With it every sample weight is at most
    /// `Fo + (1 - Fo) max(color)` ≤ 1.
    #[inline]
    fn coat_probability(&self, wo: Vec3) -> f32 {
        let f = fresnel_dielectric(wo.z, self.eta);
        let base = (1.0 - f) * self.color.max_element();
        (f / (f + base).max(1e-6)).clamp(0.0, 1.0)
    }

    /// Plastic-like coat: a GGX lobe scaled by the coat's Fresnel reflectance at
    /// the macro normal, over a Lambertian base that sees the light that passed
    /// the coat on the way in and out.
    fn eval_glossy(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let m = (wo + wi).normalize();
        let d = self.ggx.d(m);
        let f_o = fresnel_dielectric(wo.z, self.eta);
        let spec = f_o * d * self.ggx.g2(wo, wi) / (4.0 * wo.z);
        let transmit = (1.0 - f_o) * (1.0 - fresnel_dielectric(wi.z, self.eta));
        let diffuse = self.color * (transmit * wi.z * FRAC_1_PI);
        let p = self.coat_probability(wo);
        let pdf_spec = self.ggx.g1(wo) * d / (4.0 * wo.z);
        let pdf = p * pdf_spec + (1.0 - p) * wi.z * FRAC_1_PI;
        (Vec3::splat(spec) + diffuse, pdf)
    }

    pub(super) fn eval_dielectric(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let reflected = cos_i * cos_o > 0.0;
        let etap = if reflected {
            1.0
        } else if cos_o > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let wm = wi * etap + wo;
        if wm.length_squared() == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let mut wm = wm.normalize();
        if wm.z < 0.0 {
            wm = -wm;
        }
        // Discard back-facing microfacets.
        if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let fr = fresnel_dielectric(wo.dot(wm), self.eta);
        let d = self.ggx.d(wm);
        let g = self.ggx.g2(wo, wi);
        let pdf_m = self.ggx.pdf_visible(wo, wm);
        if reflected {
            let f = d * g * fr / (4.0 * cos_i * cos_o).abs();
            let pdf = pdf_m / (4.0 * wo.dot(wm).abs()) * fr;
            (Vec3::splat(f * cos_i.abs()), pdf)
        } else {
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
            let t = 1.0 - fr;
            let f = t * d * g * (wi.dot(wm) * wo.dot(wm) / (cos_i * cos_o * denom)).abs();
            // Radiance is compressed by the squared index ratio when it enters.
            let f = f / (etap * etap);
            let pdf = pdf_m * wi.dot(wm).abs() / denom * t;
            (self.color * (f * cos_i.abs()), pdf)
        }
    }

    fn sample_dielectric(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        if self.is_delta() {
            let fr = fresnel_dielectric(wo.z, self.eta);
            if u[0] < fr {
                let wi = Vec3::new(-wo.x, -wo.y, wo.z);
                return Some(BsdfSample { wi, weight: Vec3::ONE, pdf: 1.0, delta: true });
            }
            let (wi, etap) = refract(wo, Vec3::Z, self.eta)?;
            let weight = self.color / (etap * etap);
            return Some(BsdfSample { wi, weight, pdf: 1.0, delta: true });
        }
        let u2 = Vec2::new(u[1], u[2]);
        let wi = sample_rough_dielectric(self.ggx, self.eta, wo, u[0], u2)?;
        self.weighted(wo, wi)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::render::sampler::SampleStream;
    use std::f32::consts::PI;

    fn materials() -> Vec<(&'static str, Bsdf)> {
        let white = Vec3::ONE;
        vec![
            ("diffuse", Bsdf::new(MaterialKind::Diffuse, white, 1.0, 1.5)),
            ("conductor rough", Bsdf::new(MaterialKind::Conductor, white, 0.5, 1.5)),
            ("conductor shiny", Bsdf::new(MaterialKind::Conductor, white, 0.35, 1.5)),
            ("conductor smooth", Bsdf::new(MaterialKind::Conductor, white, 0.0, 1.5)),
            ("glossy", Bsdf::new(MaterialKind::Glossy, white, 0.3, 1.5)),
            ("glossy rough", Bsdf::new(MaterialKind::Glossy, white, 0.8, 1.5)),
            ("glass smooth", Bsdf::new(MaterialKind::Dielectric, white, 0.0, 1.5)),
            ("glass rough", Bsdf::new(MaterialKind::Dielectric, white, 0.4, 1.5)),
        ]
    }

    pub(in crate::render) fn directions() -> Vec<Vec3> {
        [0.95f32, 0.6, 0.25, 0.05]
            .iter()
            .map(|&c| Vec3::new((1.0 - c * c).sqrt(), 0.0, c))
            .collect()
    }

    pub(in crate::render) fn uniforms(n: u32, seed: u64) -> impl Iterator<Item = [f32; 3]> {
        (0..n).map(move |i| {
            let p = SampleStream::new(seed, 0, 0, i).next4();
            [p[0], p[1], p[2]]
        })
    }

    #[test]
    fn sampling_conserves_energy() {
        for (name, bsdf) in materials() {
            for wo in directions() {
                let mut albedo = Vec3::ZERO;
                let n = 20_000;
                for u in uniforms(n, 11) {
                    if let Some(s) = bsdf.sample(wo, u) {
                        // Entering glass compresses radiance (≤ 1); the weight may
                        // not exceed one by more than rounding.
                        assert!(
                            s.weight.max_element() <= 1.0 + 1e-3,
                            "{name}: weight {} at {wo}",
                            s.weight
                        );
                        assert!(s.weight.min_element() >= 0.0);
                        albedo += s.weight;
                    }
                }
                let albedo = albedo / n as f32;
                assert!(albedo.max_element() <= 1.0 + 1e-3, "{name}: albedo {albedo} at {wo}");
            }
        }
    }

    #[test]
    fn diffuse_and_smooth_glass_keep_all_energy() {
        // Lambertian with albedo 1 reflects everything; smooth glass entering from
        // outside loses exactly the 1/η² radiance compression on transmission.
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let n = 4096;
        let diffuse = Bsdf::new(MaterialKind::Diffuse, Vec3::ONE, 1.0, 1.5);
        let sum: f32 =
            uniforms(n, 3).filter_map(|u| diffuse.sample(wo, u)).map(|s| s.weight.x).sum();
        assert!((sum / n as f32 - 1.0).abs() < 1e-4);
        let glass = Bsdf::new(MaterialKind::Dielectric, Vec3::ONE, 0.0, 1.5);
        let fr = fresnel_dielectric(0.8, 1.5);
        let sum: f32 = uniforms(n, 5).filter_map(|u| glass.sample(wo, u)).map(|s| s.weight.x).sum();
        let expected = fr + (1.0 - fr) / (1.5 * 1.5);
        assert!((sum / n as f32 - expected).abs() < 0.01, "{} vs {expected}", sum / n as f32);
    }

    /// Chi-square-like histogram test: sampled directions binned over (cos θ, φ)
    /// must match the integral of the evaluated pdf over each bin.
    #[test]
    fn sampled_pdf_matches_evaluated_pdf() {
        for (name, bsdf) in materials() {
            if bsdf.is_delta() {
                continue;
            }
            for wo in directions().into_iter().take(3) {
                assert_sampled_pdf_matches(name, &bsdf, wo);
            }
        }
    }

    /// Samples `bsdf` at `wo`: each sample's pdf must be the evaluated one, and their
    /// histogram over (cos θ, φ) must match the evaluated pdf's integral over each bin
    /// (chi-square; delta samples are left out of both, their share of the count too).
    pub(in crate::render) fn assert_sampled_pdf_matches(name: &str, bsdf: &Bsdf, wo: Vec3) {
        const NT: usize = 12;
        const NP: usize = 24;
        let n = 60_000u32;
        let mut observed = vec![0f64; 2 * NT * NP];
        let bin = |w: Vec3| {
            let t = (((w.z + 1.0) * 0.5 * (2 * NT) as f32) as usize).min(2 * NT - 1);
            let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
            let p = ((phi / (2.0 * PI) * NP as f32) as usize).min(NP - 1);
            t * NP + p
        };
        for u in uniforms(n, 17) {
            if let Some(s) = bsdf.sample(wo, u) {
                if s.delta {
                    continue;
                }
                observed[bin(s.wi)] += 1.0;
                let (_, pdf) = bsdf.eval(wo, s.wi);
                assert!(
                    (pdf - s.pdf).abs() <= 1e-2 * pdf.max(1.0),
                    "{name}: sampled pdf {} vs eval {pdf}",
                    s.pdf
                );
            }
        }
        // Expected counts by midpoint-rule integration of the pdf in each bin.
        let sub = 6;
        let mut expected = vec![0f64; 2 * NT * NP];
        for (b, e) in expected.iter_mut().enumerate() {
            let (t, p) = (b / NP, b % NP);
            let mut acc = 0.0;
            for i in 0..sub {
                for j in 0..sub {
                    let z =
                        -1.0 + (t as f32 + (i as f32 + 0.5) / sub as f32) * 2.0 / (2 * NT) as f32;
                    let phi = (p as f32 + (j as f32 + 0.5) / sub as f32) * 2.0 * PI / NP as f32;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    let w = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                    acc += bsdf.eval(wo, w).1 as f64;
                }
            }
            let area = (2.0 / (2 * NT) as f64) * (2.0 * std::f64::consts::PI / NP as f64);
            *e = acc / (sub * sub) as f64 * area * n as f64;
        }
        let mut chi2 = 0.0;
        let mut dof = 0;
        let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
        for (o, e) in observed.iter().zip(&expected) {
            if *e < 5.0 {
                pooled_o += o;
                pooled_e += e;
            } else {
                chi2 += (o - e) * (o - e) / e;
                dof += 1;
            }
        }
        if pooled_e >= 5.0 {
            chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
            dof += 1;
        }
        // Generous bound (midpoint integration is approximate on peaked lobes):
        // a wrong pdf gives chi² many times the degrees of freedom.
        eprintln!("{name} at {wo}: chi² {chi2:.0} with {dof} bins");
        assert!(chi2 < 2.0 * dof as f64 + 60.0, "{name} at {wo}: chi² {chi2:.0} with {dof} bins");
    }
}
