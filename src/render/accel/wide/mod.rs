//! The CPU's traversal layout: an eight-wide BVH with full-precision child boxes stored
//! component by component, and leaves of up to four triangles tested together.
//!
//! obvhs's CWBVH is built for GPUs: each child box is eight bits per plane, so a node is
//! 80 bytes but every test first widens 48 bytes to floats and scales them, which was a
//! third of a bunny frame and two fifths of a Sponza frame. This layout keeps the CWBVH's
//! topology (its SAH build is good) and decodes the boxes once, at build time, as Embree's
//! single-ray kernels store them: `[lo_x, hi_x, lo_y, hi_y, lo_z, hi_z]` × eight children.
//! A node test is then twelve lane-wise subtractions and multiplications, eight-wide in
//! the x86-64-v3 build (one AVX register per plane) and two SSE halves in the baseline,
//! and children are visited nearest first with a distance on the stack, so entries behind
//! the closest hit found so far are dropped without a test. A leaf's triangles sit in one
//! packet of four lanes, tested at once; a CWBVH leaf has at most three, so the leaves
//! of a node are merged into fuller packets where the surface area heuristic says it
//! pays, and the node slots this frees take grandchildren up (one node test fewer).
//!
//! Why not across rays: after the first bounce the rays of neighbouring paths diverge,
//! and a packet of incoherent rays visits the union of their nodes; Embree's own choice
//! for incoherent rays is one ray against a wide node, which is this. What a path does
//! have is two independent rays per vertex, the shadow ray and the next bounce: they are
//! walked in turns, one node or leaf each (`intersect_and_occluded`), so that on trees
//! larger than the caches both walks' loads are in flight together. Widening the turns to
//! all eight lanes' walks at once (sixteen, each prefetching its next node a turn ahead)
//! measured 0.82–0.92× on the bunny (a likely cause, not isolated: the walks' state then
//! lives in memory instead of registers).
//!
//! Every build gives the same hits bit for bit: the lanes are plain IEEE operations in a
//! fixed order (Rust neither contracts nor reorders float arithmetic), whatever width the
//! compiler picks, and ties go to the lower lane and the earlier stack entry.
//!
//! Coherent rays, though, do share their nodes: a G-buffer tile's camera rays walk the
//! tree together, one ray per lane of the vector types (`coherent.rs`), with the same
//! answers as their walks alone.
//!
//! Files: this one holds the layout (nodes, leaf packets, the prepared ray); `build.rs`
//! the layout made from obvhs's CWBVH, `hits.rs` the node and packet tests (in the
//! instructions of the [`crate::render::isa::Isa`] they are compiled for), `walk.rs` the
//! traversals, `coherent.rs` sixteen coherent rays' walk in lanes.

use glam::Vec3A;

mod build;
mod coherent;
mod hits;
mod walk;

pub(super) use coherent::{LaneHits, RayLanes};

/// A child reference with this bit set is a leaf (its packet's index below it).
const LEAF: u32 = 0x8000_0000;
/// Far distances of a box are scaled by this before the overlap test: Ize's robust
/// traversal factor 1 + 2γ₃ ("Robust BVH Ray Traversal", JCGT 2013), so that rounding
/// in the slab distances cannot drop a box the ray touches.
const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);
/// Stack entries held inline; deeper traversals spill to the heap.
const STACK: usize = 64;

/// One node: eight child boxes, plane by plane, and what each child is.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Node {
    /// `[lo_x, hi_x, lo_y, hi_y, lo_z, hi_z]`, each for children 0..8.
    planes: [[f32; 8]; 6],
    /// Node index, or `LEAF | packet index`.
    child: [u32; 8],
    /// Bit i set when child i exists.
    valid: u32,
}

/// Up to four triangles of one leaf, lane by lane; unused lanes have zero edges and
/// never hit.
#[derive(Clone, Copy, Default)]
#[repr(C, align(16))]
struct Packet {
    v0: [[f32; 4]; 3],
    e1: [[f32; 4]; 3],
    e2: [[f32; 4]; 3],
    /// Leaf-order triangle index of each lane.
    prim: [u32; 4],
}

/// The wide BVH of one triangle set (a mesh's BLAS or the flattened small instances).
#[derive(Default)]
pub(super) struct WideBvh {
    nodes: Vec<Node>,
    packets: Vec<Packet>,
}

/// How full a tree's SIMD lanes are: of the eight lanes of every node test, those holding
/// a child box, and of the four lanes of every leaf test, those holding a triangle.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LaneFill {
    pub node_lanes_used: u64,
    pub node_lanes: u64,
    pub leaf_lanes_used: u64,
    pub leaf_lanes: u64,
}

/// Two trees' counts together.
impl std::ops::Add for LaneFill {
    type Output = Self;

    fn add(self, o: Self) -> Self {
        Self {
            node_lanes_used: self.node_lanes_used + o.node_lanes_used,
            node_lanes: self.node_lanes + o.node_lanes,
            leaf_lanes_used: self.leaf_lanes_used + o.leaf_lanes_used,
            leaf_lanes: self.leaf_lanes + o.leaf_lanes,
        }
    }
}

impl LaneFill {
    /// Used share of the node-test lanes (0 for an empty tree).
    pub fn node_occupancy(&self) -> f64 {
        self.node_lanes_used as f64 / self.node_lanes.max(1) as f64
    }

    /// Used share of the leaf-test lanes (0 for an empty tree).
    pub fn leaf_occupancy(&self) -> f64 {
        self.leaf_lanes_used as f64 / self.leaf_lanes.max(1) as f64
    }
}

/// A ray prepared for node tests: which plane is near on each axis, and the inverse
/// direction (obvhs's safe inverse, so that axis-parallel rays stay finite).
pub(super) struct WideRay {
    o: [f32; 3],
    d: [f32; 3],
    inv: [f32; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl WideRay {
    #[inline(always)]
    pub(super) fn new(o: Vec3A, d: Vec3A) -> Self {
        let inv = [d.x, d.y, d.z].map(obvhs::ray::safe_inverse);
        let near = [0, 1, 2].map(|a| 2 * a + usize::from(inv[a] < 0.0));
        let far = near.map(|n| n ^ 1);
        Self { o: o.into(), d: d.into(), inv, near, far }
    }
}

/// Closest triangle hit: distance, leaf-order triangle and barycentrics (u at vertex 1,
/// v at vertex 2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct TriHit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}
