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

use std::mem::MaybeUninit;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;

use super::triangle::TriEdges;

/// Which instructions the node test (and the stream kernel's lanes) may use: [`Sse`] on
/// every x86-64, [`Avx`] (one eight-lane register per plane) only where the CPU has AVX
/// and AVX2, which its constructor checks. Both give the same bits.
pub trait Lanes: Copy {
    /// Whether node tests run on eight-lane AVX registers.
    const AVX: bool;
    /// The stream kernel's lane types in this build ([`crate::render::lanes`]).
    type Simd: crate::render::lanes::Isa;
}

/// Node tests in two four-lane halves (every x86-64; scalar elsewhere).
#[derive(Clone, Copy, Debug)]
pub struct Sse;

impl Lanes for Sse {
    const AVX: bool = false;
    type Simd = crate::render::lanes::Sse2;
}

/// Node tests in one eight-lane AVX register per plane: only a CPU with AVX and AVX2 has
/// one (its lanes' integer operations are AVX2).
#[derive(Clone, Copy, Debug)]
pub struct Avx(());

impl Lanes for Avx {
    const AVX: bool = true;
    type Simd = crate::render::lanes::Avx2;
}

/// [`Avx`]'s node tests with the stream kernel's paths in sixteen-lane AVX-512
/// registers: only a CPU with AVX-512 F, BW, DQ and VL has one.
#[derive(Clone, Copy, Debug)]
pub struct Avx512(());

impl Lanes for Avx512 {
    const AVX: bool = true;
    type Simd = crate::render::lanes::Avx512;
}

impl Avx512 {
    /// The token, where this CPU has AVX2 and AVX-512 F, BW, DQ and VL.
    #[cfg(target_arch = "x86_64")]
    pub fn detect() -> Option<Self> {
        let avx512 = Avx::detect().is_some()
            && std::is_x86_feature_detected!("avx512f")
            && std::is_x86_feature_detected!("avx512bw")
            && std::is_x86_feature_detected!("avx512dq")
            && std::is_x86_feature_detected!("avx512vl");
        avx512.then_some(Self(()))
    }

    /// The token, where this CPU has AVX-512 (never, off x86-64).
    #[cfg(not(target_arch = "x86_64"))]
    pub fn detect() -> Option<Self> {
        None
    }
}

impl Avx {
    /// The token, where this CPU has AVX and AVX2.
    #[cfg(target_arch = "x86_64")]
    pub fn detect() -> Option<Self> {
        let avx2 = std::is_x86_feature_detected!("avx") && std::is_x86_feature_detected!("avx2");
        avx2.then_some(Self(()))
    }

    /// The token, where this CPU has AVX and AVX2 (never, off x86-64).
    #[cfg(not(target_arch = "x86_64"))]
    pub fn detect() -> Option<Self> {
        None
    }
}

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

/// `a > b ? a : b` (and `<`): SSE's `maxps` and `minps`, NaN handling included.
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

