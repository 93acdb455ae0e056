//! Two-level ray acceleration: one bottom-level BVH per mesh, a top-level BVH over
//! the placed instances.
//!
//! Both levels are obvhs compressed wide BVHs (CWBVH, eight children per node,
//! SIMD node tests). A mesh's BLAS is built once and shared by every instance of
//! it; a new scene state only rebuilds the small TLAS, so moving an object never
//! touches its triangles. Triangles are stored in BVH leaf order as a base vertex
//! and two edges (Möller–Trumbore needs nothing else), which keeps the hot loop on
//! contiguous memory; shading data is fetched once per closest hit.

use std::sync::Arc;
use std::time::Duration;

use glam::{Affine3A, Mat3A, UVec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::cwbvh::CwBvh;
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use crate::assets::Mesh;

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

/// Bottom-level BVH of one mesh, in object space.
pub struct Blas {
    bvh: CwBvh,
    /// Triangles in BVH leaf order.
    tris: Vec<TriEdges>,
    /// Index of each leaf-order triangle in the mesh.
    original: Vec<u32>,
    pub mesh: Arc<Mesh>,
    pub bounds: Aabb,
}

/// Why a mesh cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("triangle {triangle} refers to vertex {vertex}, but the mesh has {count} vertices")]
    VertexOutOfRange { triangle: usize, vertex: u32, count: usize },
    #[error("triangle {triangle} uses material slot {slot}, but the mesh has {count} slots")]
    SlotOutOfRange { triangle: usize, slot: u32, count: u32 },
    #[error("the mesh has {normals} normals / {uvs} uvs for {positions} positions")]
    AttributeCount { positions: usize, normals: usize, uvs: usize },
    #[error("the mesh has a non-finite vertex position")]
    NonFinite,
}

/// Checks every index of a mesh so that shading never reads out of bounds.
pub fn validate_mesh(mesh: &Mesh) -> Result<(), MeshError> {
    let n = mesh.positions.len();
    let attrs_ok = |len: usize| len == 0 || len == n;
    if !attrs_ok(mesh.normals.len()) || !attrs_ok(mesh.uvs.len()) {
        return Err(MeshError::AttributeCount {
            positions: n,
            normals: mesh.normals.len(),
            uvs: mesh.uvs.len(),
        });
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err(MeshError::NonFinite);
    }
    for (triangle, tri) in mesh.indices.iter().enumerate() {
        if let Some(&vertex) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(MeshError::VertexOutOfRange { triangle, vertex, count: n });
        }
        let slot = mesh.slots.get(triangle).copied().unwrap_or(0);
        if slot >= mesh.slot_count.max(1) {
            return Err(MeshError::SlotOutOfRange { triangle, slot, count: mesh.slot_count });
        }
    }
    Ok(())
}

impl Blas {
    /// Builds the BLAS of a validated mesh.
    pub fn build(mesh: Arc<Mesh>) -> Result<Self, MeshError> {
        validate_mesh(&mesh)?;
        let tris: Vec<Triangle> = mesh
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vec3A::from(mesh.positions[i as usize]));
                Triangle { v0: a, v1: b, v2: c }
            })
            .collect();
        let mut bounds = Aabb::empty();
        for t in &tris {
            bounds = bounds.union(&t.aabb());
        }
        let (bvh, original) = if tris.is_empty() {
            (CwBvh::default(), Vec::new())
        } else {
            let bvh = build_cwbvh_from_tris(
                &tris,
                BvhBuildParams::medium_build(),
                &mut Duration::default(),
            );
            let original = bvh.primitive_indices.clone();
            (bvh, original)
        };
        let tris = original
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                TriEdges::new(t.v0, t.v1, t.v2)
            })
            .collect();
        Ok(Self { bvh, tris, original, mesh, bounds })
    }

    /// Index in the mesh of leaf-order triangle `prim`.
    #[inline]
    pub fn original(&self, prim: u32) -> u32 {
        self.original[prim as usize]
    }

    /// Leaf-order triangle `prim`.
    #[inline]
    pub fn tri(&self, prim: u32) -> &TriEdges {
        &self.tris[prim as usize]
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }
}

/// One placed instance of a BLAS.
#[derive(Clone)]
pub struct Instance {
    pub blas: Arc<Blas>,
    pub object_to_world: Affine3A,
    pub world_to_object: Affine3A,
    /// Inverse transpose of the linear part, for normals.
    pub normal_to_world: Mat3A,
    /// Index into `SceneState::objects`.
    pub object: u32,
    /// Offset of this instance's slot-to-material table in the scene's table.
    pub material_base: u32,
}

