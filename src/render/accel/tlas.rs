//! The top level: the placed instances of one scene state, small ones flattened into one
//! world-space BVH, large ones entered through their BLAS.

use std::sync::Arc;
use std::time::Duration;

use glam::{Affine3A, Mat3A, UVec2, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::{CwBvh, Traversal};
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use super::blas::{build_tri_bvh, Blas};
use super::traverse::{intersect_node, restart};
use super::triangle::TriEdges;
use super::wide::{LaneFill, LaneHits, RayLanes, TriHit, WideBvh, WideRay};
use crate::render::isa::{Cpu, Isa};
use crate::render::lanes::{Vec3s, WIDTH};

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

    /// A world-space ray in this instance's object space, ready for its BLAS.
    #[inline(always)]
    fn object_ray(&self, origin: Vec3A, dir: Vec3A) -> WideRay {
        let m = &self.world_to_object;
        WideRay::new(m.transform_point3a(origin), m.transform_vector3a(dir))
    }

    pub(super) fn world_bounds(&self) -> Aabb {
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
#[derive(Clone, Copy, Debug, PartialEq)]
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

/// The world-space triangles of every small instance, in one BVH.
#[derive(Default)]
pub(super) struct FlatGeometry {
    pub(super) bvh: CwBvh,
    /// The CPU's traversal layout of `bvh`.
    pub(super) wide: WideBvh,
    /// Triangles in BVH leaf order, in world space.
    pub(super) tris: Vec<TriEdges>,
    /// Per leaf-order triangle: (instance index, leaf-order triangle in its BLAS).
    pub(super) owner: Vec<(u32, u32)>,
}

impl FlatGeometry {
    pub(super) fn build(instances: &[Instance], flat: &[u32]) -> Self {
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
            .collect::<Vec<_>>();
        let owner = order.iter().map(|&k| owner[k as usize]).collect();
        let wide = WideBvh::build(&bvh, &tris);
        Self { bvh, wide, tris, owner }
    }
}

/// Geometric normals precomputed per scene state, at most this many (48 MB); instances
/// beyond it compute theirs at each hit.
const NORMAL_BUDGET: usize = 1 << 22;
/// [`Normals::base`] of an instance whose normals are not stored.
pub(super) const NOT_STORED: u32 = u32::MAX;

/// The unit world-space geometric normal of each triangle, instance by instance. Every
/// hit a path resolves needs one, and computed there (a cross product, the normal
/// matrix, a square root and a division, one dependent on the next) it stalled the
/// stream kernel between two lanes' walks: 6 % of a Cornell box frame.
#[derive(Default)]
pub(super) struct Normals {
    /// Per instance: where its leaf-order triangles' normals start in `normals`.
    pub(super) base: Vec<u32>,
    normals: Vec<Vec3>,
}

impl Normals {
    fn build(instances: &[Instance], budget: usize) -> Self {
        let mut out = Normals::default();
        for inst in instances {
            let count = inst.blas.triangle_count();
            if out.normals.len() + count > budget {
                out.base.push(NOT_STORED);
                continue;
            }
            out.base.push(out.normals.len() as u32);
            out.normals.extend((0..count as u32).map(|prim| inst.geometric_normal(prim)));
        }
        out
    }
}

impl Instance {
    /// Leaf-order triangle `prim`'s unit geometric normal in world space, on its front
    /// (winding) side.
    #[inline(always)]
    fn geometric_normal(&self, prim: u32) -> Vec3 {
        let tri = self.blas.tri(prim);
        Vec3::from(self.normal_to_world * tri.e1.cross(tri.e2)).normalize()
    }
}

/// Top-level BVH over the instances of one scene state.
pub struct Tlas {
    /// Over the large instances (`large`, in leaf order).
    pub(super) bvh: CwBvh,
    pub(super) large: Vec<u32>,
    pub(super) flat: FlatGeometry,
    pub(super) normals: Normals,
    /// Every instance with triangles; [`Hit::instance`] indexes this.
    pub instances: Vec<Instance>,
}

impl Tlas {
    /// Builds the TLAS; instances with no triangles are dropped.
    pub fn build(instances: Vec<Instance>) -> Self {
        Self::build_with_normal_budget(instances, NORMAL_BUDGET)
    }

    /// [`Tlas::build`] storing at most `budget` geometric normals.
    pub(super) fn build_with_normal_budget(instances: Vec<Instance>, budget: usize) -> Self {
        let instances: Vec<Instance> =
            instances.into_iter().filter(|i| i.blas.triangle_count() > 0).collect();
        let (flat, large): (Vec<u32>, Vec<u32>) = (0..instances.len() as u32)
            .partition(|&i| instances[i as usize].blas.triangle_count() <= FLAT_MAX_TRIANGLES);
        let flat = FlatGeometry::build(&instances, &flat);
        let normals = Normals::build(&instances, budget);
        if large.is_empty() {
            return Self { bvh: CwBvh::default(), large, flat, normals, instances };
        }
        let aabbs: Vec<Aabb> =
            large.iter().map(|&i| instances[i as usize].world_bounds()).collect();
        let bvh = build_cwbvh(&aabbs, BvhBuildParams::medium_build(), &mut Duration::default());
        let large = bvh.primitive_indices.iter().map(|&k| large[k as usize]).collect();
        Self { bvh, large, flat, normals, instances }
    }

    /// The unit world-space geometric normal of a hit's triangle, on its front (winding)
    /// side: stored where the budget allowed, the same bits computed otherwise.
    #[inline(always)]
    pub fn geometric_normal(&self, hit: &Hit) -> Vec3 {
        let base = self.normals.base[hit.instance as usize];
        if base != NOT_STORED {
            return self.normals.normals[(base + hit.prim) as usize];
        }
        self.instances[hit.instance as usize].geometric_normal(hit.prim)
    }

    /// Lane fill of the trees a ray may enter: the flattened small instances and each
    /// large mesh's BLAS once (however many instances share it).
    pub fn lane_fill(&self) -> LaneFill {
        let mut seen = Vec::new();
        let mut fill = self.flat.wide.lane_fill();
        for &i in &self.large {
            let blas = &self.instances[i as usize].blas;
            if !seen.iter().any(|b| Arc::ptr_eq(b, blas)) {
                fill = fill + blas.wide.lane_fill();
                seen.push(blas.clone());
            }
        }
        fill
    }

    /// Closest hit along `origin + t * dir` for t in (0, tmax).
    #[inline(always)]
    pub fn intersect(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        self.intersect_with(Cpu::BASELINE, origin, dir, tmax)
    }

    /// Whether anything blocks `origin + t * dir` for t in (0, tmax).
    #[inline(always)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_with(Cpu::BASELINE, origin, dir, tmax)
    }

    /// [`Tlas::intersect`] with node tests on `I`'s registers (same hits).
    #[inline(always)]
    pub fn intersect_with<I: Isa>(
        &self,
        _cpu: Cpu<I>,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
    ) -> Option<Hit> {
        let (origin, dir) = (Vec3A::from(origin), Vec3A::from(dir));
        let flat = self.flat.wide.intersect::<I>(&WideRay::new(origin, dir), tmax);
        self.beyond_flat::<I>(origin, dir, tmax, flat)
    }

    /// [`Tlas::intersect_with`] of sixteen coherent rays (`active` lanes of `o`, `d`; a
    /// G-buffer tile's camera rays), with no `tmax`: the same hits, the flattened
    /// instances' walked by the rays together where they can be (see
    /// `wide/coherent.rs`), large instances entered by each ray alone.
    #[inline(always)]
    pub fn intersect_lanes_with<I: Isa>(
        &self,
        cpu: Cpu<I>,
        o: &Vec3s<I>,
        d: &Vec3s<I>,
        active: u32,
    ) -> [Option<Hit>; WIDTH] {
        let mut out = [None; WIDTH];
        let Some(rays) = RayLanes::new(o, d, active) else {
            for (l, hit) in out.iter_mut().enumerate().filter(|(l, _)| active & (1 << l) != 0) {
                *hit = self.intersect_with(cpu, o.lane(l), d.lane(l), f32::INFINITY);
            }
            return out;
        };
        let h: LaneHits<I> = self.flat.wide.intersect_lanes(&rays);
        for (l, hit) in out.iter_mut().enumerate().filter(|(l, _)| active & (1 << l) != 0) {
            let (origin, dir) = (Vec3A::from(o.lane(l)), Vec3A::from(d.lane(l)));
            let flat = if h.sure & (1 << l) == 0 {
                self.flat.wide.intersect::<I>(&WideRay::new(origin, dir), f32::INFINITY)
            } else {
                (h.hit & (1 << l) != 0).then(|| TriHit {
                    t: h.t.0[l],
                    prim: h.prim.0[l],
                    u: h.u.0[l],
                    v: h.v.0[l],
                })
            };
            *hit = self.beyond_flat::<I>(origin, dir, f32::INFINITY, flat);
        }
        out
    }

    /// The rest of [`Tlas::intersect_with`] given the flattened instances' closest hit
    /// `flat`: the large instances, entered through their BLAS.
    #[inline(always)]
    fn beyond_flat<I: Isa>(
        &self,
        origin: Vec3A,
        dir: Vec3A,
        tmax: f32,
        flat: Option<TriHit>,
    ) -> Option<Hit> {
        let mut best = Hit { t: tmax, instance: u32::MAX, prim: 0, u: 0.0, v: 0.0 };
        if let Some(h) = flat {
            best = self.flat_hit(h);
        }
        if self.large.is_empty() {
            return (best.instance != u32::MAX).then_some(best);
        }
        if let [only] = self.large[..] {
            // One large instance: its BLAS root bounds it already.
            self.instance_hit::<I>(only, origin, dir, &mut best);
        } else {
            let mut world = Ray::new(origin, dir, 0.0, best.t);
            let mut state = Traversal::default();
            restart(&mut state, &self.bvh, dir);
            let mut node;
            obvhs::traverse!(
                self.bvh,
                node,
                state,
                intersect_node(node, &world, state.oct_inv4),
                {
                    let index = self.large[state.primitive_id as usize];
                    self.instance_hit::<I>(index, origin, dir, &mut best);
                    world.tmax = best.t;
                }
            );
        }
        (best.instance != u32::MAX).then_some(best)
    }

    /// [`Tlas::intersect_with`] of `closest` and [`Tlas::occluded_with`] of `shadow`
    /// (origin, direction, tmax each), their traversals interleaved where the scene has
    /// at most one large instance (see `WideBvh::intersect_and_occluded`); the same
    /// answers as the two calls.
    #[inline(always)]
    pub fn intersect_and_occluded_with<I: Isa>(
        &self,
        cpu: Cpu<I>,
        closest: (Vec3, Vec3, f32),
        shadow: (Vec3, Vec3, f32),
    ) -> (Option<Hit>, bool) {
        if self.large.len() > 1 {
            let hit = self.intersect_with(cpu, closest.0, closest.1, closest.2);
            return (hit, self.occluded_with(cpu, shadow.0, shadow.1, shadow.2));
        }
        let (o, d) = (Vec3A::from(closest.0), Vec3A::from(closest.1));
        let (so, sd) = (Vec3A::from(shadow.0), Vec3A::from(shadow.1));
        let mut best = Hit { t: closest.2, instance: u32::MAX, prim: 0, u: 0.0, v: 0.0 };
        let (h, mut blocked) = self.flat.wide.intersect_and_occluded::<I>(
            (&WideRay::new(o, d), closest.2),
            (&WideRay::new(so, sd), shadow.2),
        );
        if let Some(h) = h {
            best = self.flat_hit(h);
        }
        if let [only] = self.large[..] {
            if blocked {
                self.instance_hit::<I>(only, o, d, &mut best);
            } else {
                let inst = &self.instances[only as usize];
                let (h, b) = inst.blas.wide.intersect_and_occluded::<I>(
                    (&inst.object_ray(o, d), best.t),
                    (&inst.object_ray(so, sd), shadow.2),
                );
                if let Some(h) = h {
                    best = Hit { t: h.t, instance: only, prim: h.prim, u: h.u, v: h.v };
                }
                blocked = b;
            }
        }
        ((best.instance != u32::MAX).then_some(best), blocked)
    }

    /// A hit in the flattened small instances, as the instance and triangle it belongs to.
    #[inline(always)]
    fn flat_hit(&self, h: TriHit) -> Hit {
        let (instance, prim) = self.flat.owner[h.prim as usize];
        Hit { t: h.t, instance, prim, u: h.u, v: h.v }
    }

    /// Closest hit in instance `index`'s BLAS nearer than `best` (a method, not a closure,
    /// so that `inline(always)` carries the AVX node test into the dispatched kernel).
    #[inline(always)]
    fn instance_hit<I: Isa>(&self, index: u32, origin: Vec3A, dir: Vec3A, best: &mut Hit) {
        let inst = &self.instances[index as usize];
        if let Some(h) = inst.blas.wide.intersect::<I>(&inst.object_ray(origin, dir), best.t) {
            *best = Hit { t: h.t, instance: index, prim: h.prim, u: h.u, v: h.v };
        }
    }

    /// Whether instance `index`'s BLAS blocks the ray before `tmax`.
    #[inline(always)]
    fn instance_blocks<I: Isa>(&self, index: u32, origin: Vec3A, dir: Vec3A, tmax: f32) -> bool {
        let inst = &self.instances[index as usize];
        inst.blas.wide.occluded::<I>(&inst.object_ray(origin, dir), tmax)
    }

    /// [`Tlas::occluded`] with node tests on `I`'s registers (same answers).
    #[inline(always)]
    pub fn occluded_with<I: Isa>(&self, _cpu: Cpu<I>, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let (origin, dir) = (Vec3A::from(origin), Vec3A::from(dir));
        if self.flat.wide.occluded::<I>(&WideRay::new(origin, dir), tmax) {
            return true;
        }
        if self.large.is_empty() {
            return false;
        }
        if let [only] = self.large[..] {
            return self.instance_blocks::<I>(only, origin, dir, tmax);
        }
        let world = Ray::new(origin, dir, 0.0, tmax);
        let mut state = Traversal::default();
        restart(&mut state, &self.bvh, dir);
        let mut node;
        obvhs::traverse!(self.bvh, node, state, intersect_node(node, &world, state.oct_inv4), {
            let index = self.large[state.primitive_id as usize];
            if self.instance_blocks::<I>(index, origin, dir, tmax) {
                return true;
            }
        });
        false
    }
}