impl Node {
    /// Which children the ray enters before `tmax`, and the entry distances: two SSE
    /// halves (explicit, because the auto-vectoriser split the lanes unevenly).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn hits<L: Lanes>(&self, ray: &WideRay, tmax: f32) -> (u32, [f32; 8]) {
        use std::arch::x86_64::*;
        let p = &self.planes;
        let (n, f) = (ray.near, ray.far);
        let mut tnear = [0.0f32; 8];
        if L::AVX {
            // SAFETY: an `Avx` token exists only where the CPU has AVX; the loads read
            // whole 32-byte aligned rows of `planes`, the store all of `tnear`.
            let mask = unsafe {
                let o = ray.o.map(|x| _mm256_set1_ps(x));
                let inv = ray.inv.map(|x| _mm256_set1_ps(x));
                let (zero, tmax) = (_mm256_setzero_ps(), _mm256_set1_ps(tmax));
                let t = |row: usize, axis: usize| {
                    let b = _mm256_load_ps(p[row].as_ptr());
                    _mm256_mul_ps(_mm256_sub_ps(b, o[axis]), inv[axis])
                };
                let t0 = _mm256_max_ps(
                    _mm256_max_ps(t(n[0], 0), t(n[1], 1)),
                    _mm256_max_ps(t(n[2], 2), zero),
                );
                let far = _mm256_min_ps(_mm256_min_ps(t(f[0], 0), t(f[1], 1)), t(f[2], 2));
                let t1 = _mm256_min_ps(_mm256_mul_ps(far, _mm256_set1_ps(ROBUST)), tmax);
                _mm256_storeu_ps(tnear.as_mut_ptr(), t0);
                _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32
            };
            return (mask & self.valid, tnear);
        }
        let mut mask = 0u32;
        // SAFETY: SSE is part of x86_64; every load reads four floats inside a row of
        // `planes` (rows are 32-byte aligned by `Node`'s alignment), the store four of
        // `tnear`.
        unsafe {
            let o = ray.o.map(|x| _mm_set1_ps(x));
            let inv = ray.inv.map(|x| _mm_set1_ps(x));
            let (zero, tmax) = (_mm_setzero_ps(), _mm_set1_ps(tmax));
            for half in 0..2 {
                let t = |row: usize, axis: usize| {
                    let b = _mm_load_ps(p[row].as_ptr().add(4 * half));
                    _mm_mul_ps(_mm_sub_ps(b, o[axis]), inv[axis])
                };
                let t0 =
                    _mm_max_ps(_mm_max_ps(t(n[0], 0), t(n[1], 1)), _mm_max_ps(t(n[2], 2), zero));
                let far = _mm_min_ps(_mm_min_ps(t(f[0], 0), t(f[1], 1)), t(f[2], 2));
                let t1 = _mm_min_ps(_mm_mul_ps(far, _mm_set1_ps(ROBUST)), tmax);
                _mm_storeu_ps(tnear.as_mut_ptr().add(4 * half), t0);
                mask |= (_mm_movemask_ps(_mm_cmple_ps(t0, t1)) as u32) << (4 * half);
            }
        }
        (mask & self.valid, tnear)
    }

    /// The same test lane by lane, where there is no SSE.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn hits<L: Lanes>(&self, ray: &WideRay, tmax: f32) -> (u32, [f32; 8]) {
        let p = &self.planes;
        let (n, f) = (ray.near, ray.far);
        let t = |row: usize, axis: usize, i: usize| (p[row][i] - ray.o[axis]) * ray.inv[axis];
        let mut tnear = [0.0f32; 8];
        let mut mask = 0u32;
        for i in 0..8 {
            let t0 = max(max(t(n[0], 0, i), t(n[1], 1, i)), max(t(n[2], 2, i), 0.0));
            let far = min(min(t(f[0], 0, i), t(f[1], 1, i)), t(f[2], 2, i));
            let t1 = min(far * ROBUST, tmax);
            tnear[i] = t0;
            mask |= u32::from(t0 <= t1) << i;
        }
        (mask & self.valid, tnear)
    }
}

impl Packet {
    /// The packet of leaf-order triangles `prims` (at most four) of `tris`.
    fn new(tris: &[TriEdges], prims: &[u32]) -> Self {
        let mut p = Packet { prim: [u32::MAX; 4], ..Default::default() };
        for (lane, &prim) in prims.iter().enumerate() {
            let tri = &tris[prim as usize];
            for a in 0..3 {
                p.v0[a][lane] = tri.v0[a];
                p.e1[a][lane] = tri.e1[a];
                p.e2[a][lane] = tri.e2[a];
            }
            p.prim[lane] = prim;
        }
        p
    }

