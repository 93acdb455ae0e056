//! The steps of one camera path, shared by the stream kernel's lanes and the one-path
//! reference: trace a ray (with the last vertex's shadow ray), arrive at what it hit
//! (emission, G-buffer), scatter on (next-event estimation, BSDF sampling, roulette).

use glam::{Vec2, Vec3};

use super::nee::{next_event, ShadowRay};
use super::{MIN_ALBEDO, RR_START_DEPTH};
use crate::assets::{Lookup, Mesh};
use crate::render::alpha::{covering, still_blocked, Found};
use crate::render::isa::{Cpu, Isa};
use crate::render::lights::AreaLight;
use crate::render::microfacet::Frame;
use crate::render::normal_map::{bend, triangle_tangents};
use crate::render::sampler::SampleStream;
use crate::render::{MaterialData, PixelSample, RenderScene};

/// What a ray hit.
pub(super) enum Hit<'a> {
    Surface(Surface<'a>),
    Light(&'a AreaLight, f32),
}

/// A resolved surface hit in world space.
pub(in crate::render) struct Surface<'a> {
    pub(in crate::render) p: Vec3,
    /// Unit geometric normal on the triangle's front (winding) side.
    pub(in crate::render) ng: Vec3,
    /// Unit shading normal, on the same side as `ng`.
    pub(in crate::render) ns: Vec3,
    /// Texture coordinates; zero unless the material is textured.
    pub(in crate::render) uv: Vec2,
    pub(in crate::render) material: &'a MaterialData,
    pub(in crate::render) object: u32,
}

#[inline(always)]
pub(super) fn closest<'a, I: Isa>(
    cpu: Cpu<I>,
    scene: &'a RenderScene,
    o: Vec3,
    d: Vec3,
) -> Option<Hit<'a>> {
    let first = scene.tlas.intersect_with(cpu, o, d, f32::INFINITY);
    resolve(scene, o, d, covering(cpu, scene, (o, d, f32::INFINITY), first))
}

/// Texture coordinates of a hit on the triangle of vertices `idx` of `mesh` (which has
/// them).
#[inline(always)]
pub(in crate::render) fn interpolate_uv(
    mesh: &Mesh,
    idx: [u32; 3],
    hit: &crate::render::accel::Hit,
) -> Vec2 {
    let (u, v) = (hit.u, hit.v);
    let w = 1.0 - u - v;
    let [a, b, c] = idx.map(|i| mesh.uvs[i as usize]);
    a * w + b * u + c * v
}

/// What the ray `o + t d` reaches given the geometry's closest covering hit (`found`): an
/// area light in front of it, or the hit surface with its shading data.
#[inline(always)]
pub(super) fn resolve<'a>(
    scene: &'a RenderScene,
    o: Vec3,
    d: Vec3,
    found: Found,
) -> Option<Hit<'a>> {
    let Found { hit, from } = found;
    // The hit's distance from `o` (it was found from `from` if the ray passed a cut-out).
    let along = |t: f32| if from == o { t } else { t + (from - o).dot(d) / d.length_squared() };
    let mut tmax = hit.map_or(f32::INFINITY, |h| along(h.t));
    let mut light = None;
    for q in scene.lights.quads() {
        let edges =
            crate::render::accel::TriEdges { v0: q.v0.into(), e1: q.e1.into(), e2: q.e2.into() };
        if let Some((t, ..)) = edges.intersect_parallelogram(o.into(), d.into(), tmax) {
            tmax = t;
            light = Some(q);
        }
    }
    if let Some(q) = light {
        return Some(Hit::Light(q, tmax));
    }
    let hit = hit?;
    let inst = &scene.tlas.instances[hit.instance as usize];
    let blas = &*inst.blas;
    let leaf = blas.leaf(hit.prim);
    let mesh = &*blas.mesh;
    let material_id = scene.slot_materials[(inst.material_base + leaf.slot) as usize];
    let material = &scene.materials[material_id as usize];
    let (u, v) = (hit.u, hit.v);
    let w = 1.0 - u - v;
    let ng = scene.tlas.geometric_normal(&hit);
    // Vertex data is read only where it can change the result.
    let idx = (!leaf.flat || material.textured()).then(|| mesh.indices[leaf.original as usize]);
    let mut ns = match idx {
        Some(idx) if !leaf.flat => {
            let [a, b, c] = idx.map(|i| mesh.normals[i as usize]);
            inst.normal_to_world.mul_vec3(a * w + b * u + c * v).normalize_or(ng)
        }
        _ => ng,
    };
    if ns.dot(ng) < 0.0 {
        ns = -ns;
    }
    let uv = match idx {
        Some(idx) if material.textured() && !mesh.uvs.is_empty() => interpolate_uv(mesh, idx, &hit),
        _ => Vec2::ZERO,
    };
    if let (Some(map), Some(idx)) = (&material.normal_map, idx) {
        if !mesh.uvs.is_empty() {
            let positions = idx.map(|i| mesh.positions[i as usize]);
            // A transformed map's tangents follow its transformed coordinates.
            let lookup = material.lookups.normal.as_ref();
            let uvs = idx.map(|i| Lookup::transform(lookup, mesh.uvs[i as usize]));
            if let Some(frame) = triangle_tangents(positions, uvs, &inst.object_to_world) {
                ns = bend(map, lookup, material.normal_scale, uv, ns, ng, frame);
            }
        }
    }
    Some(Hit::Surface(Surface { p: from + d * hit.t, ng, ns, uv, material, object: inst.object }))
}

