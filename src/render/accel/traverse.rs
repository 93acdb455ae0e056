//! The inner loop of CWBVH traversal shared by both levels: restarting a traversal
//! without reallocating its stack, and the node test.

use glam::{UVec2, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::{CwBvh, Traversal};
use obvhs::faststack::FastStack;
use obvhs::ray::Ray;

/// A fresh traversal of `bvh` reusing `state`'s stack memory (obvhs's
/// `new_traversal` zero-fills a new 32-entry stack each time).
#[inline(always)]
pub(super) fn restart(state: &mut Traversal, bvh: &CwBvh, dir: Vec3A) {
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
pub(super) fn intersect_node(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
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
pub(super) fn intersect_node(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    node.intersect_ray(ray, oct_inv4)
}