    /// Möller–Trumbore on four lanes (two-sided, as [`TriEdges::intersect`]): which
    /// lanes hit within (0, tmax), and their t, u, v.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn hits(&self, ray: &WideRay, tmax: f32) -> (u32, [[f32; 4]; 3]) {
        use std::arch::x86_64::*;
        let mut tuv = [[0.0f32; 4]; 3];
        // SAFETY: SSE is part of x86_64; the loads read the packet's 16-byte aligned
        // rows, the stores write the rows of `tuv`.
        let mask = unsafe {
            let ld = |row: &[f32; 4]| _mm_load_ps(row.as_ptr());
            let (v0, e1, e2) = (
                self.v0.each_ref().map(ld),
                self.e1.each_ref().map(ld),
                self.e2.each_ref().map(ld),
            );
            let d = ray.d.map(|x| _mm_set1_ps(x));
            let o = ray.o.map(|x| _mm_set1_ps(x));
            let (mul, sub, add) =
                (|a, b| _mm_mul_ps(a, b), |a, b| _mm_sub_ps(a, b), |a, b| _mm_add_ps(a, b));
            let cross = |a: [__m128; 3], b: [__m128; 3]| {
                [
                    sub(mul(a[1], b[2]), mul(a[2], b[1])),
                    sub(mul(a[2], b[0]), mul(a[0], b[2])),
                    sub(mul(a[0], b[1]), mul(a[1], b[0])),
                ]
            };
            let dot = |a: [__m128; 3], b: [__m128; 3]| {
                add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
            };
            let pv = cross(d, e2);
            let det = dot(e1, pv);
            let inv = _mm_div_ps(_mm_set1_ps(1.0), det);
            let s = [sub(o[0], v0[0]), sub(o[1], v0[1]), sub(o[2], v0[2])];
            let u = mul(dot(s, pv), inv);
            let q = cross(s, e1);
            let v = mul(dot(d, q), inv);
            let t = mul(dot(e2, q), inv);
            let (zero, one) = (_mm_setzero_ps(), _mm_set1_ps(1.0));
            let abs_det = _mm_andnot_ps(_mm_set1_ps(-0.0), det);
            let ok = _mm_and_ps(
                _mm_and_ps(_mm_cmpge_ps(abs_det, _mm_set1_ps(1e-12)), _mm_cmpge_ps(u, zero)),
                _mm_and_ps(_mm_cmple_ps(u, one), _mm_cmpge_ps(v, zero)),
            );
            let ok = _mm_and_ps(ok, _mm_cmple_ps(add(u, v), one));
            let ok = _mm_and_ps(
                ok,
                _mm_and_ps(_mm_cmpgt_ps(t, zero), _mm_cmplt_ps(t, _mm_set1_ps(tmax))),
            );
            _mm_storeu_ps(tuv[0].as_mut_ptr(), t);
            _mm_storeu_ps(tuv[1].as_mut_ptr(), u);
            _mm_storeu_ps(tuv[2].as_mut_ptr(), v);
            _mm_movemask_ps(ok) as u32
        };
        (mask, tuv)
    }

    /// The same test lane by lane with [`TriEdges::intersect`], where there is no SSE.
    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn hits(&self, ray: &WideRay, tmax: f32) -> (u32, [[f32; 4]; 3]) {
        let (o, d) = (Vec3A::from(ray.o), Vec3A::from(ray.d));
        let mut tuv = [[0.0f32; 4]; 3];
        let mut mask = 0;
        for i in 0..4 {
            let lane = |rows: &[[f32; 4]; 3]| Vec3A::new(rows[0][i], rows[1][i], rows[2][i]);
            let tri = TriEdges { v0: lane(&self.v0), e1: lane(&self.e1), e2: lane(&self.e2) };
            if let Some((t, u, v)) = tri.intersect(o, d, 0.0, tmax) {
                mask |= 1 << i;
                [tuv[0][i], tuv[1][i], tuv[2][i]] = [t, u, v];
            }
        }
        (mask, tuv)
    }
}

/// The traversal stack: `(child reference, entry distance)`, inline up to [`STACK`]
/// entries (eight-wide trees are shallow), on the heap beyond.
struct Stack {
    inline: [MaybeUninit<(u32, f32)>; STACK],
    len: usize,
    spill: Vec<(u32, f32)>,
}

