//! glTF 2.0's metallic-roughness material (`MaterialKind::Pbr`), as the specification's
//! BRDF appendix defines it, in the local shading frame of [`super::bsdf`]:
//!
//! ```text
//! dielectric = fresnel_mix(ior, base = diffuse, layer = specular)
//! metal      = conductor_fresnel(f0 = base colour, specular)
//! material   = mix(dielectric, metal, metallic)
//! ```
//!
//! with GGX `specular` (height-correlated Smith masking, [`super::microfacet`]) and
//! Fresnel–Schlick at the microfacet normal. One deliberate departure: the appendix
//! weighs the diffuse base by `1 − F(v·h)`, which in a white furnace returns more light
//! than it receives at all but normal views (a smooth white plastic mirrors F(cos θ) and
//! still scatters 94–96 % diffusely: 1.007 in all at cos θ = 0.6, 1.22 at 0.25, 1.72 at
//! 0.05, by numerical integration). Here the base sees the light the layer lets through
//! on the way in and out, normalised so that a white base returns exactly what the layer
//! does not reflect ([`super::layering`]): no corner of the parameters gains energy
//! (`pbr/tests.rs`), and a rough floor seen at a grazing angle keeps the light Cycles
//! gives it.
//! `KHR_materials_transmission` replaces that share of the non-metal by rough glass: the
//! existing dielectric ([`Bsdf`]'s glass, exact Fresnel, refraction through the surface),
//! so a transmissive glTF object renders as the `Dielectric` kind does. The extension's
//! thin-walled reading (light leaving without bending) is not what gridlight draws: closed
//! meshes refract, as in Cycles.
//!
//! Sampling picks one of four lobes (Lambert, the dielectric's GGX layer, the metal's
//! GGX, the glass) with probabilities from their estimated albedos at `wo`, samples it
//! (cosine-weighted, or GGX visible normals) and weighs the direction by the mixture of
//! all lobes' pdfs, so next-event estimation's MIS sees the same pdf. At roughness 0
//! the three specular lobes are deltas that share the mirror direction: a mirror sample
//! sums them over the probability of choosing any of them, and only the Lambertian lobe
//! remains for light sampling.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3};

use super::bsdf::{Bsdf, BsdfSample};
use super::layering;
use super::microfacet::{
    cosine_hemisphere, fresnel_dielectric, reflect, refract, sample_rough_dielectric, Ggx,
};

/// Smallest selection weight of a lobe the material mixes in at all: a black metal still
/// reflects at grazing microfacets, so its lobe must stay sampleable.
const MIN_LOBE_WEIGHT: f32 = 0.02;

/// Schlick's Fresnel term for a scalar normal-incidence reflectance.
#[inline]
fn schlick(f0: f32, cos: f32) -> f32 {
    f0 + (1.0 - f0) * (1.0 - cos.clamp(0.0, 1.0)).powi(5)
}

/// glTF's `fresnel_mix` of a dielectric layer of normal-incidence reflectance `f0` and
/// roughness `alpha` over `base`: the layer weighted by Schlick's Fresnel at `cos_oh`
/// (view · microfacet normal), the base by what the layer lets through at the view's and
/// the light's cosines to the macro normal ([`layering::base_weight`]).
#[inline]
pub fn fresnel_mix(
    f0: f32,
    alpha: f32,
    cos_oh: f32,
    (cos_o, cos_i): (f32, f32),
    base: Vec3,
    layer: f32,
) -> Vec3 {
    let through = layering::base_weight(f0, alpha, cos_o, cos_i);
    base * through + Vec3::splat(layer * schlick(f0, cos_oh))
}

/// glTF's `conductor_fresnel`: a specular lobe tinted by Schlick's Fresnel of
/// normal-incidence reflectance `f0`.
#[inline]
pub fn conductor_fresnel(f0: Vec3, cos: f32, bsdf: f32) -> Vec3 {
    let m = (1.0 - cos.clamp(0.0, 1.0)).powi(5);
    (f0 + (Vec3::ONE - f0) * m) * bsdf
}

/// Normal-incidence reflectance of a dielectric of index `eta`: ((η − 1)/(η + 1))².
#[inline]
pub fn dielectric_f0(eta: f32) -> f32 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// Selection probabilities of the four lobes at one `wo`; they sum to one.
#[derive(Clone, Copy, Debug)]
struct Lobes {
    diffuse: f32,
    specular: f32,
    metal: f32,
    glass: f32,
}

/// `w` mirrored to the upper hemisphere when `wo` arrives from below (the opaque lobes
/// reflect on whichever side the viewer is; only the glass cares about the side).
#[inline]
fn upper(w: Vec3, side: f32) -> Vec3 {
    Vec3::new(w.x, w.y, w.z * side)
}

#[inline]
fn mean(c: Vec3) -> f32 {
    (c.x + c.y + c.z) * (1.0 / 3.0)
}

impl Bsdf {
    /// Whether every lobe the material mixes in is a delta: smooth, and no diffuse share.
    #[inline]
    pub(super) fn pbr_is_delta(&self) -> bool {
        self.ggx.alpha < Ggx::SMOOTH && self.diffuse_share() == 0.0
    }

    /// The Lambertian base's share of the material: (1 − metallic)(1 − transmission).
    #[inline]
    fn diffuse_share(&self) -> f32 {
        (1.0 - self.metallic) * (1.0 - self.transmission)
    }

