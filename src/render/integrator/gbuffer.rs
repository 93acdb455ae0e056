//! The G-buffer probe (a camera ray through each pixel's centre), the emission a pixel
//! sees directly, and picking: one closest hit each, no path.

use glam::{Vec2, Vec3};

use super::path::{albedo_of, closest, Hit};
use super::MIN_ALBEDO;
use crate::render::isa::{Cpu, Isa};
use crate::render::{PixelSample, RenderScene};

/// G-buffer sample through the pixel centre (reflected radiance zero).
pub fn primary_hit(scene: &RenderScene, pixel: u32) -> PixelSample {
    primary_hit_with(Cpu::BASELINE, scene, pixel)
}

#[inline(always)]
pub(super) fn primary_hits_with<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    first: u32,
    out: &mut [PixelSample],
) {
    for (pixel, s) in (first..).zip(out.iter_mut()) {
        *s = primary_hit_with(cpu, scene, pixel);
    }
}

#[inline(always)]
fn primary_hit_with<I: Isa>(cpu: Cpu<I>, scene: &RenderScene, pixel: u32) -> PixelSample {
    let (o, d) = primary_ray(scene, pixel);
    let mut out = PixelSample { albedo: Vec3::ONE, object: u32::MAX, ..Default::default() };
    let hit = closest(cpu, scene, o, d);
    out.emission = seen_emission(scene, &hit, d);
    match hit {
        None => {}
        Some(Hit::Light(q, t)) => {
            out.normal = q.normal;
            out.position = o + d * t;
        }
        Some(Hit::Surface(s)) => {
            out.albedo = albedo_of(s.material, s.uv).max(Vec3::splat(MIN_ALBEDO));
            out.normal = s.ns;
            out.position = s.p;
            out.object = s.object;
        }
    }
    out
}

/// Directly seen emission averaged over `count` points of `pixel`'s square (lens centre):
/// what the pixel's samples see directly on average, where [`primary_hit`] sees its centre
/// only. They differ on a pixel that an emitter's edge crosses, and not by noise: the
/// Cornell box's light, a few pixels tall, came out 2 % too dark at 160×120 and 0.7–1 %
/// too bright at 640×480 from centres alone. The points are a Hammersley set: `count`
/// distinct rows and columns, so that an edge along a row or a column (the light's, seen
/// from the front) is located to 1/`count` of a pixel, where an n×n grid locates it to 1/n
/// (an 8×8 grid still left the light 1.6 % too bright).
pub fn area_emission(scene: &RenderScene, pixel: u32, count: u32) -> Vec3 {
    let width = scene.state().resolution.width.max(1);
    let corner = Vec2::new((pixel % width) as f32, (pixel / width) as f32);
    let count = count.max(1);
    let mut sum = Vec3::ZERO;
    for i in 0..count {
        let x = (i as f32 + 0.5) / count as f32;
        let y = (i.reverse_bits() as f64 / 4_294_967_296.0) as f32 + 0.5 / count as f32;
        let (o, d) = scene.camera.ray(corner + Vec2::new(x, y.min(0.999_999)), Vec2::splat(0.5));
        sum += seen_emission(scene, &closest(Cpu::BASELINE, scene, o, d), d);
    }
    sum / count as f32
}

/// Emission a camera ray along `d` sees at its first hit (the environment if it escapes).
fn seen_emission(scene: &RenderScene, hit: &Option<Hit>, d: Vec3) -> Vec3 {
    match hit {
        None => escaped(scene, d),
        Some(Hit::Light(q, _)) if -d.dot(q.normal) > 0.0 => q.radiance,
        Some(Hit::Surface(s)) if s.material.is_emissive() && -d.dot(s.ng) > 0.0 => {
            s.material.emission_at(s.uv)
        }
        _ => Vec3::ZERO,
    }
}

/// The G-buffer's camera ray through the centre of `pixel` (lens centre for thin lenses).
fn primary_ray(scene: &RenderScene, pixel: u32) -> (Vec3, Vec3) {
    let width = scene.state().resolution.width.max(1);
    let pos = Vec2::new((pixel % width) as f32 + 0.5, (pixel / width) as f32 + 0.5);
    scene.camera.ray(pos, Vec2::splat(0.5))
}

/// Environment and sun radiance along an escaping ray.
fn escaped(scene: &RenderScene, d: Vec3) -> Vec3 {
    scene.lights.escaped(d).iter().map(|e| e.0).sum()
}

/// The emission [`primary_hit`] reports for `pixel` if its ray hits nothing, for
/// G-buffers that find the hits another way (the raster pass).
pub fn escaped_emission(scene: &RenderScene, pixel: u32) -> Vec3 {
    escaped(scene, primary_ray(scene, pixel).1)
}

/// Picking for the window: the object hit by the ray through (x, y) in pixels.
pub fn pick(scene: &RenderScene, x: f32, y: f32) -> Option<u32> {
    let (o, d) = scene.camera.ray(Vec2::new(x, y), Vec2::splat(0.5));
    match closest(Cpu::BASELINE, scene, o, d)? {
        Hit::Surface(s) => Some(s.object),
        Hit::Light(..) => None,
    }
}
