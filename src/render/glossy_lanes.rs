//! The glossy BSDF (a GGX coat over a Lambertian base, [`super::bsdf::Bsdf`]) of sixteen
//! lanes, for the stream kernel's vector stage ([`super::stream`]).
//!
//! Each function is its scalar counterpart in [`super::bsdf`] and [`super::microfacet`],
//! operation for operation and in the same order, branches turned into blends of both
//! sides, so that every lane holds the scalar code's bits (tested below against the
//! scalar functions). Glossy vertices took the one-path step in their lane before
//! (11 % of the bunny's vertices, 15 % of Sponza's); in the vector stage the bunny and
//! Sponza render 1.04× as fast (AMD EPYC Zen 4, paired medians of 25 alternating rounds).

use std::f32::consts::{FRAC_1_PI, PI};

use super::lanes::{F32s, Isa, Vec3s};
use super::trig::sin_cos_lanes;

/// The glossy lobes' parameters in sixteen lanes.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Glossy<I> {
    /// GGX roughness ([`super::microfacet::Ggx::alpha`]).
    pub alpha: F32s<I>,
    /// The coat's index of refraction.
    pub eta: F32s<I>,
    /// Base albedo.
    pub color: Vec3s<I>,
}

/// `v.normalize()` as glam computes it: `v * (1 / |v|)`.
#[inline(always)]
fn normalize<I: Isa>(v: Vec3s<I>) -> Vec3s<I> {
    v.scale(F32s::splat(1.0) / v.dot(v).sqrt())
}

/// [`super::microfacet::fresnel_dielectric`] in lanes.
#[inline(always)]
fn fresnel_dielectric<I: Isa>(cos_i: F32s<I>, eta: F32s<I>) -> F32s<I> {
    let one = F32s::splat(1.0);
    let inside = cos_i.lt(F32s::splat(0.0));
    let cos_i = F32s::select(inside, -cos_i, cos_i);
    let eta = F32s::select(inside, one / eta, eta);
    let sin2_t = (one - cos_i * cos_i).max(F32s::splat(0.0)) / (eta * eta);
    let cos_t = (one - sin2_t).sqrt();
    let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let r = F32s::splat(0.5) * (r_parl * r_parl + r_perp * r_perp);
    F32s::select(sin2_t.ge(one), one, r)
}

/// [`super::microfacet::Ggx::d`] in lanes.
#[inline(always)]
fn ggx_d<I: Isa>(alpha: F32s<I>, m: Vec3s<I>) -> F32s<I> {
    let one = F32s::splat(1.0);
    let a2 = alpha * alpha;
    let cos2 = m.z * m.z;
    let k = cos2 * (a2 - one) + one;
    F32s::select(m.z.le(F32s::splat(0.0)), F32s::splat(0.0), a2 / (F32s::splat(PI) * k * k))
}

/// Smith Λ(w) ([`super::microfacet::Ggx`]) in lanes.
#[inline(always)]
fn lambda<I: Isa>(alpha: F32s<I>, w: Vec3s<I>) -> F32s<I> {
    let one = F32s::splat(1.0);
    let cos2 = w.z * w.z;
    let tan2 = (one - cos2).max(F32s::splat(0.0)) / cos2;
    let l = ((one + alpha * alpha * tan2).sqrt() - one) * F32s::splat(0.5);
    F32s::select(cos2.ge(one), F32s::splat(0.0), l)
}

/// What the glossy lobes need of the direction `wo` they are seen from: the scalar
/// `Bsdf` recomputes these in every call, the stage once for its two evaluations and
/// its sample (the same values, so the same bits).
#[derive(Clone, Copy, Debug)]
pub(super) struct Seen<I> {
    wo: Vec3s<I>,
    /// The coat's Fresnel reflectance at the macro normal.
    f_o: F32s<I>,
    /// Smith Λ(wo).
    lambda_o: F32s<I>,
    /// Probability of sampling the coat rather than the base.
    coat: F32s<I>,
}

