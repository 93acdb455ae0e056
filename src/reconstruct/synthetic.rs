//! Analytic test inputs: a G-buffer of a few planes and spheres ray-cast exactly, and
//! noisy demodulated radiance over it, deterministic per (seed, frame, pixel).
//!
//! Used by the tests and the benchmark where no path tracer is needed: the geometry has
//! depth and orientation edges in known places, which is what the filters must respect.

use glam::Vec3;

use crate::gbuffer::{GBuffer, NO_OBJECT};

/// A camera at `eye` looking down −z (towards the origin), 45° vertical field of view.
#[derive(Clone, Copy, Debug)]
pub struct SyntheticView {
    pub eye: Vec3,
}

impl Default for SyntheticView {
    fn default() -> Self {
        Self { eye: Vec3::new(0.0, 0.2, 4.0) }
    }
}

enum Shape {
    /// Plane through `point` with unit `normal`.
    Plane {
        point: Vec3,
        normal: Vec3,
    },
    Sphere {
        centre: Vec3,
        radius: f32,
    },
}

/// Floor, back wall and left wall of the box [-1, 1]³ and two spheres inside it.
fn shapes() -> [(Shape, Vec3, Vec3); 5] {
    [
        (
            Shape::Plane { point: Vec3::new(0.0, -1.0, 0.0), normal: Vec3::Y },
            Vec3::splat(0.8),
            Vec3::ZERO,
        ),
        (
            Shape::Plane { point: Vec3::new(0.0, 0.0, -1.0), normal: Vec3::Z },
            Vec3::new(0.7, 0.7, 0.6),
            Vec3::ZERO,
        ),
        (
            Shape::Plane { point: Vec3::new(-1.0, 0.0, 0.0), normal: Vec3::X },
            Vec3::new(0.6, 0.1, 0.1),
            Vec3::ZERO,
        ),
        (
            Shape::Sphere { centre: Vec3::new(-0.35, -0.6, -0.2), radius: 0.4 },
            Vec3::new(0.2, 0.5, 0.8),
            Vec3::ZERO,
        ),
        (
            Shape::Sphere { centre: Vec3::new(0.45, 0.3, -0.5), radius: 0.3 },
            Vec3::ONE,
            Vec3::new(4.0, 3.5, 3.0),
        ),
    ]
}

fn intersect(shape: &Shape, o: Vec3, d: Vec3) -> Option<(f32, Vec3)> {
    match *shape {
        Shape::Plane { point, normal } => {
            let den = d.dot(normal);
            if den.abs() < 1e-6 {
                return None;
            }
            let t = (point - o).dot(normal) / den;
            // The walls are the faces of the box [-1, 1]³.
            let inside = (o + d * t).abs().max_element() <= 1.0 + 1e-4;
            (t > 1e-4 && inside).then_some((t, normal))
        }
        Shape::Sphere { centre, radius } => {
            let oc = o - centre;
            let b = oc.dot(d);
            let disc = b * b - (oc.dot(oc) - radius * radius);
            if disc < 0.0 {
                return None;
            }
            let t = -b - disc.sqrt();
            (t > 1e-4).then(|| (t, (o + d * t - centre) / radius))
        }
    }
}

