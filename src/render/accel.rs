//! Two-level ray acceleration: one bottom-level BVH per mesh, a top-level BVH over
//! the placed instances.
//!
//! Both levels are obvhs compressed wide BVHs (CWBVH, eight children per node,
//! SIMD node tests). A mesh's BLAS is built once and shared by every instance of
//! it; a new scene state only rebuilds the small TLAS, so moving an object never
//! touches its triangles. Triangles are stored in BVH leaf order as a base vertex
//! and two edges (Möller–Trumbore needs nothing else), which keeps the hot loop on
//! contiguous memory; shading data is fetched once per closest hit.
//!
//! Instances of small meshes (at most [`FLAT_MAX_TRIANGLES`], such as the walls
//! and boxes of a Cornell box) are not traversed through their own BLAS: per
//! scene state their triangles are copied to world space into one shared BVH.
//! Entering an instance costs a ray transform, a traversal set-up and a root node
//! test, far more than testing a handful of triangles, and rebuilding a few
//! hundred world-space triangles per state costs about as little as the TLAS
//! itself. Large meshes keep the two-level path, so moving them stays cheap.

use std::sync::Arc;
use std::time::Duration;

use glam::{Affine3A, Mat3A, UVec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::{build_cwbvh, build_cwbvh_from_tris};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{CwBvh, Traversal};
use obvhs::faststack::FastStack;
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

/// Bottom-level BVH of one mesh, in object space.
pub struct Blas {
    bvh: CwBvh,
    /// Triangles in BVH leaf order.
    tris: Vec<TriEdges>,
    /// Shading data of each leaf-order triangle.
    leaves: Vec<LeafTri>,
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
        let slot = mesh.slot(triangle);
        if slot >= mesh.slot_count.max(1) {
            return Err(MeshError::SlotOutOfRange { triangle, slot, count: mesh.slot_count });
        }
    }
    Ok(())
}

/// Vertex normals within this cosine of the face normal count as flat shading
/// (about 0.1°: below what shading could show).
const FLAT_COS: f32 = 0.999_998;

