//! Triangles as the traversal tests them (a base vertex and two edges,
//! Möller–Trumbore) and the shading data of a leaf-order triangle.

use glam::Vec3A;

/// A triangle ready for Möller–Trumbore: base vertex and the two edges from it.
#[derive(Clone, Copy, Debug)]
pub struct TriEdges {
    pub v0: Vec3A,
    pub e1: Vec3A,
    pub e2: Vec3A,
}

impl TriEdges {
    pub fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Self {
        Self { v0: a, e1: b - a, e2: c - a }
    }

    /// Distance along the ray and barycentrics (u at vertex 1, v at vertex 2) of
    /// the intersection within (tmin, tmax), or `None`. Two-sided.
    #[inline(always)]
    pub fn intersect(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmin: f32,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        let p = dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = origin - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = self.e2.dot(q) * inv;
        (t > tmin && t < tmax).then_some((t, u, v))
    }
}

impl TriEdges {
    /// Intersection with the parallelogram `v0 + s e1 + t e2`, s, t in [0, 1].
    #[inline]
    pub fn intersect_parallelogram(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
    ) -> Option<(f32, f32, f32)> {
        let p = dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = origin - self.v0;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = dir.dot(q) * inv;
        if !(0.0..=1.0).contains(&v) {
            return None;
        }
        let t = self.e2.dot(q) * inv;
        (t > 0.0 && t < tmax).then_some((t, u, v))
    }
}

/// What shading needs of a leaf-order triangle beyond its edges, gathered at
/// build time so that a closest hit on a flat-shaded triangle reads no mesh data.
#[derive(Clone, Copy, Debug)]
pub struct LeafTri {
    /// Index of the triangle in the mesh.
    pub original: u32,
    /// Its material slot.
    pub slot: u32,
    /// Its vertex normals are absent or all along the geometric normal, so the
    /// shading normal is the geometric one and need not be interpolated.
    pub flat: bool,
}
