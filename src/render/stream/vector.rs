//! The vector stage: next-event estimation and BSDF sampling of the lanes at diffuse and
//! glossy vertices, as sixteen-lane code.

use super::group::Group;
use crate::render::glossy_lanes::Glossy;
use crate::render::integrator::RR_START_DEPTH;
use crate::render::lanes::{F32s, Isa, Mask, U32s, Vec3s, WIDTH};
use crate::render::lights::Lights;
use crate::render::sampler::next4_lanes;
use crate::render::trig::sin_cos_lanes;
use crate::render::RenderScene;

/// [`crate::render::microfacet::Frame`] of sixteen normals: tangents `s`, `t`.
#[inline(always)]
fn frame<I: Isa>(n: Vec3s<I>) -> (Vec3s<I>, Vec3s<I>) {
    let one = F32s::splat(1.0);
    let sign = F32s::from_bits(one.to_bits() | (n.z.to_bits() & U32s::splat(0x8000_0000)));
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    let s = Vec3s { x: one + sign * n.x * n.x * a, y: sign * b, z: -sign * n.x };
    let t = Vec3s { x: b, y: sign + n.y * n.y * a, z: -n.y };
    (s, t)
}

/// [`crate::render::integrator::offset`] in lanes.
#[inline(always)]
fn offset<I: Isa>(p: Vec3s<I>, ng: Vec3s<I>, dir: Vec3s<I>) -> Vec3s<I> {
    let eps = F32s::splat(1e-4) * (F32s::splat(1.0) + p.abs().max_element());
    Vec3s::select(ng.dot(dir).ge(F32s::splat(0.0)), p + ng.scale(eps), p - ng.scale(eps))
}

/// [`crate::render::microfacet::cosine_hemisphere`] in lanes.
#[inline(always)]
pub(in crate::render) fn cosine_hemisphere<I: Isa>(u1: F32s<I>, u2: F32s<I>) -> Vec3s<I> {
    use std::f32::consts::PI;
    let (one, zero) = (F32s::splat(1.0), F32s::splat(0.0));
    let (ax, ay) = (F32s::splat(2.0) * u1 - one, F32s::splat(2.0) * u2 - one);
    let centre = ax.eq(zero) & ay.eq(zero);
    let x_major = ax.abs().gt(ay.abs());
    let r = F32s::select(x_major, ax, ay);
    let phi = F32s::select(
        x_major,
        F32s::splat(PI / 4.0) * (ay / ax),
        F32s::splat(PI / 2.0) - F32s::splat(PI / 4.0) * (ax / ay),
    );
    let (s, c) = sin_cos_lanes(phi);
    let (x, y) = (r * c, r * s);
    let z = (one - x * x - y * y).max(zero).sqrt();
    Vec3s::select(centre, Vec3s { x: zero, y: zero, z: one }, Vec3s { x, y, z })
}

/// Power heuristic with β = 2 in lanes.
#[inline(always)]
fn mis_lanes<I: Isa>(a: F32s<I>, b: F32s<I>) -> F32s<I> {
    let (a2, b2) = (a * a, b * b);
    let zero = F32s::splat(0.0);
    F32s::select((a2 + b2).gt(zero), a2 / (a2 + b2), zero)
}

/// Sixteen lanes' light samples.
struct LightSamples<I> {
    wi: Vec3s<I>,
    dist: F32s<I>,
    radiance: Vec3s<I>,
    /// Solid-angle pdf.
    pdf: F32s<I>,
    /// Lanes where a sample was drawn.
    sampled: Mask<I>,
}