/// The G-buffer of the analytic scene seen from `view` (scene scale 1).
pub fn gbuffer(width: u32, height: u32, view: SyntheticView) -> GBuffer {
    let mut g = GBuffer::empty(width, height, 1.0);
    let scene = shapes();
    let aspect = width as f32 / height as f32;
    let tan = (45f32.to_radians() * 0.5).tan();
    let forward = (Vec3::ZERO - view.eye).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    for y in 0..height {
        for x in 0..width {
            let i = (y * width + x) as usize;
            let u = ((x as f32 + 0.5) / width as f32 * 2.0 - 1.0) * tan * aspect;
            let v = (1.0 - (y as f32 + 0.5) / height as f32 * 2.0) * tan;
            let d = (forward + right * u + up * v).normalize();
            let mut best: Option<(f32, Vec3, usize)> = None;
            for (k, (shape, _, _)) in scene.iter().enumerate() {
                if let Some((t, n)) = intersect(shape, view.eye, d) {
                    if best.is_none_or(|b| t < b.0) {
                        best = Some((t, n, k));
                    }
                }
            }
            match best {
                Some((t, n, k)) => {
                    let p = view.eye + d * t;
                    let (_, base, emission) = &scene[k];
                    // A checker in the albedo: reconstruction must not blur it (it is
                    // remodulated after filtering).
                    let checker = ((p.x * 4.0).floor() + (p.y * 4.0).floor() + (p.z * 4.0).floor())
                        as i32
                        & 1;
                    g.normal[i] = n;
                    g.position[i] = p;
                    g.albedo[i] = *base * if checker == 0 { 1.0 } else { 0.6 };
                    g.emission[i] = *emission;
                    g.object[i] = k as u32;
                }
                None => {
                    g.emission[i] = Vec3::new(0.1, 0.15, 0.3);
                    g.object[i] = NO_OBJECT;
                }
            }
        }
    }
    g
}

/// Noise-free demodulated radiance of the analytic scene: smooth shading that depends on
/// position and normal, 0 where no surface was hit.
pub fn clean_radiance(g: &GBuffer) -> Vec<Vec3> {
    let light = Vec3::new(0.3, 0.9, 0.5).normalize();
    g.normal
        .iter()
        .zip(&g.position)
        .map(|(&n, &p)| {
            if n == Vec3::ZERO {
                return Vec3::ZERO;
            }
            let falloff = 1.0 / (1.0 + (p - Vec3::new(0.0, 1.0, 0.0)).length_squared());
            Vec3::new(1.0, 0.9, 0.8) * (n.dot(light).max(0.0) * 2.0 + 0.2) * falloff
        })
        .collect()
}

/// Deterministic hash of (seed, frame, pixel) to [0, 1).
fn hash01(seed: u64, frame: u64, pixel: u64) -> f32 {
    let mut z = seed
        ^ frame.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ pixel.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32
}

/// Clean radiance with multiplicative path-tracing-like noise of relative amplitude
/// `noise` (mean preserved), different for each frame.
pub fn noisy_radiance(clean: &[Vec3], noise: f32, seed: u64, frame: u64) -> Vec<Vec3> {
    clean
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let r = hash01(seed, frame, i as u64) * 2.0 - 1.0;
            c * (1.0 + noise * r).max(0.0)
        })
        .collect()
}

/// A mask with about `keep` of the pixels set, pseudo-random per (seed, frame).
pub fn random_mask(n: usize, keep: f32, seed: u64, frame: u64) -> Vec<bool> {
    (0..n).map(|i| hash01(seed ^ 0x5151, frame, i as u64) < keep).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scene_has_surfaces_sky_and_unit_normals() {
        let g = gbuffer(48, 36, SyntheticView::default());
        g.validate(48, 36).expect("consistent");
        let hits = g.object.iter().filter(|&&o| o != NO_OBJECT).count();
        assert!(hits > g.len() / 4 && hits < g.len(), "{hits}");
        for &n in g.normal.iter().filter(|n| **n != Vec3::ZERO) {
            assert!((n.length() - 1.0).abs() < 1e-4);
        }
        assert!(g.object.contains(&3) && g.object.contains(&4), "both spheres visible");
    }

    #[test]
    fn noise_is_deterministic_and_changes_per_frame() {
        let c = vec![Vec3::ONE; 16];
        assert_eq!(noisy_radiance(&c, 0.5, 1, 2), noisy_radiance(&c, 0.5, 1, 2));
        assert_ne!(noisy_radiance(&c, 0.5, 1, 2), noisy_radiance(&c, 0.5, 1, 3));
    }
}
