//! Alpha coverage (glTF's `alphaMode`): surfaces that let rays through. A `Mask`
//! material is absent where its coverage (alpha factor × base colour map alpha) is below
//! its cutoff; a `Blend` material lets a ray through with probability 1 − coverage, camera,
//! bounce and shadow rays alike, which is blending's mean in a path tracer.
//!
//! A ray that reaches such a surface and passes goes on from it (the traversal has no
//! any-hit filter; the surface is left as a bounce leaves it, [`offset`]), so what a ray
//! finds does not depend on the order a traversal meets its triangles. The blend choice
//! is a hash of the ray's origin and direction bits and the triangle's (instance, prim),
//! not a draw from the path's sample stream: every kernel (the one-path reference, the
//! stream kernel's lanes, the G-buffer) makes the same choice for the same ray, and a
//! shadow ray, which has no stream, makes one too.
//!
//! Opaque scenes pay nothing: [`RenderScene::cutouts`] is false and hits are taken as
//! the traversal found them; in a scene with cut-outs a material's
//! [`MaterialData::cutout`] is checked before any texture lookup.

use glam::{Vec2, Vec3};
use gridlight_actors::state::AlphaMode;

use super::accel::Hit;
use super::integrator::offset;
use super::isa::{Cpu, Isa};
use super::sampler::to_unit;
use super::{MaterialData, RenderScene};

/// Surfaces a ray may pass before the next is taken as covering it whatever its alpha
/// (a stack of cut-outs deeper than any real scene's; it bounds the loop).
const MAX_PASSES: u32 = 64;

/// Whether some hit on `m` can let a ray through.
pub fn can_let_through(m: &MaterialData) -> bool {
    let mapped = m.texture.as_ref().is_some_and(|t| t.alpha.is_some());
    match m.alpha_mode {
        AlphaMode::Opaque => false,
        AlphaMode::Mask => mapped || m.alpha < m.alpha_cutoff,
        AlphaMode::Blend => mapped || m.alpha < 1.0,
    }
}

/// Coverage of `m` at texture coordinates `uv`: its alpha times its base colour map's.
#[inline(always)]
pub fn coverage(m: &MaterialData, uv: Vec2) -> f32 {
    match &m.texture {
        Some(t) => m.alpha * t.sample_alpha(uv, m.lookups.base_color.as_ref()),
        None => m.alpha,
    }
}

/// Whether the ray `(o, d)` passes `m` at `uv` where it meets triangle `(instance, prim)`.
#[inline(always)]
pub fn lets_through(m: &MaterialData, uv: Vec2, (o, d): (Vec3, Vec3), triangle: [u32; 2]) -> bool {
    match m.alpha_mode {
        AlphaMode::Opaque => false,
        AlphaMode::Mask => coverage(m, uv) < m.alpha_cutoff,
        AlphaMode::Blend => to_unit(ray_hash(o, d, triangle)) >= coverage(m, uv),
    }
}

/// What a ray found: its closest hit past the surfaces that let it through, and the
/// origin of the segment that hit was found on (the ray's own unless it passed one).
#[derive(Clone, Copy, Debug)]
pub struct Found {
    pub hit: Option<Hit>,
    pub from: Vec3,
}

/// The first hit covering the ray `(o, d)` within `tmax`, given the traversal's closest
/// `hit` from `o`: surfaces that let the ray through are passed.
#[inline(always)]
pub(super) fn covering<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    (o, d, tmax): (Vec3, Vec3, f32),
    mut hit: Option<Hit>,
) -> Found {
    let mut from = o;
    if !scene.cutouts {
        return Found { hit, from };
    }
    for _ in 0..MAX_PASSES {
        let Some(h) = hit else { break };
        let Some(next) = passed(scene, (o, d), from, &h) else { break };
        from = next;
        let left = tmax - (from - o).dot(d) / d.length_squared();
        if left <= 0.0 {
            return Found { hit: None, from };
        }
        hit = scene.tlas.intersect_with(cpu, from, d, left);
    }
    Found { hit, from }
}

/// Whether a shadow ray `(o, d)` up to `tmax` that an any-hit traversal found blocked is
/// still blocked once surfaces that let it through are passed.
#[inline(always)]
pub(super) fn still_blocked<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    (o, d, tmax): (Vec3, Vec3, f32),
) -> bool {
    if !scene.cutouts {
        return true;
    }
    let first = scene.tlas.intersect_with(cpu, o, d, tmax);
    covering(cpu, scene, (o, d, tmax), first).hit.is_some()
}

/// Where the ray `(o, d)`, on its segment from `from`, goes on past hit `h` if the
/// surface lets it through.
#[inline(always)]
fn passed(scene: &RenderScene, (o, d): (Vec3, Vec3), from: Vec3, h: &Hit) -> Option<Vec3> {
    let inst = &scene.tlas.instances[h.instance as usize];
    let leaf = inst.blas.leaf(h.prim);
    let material_id = scene.slot_materials[(inst.material_base + leaf.slot) as usize];
    let material = &scene.materials[material_id as usize];
    if !material.cutout {
        return None;
    }
    let mesh = &*inst.blas.mesh;
    let uv = match &material.texture {
        Some(_) if !mesh.uvs.is_empty() => {
            super::integrator::interpolate_uv(mesh, mesh.indices[leaf.original as usize], h)
        }
        _ => Vec2::ZERO,
    };
    if !lets_through(material, uv, (o, d), [h.instance, h.prim]) {
        return None;
    }
    Some(offset(from + d * h.t, scene.tlas.geometric_normal(h), d))
}

/// A 32-bit hash of a ray's bits and a triangle (murmur3's finaliser after each word).
#[inline(always)]
fn ray_hash(o: Vec3, d: Vec3, [instance, prim]: [u32; 2]) -> u32 {
    let words = [o.x, o.y, o.z, d.x, d.y, d.z].map(f32::to_bits);
    let mut h = 0x9e37_79b9u32;
    for w in words.into_iter().chain([instance, prim]) {
        h = fmix(h ^ w).rotate_left(13).wrapping_mul(5).wrapping_add(0xe654_6b64);
    }
    fmix(h)
}

#[inline(always)]
fn fmix(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

#[cfg(test)]
mod tests;