/// Light samples of sixteen lanes in a scene lit by area emitters only, as
/// [`crate::render::lights::Lights::sample`] draws them: an emitter by power, then a point on
/// it.
#[inline(always)]
fn sample_area_lanes<I: Isa>(
    lights: &Lights,
    p: Vec3s<I>,
    u_light: &[F32s<I>; 4],
) -> LightSamples<I> {
    let (zero, one) = (F32s::splat(0.0), F32s::splat(1.0));
    let mut v0 = Vec3s::default();
    let mut e1 = Vec3s::default();
    let mut e2 = Vec3s::default();
    let mut normal = Vec3s::default();
    let mut radiance = Vec3s::default();
    let mut parallelogram = U32s::default();
    for l in 0..WIDTH {
        let a = &lights.areas[lights.pick_area(lights.area_u(u_light[0].0[l], 0))];
        v0.set_lane(l, a.v0);
        e1.set_lane(l, a.e1);
        e2.set_lane(l, a.e2);
        normal.set_lane(l, a.normal);
        radiance.set_lane(l, a.radiance);
        parallelogram.0[l] = if a.parallelogram { u32::MAX } else { 0 };
    }
    let r = u_light[1].sqrt();
    let s = F32s::select(parallelogram, u_light[1], one - r);
    let t = F32s::select(parallelogram, u_light[2], u_light[2] * r);
    let q = v0 + e1.scale(s) + e2.scale(t);
    let d = q - p;
    let dist2 = d.dot(d);
    let dist = dist2.sqrt();
    let wi = d.div_by(dist);
    let cos_light = -wi.dot(normal);
    let sampled = !(cos_light.le(zero) | dist2.eq(zero));
    let per_area = (radiance.x + radiance.y + radiance.z) / F32s::splat(lights.area_power);
    let light_pdf = F32s::splat(lights.strategy_pmf) * per_area * dist2 / cos_light;
    LightSamples { wi, dist, radiance, pdf: light_pdf, sampled }
}

/// The same for the `group` lanes of a scene with other lights (the sun, the sky,
/// point lights, or several kinds): [`crate::render::lights::Lights::sample`] lane by lane,
/// whose choice among strategies and their sampling are data-dependent.
#[inline(always)]
fn sample_lights_per_lane<I: Isa>(
    lights: &Lights,
    p: Vec3s<I>,
    u_light: &[F32s<I>; 4],
    group: u32,
) -> LightSamples<I> {
    let (mut wi, mut dist, mut radiance) = (Vec3s::default(), F32s::splat(0.0), Vec3s::default());
    let (mut pdf, mut sampled) = (F32s::splat(0.0), 0u32);
    let mut left = group;
    while left != 0 {
        let l = left.trailing_zeros() as usize;
        left &= left - 1;
        let u = [u_light[0].0[l], u_light[1].0[l], u_light[2].0[l]];
        if let Some(ls) = lights.sample(p.lane(l), u) {
            wi.set_lane(l, ls.wi);
            dist.0[l] = ls.dist;
            radiance.set_lane(l, ls.radiance);
            pdf.0[l] = ls.pdf;
            sampled |= 1 << l;
        }
    }
    LightSamples { wi, dist, radiance, pdf, sampled: U32s::from_bitmask(sampled) }
}

