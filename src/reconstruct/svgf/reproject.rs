//! Motion vectors and reprojection: where each pixel's primary hit was in the previous
//! frame, and the accumulated history carried there.
//!
//! The master knows both scene states, so nothing is estimated: a pixel's hit point is
//! taken back through its object's motion (previous object-to-world times the inverse of
//! the current one; the identity for objects that did not move) and projected with the
//! previous camera. The history of the four previous pixels around that point is
//! interpolated bilinearly, each tap kept only where the previous G-buffer saw the same
//! object there, with a normal that agrees and on the pixel's tangent plane (the
//! discontinuity test of the filters, so that disoccluded pixels start empty rather than
//! inherit a foreground's light). What is kept counts for at most a few samples: new
//! samples soon outweigh shading that depends on the view or on an edit.

use std::collections::HashMap;

use glam::{Mat4, Vec2, Vec3, Vec4};
use gridlight_actors::state::SceneState;

use crate::gbuffer::{GBuffer, NO_OBJECT};
use crate::reconstruct::discontinuity::is_surface;
use crate::reconstruct::rows::{run_rows, RowKernel};
use crate::render::camera::CameraRays;
use crate::render::isa::Isa;

/// A pixel's accumulated history: demodulated samples and their luminance moments.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    /// rgb: sum of samples; w: their number (as the paper's accumulation keeps it).
    pub sum: Vec4,
    /// Σ luminance, Σ luminance² of the same samples.
    pub lum: Vec2,
}

impl Moments {
    /// Adds one sample.
    #[inline]
    pub fn add(&mut self, v: Vec3) {
        let l = luminance(v);
        self.sum += v.extend(1.0);
        self.lum += Vec2::new(l, l * l);
    }

    /// The same mean and variance, counting for at most `samples`.
    #[inline]
    fn capped(self, samples: f32) -> Self {
        if self.sum.w <= samples {
            return self;
        }
        let k = samples / self.sum.w;
        Self { sum: self.sum * k, lum: self.lum * k }
    }
}

/// Rec. 709 luminance.
#[inline]
pub fn luminance(v: Vec3) -> f32 {
    v.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// How the previous frame's pixels map to this frame's.
#[derive(Clone, Debug)]
pub struct Motion {
    /// The previous camera, or `None` when no scene states are known: then nothing moved
    /// and each pixel maps to itself.
    camera: Option<Projection>,
    /// Per current object index: current-world to previous-world, and the object's index
    /// in the previous state; `None` for an object the previous state did not have.
    objects: Vec<Option<(Mat4, u32)>>,
    /// Whether materials, lights, the environment or the path settings changed.
    pub lighting_changed: bool,
}

impl Motion {
    /// Nothing moved and nothing changed (the same view, no states known).
    pub fn still(objects: usize) -> Self {
        Self {
            camera: None,
            objects: (0..objects as u32).map(|i| Some((Mat4::IDENTITY, i))).collect(),
            lighting_changed: false,
        }
    }

    /// From `prev` to `cur`; `None` when the previous camera cannot project (then the
    /// history is dropped).
    pub fn between(prev: &SceneState, cur: &SceneState) -> Option<Self> {
        let camera = Projection::new(prev)?;
        let by_name: HashMap<&str, usize> =
            prev.objects.iter().enumerate().map(|(i, o)| (o.name.as_str(), i)).collect();
        let objects = cur
            .objects
            .iter()
            .map(|o| {
                let &i = by_name.get(o.name.as_str())?;
                let p = &prev.objects[i];
                (p.geometry == o.geometry && p.visible && o.visible)
                    .then(|| (p.transform.matrix() * o.transform.matrix().inverse(), i as u32))
            })
            .collect();
        let material_slots = prev.objects.len() != cur.objects.len()
            || prev.objects.iter().zip(&cur.objects).any(|(a, b)| a.materials != b.materials);
        let lighting_changed = prev.materials != cur.materials
            || prev.lights != cur.lights
            || prev.environment != cur.environment
            || prev.render.max_depth != cur.render.max_depth
            || material_slots;
        Some(Self { camera: Some(camera), objects, lighting_changed })
    }
}

impl Motion {
    /// The previous camera for the GPU twin (`shaders/reconstruct/svgf/reproject.wgsl`):
    /// origin | half_w, forward | half_h, right | width, up | height.
    pub fn camera_vectors(&self) -> Option<[Vec4; 4]> {
        self.camera.map(|c| {
            let r = &c.rays;
            [
                r.origin.extend(r.half_w),
                r.forward.extend(r.half_h),
                r.right.extend(c.width),
                r.up.extend(c.height),
            ]
        })
    }

    /// Per current object index: current-world to previous-world and its previous index.
    pub fn objects(&self) -> &[Option<(Mat4, u32)>] {
        &self.objects
    }

    /// Whether the light may have changed: an edit of the lighting, or an object that
    /// moved (its shadow and light bounced off it moved too). The camera alone changes
    /// only view-dependent shading.
    pub fn relights(&self) -> bool {
        let moved = |o: &Option<(Mat4, u32)>| {
            o.as_ref().is_none_or(|(m, _)| !m.abs_diff_eq(Mat4::IDENTITY, 1e-5))
        };
        self.lighting_changed || self.objects.iter().any(moved)
    }
}

/// A pinhole projection of world points to image positions in pixels (y down), the
/// inverse of the G-buffer's primary rays through pixel centres (`render::camera`).
#[derive(Clone, Copy, Debug)]
struct Projection {
    rays: CameraRays,
    width: f32,
    height: f32,
}

impl Projection {
    fn new(state: &SceneState) -> Option<Self> {
        let rays = CameraRays::new(&state.camera, state.resolution).ok()?;
        let res = state.resolution;
        Some(Self { rays, width: res.width as f32, height: res.height as f32 })
    }

    /// The image position of world point `p`, or `None` behind the camera.
    #[inline]
    fn project(&self, p: Vec3) -> Option<Vec2> {
        let r = &self.rays;
        let v = p - r.origin;
        let depth = v.dot(r.forward);
        if depth <= 1e-6 {
            return None;
        }
        let x = v.dot(r.right) / (depth * r.half_w);
        let y = v.dot(r.up) / (depth * r.half_h);
        Some(Vec2::new((x + 1.0) * 0.5 * self.width, (1.0 - y) * 0.5 * self.height))
    }

    /// The world size of a pixel at point `p`.
    #[inline]
    fn footprint(&self, p: Vec3) -> f32 {
        (p - self.rays.origin).length() * 2.0 * self.rays.half_h / self.height
    }
}

/// The previous frame's G-buffer planes that reprojection compares against.
#[derive(Debug, Default)]
pub struct PreviousGuide {
    pub normal: Vec<Vec3>,
    pub position: Vec<Vec3>,
    pub object: Vec<u32>,
}

impl PreviousGuide {
    /// Keeps `g`'s planes (reusing the buffers).
    pub fn keep(&mut self, g: &GBuffer) {
        self.normal.clone_from(&g.normal);
        self.position.clone_from(&g.position);
        self.object.clone_from(&g.object);
    }
}

/// Normals closer than this (cosine) count as the same surface.
const SAME_NORMAL: f32 = 0.9;
/// A previous hit farther than this many pixel footprints from the pixel's tangent plane
/// (or from the point itself, without a camera) is another surface.
const SAME_PLANE_PIXELS: f32 = 2.0;
/// Without a camera (nothing moved): the tolerance off the plane, in scene scales.
pub const STILL_PLANE: f32 = 0.01;
/// Bilinear weight below which a reprojected pixel starts empty.
const MIN_WEIGHT: f32 = 1e-3;

/// Carries `history` (the previous frame's pixels) to this frame's pixels in `out`,
/// counting each for at most `cap` samples.
pub fn reproject(
    motion: &Motion,
    prev: &PreviousGuide,
    history: &[Moments],
    g: &GBuffer,
    cap: f32,
    out: &mut [Moments],
) {
    let (w, h) = (g.width as usize, g.height as usize);
    assert!(prev.normal.len() == w * h && history.len() == w * h && out.len() == w * h);
    let kernel = Reproject { motion, prev, history, g, cap, width: w, height: h };
    run_rows(&kernel, out.chunks_mut(w).enumerate().collect());
}

struct Reproject<'a> {
    motion: &'a Motion,
    prev: &'a PreviousGuide,
    history: &'a [Moments],
    g: &'a GBuffer,
    cap: f32,
    width: usize,
    height: usize,
}

