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
    pub fn sample(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv.x.rem_euclid(1.0) * w - 0.5;
        let y = (1.0 - uv.y.rem_euclid(1.0)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let texel = |xi: f32, yi: f32| {
            let xi = (xi as i64).rem_euclid(self.width as i64) as usize;
            let yi = (yi as i64).rem_euclid(self.height as i64) as usize;
            self.texels[yi * self.width as usize + xi]
        };
        let top = texel(x0, y0).lerp(texel(x0 + 1.0, y0), fx);
        let bottom = texel(x0, y0 + 1.0).lerp(texel(x0 + 1.0, y0 + 1.0), fx);
        top.lerp(bottom, fy)
    }
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