impl<I: Isa> Glossy<I> {
    /// The terms of `wo` (above the surface) shared by [`Glossy::eval`] and
    /// [`Glossy::sample`].
    #[inline(always)]
    pub(super) fn seen_from(&self, wo: Vec3s<I>) -> Seen<I> {
        let (zero, one) = (F32s::splat(0.0), F32s::splat(1.0));
        let f_o = fresnel_dielectric(wo.z, self.eta);
        // `Bsdf`'s coat probability: the coat's share of the lobes' albedo.
        let base = (one - f_o) * self.color.max_element();
        let p = f_o / (f_o + base).max(F32s::splat(1e-6));
        // f32::clamp: NaN stays NaN.
        let p = F32s::select(p.lt(zero), zero, p);
        let coat = F32s::select(p.gt(one), one, p);
        Seen { wo, f_o, lambda_o: lambda(self.alpha, wo), coat }
    }

    /// `f(wo, wi) · cos θi` and the pdf of sampling `wi` (`Bsdf::eval` of a glossy
    /// surface).
    #[inline(always)]
    pub(super) fn eval(&self, seen: &Seen<I>, wi: Vec3s<I>) -> (Vec3s<I>, F32s<I>) {
        let (zero, one) = (F32s::splat(0.0), F32s::splat(1.0));
        let Seen { wo, f_o, lambda_o: lo, coat } = *seen;
        let below = wi.z.le(zero) | wo.z.le(zero);
        let m = normalize(wo + wi);
        let d = ggx_d(self.alpha, m);
        let g2 = one / (one + lo + lambda(self.alpha, wi));
        let g1 = one / (one + lo);
        let four_cos = F32s::splat(4.0) * wo.z;
        let spec = f_o * d * g2 / four_cos;
        let transmit = (one - f_o) * (one - fresnel_dielectric(wi.z, self.eta));
        let diffuse = self.color.scale(transmit * wi.z * F32s::splat(FRAC_1_PI));
        let pdf_spec = g1 * d / four_cos;
        let pdf = coat * pdf_spec + (one - coat) * wi.z * F32s::splat(FRAC_1_PI);
        let value = Vec3s { x: spec, y: spec, z: spec } + diffuse;
        (Vec3s::select(below, Vec3s::default(), value), F32s::select(below, zero, pdf))
    }

    /// [`super::microfacet::Ggx::sample_visible`] for `w` above the surface.
    #[inline(always)]
    fn sample_visible(&self, w: Vec3s<I>, u1: F32s<I>, u2: F32s<I>) -> Vec3s<I> {
        let (zero, one) = (F32s::splat(0.0), F32s::splat(1.0));
        let a = self.alpha;
        let vh = normalize(Vec3s { x: a * w.x, y: a * w.y, z: w.z });
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let inv = one / len2.sqrt();
        let t1 = Vec3s::select(
            len2.gt(zero),
            Vec3s { x: -vh.y * inv, y: vh.x * inv, z: zero * inv },
            Vec3s { x: one, y: zero, z: zero },
        );
        let t2 = cross(vh, t1);
        let r = u1.sqrt();
        let (sin, cos) = sin_cos_lanes(F32s::splat(2.0 * PI) * u2);
        let p1 = r * cos;
        let s = F32s::splat(0.5) * (one + vh.z);
        let p2 = (one - s) * (one - p1 * p1).max(zero).sqrt() + s * (r * sin);
        let h = (one - p1 * p1 - p2 * p2).max(zero).sqrt();
        let nh = t1.scale(p1) + t2.scale(p2) + vh.scale(h);
        normalize(Vec3s { x: a * nh.x, y: a * nh.y, z: nh.z.max(F32s::splat(1e-6)) })
    }

    /// The sampled direction of `Bsdf::sample` on a glossy surface: the coat's
    /// reflection of a visible normal where `u0` falls on the coat, else `diffuse`, the
    /// cosine-weighted direction drawn from the same `u1`, `u2`.
    #[inline(always)]
    pub(super) fn sample(
        &self,
        seen: &Seen<I>,
        [u0, u1, u2]: [F32s<I>; 3],
        diffuse: Vec3s<I>,
    ) -> Vec3s<I> {
        let wo = seen.wo;
        let m = self.sample_visible(wo, u1, u2);
        let reflected = m.scale(F32s::splat(2.0) * wo.dot(m)) - wo;
        Vec3s::select(u0.lt(seen.coat), reflected, diffuse)
    }
}

