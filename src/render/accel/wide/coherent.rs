//! Coherent rays through the tree together: sixteen rays (a G-buffer tile's camera rays),
//! one per lane, test each node's children and each leaf's triangles in vector code, and
//! each ray's answer is what [`WideBvh::intersect`] gives it, bit for bit, or the ray is
//! left to that walk.
//!
//! Rays of a 4×4 pixel tile enter nearly the same boxes, so one walk serves them all:
//! a node's child box is tested against the sixteen rays at once (broadcast planes, ray
//! lanes), where each ray alone tests its eight children in its own walk, with its own
//! set-up, sort and stack.
//!
//! Why the answer is the one-ray walk's. That walk returns the first triangle it finds
//! at the smallest distance among those it tests, and which it tests depends on the
//! order it visits boxes in and the closest hit so far. This walk culls nothing by
//! distance: each ray visits every leaf whose boxes it enters at all (the node test with
//! an unbounded `tmax`), a superset of what its own walk visits, with the same arithmetic
//! per ray, so it sees every triangle hit the one-ray walk could see with the same t, u,
//! v. It keeps the nearest; where that one is unique (no other hit at the same t) and no
//! box on its way down is entered beyond it (entry distance ≤ its t, so that the one-ray
//! walk, whose closest distance never falls below it, cannot skip that box), the one-ray
//! walk finds it too and keeps it. Other rays (ties on shared edges, rounding that puts a
//! hit in front of its box) are marked unsure and traced alone by the caller. Culling by
//! the closest hit so far would save tests but could hide a triangle that rounding puts
//! in front of a box behind that hit, which the one-ray walk can still find.
//!
//! Also why only coherent rays: without culling, a ray visits every leaf along it. For
//! camera rays over the flattened small instances (a Cornell box's few dozen triangles)
//! that is a few leaves; rays of large meshes keep their one-ray walks.

use super::walk::Stack;
use super::{Node, Packet, WideBvh, LEAF, ROBUST};
use crate::render::lanes::{F32s, Isa, Mask, U32s, Vec3s, WIDTH};

/// Sixteen rays prepared for the lane tests: origins, directions and inverse directions
/// (obvhs's safe inverse, as [`super::WideRay`]), and which plane is near on each axis,
/// the same for every lane.
pub(in crate::render::accel) struct RayLanes<I> {
    o: [F32s<I>; 3],
    d: [F32s<I>; 3],
    inv: [F32s<I>; 3],
    near: [usize; 3],
    far: [usize; 3],
    /// Lanes holding a ray.
    active: u32,
}

impl<I: Isa> RayLanes<I> {
    /// The rays `(o, d)` of the `active` lanes, or `None` where their directions' signs
    /// differ on some axis (the node test picks near planes by sign, per ray).
    #[inline(always)]
    pub(in crate::render::accel) fn new(o: &Vec3s<I>, d: &Vec3s<I>, active: u32) -> Option<Self> {
        let inv = d.to_array().map(|c| c.map(obvhs::ray::safe_inverse));
        let mut near = [0; 3];
        for a in 0..3 {
            let negative = inv[a].lt(F32s::splat(0.0)).bitmask() & active;
            if negative != 0 && negative != active {
                return None;
            }
            near[a] = 2 * a + usize::from(negative != 0);
        }
        let far = near.map(|n| n ^ 1);
        Some(Self { o: o.to_array(), d: d.to_array(), inv, near, far, active })
    }
}

/// The nearest triangle hit of each lane's ray, where [`RayLanes::active`] lanes in
/// `sure` have their one-ray walk's answer: a hit (bit set in `hit`: t, leaf-order
/// triangle, u, v) or none.
pub(in crate::render::accel) struct LaneHits<I> {
    pub t: F32s<I>,
    pub prim: U32s<I>,
    pub u: F32s<I>,
    pub v: F32s<I>,
    pub hit: u32,
    pub sure: u32,
}

/// A node or leaf to visit, the lanes whose rays enter it, and the largest entry
/// distance of each lane on the way down.
#[derive(Clone, Copy)]
struct Entry<I> {
    child: u32,
    lanes: u32,
    entered: F32s<I>,
}