impl Stack {
    #[inline(always)]
    fn new() -> Self {
        // Not zeroed: a memset per ray cost 4 % of a bunny frame (and the array-repeat
        // form still compiled to one).
        // SAFETY: an array of `MaybeUninit` needs no initialisation.
        let inline =
            unsafe { MaybeUninit::<[MaybeUninit<(u32, f32)>; STACK]>::uninit().assume_init() };
        Self { inline, len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    fn push(&mut self, entry: (u32, f32)) {
        if self.len < STACK {
            self.inline[self.len] = MaybeUninit::new(entry);
            self.len += 1;
        } else {
            self.spill.push(entry);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(e) = self.spill.pop() {
            return Some(e);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were written by `push`.
        Some(unsafe { self.inline[self.len].assume_init() })
    }
}

/// Merges the leaf children of one node (box, triangles) into packets of up to four.
/// A CWBVH leaf holds at most three triangles, so most packets ran with lanes empty
/// (two fifths full on bunny and Sponza), and a packet costs the same test however full.
/// Two leaves merge when the surface area heuristic says it pays: a ray reaches a box
/// with probability in proportion to its area, so one test of the union box costs less
/// than the two separate tests when area(a ∪ b) < area(a) + area(b). The best such pair
/// merges first, until no pair fits in four lanes and pays.
fn pack_leaves(mut leaves: Vec<(Aabb, Vec<u32>)>) -> Vec<(Aabb, Vec<u32>)> {
    loop {
        let mut best: Option<(f32, usize, usize)> = None;
        for i in 0..leaves.len() {
            for j in i + 1..leaves.len() {
                if leaves[i].1.len() + leaves[j].1.len() > 4 {
                    continue;
                }
                let (a, b) = (&leaves[i].0, &leaves[j].0);
                let ratio = a.union(b).half_area() / (a.half_area() + b.half_area()).max(1e-30);
                if ratio < 1.0 && best.is_none_or(|(r, ..)| ratio < r) {
                    best = Some((ratio, i, j));
                }
            }
        }
        let Some((_, i, j)) = best else { return leaves };
        let (bounds, prims) = leaves.swap_remove(j);
        leaves[i].0 = leaves[i].0.union(&bounds);
        leaves[i].1.extend(prims);
    }
}

/// Fills the slots that packing freed: a node takes the children of its largest inner
/// child in that child's place while they fit in eight slots, so that a ray tests them
/// in the parent's node test instead of a further one. Parents come before children in
/// the CWBVH's order, so a pulled-up grandchild can be expanded in turn; the nodes this
/// leaves unreferenced are dropped by [`reachable`].
fn pull_up(lists: &mut [Vec<(Aabb, u32)>]) {
    for n in 0..lists.len() {
        loop {
            let free = 8 - lists[n].len();
            let pick = lists[n]
                .iter()
                .enumerate()
                .filter(|(_, (_, c))| c & LEAF == 0 && lists[*c as usize].len() <= free + 1)
                .max_by(|a, b| a.1 .0.half_area().total_cmp(&b.1 .0.half_area()))
                .map(|(i, _)| i);
            let Some(i) = pick else { break };
            let (_, child) = lists[n].swap_remove(i);
            let grandchildren = lists[child as usize].clone();
            lists[n].extend(grandchildren);
        }
    }
}

/// The nodes reachable from the root, renumbered in depth-first order (the order a
/// traversal meets them, which keeps a subtree's nodes together in memory).
fn reachable(mut lists: Vec<Vec<(Aabb, u32)>>) -> Vec<Vec<(Aabb, u32)>> {
    if lists.is_empty() {
        return lists;
    }
    let mut order = Vec::with_capacity(lists.len());
    let mut new_index = vec![u32::MAX; lists.len()];
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        new_index[n as usize] = order.len() as u32;
        order.push(n);
        for &(_, c) in lists[n as usize].iter().rev() {
            if c & LEAF == 0 {
                stack.push(c);
            }
        }
    }
    order
        .into_iter()
        .map(|n| {
            let mut children = std::mem::take(&mut lists[n as usize]);
            for (_, c) in &mut children {
                if *c & LEAF == 0 {
                    *c = new_index[*c as usize];
                }
            }
            children
        })
        .collect()
}

impl WideBvh {
    /// Decodes `bvh` (built over `tris`, which are in its leaf order), packing the leaf
    /// children of each node into as few four-lane packets as pays (see [`pack_leaves`]).
    pub(super) fn build(bvh: &CwBvh, tris: &[TriEdges]) -> Self {
        let mut out = WideBvh { nodes: Vec::with_capacity(bvh.nodes.len()), packets: Vec::new() };
        // Each node's children as (box, reference) before they are laid out.
        let mut lists: Vec<Vec<(Aabb, u32)>> = Vec::with_capacity(bvh.nodes.len());
        for cw in &bvh.nodes {
            let ext = cw.compute_extent();
            let quantised = [
                &cw.child_min_x,
                &cw.child_max_x,
                &cw.child_min_y,
                &cw.child_max_y,
                &cw.child_min_z,
                &cw.child_max_z,
            ];
            let mut children = Vec::with_capacity(8);
            let mut leaves = Vec::with_capacity(8);
            for i in 0..8 {
                let meta = cw.child_meta[i];
                if meta == 0 {
                    continue;
                }
                let mut bounds = Aabb::empty();
                for (plane, q) in quantised.iter().enumerate() {
                    let axis = plane / 2;
                    // The CWBVH quantised a rounded difference, so its planes may sit a
                    // rounding inside the true bounds; a 4096th of a quantum and two
                    // ulps of the decoded plane outwards cover that and the decoding.
                    let x = cw.p[axis] + q[i] as f32 * ext[axis];
                    let pad = ext[axis] * (1.0 / 4096.0);
                    if plane % 2 == 0 {
                        bounds.min[axis] = (x - pad).next_down().next_down();
                    } else {
                        bounds.max[axis] = (x + pad).next_up().next_up();
                    }
                }
                let low = u32::from(meta & 0x1f);
                if low >= 24 {
                    let slot = low - 24;
                    debug_assert!(cw.imask & (1 << slot) != 0);
                    let child = cw.child_base_idx
                        + (u32::from(cw.imask) & ((1u32 << slot) - 1)).count_ones();
                    children.push((bounds, child));
                } else {
                    let first = cw.primitive_base_idx + low;
                    let count = (meta >> 5).count_ones();
                    leaves.push((bounds, (first..first + count).collect::<Vec<u32>>()));
                }
            }
            for (bounds, prims) in pack_leaves(leaves) {
                out.packets.push(Packet::new(tris, &prims));
                children.push((bounds, LEAF | (out.packets.len() as u32 - 1)));
            }
            lists.push(children);
        }
        pull_up(&mut lists);
        for children in reachable(lists) {
            let mut node = Node { planes: [[0.0; 8]; 6], child: [0; 8], valid: 0 };
            for (i, (bounds, child)) in children.into_iter().enumerate() {
                for axis in 0..3 {
                    node.planes[2 * axis][i] = bounds.min[axis];
                    node.planes[2 * axis + 1][i] = bounds.max[axis];
                }
                node.child[i] = child;
                node.valid |= 1 << i;
            }
            out.nodes.push(node);
        }
        out
    }

    /// How many of this tree's node and leaf lanes hold something.
    pub(super) fn lane_fill(&self) -> LaneFill {
        LaneFill {
            node_lanes_used: self.nodes.iter().map(|n| u64::from(n.valid.count_ones())).sum(),
            node_lanes: 8 * self.nodes.len() as u64,
            leaf_lanes_used: self
                .packets
                .iter()
                .map(|p| p.prim.iter().filter(|&&i| i != u32::MAX).count() as u64)
                .sum(),
            leaf_lanes: 4 * self.packets.len() as u64,
        }
    }

    /// The closest triangle the ray hits in (0, tmax).
    #[inline(always)]
    pub(super) fn intersect<L: Lanes>(&self, ray: &WideRay, tmax: f32) -> Option<TriHit> {
        let mut walk = ClosestWalk::new(self, tmax);
        while !walk.done {
            walk.step::<L>(self, ray);
        }
        walk.hit()
    }

    /// Whether any triangle blocks the ray in (0, tmax).
    #[inline(always)]
    pub(super) fn occluded<L: Lanes>(&self, ray: &WideRay, tmax: f32) -> bool {
        let mut walk = AnyWalk::new(self);
        while !walk.done {
            walk.step::<L>(self, ray, tmax);
        }
        walk.blocked
    }

    /// [`WideBvh::intersect`] of `closest` and [`WideBvh::occluded`] of `shadow`, the two
    /// walks advanced in turns, one node or leaf each. A path's bounce ray and shadow ray
    /// are independent, and on a tree larger than the caches each step waits on a load
    /// from memory: interleaved, the core has both loads in flight at once. Each walk
    /// takes the steps it takes alone, so the answers are the same bit for bit.
    #[inline(always)]
    pub(super) fn intersect_and_occluded<L: Lanes>(
        &self,
        (closest, tmax): (&WideRay, f32),
        (shadow, shadow_tmax): (&WideRay, f32),
    ) -> (Option<TriHit>, bool) {
        let mut a = ClosestWalk::new(self, tmax);
        let mut b = AnyWalk::new(self);
        while !a.done && !b.done {
            a.step::<L>(self, closest);
            b.step::<L>(self, shadow, shadow_tmax);
        }
        while !a.done {
            a.step::<L>(self, closest);
        }
        while !b.done {
            b.step::<L>(self, shadow, shadow_tmax);
        }
        (a.hit(), b.blocked)
    }
}

/// A closest-hit traversal in progress: children visited nearest first, stacked entries
/// behind the closest hit dropped unvisited.
struct ClosestWalk {
    best: TriHit,
    stack: Stack,
    /// The node or leaf the next step tests.
    current: u32,
    done: bool,
}

impl ClosestWalk {
    #[inline(always)]
    fn new(bvh: &WideBvh, tmax: f32) -> Self {
        let best = TriHit { t: tmax, prim: u32::MAX, u: 0.0, v: 0.0 };
        Self { best, stack: Stack::new(), current: 0, done: bvh.nodes.is_empty() }
    }

    #[inline(always)]
    fn hit(&self) -> Option<TriHit> {
        (self.best.prim != u32::MAX).then_some(self.best)
    }

    /// Tests the current node or leaf and moves to the next (or finishes).
    #[inline(always)]
    fn step<L: Lanes>(&mut self, bvh: &WideBvh, ray: &WideRay) {
        let current = self.current;
        if current & LEAF == 0 {
            let node = &bvh.nodes[current as usize];
            let (mask, tnear) = node.hits::<L>(ray, self.best.t);
            if mask != 0 {
                let first = mask.trailing_zeros() as usize;
                if mask & (mask - 1) == 0 {
                    self.current = node.child[first];
                    return;
                }
                // Nearest first: sort the entered children by distance, farthest at
                // the bottom (stable, so ties keep child order).
                let mut order = [(0u32, 0.0f32); 8];
                let mut n = 0;
                let mut m = mask;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let entry = (node.child[i], tnear[i]);
                    let mut j = n;
                    while j > 0 && order[j - 1].1 < entry.1 {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = entry;
                    n += 1;
                }
                for &entry in &order[..n - 1] {
                    self.stack.push(entry);
                }
                self.current = order[n - 1].0;
                return;
            }
        } else {
            let packet = &bvh.packets[(current & !LEAF) as usize];
            let (mut mask, tuv) = packet.hits(ray, self.best.t);
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if tuv[0][i] < self.best.t {
                    self.best =
                        TriHit { t: tuv[0][i], prim: packet.prim[i], u: tuv[1][i], v: tuv[2][i] };
                }
            }
        }
        // Next: the nearest stacked entry not behind the closest hit.
        loop {
            let Some((r, t)) = self.stack.pop() else {
                self.done = true;
                return;
            };
            if t < self.best.t {
                self.current = r;
                return;
            }
        }
    }
}

/// An any-hit traversal in progress: it stops at the first triangle in range.
struct AnyWalk {
    stack: Stack,
    current: u32,
    blocked: bool,
    done: bool,
}

impl AnyWalk {
    #[inline(always)]
    fn new(bvh: &WideBvh) -> Self {
        Self { stack: Stack::new(), current: 0, blocked: false, done: bvh.nodes.is_empty() }
    }

    /// Tests the current node or leaf and moves to the next (or finishes).
    #[inline(always)]
    fn step<L: Lanes>(&mut self, bvh: &WideBvh, ray: &WideRay, tmax: f32) {
        let current = self.current;
        if current & LEAF == 0 {
            let node = &bvh.nodes[current as usize];
            let (mut mask, _) = node.hits::<L>(ray, tmax);
            if mask != 0 {
                self.current = node.child[mask.trailing_zeros() as usize];
                mask &= mask - 1;
                while mask != 0 {
                    self.stack.push((node.child[mask.trailing_zeros() as usize], 0.0));
                    mask &= mask - 1;
                }
                return;
            }
        } else if bvh.packets[(current & !LEAF) as usize].hits(ray, tmax).0 != 0 {
            self.blocked = true;
            self.done = true;
            return;
        }
        match self.stack.pop() {
            Some((r, _)) => self.current = r,
            None => self.done = true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::accel::Blas;
    use std::sync::Arc;

    /// Packing and pulling up keep every triangle exactly once, inside every box on the
    /// way to it (so a ray that hits it reaches it), with every node reachable and the
    /// lanes fuller than the CWBVH's three-per-leaf packets left them.
    #[test]
    fn packed_layout_keeps_every_triangle_inside_its_boxes() {
        let blas = Blas::build(Arc::new(crate::shapes::sphere(4))).unwrap();
        let wide = &blas.wide;
        let mut seen = vec![0u32; blas.tris.len()];
        let mut reached = vec![false; wide.nodes.len()];
        let mut stack = vec![(0u32, [f32::NEG_INFINITY, f32::INFINITY].repeat(3))];
        while let Some((n, bounds)) = stack.pop() {
            reached[n as usize] = true;
            let node = &wide.nodes[n as usize];
            assert_eq!(node.valid & (node.valid + 1), 0, "node {n}: slots not packed low");
            for i in 0..node.valid.count_ones() as usize {
                // What a ray must pass to get here: this box within all its ancestors'.
                let b: Vec<f32> = (0..6)
                    .map(|p| {
                        let x = node.planes[p][i];
                        if p % 2 == 0 {
                            x.max(bounds[p])
                        } else {
                            x.min(bounds[p])
                        }
                    })
                    .collect();
                let child = node.child[i];
                if child & LEAF == 0 {
                    stack.push((child, b));
                    continue;
                }
                let packet = &wide.packets[(child & !LEAF) as usize];
                for lane in (0..4).filter(|&l| packet.prim[l] != u32::MAX) {
                    let prim = packet.prim[lane];
                    seen[prim as usize] += 1;
                    let t = &blas.tris[prim as usize];
                    for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
                        for axis in 0..3 {
                            assert!(v[axis] >= b[2 * axis] && v[axis] <= b[2 * axis + 1]);
                        }
                    }
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "a triangle is missing or repeated");
        assert!(reached.iter().all(|&r| r), "unreachable nodes were kept");
        let fill = wide.lane_fill();
        assert!(fill.leaf_occupancy() > 0.6, "leaf lanes {:.2}", fill.leaf_occupancy());
    }
}