impl Instance {
    pub fn new(
        blas: Arc<Blas>,
        object_to_world: Affine3A,
        object: u32,
        material_base: u32,
    ) -> Self {
        let world_to_object = object_to_world.inverse();
        let normal_to_world = world_to_object.matrix3.transpose();
        Self { blas, object_to_world, world_to_object, normal_to_world, object, material_base }
    }

    fn world_bounds(&self) -> Aabb {
        let b = &self.blas.bounds;
        let mut out = Aabb::empty();
        for i in 0..8 {
            let corner = Vec3A::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            );
            out.extend(self.object_to_world.transform_point3a(corner));
        }
        out
    }
}

/// The closest intersection found by [`Tlas::intersect`].
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    pub instance: u32,
    /// Leaf-order triangle index within the instance's BLAS.
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// Top-level BVH over the instances of one scene state.
pub struct Tlas {
    bvh: CwBvh,
    /// Instances in TLAS leaf order.
    pub instances: Vec<Instance>,
}

impl Tlas {
    /// Builds the TLAS; instances with no triangles are dropped.
    pub fn build(instances: Vec<Instance>) -> Self {
        let instances: Vec<Instance> =
            instances.into_iter().filter(|i| i.blas.triangle_count() > 0).collect();
        if instances.is_empty() {
            return Self { bvh: CwBvh::default(), instances };
        }
        let aabbs: Vec<Aabb> = instances.iter().map(Instance::world_bounds).collect();
        let bvh = build_cwbvh(&aabbs, BvhBuildParams::medium_build(), &mut Duration::default());
        let instances =
            bvh.primitive_indices.iter().map(|&i| instances[i as usize].clone()).collect();
        Self { bvh, instances }
    }

