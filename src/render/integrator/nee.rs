//! Next-event estimation: one light sample at a path vertex, weighted against the BSDF
//! by multiple importance sampling, and the shadow ray that decides whether it counts.

use glam::Vec3;

use super::path::{mis, offset};
use crate::render::bsdf::Bsdf;
use crate::render::isa::{Cpu, Isa};
use crate::render::microfacet::Frame;
use crate::render::RenderScene;

/// A light sample's contribution, to be added unless its shadow ray is blocked.
#[derive(Clone, Copy, Debug)]
pub(in crate::render) struct ShadowRay {
    pub(in crate::render) contribution: Vec3,
    pub(in crate::render) origin: Vec3,
    pub(in crate::render) dir: Vec3,
    pub(in crate::render) tmax: f32,
}

impl ShadowRay {
    /// Traces this shadow ray alone (its path has no next ray to go with): adds its
    /// contribution to `indirect` unless blocked.
    #[inline(always)]
    pub(in crate::render) fn settle<I: Isa>(
        &self,
        cpu: Cpu<I>,
        scene: &RenderScene,
        indirect: &mut Vec3,
    ) {
        let ray = (self.origin, self.dir, self.tmax);
        if !scene.tlas.occluded_with(cpu, ray.0, ray.1, ray.2)
            || !crate::render::alpha::still_blocked(cpu, scene, ray)
        {
            *indirect += self.contribution;
        }
    }
}

/// Next-event estimation at a surface point `at` = (position, geometric normal), seen
/// along `wo` in the shading `frame`: one light sample, MIS-weighted against the BSDF,
/// and the shadow ray (counted in `rays`) that decides whether it counts; `None` when
/// it adds nothing. The contribution still has to be multiplied by the path throughput.
#[inline(always)]
pub(super) fn next_event(
    scene: &RenderScene,
    bsdf: &Bsdf,
    (frame, wo): (&Frame, Vec3),
    (p, ng): (Vec3, Vec3),
    u: [f32; 3],
    rays: &mut u64,
) -> Option<ShadowRay> {
    let ls = scene.lights.sample(p, u)?;
    let (f, bsdf_pdf) = bsdf.eval(wo, frame.to_local(ls.wi));
    if f == Vec3::ZERO || ls.radiance == Vec3::ZERO {
        return None;
    }
    let origin = offset(p, ng, ls.wi);
    let tmax = if ls.dist.is_finite() { (ls.dist * (1.0 - 1e-3)).max(0.0) } else { f32::INFINITY };
    *rays += 1;
    let contribution = if ls.pdf == 0.0 {
        f * ls.radiance
    } else {
        f * ls.radiance * (mis(ls.pdf, bsdf_pdf) / ls.pdf)
    };
    Some(ShadowRay { contribution, origin, dir: ls.wi, tmax })
}