fn leaf_tri(mesh: &Mesh, original: u32) -> LeafTri {
    let i = original as usize;
    let idx = mesh.indices[i];
    let flat = mesh.normals.is_empty() || {
        let [a, b, c] = idx.map(|v| mesh.positions[v as usize]);
        let face = (b - a).cross(c - a).normalize_or_zero();
        let cos = idx.map(|v| mesh.normals[v as usize].normalize_or_zero().dot(face));
        // Normals facing away are flipped to the geometric side when shading, so
        // all-opposite is as flat as all-aligned; a mix is not.
        face != glam::Vec3::ZERO
            && (cos.iter().all(|&c| c >= FLAT_COS) || cos.iter().all(|&c| c <= -FLAT_COS))
    };
    LeafTri { original, slot: mesh.slot(i), flat }
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
        let (bvh, original) = build_tri_bvh(&tris, BvhBuildParams::medium_build());
        let leaves = original.iter().map(|&i| leaf_tri(&mesh, i)).collect();
        let tris = original
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                TriEdges::new(t.v0, t.v1, t.v2)
            })
            .collect();
        Ok(Self { bvh, tris, leaves, mesh, bounds })
    }

    /// Shading data of leaf-order triangle `prim`.
    #[inline]
    pub fn leaf(&self, prim: u32) -> &LeafTri {
        &self.leaves[prim as usize]
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

/// Instances whose mesh has at most this many triangles are flattened into the
/// per-state world-space BVH instead of being entered through their BLAS.
pub const FLAT_MAX_TRIANGLES: usize = 256;

/// Builds a CWBVH over triangles, returning it with the leaf order (a triangle
/// may appear more than once when `params` pre-split).
fn build_tri_bvh(tris: &[Triangle], params: BvhBuildParams) -> (CwBvh, Vec<u32>) {
    if tris.is_empty() {
        return (CwBvh::default(), Vec::new());
    }
    let bvh = build_cwbvh_from_tris(tris, params, &mut Duration::default());
    let order = bvh.primitive_indices.clone();
    (bvh, order)
}

/// A fresh traversal of `bvh` reusing `state`'s stack memory (obvhs's
/// `new_traversal` zero-fills a new 32-entry stack each time).
#[inline(always)]
fn restart(state: &mut Traversal, bvh: &CwBvh, dir: Vec3A) {
    state.stack.clear();
    state.current_group =
        if bvh.nodes.is_empty() { UVec2::ZERO } else { UVec2::new(0, 0x8000_0000) };
    state.primitive_group = UVec2::ZERO;
    // Child order by ray octant, as obvhs's `new_traversal` computes it.
    state.oct_inv4 = (if dir.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if dir.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if dir.z < 0.0 { 0 } else { 0x0101_0101 });
    state.traversal_direction = dir;
}

/// Which children of a CWBVH node the ray enters, as obvhs's
/// `CwBvhNode::intersect_ray` hit mask (same arithmetic, same results).
///
/// obvhs converts the 48 quantised child bounds one byte at a time with scalar
/// conversions, which its own comments name the most expensive part of the test;
/// here eight bytes widen to two float vectors with SSE2 unpacks, and only the
/// children actually hit are looked at for the mask.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn intersect_node(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    use std::arch::x86_64::*;
    // obvhs's lower bound on entry distances (its `EPSILON`, not public).
    const EPSILON: f32 = 0.0001;
    let scale = node.compute_extent() * ray.inv_direction;
    let shift = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    // SAFETY: SSE2 is part of x86_64; the loads read exactly the 8 bytes of a `[u8; 8]`.
    let mask = unsafe {
        let zero = _mm_setzero_si128();
        let widen = |bytes: &[u8; 8]| {
            let b = _mm_loadl_epi64(bytes.as_ptr() as *const __m128i);
            let w = _mm_unpacklo_epi8(b, zero);
            [
                _mm_cvtepi32_ps(_mm_unpacklo_epi16(w, zero)),
                _mm_cvtepi32_ps(_mm_unpackhi_epi16(w, zero)),
            ]
        };
        let axis = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, scale: f32, shift: f32| {
            let (lo, hi) = (widen(lo), widen(hi));
            let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
            let (s, o) = (_mm_set1_ps(scale), _mm_set1_ps(shift));
            let t = |q: __m128| _mm_add_ps(_mm_mul_ps(q, s), o);
            ([t(near[0]), t(near[1])], [t(far[0]), t(far[1])])
        };
        let d = ray.direction;
        let (nx, fx) = axis(&node.child_min_x, &node.child_max_x, d.x < 0.0, scale.x, shift.x);
        let (ny, fy) = axis(&node.child_min_y, &node.child_max_y, d.y < 0.0, scale.y, shift.y);
        let (nz, fz) = axis(&node.child_min_z, &node.child_max_z, d.z < 0.0, scale.z, shift.z);
        let half = |i: usize| {
            let tmin = _mm_max_ps(nx[i], _mm_max_ps(ny[i], nz[i]));
            let tmax = _mm_min_ps(fx[i], _mm_min_ps(fy[i], fz[i]));
            let tmin = _mm_max_ps(tmin, _mm_set1_ps(EPSILON));
            let tmax = _mm_min_ps(tmax, _mm_set1_ps(ray.tmax));
            _mm_movemask_ps(_mm_cmple_ps(tmin, tmax)) as u32
        };
        half(0) | (half(1) << 4)
    };
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut hit_mask = 0u32;
    let mut m = mask;
    while m != 0 {
        let j = m.trailing_zeros() * 8;
        hit_mask |= (((child_bits8 >> j) & 0xff) as u32) << ((bit_index8 >> j) & 0xff);
        m &= m - 1;
    }
    hit_mask
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn intersect_node(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    node.intersect_ray(ray, oct_inv4)
}

/// The world-space triangles of every small instance, in one BVH.
#[derive(Default)]
struct FlatGeometry {
    bvh: CwBvh,
    /// Triangles in BVH leaf order, in world space.
    tris: Vec<TriEdges>,
    /// Per leaf-order triangle: (instance index, leaf-order triangle in its BLAS).
    owner: Vec<(u32, u32)>,
}

impl FlatGeometry {
    fn build(instances: &[Instance], flat: &[u32]) -> Self {
        let mut tris = Vec::new();
        let mut owner = Vec::new();
        for &i in flat {
            let inst = &instances[i as usize];
            let m = &inst.object_to_world;
            for (prim, t) in inst.blas.tris.iter().enumerate() {
                let v0 = m.transform_point3a(t.v0);
                // Same vertex order, so barycentrics keep their meaning; an affine map
                // also keeps the ray parameter t.
                let v1 = m.transform_point3a(t.v0 + t.e1);
                let v2 = m.transform_point3a(t.v0 + t.e2);
                tris.push(Triangle { v0, v1, v2 });
                owner.push((i, prim as u32));
            }
        }
        // At most a few hundred triangles per instance: the best (slowest) build
        // is cheap, and every ray of the state traverses it.
        let (bvh, order) = build_tri_bvh(&tris, BvhBuildParams::very_slow_build());
        let tris = order
            .iter()
            .map(|&k| {
                let t = &tris[k as usize];
                TriEdges::new(t.v0, t.v1, t.v2)
            })
            .collect();
        let owner = order.iter().map(|&k| owner[k as usize]).collect();
        Self { bvh, tris, owner }
    }
}

/// Top-level BVH over the instances of one scene state.
pub struct Tlas {
    /// Over the large instances (`large`, in leaf order).
    bvh: CwBvh,
    large: Vec<u32>,
    flat: FlatGeometry,
    /// Every instance with triangles; [`Hit::instance`] indexes this.
    pub instances: Vec<Instance>,
}

impl Tlas {
    /// Builds the TLAS; instances with no triangles are dropped.
    pub fn build(instances: Vec<Instance>) -> Self {
        let instances: Vec<Instance> =
            instances.into_iter().filter(|i| i.blas.triangle_count() > 0).collect();
        let (flat, large): (Vec<u32>, Vec<u32>) = (0..instances.len() as u32)
            .partition(|&i| instances[i as usize].blas.triangle_count() <= FLAT_MAX_TRIANGLES);
        let flat = FlatGeometry::build(&instances, &flat);
        if large.is_empty() {
            return Self { bvh: CwBvh::default(), large, flat, instances };
        }
        let aabbs: Vec<Aabb> =
            large.iter().map(|&i| instances[i as usize].world_bounds()).collect();
        let bvh = build_cwbvh(&aabbs, BvhBuildParams::medium_build(), &mut Duration::default());
        let large = bvh.primitive_indices.iter().map(|&k| large[k as usize]).collect();
        Self { bvh, large, flat, instances }
    }

    /// Closest hit along `origin + t * dir` for t in (0, tmax).
    #[inline(always)]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let mut best = Hit { t: tmax, instance: u32::MAX, prim: 0, u: 0.0, v: 0.0 };
        let (origin, dir) = (Vec3A::from(origin), Vec3A::from(dir));
        let mut state = Traversal::default();
        if !self.flat.tris.is_empty() {
            let flat = &self.flat;
            let mut ray = Ray::new(origin, dir, 0.0, tmax);
            restart(&mut state, &flat.bvh, dir);
            let mut node;
            obvhs::traverse!(flat.bvh, node, state, intersect_node(node, &ray, state.oct_inv4), {
                let prim = state.primitive_id;
                if let Some((t, u, v)) =
                    flat.tris[prim as usize].intersect(origin, dir, 0.0, ray.tmax)
                {
                    ray.tmax = t;
                    let (instance, prim) = flat.owner[prim as usize];
                    best = Hit { t, instance, prim, u, v };
                }
            });
        }
        if self.large.is_empty() {
            return (best.instance != u32::MAX).then_some(best);
        }
        let mut inner = Traversal::default();
        let mut instance_hit = |index: u32, best: &mut Hit| {
            let inst = &self.instances[index as usize];
            let o = inst.world_to_object.transform_point3a(origin);
            let d = inst.world_to_object.transform_vector3a(dir);
            let blas = &*inst.blas;
            let mut ray = Ray::new(o, d, 0.0, best.t);
            restart(&mut inner, &blas.bvh, d);
            let mut node;
            obvhs::traverse!(blas.bvh, node, inner, intersect_node(node, &ray, inner.oct_inv4), {
                let prim = inner.primitive_id;
                if let Some((t, u, v)) = blas.tris[prim as usize].intersect(o, d, 0.0, ray.tmax) {
                    ray.tmax = t;
                    *best = Hit { t, instance: index, prim, u, v };
                }
            });
        };
        if let [only] = self.large[..] {
            // One large instance: its BLAS root bounds it already.
            instance_hit(only, &mut best);
        } else {
            let mut world = Ray::new(origin, dir, 0.0, best.t);
            restart(&mut state, &self.bvh, dir);
            let mut node;
            obvhs::traverse!(
                self.bvh,
                node,
                state,
                intersect_node(node, &world, state.oct_inv4),
                {
                    instance_hit(self.large[state.primitive_id as usize], &mut best);
                    world.tmax = best.t;
                }
            );
        }
        (best.instance != u32::MAX).then_some(best)
    }

    /// Whether anything blocks `origin + t * dir` for t in (0, tmax).
    #[inline(always)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let (origin, dir) = (Vec3A::from(origin), Vec3A::from(dir));
        let mut state = Traversal::default();
        if !self.flat.tris.is_empty() {
            let flat = &self.flat;
            let ray = Ray::new(origin, dir, 0.0, tmax);
            restart(&mut state, &flat.bvh, dir);
            let mut node;
            obvhs::traverse!(flat.bvh, node, state, intersect_node(node, &ray, state.oct_inv4), {
                if flat.tris[state.primitive_id as usize]
                    .intersect(origin, dir, 0.0, tmax)
                    .is_some()
                {
                    return true;
                }
            });
        }
        if self.large.is_empty() {
            return false;
        }
        let mut inner = Traversal::default();
        let mut instance_blocks = |index: u32| {
            let inst = &self.instances[index as usize];
            let o = inst.world_to_object.transform_point3a(origin);
            let d = inst.world_to_object.transform_vector3a(dir);
            let blas = &*inst.blas;
            let ray = Ray::new(o, d, 0.0, tmax);
            restart(&mut inner, &blas.bvh, d);
            let mut node;
            obvhs::traverse!(blas.bvh, node, inner, intersect_node(node, &ray, inner.oct_inv4), {
                if blas.tris[inner.primitive_id as usize].intersect(o, d, 0.0, tmax).is_some() {
                    return true;
                }
            });
            false
        };
        if let [only] = self.large[..] {
            return instance_blocks(only);
        }
        let world = Ray::new(origin, dir, 0.0, tmax);
        restart(&mut state, &self.bvh, dir);
        let mut node;
        obvhs::traverse!(self.bvh, node, state, intersect_node(node, &world, state.oct_inv4), {
            if instance_blocks(self.large[state.primitive_id as usize]) {
                return true;
            }
        });
        false
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
                    best = Some((t, inst.object * 1_000_000 + inst.blas.leaf(i as u32).original));
                }
            }
        }
        best
    }

    /// Random rays through the scene must find what brute force finds.
    fn check_against_brute_force(instances: Vec<Instance>, rng: &mut u64) {
        let tlas = Tlas::build(instances.clone());
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(lcg(rng) - 0.5, lcg(rng) - 0.5, lcg(rng) - 0.5) * 12.0;
            let target = (Vec3::new(lcg(rng), lcg(rng), lcg(rng)) - 0.5) * 6.0;
            let d = (target - o).normalize();
            let expected = brute_force(&instances, o, d);
            let got = tlas.intersect(o, d, f32::INFINITY).map(|h| {
                let inst = &tlas.instances[h.instance as usize];
                (h.t, inst.object * 1_000_000 + inst.blas.leaf(h.prim).original)
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
        assert!(hits > 300, "too few hits ({hits}) to test anything");
    }

    fn random_transform(rng: &mut u64) -> Affine3A {
        let t = Vec3::new(lcg(rng) * 6.0 - 3.0, lcg(rng) * 6.0 - 3.0, lcg(rng) * 6.0 - 3.0);
        let r = Quat::from_euler(glam::EulerRot::XYZ, lcg(rng) * 3.0, lcg(rng), 0.5);
        let s = Vec3::new(0.3 + lcg(rng), 0.3 + lcg(rng), 0.3 + lcg(rng));
        Affine3A::from_scale_rotation_translation(s, r, t)
    }

    #[test]
    fn bvh_hits_match_brute_force() {
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        // Spheres go through their own BLAS, cubes into the flattened world-space BVH.
        assert!(sphere.triangle_count() > FLAT_MAX_TRIANGLES);
        assert!(cube.triangle_count() <= FLAT_MAX_TRIANGLES);
        let mut rng = 12345u64;
        let mut instances = Vec::new();
        for object in 0..12u32 {
            let blas = if object % 3 == 0 { cube.clone() } else { sphere.clone() };
            instances.push(Instance::new(blas, random_transform(&mut rng), object, 0));
        }
        check_against_brute_force(instances, &mut rng);
        // A single large instance skips the top level; a lone small one is flat only.
        for blas in [sphere, cube] {
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::new(2.5, 2.0, 3.0),
                Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.2),
                Vec3::new(0.2, -0.1, 0.3),
            );
            check_against_brute_force(vec![Instance::new(blas, m, 0, 0)], &mut rng);
        }
    }

    #[test]
    fn flat_shading_is_detected_per_triangle() {
        let cube = Blas::build(Arc::new(shapes::cube())).unwrap();
        assert!((0..cube.triangle_count() as u32).all(|p| cube.leaf(p).flat));
        let sphere = Blas::build(Arc::new(shapes::sphere(2))).unwrap();
        assert!((0..sphere.triangle_count() as u32).all(|p| !sphere.leaf(p).flat));
        // Normals all facing away are flat too (shading flips them); a mix is not.
        let mut mesh = shapes::quad();
        mesh.normals.iter_mut().for_each(|n| *n = -*n);
        let flipped = Blas::build(Arc::new(mesh.clone())).unwrap();
        assert!((0..2).all(|p| flipped.leaf(p).flat));
        mesh.normals[mesh.indices[0][1] as usize] *= -1.0;
        let mixed = Blas::build(Arc::new(mesh)).unwrap();
        assert!((0..2).any(|p| !mixed.leaf(p).flat));
        // Without vertex normals every triangle is flat.
        let mut bare = shapes::quad();
        bare.normals.clear();
        let bare = Blas::build(Arc::new(bare)).unwrap();
        assert!((0..2).all(|p| bare.leaf(p).flat));
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
