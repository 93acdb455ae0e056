//! The G-buffer probe (a camera ray through each pixel's centre), the emission a pixel
//! sees directly, and picking: one closest hit each, no path. The G-buffer's rays are
//! traced a tile at a time, together (`primary_block_with`), and each hit shaded alone.

use glam::{Vec2, Vec3};

use super::path::{albedo_of, closest, resolve, Hit};
use super::MIN_ALBEDO;
use crate::render::alpha::covering;
use crate::render::isa::{Cpu, Isa};
use crate::render::lanes::{F32s, WIDTH};
use crate::render::{PixelSample, RenderScene};

/// G-buffer sample through the pixel centre (reflected radiance zero).
pub fn primary_hit(scene: &RenderScene, pixel: u32) -> PixelSample {
    let (o, d) = primary_ray(scene, pixel);
    primary_sample(Cpu::BASELINE, scene, o, d, scene.tlas.intersect(o, d, f32::INFINITY))
}

/// Side of the square tiles whose camera rays [`primary_block_with`] traces together:
/// sixteen rays, one per lane.
pub const PRIMARY_TILE: u32 = 4;
const _: () = assert!((PRIMARY_TILE * PRIMARY_TILE) as usize == WIDTH);

/// [`primary_hit`] of the block of pixels `x0..x0 + width` × `y0..y0 + height` (`height`
/// ≤ [`PRIMARY_TILE`]) into `out`, row by row: the camera rays of each tile are made in
/// lanes and traced together (`Tlas::intersect_lanes_with`), then each pixel's hit is
/// shaded alone, as [`primary_hit`] shades it; the same values bit for bit.
#[inline(always)]
pub(super) fn primary_block_with<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    (x0, y0): (u32, u32),
    (width, height): (u32, u32),
    out: &mut [PixelSample],
) {
    debug_assert!(height <= PRIMARY_TILE && out.len() == (width * height) as usize);
    let half = F32s::<I>::splat(0.5);
    for tx in (0..width).step_by(PRIMARY_TILE as usize) {
        let cols = PRIMARY_TILE.min(width - tx);
        let (mut px, mut py) = (F32s::<I>::splat(0.0), F32s::<I>::splat(0.0));
        let mut active = 0u32;
        for l in 0..WIDTH {
            let (col, row) = (l as u32 % PRIMARY_TILE, l as u32 / PRIMARY_TILE);
            let inside = col < cols && row < height;
            active |= u32::from(inside) << l;
            // Lanes past the block's edge make the tile's first ray again, unused.
            let (col, row) = if inside { (col, row) } else { (0, 0) };
            // As `primary_ray`: the pixel's centre.
            px.0[l] = (x0 + tx + col) as f32 + 0.5;
            py.0[l] = (y0 + row) as f32 + 0.5;
        }
        let (o, d) = scene.camera.ray_lanes((px, py), (half, half));
        let hits = scene.tlas.intersect_lanes_with(cpu, &o, &d, active);
        for (l, hit) in hits.into_iter().enumerate().filter(|(l, _)| active & (1 << l) != 0) {
            let (col, row) = (l as u32 % PRIMARY_TILE, l as u32 / PRIMARY_TILE);
            let i = (row * width + tx + col) as usize;
            out[i] = primary_sample(cpu, scene, o.lane(l), d.lane(l), hit);
        }
    }
}

/// The G-buffer values of the camera ray `(o, d)` whose closest geometry hit is `hit`
/// (surfaces that let the ray through are passed, tracing on with `cpu`).
#[inline(always)]
fn primary_sample<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    o: Vec3,
    d: Vec3,
    hit: Option<crate::render::accel::Hit>,
) -> PixelSample {
    let mut out = PixelSample { albedo: Vec3::ONE, object: u32::MAX, ..Default::default() };
    let hit = resolve(scene, o, d, covering(cpu, scene, (o, d, f32::INFINITY), hit));
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