/// glam's `cross`.
#[inline(always)]
fn cross<I: Isa>(a: Vec3s<I>, b: Vec3s<I>) -> Vec3s<I> {
    Vec3s { x: a.y * b.z - b.y * a.z, y: a.z * b.x - b.z * a.x, z: a.x * b.y - b.x * a.y }
}

#[cfg(test)]
mod tests {
    use glam::{Vec2, Vec3};
    use gridlight_actors::state::MaterialKind;

    use super::*;
    use crate::render::bsdf::Bsdf;
    use crate::render::lanes::tests::isa_tests;
    use crate::render::lanes::WIDTH;
    use crate::render::microfacet::cosine_hemisphere;

    /// A small deterministic generator of test inputs in [0, 1).
    fn uniform(state: &mut u32) -> f32 {
        *state ^= *state << 13;
        *state ^= *state >> 17;
        *state ^= *state << 5;
        (*state >> 8) as f32 / (1 << 24) as f32
    }

    fn direction(state: &mut u32) -> Vec3 {
        let v = Vec3::new(uniform(state), uniform(state), uniform(state)) * 2.0 - Vec3::ONE;
        v.normalize()
    }

    fn bits(v: Vec3) -> [u32; 3] {
        [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
    }

    /// Random surfaces, directions and draws (half of them below the surface, some at
    /// grazing and normal incidence): every lane must hold the scalar `Bsdf`'s bits.
    fn scalar_bits<I: Isa>() {
        let mut state = 0x2545_f491;
        for round in 0..2000 {
            let mut lanes = Glossy::<I>::default();
            let (mut wo, mut wi) = (Vec3s::<I>::default(), Vec3s::<I>::default());
            let mut u = [F32s::<I>::default(); 3];
            let mut bsdfs = Vec::new();
            for l in 0..WIDTH {
                let roughness = [0.0, 0.05, 0.3, 0.7, 1.0][(round + l) % 5];
                let ior = [1.5, 1.33, 2.4, 1.0][(round / 5 + l) % 4];
                let color = Vec3::new(uniform(&mut state), uniform(&mut state), 0.5);
                let b = Bsdf::new(MaterialKind::Glossy, color, roughness, ior);
                lanes.alpha.0[l] = b.ggx.alpha;
                lanes.eta.0[l] = b.eta;
                lanes.color.set_lane(l, color);
                let mut o = direction(&mut state);
                if l == 0 {
                    o = Vec3::Z;
                }
                o.z = o.z.abs();
                wo.set_lane(l, o);
                wi.set_lane(l, direction(&mut state));
                for d in &mut u {
                    d.0[l] = uniform(&mut state);
                }
                bsdfs.push(b);
            }
            let seen = lanes.seen_from(wo);
            let (f, pdf) = lanes.eval(&seen, wi);
            let diffuse = crate::render::stream::cosine_hemisphere(u[1], u[2]);
            let sampled = lanes.sample(&seen, u, diffuse);
            for (l, b) in bsdfs.iter().enumerate() {
                let (o, i) = (wo.lane(l), wi.lane(l));
                let (ef, epdf) = b.eval(o, i);
                assert_eq!(bits(f.lane(l)), bits(ef), "eval, lane {l}, round {round}");
                assert_eq!(pdf.0[l].to_bits(), epdf.to_bits(), "pdf, lane {l}, round {round}");
                let uu = [u[0].0[l], u[1].0[l], u[2].0[l]];
                assert_eq!(diffuse.lane(l), cosine_hemisphere(Vec2::new(uu[1], uu[2])));
                // Bsdf::sample returns the direction only where its pdf is positive.
                if let Some(s) = b.sample(o, uu) {
                    assert_eq!(bits(sampled.lane(l)), bits(s.wi), "sample, lane {l}");
                }
            }
        }
    }

    isa_tests!(scalar_bits: sse2_lanes_give_the_scalar_bits, avx2_lanes_give_the_scalar_bits,
        avx512_lanes_give_the_scalar_bits);
}