/// Next-event estimation and BSDF sampling of the `group` lanes, at diffuse vertices and
/// at the `glossy` ones among them; returns the lanes whose paths ended (their pending
/// shadow rays still to be traced). The glossy lobes are computed only in rounds that
/// have a glossy lane, and blended in there.
#[inline(always)]
pub(super) fn scatter_vector<I: Isa>(
    scene: &RenderScene,
    g: &mut Group<I>,
    group: u32,
    glossy: u32,
    rays: &mut u64,
) -> u32 {
    use std::f32::consts::FRAC_1_PI;
    let lights = &scene.lights;
    let zero = F32s::splat(0.0);
    let gm = U32s::from_bitmask(group);

    let u_light = next4_lanes(g.seed, g.index, g.draw);
    let u = next4_lanes(g.seed, g.index, g.draw.wrapping_add(U32s::splat(1)));

    // Two-sided: flip the normals to the viewer's side, then the shading frame (the
    // geometric one where the shading normal faces away).
    let wo_world = -g.d;
    let flip = g.ng.dot(wo_world).lt(zero);
    let ng = Vec3s::select(flip, -g.ng, g.ng);
    let ns = Vec3s::select(flip, -g.ns, g.ns);
    let (s1, t1) = frame(ns);
    let wo1 = Vec3s { x: wo_world.dot(s1), y: wo_world.dot(t1), z: wo_world.dot(ns) };
    let (s2, t2) = frame(ng);
    let wo2 = Vec3s { x: wo_world.dot(s2), y: wo_world.dot(t2), z: wo_world.dot(ng) };
    let geo = wo1.z.le(zero);
    let fs = Vec3s::select(geo, s2, s1);
    let ft = Vec3s::select(geo, t2, t1);
    let fn_ = Vec3s::select(geo, ng, ns);
    let wo = Vec3s::select(geo, wo2, wo1);
    let p = g.p;
    let color = g.color;
    let coated = Glossy { alpha: g.alpha, eta: g.eta, color };
    let glossy_mask = U32s::from_bitmask(glossy);
    let seen = (glossy != 0).then(|| coated.seen_from(wo));

    let LightSamples { wi, dist, radiance, pdf: light_pdf, sampled } = if lights.area_only() {
        sample_area_lanes(lights, p, &u_light)
    } else {
        sample_lights_per_lane(lights, p, &u_light, group)
    };

    // The BSDF's value and pdf there.
    let wl = Vec3s { x: wi.dot(fs), y: wi.dot(ft), z: wi.dot(fn_) };
    let above = !(wl.z.le(zero) | wo.z.le(zero));
    let cos_pi = wl.z * F32s::splat(FRAC_1_PI);
    let mut f = Vec3s::select(above, color.scale(cos_pi), Vec3s::default());
    let mut bsdf_pdf = F32s::select(above, cos_pi, zero);
    if let Some(seen) = &seen {
        let (fg, pdf_g) = coated.eval(seen, wl);
        f = Vec3s::select(glossy_mask, fg, f);
        bsdf_pdf = F32s::select(glossy_mask, pdf_g, bsdf_pdf);
    }
    let lit = gm & sampled & !(f.eq(Vec3s::default()) | radiance.eq(Vec3s::default()));

    let origin = offset(p, ng, wi);
    let tmax = F32s::select(
        dist.abs().lt(F32s::splat(f32::INFINITY)),
        (dist * F32s::splat(1.0 - 1e-3)).max(zero),
        F32s::splat(f32::INFINITY),
    );
    let fl = f * radiance;
    let c =
        Vec3s::select(light_pdf.eq(zero), fl, fl.scale(mis_lanes(light_pdf, bsdf_pdf) / light_pdf));
    let mut throughput = g.throughput;
    g.sh_o = Vec3s::select(lit, origin, g.sh_o);
    g.sh_d = Vec3s::select(lit, wi, g.sh_d);
    g.sh_tmax = F32s::select(lit, tmax, g.sh_tmax);
    g.sh_c = Vec3s::select(lit, throughput * c, g.sh_c);
    let lit = lit.bitmask();
    g.shadow |= lit;
    *rays += lit.count_ones() as u64;

    // The continuation (cosine-weighted, or the glossy lobes' choice weighted by their
    // value over their pdf, where that is positive), then Russian roulette.
    let mut alive = !wo.z.le(zero);
    let mut wi = cosine_hemisphere(u[1], u[2]);
    let mut pdf = wi.z * F32s::splat(FRAC_1_PI);
    let mut weight = color;
    if let Some(seen) = &seen {
        let wg = coated.sample(seen, [u[0], u[1], u[2]], wi);
        let (fg, pdf_g) = coated.eval(seen, wg);
        alive = alive & !(glossy_mask & !pdf_g.gt(zero));
        wi = Vec3s::select(glossy_mask, wg, wi);
        pdf = F32s::select(glossy_mask, pdf_g, pdf);
        weight = Vec3s::select(glossy_mask, fg.div_by(pdf_g), weight);
    }
    let dir = fs.scale(wi.x) + ft.scale(wi.y) + fn_.scale(wi.z);
    throughput = throughput * weight;
    let o = offset(p, ng, dir);
    let depth = g.depth.wrapping_add(U32s::splat(1));
    let roulette = depth.gt_i32(U32s::splat(RR_START_DEPTH));
    let rq = throughput.max_element().min(F32s::splat(0.95));
    let killed = roulette & u[3].ge(rq);
    throughput = Vec3s::select(roulette, throughput.div_by(rq), throughput);
    let live: Mask<I> = alive & !killed & !throughput.eq(Vec3s::default());

    g.draw = U32s::select(gm, g.draw.wrapping_add(U32s::splat(2)), g.draw);
    g.throughput = Vec3s::select(gm, throughput, g.throughput);
    g.prev_pdf = F32s::select(gm, pdf, g.prev_pdf);
    g.prev_delta &= !group;
    g.o = Vec3s::select(gm, o, g.o);
    g.d = Vec3s::select(gm, dir, g.d);
    g.depth = U32s::select(gm, depth, g.depth);
    group & !live.bitmask()
}