    /// Closest hit along `origin + t * dir` for t in (0, tmax).
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        if self.instances.is_empty() {
            return None;
        }
        let mut best = Hit { t: tmax, instance: u32::MAX, prim: 0, u: 0.0, v: 0.0 };
        let world = Ray::new(origin.into(), dir.into(), 0.0, tmax);
        let mut world_ray = world;
        let mut state = self.bvh.new_traversal(world.direction);
        let mut node;
        obvhs::traverse!(self.bvh, node, state, node.intersect_ray(&world_ray, state.oct_inv4), {
            let instance_index = state.primitive_id;
            let inst = &self.instances[instance_index as usize];
            let o = inst.world_to_object.transform_point3a(world.origin);
            let d = inst.world_to_object.transform_vector3a(world.direction);
            let ray = Ray::new(o, d, 0.0, best.t);
            let blas = &*inst.blas;
            let mut local_ray = ray;
            let mut inner = blas.bvh.new_traversal(d);
            let mut inner_node;
            obvhs::traverse!(
                blas.bvh,
                inner_node,
                inner,
                inner_node.intersect_ray(&local_ray, inner.oct_inv4),
                {
                    let prim = inner.primitive_id;
                    if let Some((t, u, v)) =
                        blas.tris[prim as usize].intersect(o, d, 0.0, local_ray.tmax)
                    {
                        local_ray.tmax = t;
                        best = Hit { t, instance: instance_index, prim, u, v };
                    }
                }
            );
            world_ray.tmax = best.t;
        });
        (best.instance != u32::MAX).then_some(best)
    }

    /// Whether anything blocks `origin + t * dir` for t in (0, tmax).
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        if self.instances.is_empty() {
            return false;
        }
        let world = Ray::new(origin.into(), dir.into(), 0.0, tmax);
        let mut state = self.bvh.new_traversal(world.direction);
        let mut node;
        let mut blocked = false;
        'outer: {
            obvhs::traverse!(self.bvh, node, state, node.intersect_ray(&world, state.oct_inv4), {
                let inst = &self.instances[state.primitive_id as usize];
                let o = inst.world_to_object.transform_point3a(world.origin);
                let d = inst.world_to_object.transform_vector3a(world.direction);
                let ray = Ray::new(o, d, 0.0, tmax);
                let blas = &*inst.blas;
                let mut inner = blas.bvh.new_traversal(d);
                let mut inner_node;
                obvhs::traverse!(
                    blas.bvh,
                    inner_node,
                    inner,
                    inner_node.intersect_ray(&ray, inner.oct_inv4),
                    {
                        if blas.tris[inner.primitive_id as usize]
                            .intersect(o, d, 0.0, tmax)
                            .is_some()
                        {
                            blocked = true;
                            break 'outer;
                        }
                    }
                );
            });
        }
        blocked
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;
    use glam::{Quat, Vec3};

    /// Tiny deterministic generator for test inputs only (not used for rendering).
    fn lcg(state: &mut u64) -> f32 {
        *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    fn brute_force(instances: &[Instance], o: Vec3, d: Vec3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for inst in instances {
            let lo = inst.world_to_object.transform_point3a(o.into());
            let ld = inst.world_to_object.transform_vector3a(d.into());
            for (i, t) in inst.blas.tris.iter().enumerate() {
                let tmax = best.map_or(f32::INFINITY, |b| b.0);
                if let Some((t, ..)) = t.intersect(lo, ld, 0.0, tmax) {
                    best = Some((t, inst.object * 1_000_000 + inst.blas.original(i as u32)));
                }
            }
        }
        best
    }

    #[test]
    fn bvh_hits_match_brute_force() {
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        let mut rng = 12345u64;
        let mut instances = Vec::new();
        for object in 0..12u32 {
            let blas = if object % 3 == 0 { cube.clone() } else { sphere.clone() };
            let t = Vec3::new(
                lcg(&mut rng) * 6.0 - 3.0,
                lcg(&mut rng) * 6.0 - 3.0,
                lcg(&mut rng) * 6.0 - 3.0,
            );
            let r = Quat::from_euler(glam::EulerRot::XYZ, lcg(&mut rng) * 3.0, lcg(&mut rng), 0.5);
            let s = Vec3::new(0.3 + lcg(&mut rng), 0.3 + lcg(&mut rng), 0.3 + lcg(&mut rng));
            let m = Affine3A::from_scale_rotation_translation(s, r, t);
            instances.push(Instance::new(blas, m, object, 0));
        }
        let tlas = Tlas::build(instances.clone());
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(lcg(&mut rng) - 0.5, lcg(&mut rng) - 0.5, lcg(&mut rng) - 0.5) * 12.0;
            let target = (Vec3::new(lcg(&mut rng), lcg(&mut rng), lcg(&mut rng)) - 0.5) * 6.0;
            let d = (target - o).normalize();
            let expected = brute_force(&instances, o, d);
            let got = tlas.intersect(o, d, f32::INFINITY).map(|h| {
                let inst = &tlas.instances[h.instance as usize];
                (h.t, inst.object * 1_000_000 + inst.blas.original(h.prim))
            });
            match (expected, got) {
                (None, None) => {}
                (Some(e), Some(g)) => {
                    hits += 1;
                    assert!((e.0 - g.0).abs() < 1e-4 * e.0.max(1.0), "t {} vs {}", e.0, g.0);
                    assert!(tlas.occluded(o, d, e.0 * 1.001));
                    assert!(!tlas.occluded(o, d, e.0 * 0.999));
                }
                other => panic!("brute force and BVH disagree: {other:?}"),
            }
        }
        assert!(hits > 500, "too few hits ({hits}) to test anything");
    }

    #[test]
    fn single_instance_single_triangle_scene_works() {
        let mut mesh = shapes::quad();
        mesh.indices.truncate(1);
        mesh.slots.truncate(1);
        let blas = Arc::new(Blas::build(Arc::new(mesh)).unwrap());
        let tlas = Tlas::build(vec![Instance::new(blas, Affine3A::IDENTITY, 0, 0)]);
        let hit = tlas.intersect(Vec3::new(0.1, 1.0, 0.1), Vec3::NEG_Y, f32::INFINITY);
        let miss = tlas.intersect(Vec3::new(-0.1, 1.0, -0.1), Vec3::NEG_Y, f32::INFINITY);
        // The first triangle of the quad covers one half of the square.
        assert!(hit.is_some() != miss.is_some());
    }

    #[test]
    fn bad_meshes_are_rejected() {
        let mut mesh = shapes::quad();
        mesh.indices[1][2] = 99;
        assert!(matches!(
            validate_mesh(&mesh),
            Err(MeshError::VertexOutOfRange { vertex: 99, .. })
        ));
        let mut mesh = shapes::quad();
        mesh.slots[0] = 3;
        assert!(matches!(validate_mesh(&mesh), Err(MeshError::SlotOutOfRange { slot: 3, .. })));
    }
}
