//! Loaded asset data: triangle meshes, textures and environment maps.
//!
//! Scene states name assets by path (see `gridlight_actors::state`); the scene loader
//! turns those names into the values here, once per process, and the renderer, the
//! G-buffer and the worker share them read-only behind `Arc`s.

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Vec2, Vec3};
use gridlight_actors::state::Geometry;

/// Triangles of one [`Geometry`], in object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals; empty means "use the geometric normal".
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates; empty means none.
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle.
    pub indices: Vec<[u32; 3]>,
    /// Material slot of each triangle (see `Object::materials`).
    pub slots: Vec<u32>,
    /// Number of material slots; every entry of `slots` is below it.
    pub slot_count: u32,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// Material slot of `triangle` (slot 0 when the mesh lists none).
    #[inline]
    pub fn slot(&self, triangle: usize) -> u32 {
        self.slots.get(triangle).copied().unwrap_or(0)
    }
}

/// A 2-D image of linear RGB values (albedo maps are decoded from sRGB on load).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// Row-major, top row first.
    pub texels: Vec<Vec3>,
}

impl Texture {
    /// Bilinear lookup with wrap-around; `uv` (0,0) is the bottom-left corner as in OBJ.
    ///
    /// The wrap costs two float remainders and four texel-index wraps per lookup; done with
    /// `rem_euclid` they were 16 % of a Sponza frame (a libm `fmodf` call each and 64-bit
    /// divisions), so both are done here without division, with the same results. Inlined
    /// into each dispatched build of the kernel (floor is an instruction on x86-64-v3).
    #[inline(always)]
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = unit_wrap(uv.x) * w - 0.5;
        let y = (1.0 - unit_wrap(uv.y)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        // x, y lie in [-0.5, size - 0.5], so the texel indices lie in [-1, size].
        let (xs, ys) = (self.width as i64, self.height as i64);
        let (cx0, cy0) = (x0 as i64, y0 as i64);
        let (cx0, cx1) = (index_wrap(cx0, xs), index_wrap(cx0 + 1, xs));
        let (cy0, cy1) = (index_wrap(cy0, ys), index_wrap(cy0 + 1, ys));
        let row = self.width as usize;
        let texel = |xi: usize, yi: usize| self.texels[yi * row + xi];
        let top = texel(cx0, cy0).lerp(texel(cx1, cy0), fx);
        let bottom = texel(cx0, cy1).lerp(texel(cx1, cy1), fx);
        top.lerp(bottom, fy)
    }
}

/// `x.rem_euclid(1.0)` bit for bit up to the sign of a zero result (which the lookup
/// cannot see): `x - x.trunc()` is exact (Sterbenz), as `x % 1.0` is, and both round
/// the negative case's `+ 1.0` once.
#[inline]
fn unit_wrap(x: f32) -> f32 {
    let r = x - x.trunc();
    if r < 0.0 {
        r + 1.0
    } else {
        r
    }
}

/// `i.rem_euclid(n)` for `i` in [-n, 2n), which is every index [`Texture::sample`] forms
/// (a NaN coordinate casts to 0), without a 64-bit division.
#[inline]
fn index_wrap(i: i64, n: i64) -> usize {
    debug_assert!((-n..2 * n).contains(&i), "texel index {i} outside [-{n}, {})", 2 * n);
    (if i < 0 {
        i + n
    } else if i >= n {
        i - n
    } else {
        i
    }) as usize
}

/// All asset data a set of scene states refers to.
#[derive(Clone, Debug, Default)]
pub struct Assets {
    /// Geometry of every object, keyed by what the state names.
    pub meshes: HashMap<Geometry, Arc<Mesh>>,
    /// Albedo textures by asset path (linear RGB).
    pub textures: HashMap<String, Arc<Texture>>,
    /// Equirectangular environment maps by asset path (linear RGB radiance).
    pub environments: HashMap<String, Arc<Texture>>,
    /// The MTL files each OBJ named, by the OBJ's asset path: what the manifest lists
    /// after it, known from loading so that the master need not parse the OBJ again.
    pub obj_libraries: HashMap<String, Vec<String>>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The lookup as first written, with `rem_euclid` wraps: the reference the cheaper
    /// wraps must match bit for bit (CPU and GPU pictures depend on it).
    fn sample_by_rem_euclid(t: &Texture, uv: Vec2) -> Vec3 {
        let (w, h) = (t.width as f32, t.height as f32);
        let x = uv.x.rem_euclid(1.0) * w - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |xi: f32, yi: f32| {
            let xi = (xi as i64).rem_euclid(t.width as i64) as usize;
            let yi = (yi as i64).rem_euclid(t.height as i64) as usize;
            t.texels[yi * t.width as usize + xi]
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }

    #[test]
    fn wrapped_lookup_matches_rem_euclid_bit_for_bit() {
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            2.0,
            -3.0,
            0.5,
            -0.5,
            1e-9,
            -1e-9,
            0.999_999_9,
            -0.999_999_9,
            1e7,
            -1e7,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::EPSILON,
            -f32::EPSILON,
        ];
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut coords: Vec<f32> = special.to_vec();
        coords.extend((0..2000).map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 40.0
        }));
        for (w, h) in [(1, 1), (2, 3), (7, 5), (64, 32)] {
            let texels =
                (0..w * h).map(|i| Vec3::new(i as f32, 1.0 / (1 + i) as f32, 0.5)).collect();
            let t = Texture { width: w, height: h, texels };
            for (i, &u) in coords.iter().enumerate() {
                let v = coords[(i * 7 + 3) % coords.len()];
                let (a, b) = (t.sample(Vec2::new(u, v)), sample_by_rem_euclid(&t, Vec2::new(u, v)));
                assert_eq!(
                    a.to_array().map(f32::to_bits),
                    b.to_array().map(f32::to_bits),
                    "{w}x{h} at ({u}, {v})"
                );
            }
        }
        // Non-finite coordinates give the same NaNs.
        let t = Texture { width: 2, height: 2, texels: vec![Vec3::ONE; 4] };
        for uv in [Vec2::new(f32::NAN, 0.3), Vec2::new(f32::INFINITY, 0.3)] {
            assert!(t.sample(uv).is_nan() && sample_by_rem_euclid(&t, uv).is_nan());
        }
    }
}