impl RowKernel<&mut [Moments]> for Reproject<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, out: &mut [Moments], _: &mut ()) {
        for (x, o) in out.iter_mut().enumerate() {
            *o = self.pixel(x, y).map_or(Moments::default(), |m| m.capped(self.cap));
        }
    }
}

impl Reproject<'_> {
    /// The reprojected history of pixel (x, y), if any of it is the same surface.
    #[inline(always)]
    fn pixel(&self, x: usize, y: usize) -> Option<Moments> {
        let i = y * self.width + x;
        let (n, p, object) = (self.g.normal[i], self.g.position[i], self.g.object[i]);
        if !is_surface(n) || object == NO_OBJECT {
            return None;
        }
        let &(to_prev, prev_object) = self.motion.objects.get(object as usize)?.as_ref()?;
        let (p, n) = (to_prev.transform_point3(p), to_prev.transform_vector3(n).normalize());
        // The image position (pixel centres at +0.5) and the tolerance off the plane.
        let (at, tolerance) = match &self.motion.camera {
            Some(cam) => (cam.project(p)?, SAME_PLANE_PIXELS * cam.footprint(p)),
            None => (Vec2::new(x as f32 + 0.5, y as f32 + 0.5), STILL_PLANE * self.g.scene_scale),
        };
        let f = at - Vec2::splat(0.5);
        let (x0, y0) = (f.x.floor(), f.y.floor());
        let (fx, fy) = (f.x - x0, f.y - y0);
        let mut acc = (Vec4::ZERO, Vec2::ZERO, 0.0);
        for (dx, dy, wgt) in
            [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy)]
                .into_iter()
                .chain([(1, 1, fx * fy)])
        {
            let (tx, ty) = (x0 as i64 + dx, y0 as i64 + dy);
            if wgt <= 0.0 || tx < 0 || ty < 0 || tx >= self.width as i64 || ty >= self.height as i64
            {
                continue;
            }
            let j = ty as usize * self.width + tx as usize;
            let same = self.prev.object[j] == prev_object
                && self.prev.normal[j].dot(n) > SAME_NORMAL
                && (self.prev.position[j] - p).dot(n).abs() <= tolerance;
            if same {
                let m = self.history[j];
                acc = (acc.0 + m.sum * wgt, acc.1 + m.lum * wgt, acc.2 + wgt);
            }
        }
        (acc.2 > MIN_WEIGHT).then(|| Moments { sum: acc.0 / acc.2, lum: acc.1 / acc.2 })
    }
}
