//! The node test (which of eight children a ray enters, and where) and the leaf test
//! (Möller–Trumbore on a packet of four triangles), SIMD on x86-64 and lane by lane
//! elsewhere.

#[cfg(not(target_arch = "x86_64"))]
use super::super::triangle::TriEdges;
use super::{Node, Packet, WideRay, ROBUST};
use crate::render::isa::Isa;
#[cfg(target_arch = "x86_64")]
use crate::render::isa::IsaLevel;
#[cfg(not(target_arch = "x86_64"))]
use glam::Vec3A;

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
    pub(super) fn hits<I: Isa>(&self, ray: &WideRay, tmax: f32) -> (u32, [f32; 8]) {
        use std::arch::x86_64::*;
        let p = &self.planes;
        let (n, f) = (ray.near, ray.far);
        let mut tnear = [0.0f32; 8];
        if I::LEVEL != IsaLevel::Baseline {
            // SAFETY: the v3 and v4 levels are reached only through a `Cpu` of theirs,
            // which exists only where the CPU has AVX; the loads read
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
    pub(super) fn hits<I: Isa>(&self, ray: &WideRay, tmax: f32) -> (u32, [f32; 8]) {
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
    /// Möller–Trumbore on four lanes (two-sided, as [`TriEdges::intersect`]): which
    /// lanes hit within (0, tmax), and their t, u, v.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn hits(&self, ray: &WideRay, tmax: f32) -> (u32, [[f32; 4]; 3]) {
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
    pub(super) fn hits(&self, ray: &WideRay, tmax: f32) -> (u32, [[f32; 4]; 3]) {
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