    fn lobes(&self, wo: Vec3) -> Lobes {
        let cos = wo.z.abs();
        let (m, t) = (self.metallic, self.transmission);
        // What the dielectric layer reflects at this view (Schlick's F when smooth).
        let f = layering::albedo(dielectric_f0(self.eta), self.ggx.alpha, cos);
        let opaque = (1.0 - m) * (1.0 - t);
        let floor = |share: f32, estimate: f32| {
            if share > 0.0 {
                share * estimate.max(MIN_LOBE_WEIGHT)
            } else {
                0.0
            }
        };
        let diffuse = if opaque > 0.0 { opaque * (1.0 - f) * mean(self.color) } else { 0.0 };
        let specular = floor(opaque, f);
        let metal = floor(m, mean(conductor_fresnel(self.color, cos, 1.0)));
        let fr = fresnel_dielectric(wo.z, self.eta);
        let glass = floor((1.0 - m) * t, fr + (1.0 - fr) * mean(self.color));
        let total = diffuse + specular + metal + glass;
        if total <= 0.0 {
            return Lobes { diffuse: 0.0, specular: 0.0, metal: 0.0, glass: 0.0 };
        }
        let inv = 1.0 / total;
        Lobes {
            diffuse: diffuse * inv,
            specular: specular * inv,
            metal: metal * inv,
            glass: glass * inv,
        }
    }

    /// `f · |cos θi|` and the mixture pdf of the lobes that are not deltas.
    pub(super) fn eval_pbr(&self, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        if wo.z == 0.0 || wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let lobes = self.lobes(wo);
        let smooth = self.ggx.alpha < Ggx::SMOOTH;
        let (mut f, mut pdf) = (Vec3::ZERO, 0.0);
        let side = wo.z.signum();
        let (o, i) = (upper(wo, side), upper(wi, side));
        if i.z > 0.0 {
            let opaque = self.diffuse_share();
            let f0 = dielectric_f0(self.eta);
            let h = (o + i).normalize();
            let cos_oh = o.dot(h);
            let diffuse = self.color * (i.z * FRAC_1_PI);
            pdf += lobes.diffuse * i.z * FRAC_1_PI;
            if smooth {
                // Only the Lambertian base is not a delta.
                f += fresnel_mix(f0, self.ggx.alpha, cos_oh, (o.z, i.z), diffuse, 0.0) * opaque;
            } else {
                let d = self.ggx.d(h);
                let spec = d * self.ggx.g2(o, i) / (4.0 * o.z);
                f += fresnel_mix(f0, self.ggx.alpha, cos_oh, (o.z, i.z), diffuse, spec) * opaque
                    + conductor_fresnel(self.color, cos_oh, spec) * self.metallic;
                pdf += (lobes.specular + lobes.metal) * self.ggx.g1(o) * d / (4.0 * o.z);
            }
        }
        let glass = (1.0 - self.metallic) * self.transmission;
        if glass > 0.0 && !smooth {
            let (glass_f, glass_pdf) = self.eval_dielectric(wo, wi);
            f += glass_f * glass;
            pdf += lobes.glass * glass_pdf;
        }
        (f, pdf)
    }

    /// Samples one lobe by its estimated weight, then the direction from it.
    pub(super) fn sample_pbr(&self, wo: Vec3, u: [f32; 3]) -> Option<BsdfSample> {
        if wo.z == 0.0 {
            return None;
        }
        let lobes = self.lobes(wo);
        let u2 = Vec2::new(u[1], u[2]);
        let side = wo.z.signum();
        let o = upper(wo, side);
        let smooth = self.ggx.alpha < Ggx::SMOOTH;
        let specular = lobes.specular + lobes.metal;
        if u[0] < lobes.diffuse {
            let wi = upper(cosine_hemisphere(u2), side);
            return self.weighted(wo, wi);
        }
        if u[0] < lobes.diffuse + specular {
            if smooth {
                return self.mirror(wo, lobes);
            }
            let wi = reflect(o, self.ggx.sample_visible(o, u2));
            return (wi.z > 0.0).then(|| self.weighted(wo, upper(wi, side))).flatten();
        }
        if lobes.glass <= 0.0 {
            return None;
        }
        // The glass decides reflection against refraction with its own uniform number.
        let u0 = ((u[0] - lobes.diffuse - specular) / lobes.glass).clamp(0.0, 1.0 - f32::EPSILON);
        if smooth {
            let fr = fresnel_dielectric(wo.z, self.eta);
            if u0 < fr {
                return self.mirror(wo, lobes);
            }
            let (wi, etap) = refract(wo, Vec3::Z, self.eta)?;
            // f = share (1 − Fr) colour / η'², chosen with probability glass (1 − Fr).
            let share = (1.0 - self.metallic) * self.transmission;
            let weight = self.color * (share / (etap * etap * lobes.glass));
            return Some(BsdfSample { wi, weight, pdf: lobes.glass * (1.0 - fr), delta: true });
        }
        let wi = sample_rough_dielectric(self.ggx, self.eta, wo, u0, u2)?;
        self.weighted(wo, wi)
    }

    /// The smooth material's mirror direction: every specular lobe reflects there, so its
    /// weight sums them over the probability that any of them was chosen.
    fn mirror(&self, wo: Vec3, lobes: Lobes) -> Option<BsdfSample> {
        let cos = wo.z.abs();
        let fr = fresnel_dielectric(wo.z, self.eta);
        let (m, t) = (self.metallic, self.transmission);
        let f = conductor_fresnel(self.color, cos, m)
            + Vec3::splat(
                self.diffuse_share() * schlick(dielectric_f0(self.eta), cos) + (1.0 - m) * t * fr,
            );
        let pdf = lobes.specular + lobes.metal + lobes.glass * fr;
        if pdf <= 0.0 {
            return None;
        }
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        Some(BsdfSample { wi, weight: f / pdf, pdf, delta: true })
    }
}

#[cfg(test)]
mod tests;