impl WideBvh {
    /// The nearest hits of `rays` (see the module's notes for when a lane is sure).
    #[inline(always)]
    pub(in crate::render::accel) fn intersect_lanes<I: Isa>(
        &self,
        rays: &RayLanes<I>,
    ) -> LaneHits<I> {
        let mut best = LaneHits {
            t: F32s::splat(f32::INFINITY),
            prim: U32s::splat(u32::MAX),
            u: F32s::splat(0.0),
            v: F32s::splat(0.0),
            hit: 0,
            sure: rays.active,
        };
        if self.nodes.is_empty() {
            return best;
        }
        // The largest entry distance on the way to each lane's nearest hit, and lanes
        // with another hit at that distance.
        let (mut entered, mut tie) = (F32s::splat(0.0), 0u32);
        let mut stack = Stack::<Entry<I>>::new();
        stack.push(Entry { child: 0, lanes: rays.active, entered: F32s::splat(0.0) });
        while let Some(e) = stack.pop() {
            if e.child & LEAF == 0 {
                let node = &self.nodes[e.child as usize];
                let mut valid = node.valid;
                while valid != 0 {
                    let c = valid.trailing_zeros() as usize;
                    valid &= valid - 1;
                    let (enter, tnear) = node.enters(c, rays);
                    let lanes = enter & e.lanes;
                    if lanes != 0 {
                        let entered = e.entered.max(tnear);
                        stack.push(Entry { child: node.child[c], lanes, entered });
                    }
                }
                continue;
            }
            let packet = &self.packets[(e.child & !LEAF) as usize];
            for k in 0..4 {
                let prim = packet.prim[k];
                if prim == u32::MAX {
                    continue;
                }
                let (hits, [t, u, v]) = packet.lane_hits(k, rays);
                let lanes = hits & e.lanes;
                if lanes == 0 {
                    continue;
                }
                let m = Mask::<I>::from_bitmask(lanes);
                let closer = t.lt(best.t) & m;
                tie = (tie & !closer.bitmask()) | (t.eq(best.t) & m).bitmask();
                best.t = F32s::select(closer, t, best.t);
                best.u = F32s::select(closer, u, best.u);
                best.v = F32s::select(closer, v, best.v);
                best.prim = U32s::select(closer, U32s::splat(prim), best.prim);
                entered = F32s::select(closer, e.entered, entered);
            }
        }
        best.hit = best.t.lt(F32s::splat(f32::INFINITY)).bitmask() & rays.active;
        let reachable = best.t.ge(entered).bitmask();
        best.sure = rays.active & !(best.hit & (tie | !reachable));
        best
    }
}

impl Node {
    /// Which lanes' rays enter child `c` (the node test of [`Node::hits`] per lane, with
    /// no `tmax`), and where.
    #[inline(always)]
    fn enters<I: Isa>(&self, c: usize, rays: &RayLanes<I>) -> (u32, F32s<I>) {
        let p = &self.planes;
        let t = |row: usize, axis: usize| (F32s::splat(p[row][c]) - rays.o[axis]) * rays.inv[axis];
        let (n, f) = (rays.near, rays.far);
        let t0 = t(n[0], 0).maxps(t(n[1], 1)).maxps(t(n[2], 2).maxps(F32s::splat(0.0)));
        let far = t(f[0], 0).minps(t(f[1], 1)).minps(t(f[2], 2));
        let t1 = (far * F32s::splat(ROBUST)).minps(F32s::splat(f32::INFINITY));
        (t0.le(t1).bitmask(), t0)
    }
}

impl Packet {
    /// Möller–Trumbore of triangle `k` against each lane's ray, as [`Packet::hits`]
    /// computes it (the same operations in the same order, so the same t, u, v): the
    /// lanes hit at t > 0, and t, u, v.
    #[inline(always)]
    fn lane_hits<I: Isa>(&self, k: usize, rays: &RayLanes<I>) -> (u32, [F32s<I>; 3]) {
        let s = F32s::<I>::splat;
        let v0 = [0, 1, 2].map(|a| s(self.v0[a][k]));
        let e1 = [0, 1, 2].map(|a| s(self.e1[a][k]));
        let e2 = [0, 1, 2].map(|a| s(self.e2[a][k]));
        let (d, o) = (rays.d, rays.o);
        let cross = |a: [F32s<I>; 3], b: [F32s<I>; 3]| {
            [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
        };
        let dot = |a: [F32s<I>; 3], b: [F32s<I>; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let pv = cross(d, e2);
        let det = dot(e1, pv);
        let inv = s(1.0) / det;
        let sv = [o[0] - v0[0], o[1] - v0[1], o[2] - v0[2]];
        let u = dot(sv, pv) * inv;
        let q = cross(sv, e1);
        let v = dot(d, q) * inv;
        let t = dot(e2, q) * inv;
        let (zero, one) = (s(0.0), s(1.0));
        let ok = det.abs().ge(s(1e-12))
            & u.ge(zero)
            & u.le(one)
            & v.ge(zero)
            & (u + v).le(one)
            & t.gt(zero)
            & t.lt(s(f32::INFINITY));
        (ok.bitmask() & ((1u32 << WIDTH) - 1), [t, u, v])
    }
}