/// Offsets a ray origin off the surface to the side `dir` leaves towards (public for the
/// stage benchmarks, which cast the kernel's rays).
#[inline]
pub fn offset(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    let eps = 1e-4 * (1.0 + p.abs().max_element());
    if ng.dot(dir) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}

/// Power heuristic with β = 2.
#[inline]
pub(super) fn mis(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

#[inline]
pub(super) fn albedo_of(material: &MaterialData, uv: Vec2) -> Vec3 {
    match &material.texture {
        Some(t) => t.sample_with(uv, material.lookups.base_color.as_ref()) * material.base_color,
        None => material.base_color,
    }
}

/// What a camera path carries from one vertex to the next (besides its ray).
#[derive(Clone, Copy, Debug)]
pub(in crate::render) struct PathState {
    pub(in crate::render) stream: SampleStream,
    pub(in crate::render) throughput: Vec3,
    pub(in crate::render) indirect: Vec3,
    pub(in crate::render) prev_pdf: f32,
    /// Whether the previous bounce was a delta choice (the camera ray counts as one).
    pub(in crate::render) prev_delta: bool,
    /// Segments so far, the one being traced included.
    pub(in crate::render) depth: u32,
}

impl PathState {
    /// A path whose camera ray is being traced.
    #[inline(always)]
    pub(in crate::render) fn start(stream: SampleStream) -> Self {
        Self {
            stream,
            throughput: Vec3::ONE,
            indirect: Vec3::ZERO,
            prev_pdf: 0.0,
            prev_delta: true,
            depth: 1,
        }
    }
}

/// The G-buffer values of a path before its first vertex.
pub(in crate::render) const EMPTY_SAMPLE: PixelSample = PixelSample {
    reflected: Vec3::ZERO,
    emission: Vec3::ZERO,
    albedo: Vec3::ONE,
    normal: Vec3::ZERO,
    position: Vec3::ZERO,
    object: u32::MAX,
};

/// The closest covering hit of the ray `(o, d)`; a pending `shadow` ray is traced together
/// with it (the two walks in turns) and its contribution added to `indirect` unless
/// blocked.
#[inline(always)]
pub(in crate::render) fn trace<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    (o, d): (Vec3, Vec3),
    shadow: Option<ShadowRay>,
    indirect: &mut Vec3,
) -> Found {
    let ray = (o, d, f32::INFINITY);
    let Some(s) = shadow else {
        return covering(cpu, scene, ray, scene.tlas.intersect_with(cpu, o, d, f32::INFINITY));
    };
    let shadow_ray = (s.origin, s.dir, s.tmax);
    let (hit, blocked) = scene.tlas.intersect_and_occluded_with(cpu, ray, shadow_ray);
    if !blocked || !still_blocked(cpu, scene, shadow_ray) {
        *indirect += s.contribution;
    }
    covering(cpu, scene, ray, hit)
}

/// What the ray `(o, d)` `found` (the geometry's closest covering hit): adds the emission it
/// reached, MIS-weighted against light sampling unless the previous bounce could not have
/// sampled a light, and records the G-buffer at the first vertex. Returns the surface and
/// its albedo where the path scatters on; `None` when it ends.
#[inline(always)]
pub(in crate::render) fn arrive<'a>(
    scene: &'a RenderScene,
    path: &mut PathState,
    (o, d): (Vec3, Vec3),
    found: Found,
    max_depth: u32,
    nee: bool,
    out: &mut PixelSample,
) -> Option<(Surface<'a>, Vec3)> {
    let lights = &scene.lights;
    let emit = |radiance: Vec3, light_pdf: f32, path: &mut PathState, out: &mut PixelSample| {
        if path.depth == 1 {
            out.emission += radiance;
        } else {
            let w = if path.prev_delta || !nee { 1.0 } else { mis(path.prev_pdf, light_pdf) };
            path.indirect += path.throughput * radiance * w;
        }
    };
    let surface = match resolve(scene, o, d, found) {
        None => {
            for (radiance, pdf) in lights.escaped(d) {
                if radiance != Vec3::ZERO {
                    emit(radiance, pdf, path, out);
                }
            }
            return None;
        }
        Some(Hit::Light(q, t)) => {
            let cos = -d.dot(q.normal);
            if cos > 0.0 {
                emit(q.radiance, lights.area_pdf(q.radiance, t * t, cos), path, out);
            }
            if path.depth == 1 {
                out.normal = q.normal;
                out.position = o + d * t;
            }
            return None;
        }
        Some(Hit::Surface(s)) => s,
    };
    let material = surface.material;
    if material.is_emissive() {
        let cos = (-d).dot(surface.ng);
        if cos > 0.0 {
            let pdf = if material.is_sampled_light() {
                let dist2 = (surface.p - o).length_squared();
                lights.area_pdf(material.emission, dist2, cos)
            } else {
                0.0
            };
            emit(material.emission_at(surface.uv), pdf, path, out);
        }
    }
    let albedo = albedo_of(material, surface.uv);
    if path.depth == 1 {
        out.albedo = albedo.max(Vec3::splat(MIN_ALBEDO));
        out.normal = surface.ns;
        out.position = surface.p;
        out.object = surface.object;
    }
    (path.depth < max_depth).then_some((surface, albedo))
}

/// Next-event estimation (its shadow ray returned, to be traced) and BSDF sampling at
/// `surface`, reached along `d`: moves the ray `(o, d)` on and says whether the path
/// lives.
#[inline(always)]
pub(in crate::render) fn scatter(
    scene: &RenderScene,
    path: &mut PathState,
    (o, d): (&mut Vec3, &mut Vec3),
    surface: &Surface,
    albedo: Vec3,
    nee: bool,
    rays: &mut u64,
) -> (bool, Option<ShadowRay>) {
    let material = surface.material;
    let wo_world = -*d;
    let bsdf = material.bsdf(albedo, surface.uv);
    let (mut ng, mut ns) = (surface.ng, surface.ns);
    if bsdf.two_sided() && ng.dot(wo_world) < 0.0 {
        ng = -ng;
        ns = -ns;
    }
    let mut frame = Frame::new(ns);
    let mut wo = frame.to_local(wo_world);
    if bsdf.two_sided() && wo.z <= 0.0 {
        // The shading normal faces away from the viewer: fall back to geometry.
        frame = Frame::new(ng);
        wo = frame.to_local(wo_world);
    }

    // Next-event estimation; its random numbers are drawn either way, so that the
    // stream's indices do not depend on the strategy or the material.
    let u_light = path.stream.next4();
    let mut shadow = None;
    if nee && !bsdf.is_delta() {
        let u = [u_light[0], u_light[1], u_light[2]];
        shadow = next_event(scene, &bsdf, (&frame, wo), (surface.p, ng), u, rays)
            .map(|s| ShadowRay { contribution: path.throughput * s.contribution, ..s });
    }

    // Continue the path by sampling the BSDF.
    let u = path.stream.next4();
    let Some(sample) = bsdf.sample(wo, [u[0], u[1], u[2]]) else { return (false, shadow) };
    let wi = frame.to_world(sample.wi);
    path.throughput *= sample.weight;
    path.prev_pdf = sample.pdf;
    path.prev_delta = sample.delta;
    *o = offset(surface.p, ng, wi);
    *d = wi;
    path.depth += 1;
    if path.depth > RR_START_DEPTH {
        let q = path.throughput.max_element().min(0.95);
        if u[3] >= q {
            return (false, shadow);
        }
        path.throughput /= q;
    }
    (path.throughput != Vec3::ZERO, shadow)
}
