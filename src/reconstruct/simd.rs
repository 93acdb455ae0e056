//! Vectors of [`LANES`] f32 for the CPU passes' kernels, and the dispatch that runs each
//! kernel with the best instruction set the CPU has.
//!
//! The kernels are written once, generic over an [`Isa`]: [`F32s`] and [`Vec3s`] are
//! [`LANES`] pixels' values, and every operation on them is one instruction of that
//! instruction set (AVX2 on x86-64 where the CPU has it, compiled with AVX-512 VL's extra
//! registers where it has that too; else plain arrays the compiler may vectorise as it
//! can). Explicit instructions keep the code the compiler emits for
//! the filters' loops predictable, which auto-vectorisation of such large loop bodies was
//! not. Every operation rounds as the scalar f32 one does (no fused multiply-add), so a
//! lane computes exactly what the scalar expression computes.

use std::ops::{Add, AddAssign, Div, Mul, Sub};

use glam::Vec3;
use rayon::prelude::*;

use super::discontinuity::Real;

/// Pixels per vector: one 256-bit vector of f32.
pub const LANES: usize = 8;

/// The vector instructions the kernels are written in.
///
/// # Safety
/// An implementation's functions may only run on a CPU that has its instructions;
/// [`run_rows`] only runs kernels with one the CPU has.
pub unsafe trait Isa: Copy + Send + Sync + 'static {
    /// [`LANES`] f32.
    type V: Copy + std::fmt::Debug;

    fn splat(v: f32) -> Self::V;
    fn load(a: &[f32; LANES]) -> Self::V;
    fn to_array(v: Self::V) -> [f32; LANES];
    fn store(v: Self::V, a: &mut [f32; LANES]);
    fn add(a: Self::V, b: Self::V) -> Self::V;
    fn sub(a: Self::V, b: Self::V) -> Self::V;
    fn mul(a: Self::V, b: Self::V) -> Self::V;
    fn div(a: Self::V, b: Self::V) -> Self::V;
    /// max(0, a) lane by lane, NaN giving 0 (as `if a > 0 { a } else { 0 }`).
    fn positive_part(a: Self::V) -> Self::V;
    /// The bits of `a` and `mask`.
    fn and(a: Self::V, mask: Self::V) -> Self::V;
    /// `a` in the lanes where `c` > 0, `b` in the others.
    fn if_positive(c: Self::V, a: Self::V, b: Self::V) -> Self::V;
}

/// Arrays of f32, for CPUs without AVX2 (and other architectures).
#[derive(Clone, Copy, Debug)]
pub struct Portable;

// SAFETY: plain Rust, which runs anywhere.
unsafe impl Isa for Portable {
    type V = [f32; LANES];

    #[inline(always)]
    fn splat(v: f32) -> Self::V {
        [v; LANES]
    }

    #[inline(always)]
    fn load(a: &[f32; LANES]) -> Self::V {
        *a
    }

    #[inline(always)]
    fn to_array(v: Self::V) -> [f32; LANES] {
        v
    }

    #[inline(always)]
    fn store(v: Self::V, a: &mut [f32; LANES]) {
        *a = v;
    }

    #[inline(always)]
    fn add(a: Self::V, b: Self::V) -> Self::V {
        std::array::from_fn(|k| a[k] + b[k])
    }

    #[inline(always)]
    fn sub(a: Self::V, b: Self::V) -> Self::V {
        std::array::from_fn(|k| a[k] - b[k])
    }

    #[inline(always)]
    fn mul(a: Self::V, b: Self::V) -> Self::V {
        std::array::from_fn(|k| a[k] * b[k])
    }

    #[inline(always)]
    fn div(a: Self::V, b: Self::V) -> Self::V {
        std::array::from_fn(|k| a[k] / b[k])
    }

    #[inline(always)]
    fn positive_part(a: Self::V) -> Self::V {
        std::array::from_fn(|k| a[k].positive_part())
    }

    #[inline(always)]
    fn and(a: Self::V, mask: Self::V) -> Self::V {
        std::array::from_fn(|k| f32::from_bits(a[k].to_bits() & mask[k].to_bits()))
    }

    #[inline(always)]
    fn if_positive(c: Self::V, a: Self::V, b: Self::V) -> Self::V {
        std::array::from_fn(|k| if c[k] > 0.0 { a[k] } else { b[k] })
    }
}

#[cfg(target_arch = "x86_64")]
pub use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Isa, LANES};

    /// 256-bit AVX2 vectors.
    #[derive(Clone, Copy, Debug)]
    pub struct Avx2;

    // SAFETY: `run_rows` runs `Avx2` kernels only where the CPU has AVX2. The intrinsics
    // below need nothing else: loads take a reference to LANES f32, and none of them has
    // a precondition beyond the instruction set.
    unsafe impl Isa for Avx2 {
        type V = __m256;

        #[inline(always)]
        fn splat(v: f32) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_set1_ps(v) }
        }

        #[inline(always)]
        fn load(a: &[f32; LANES]) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_loadu_ps(a.as_ptr()) }
        }

        #[inline(always)]
        fn to_array(v: __m256) -> [f32; LANES] {
            let mut a = [0.0; LANES];
            Self::store(v, &mut a);
            a
        }

        #[inline(always)]
        fn store(v: __m256, a: &mut [f32; LANES]) {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), v) }
        }

        #[inline(always)]
        fn add(a: __m256, b: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_add_ps(a, b) }
        }

        #[inline(always)]
        fn sub(a: __m256, b: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_sub_ps(a, b) }
        }

        #[inline(always)]
        fn mul(a: __m256, b: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_mul_ps(a, b) }
        }

        #[inline(always)]
        fn div(a: __m256, b: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_div_ps(a, b) }
        }

        #[inline(always)]
        fn positive_part(a: __m256) -> __m256 {
            // maxps returns its second operand where either is NaN (or both are zero).
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_max_ps(a, _mm256_setzero_ps()) }
        }

        #[inline(always)]
        fn and(a: __m256, mask: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe { _mm256_and_ps(a, mask) }
        }

        #[inline(always)]
        fn if_positive(c: __m256, a: __m256, b: __m256) -> __m256 {
            // SAFETY: an AVX2 intrinsic; `Avx2` kernels run only where the CPU has AVX2.
            unsafe {
                let positive = _mm256_cmp_ps::<_CMP_GT_OQ>(c, _mm256_setzero_ps());
                _mm256_blendv_ps(b, a, positive)
            }
        }
    }
}

/// [`LANES`] f32, one per pixel of a run.
#[derive(Clone, Copy, Debug)]
pub struct F32s<I: Isa>(pub I::V);

impl<I: Isa> F32s<I> {
    #[inline(always)]
    pub fn zero() -> Self {
        Self(I::splat(0.0))
    }

    #[inline(always)]
    pub fn from_array(a: &[f32; LANES]) -> Self {
        Self(I::load(a))
    }

    /// The entries `i..i + LANES` of a plane.
    #[inline(always)]
    pub fn load(plane: &[f32], i: usize) -> Self {
        Self(I::load(plane[i..i + LANES].try_into().expect("LANES entries")))
    }

    /// [`Self::load`] without the bounds check, for the filters' innermost loops.
    ///
    /// # Safety
    /// `i + LANES <= plane.len()`.
    #[inline(always)]
    pub unsafe fn load_unchecked(plane: &[f32], i: usize) -> Self {
        debug_assert!(i + LANES <= plane.len(), "{i} + LANES is past {}", plane.len());
        // SAFETY: the caller guarantees that the LANES entries are in `plane`.
        Self(I::load(unsafe { &*plane.as_ptr().add(i).cast::<[f32; LANES]>() }))
    }

    #[inline(always)]
    pub fn to_array(self) -> [f32; LANES] {
        I::to_array(self.0)
    }

    /// Writes the lanes to `a`.
    #[inline(always)]
    pub fn store(self, a: &mut [f32; LANES]) {
        I::store(self.0, a)
    }

    /// The lanes' sum.
    #[inline(always)]
    pub fn sum(self) -> f32 {
        self.to_array().iter().sum()
    }

    /// Each lane where `keep` is all ones, +0 where it is 0 (whatever the lane held).
    #[inline(always)]
    pub fn masked(self, keep: Self) -> Self {
        Self(I::and(self.0, keep.0))
    }

    /// `a` in the lanes where `self` is positive, `b` in the others.
    #[inline(always)]
    pub fn if_positive(self, a: Self, b: Self) -> Self {
        Self(I::if_positive(self.0, a.0, b.0))
    }
}

impl<I: Isa> Real for F32s<I> {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Self(I::splat(v))
    }

    #[inline(always)]
    fn positive_part(self) -> Self {
        Self(I::positive_part(self.0))
    }
}

impl<I: Isa> Add for F32s<I> {
    type Output = Self;

    #[inline(always)]
    fn add(self, other: Self) -> Self {
        Self(I::add(self.0, other.0))
    }
}

impl<I: Isa> Sub for F32s<I> {
    type Output = Self;

    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        Self(I::sub(self.0, other.0))
    }
}

impl<I: Isa> Mul for F32s<I> {
    type Output = Self;

    #[inline(always)]
    fn mul(self, other: Self) -> Self {
        Self(I::mul(self.0, other.0))
    }
}

impl<I: Isa> Div for F32s<I> {
    type Output = Self;

    #[inline(always)]
    fn div(self, other: Self) -> Self {
        Self(I::div(self.0, other.0))
    }
}

impl<I: Isa> AddAssign for F32s<I> {
    #[inline(always)]
    fn add_assign(&mut self, other: Self) {
        *self = *self + other;
    }
}

/// [`LANES`] vectors, one [`F32s`] per component. (The operations spell out the three
/// components rather than use `array::map`, which the compiler may leave out of line:
/// a call out of the AVX2 function would lose the vector instructions.)
#[derive(Clone, Copy, Debug)]
pub struct Vec3s<I: Isa>(pub [F32s<I>; 3]);

impl<I: Isa> Vec3s<I> {
    #[inline(always)]
    pub fn zero() -> Self {
        Self([F32s::zero(); 3])
    }

    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> Self {
        Self([F32s::splat(v.x), F32s::splat(v.y), F32s::splat(v.z)])
    }

    /// The entries `i..i + LANES` of three planes.
    #[inline(always)]
    pub fn load(planes: &[&[f32]; 3], i: usize) -> Self {
        let [x, y, z] = planes;
        Self([F32s::load(x, i), F32s::load(y, i), F32s::load(z, i)])
    }

    /// [`Self::load`] without the bounds checks.
    ///
    /// # Safety
    /// `i + LANES <= p.len()` for each plane `p`.
    #[inline(always)]
    pub unsafe fn load_unchecked(planes: &[&[f32]; 3], i: usize) -> Self {
        let [x, y, z] = planes;
        // SAFETY: as the caller guarantees.
        unsafe {
            Self([
                F32s::load_unchecked(x, i),
                F32s::load_unchecked(y, i),
                F32s::load_unchecked(z, i),
            ])
        }
    }

    /// The lanes as vectors.
    #[inline(always)]
    pub fn to_vec3s(self) -> [Vec3; LANES] {
        let [x, y, z] = self.0;
        let (x, y, z) = (x.to_array(), y.to_array(), z.to_array());
        std::array::from_fn(|k| Vec3::new(x[k], y[k], z[k]))
    }

    #[inline(always)]
    pub fn masked(self, keep: F32s<I>) -> Self {
        let [x, y, z] = self.0;
        Self([x.masked(keep), y.masked(keep), z.masked(keep)])
    }

    /// The sum over the lanes.
    #[inline(always)]
    pub fn sum(self) -> Vec3 {
        let [x, y, z] = self.0;
        Vec3::new(x.sum(), y.sum(), z.sum())
    }
}

impl<I: Isa> Mul<F32s<I>> for Vec3s<I> {
    type Output = Self;

    #[inline(always)]
    fn mul(self, w: F32s<I>) -> Self {
        let [x, y, z] = self.0;
        Self([x * w, y * w, z * w])
    }
}

impl<I: Isa> Div<F32s<I>> for Vec3s<I> {
    type Output = Self;

    #[inline(always)]
    fn div(self, w: F32s<I>) -> Self {
        let [x, y, z] = self.0;
        Self([x / w, y / w, z / w])
    }
}

impl<I: Isa> AddAssign for Vec3s<I> {
    #[inline(always)]
    fn add_assign(&mut self, other: Self) {
        let [x, y, z] = other.0;
        self.0[0] += x;
        self.0[1] += y;
        self.0[2] += z;
    }
}

/// A pass that writes its output one row at a time; `R` is one row of the output.
pub trait RowKernel<R>: Sync {
    /// What a thread keeps from one row to the next: it is handed consecutive rows.
    type Scratch: Send;

    fn scratch(&self) -> Self::Scratch;

    /// Writes row `y` with the vectors of `I`. Implementations are `#[inline(always)]`, so
    /// that [`run_rows`] compiles them within functions that enable `I`'s instructions.
    fn row<I: Isa>(&self, y: usize, out: R, scratch: &mut Self::Scratch);
}

/// Bands of consecutive rows that a thread takes at a time: about four per thread, enough
/// to share out uneven rows, few enough that the kernels' warm-up at a band's first row
/// costs little.
fn band(rows: usize) -> usize {
    rows.div_ceil(4 * rayon::current_num_threads()).max(1)
}

/// Runs `kernel` on every row of `rows` (each with its y), in parallel.
pub fn run_rows<R: Send, K: RowKernel<R>>(kernel: &K, rows: Vec<(usize, R)>) {
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::is_x86_feature_detected!("avx2");
    #[cfg(target_arch = "x86_64")]
    let avx512 = avx2
        && std::is_x86_feature_detected!("avx512f")
        && std::is_x86_feature_detected!("avx512vl");
    let band = band(rows.len());
    rows.into_par_iter().with_min_len(band).for_each_init(
        || kernel.scratch(),
        |scratch, (y, row)| {
            #[cfg(target_arch = "x86_64")]
            if avx512 {
                // SAFETY: the CPU has AVX2, AVX-512 F and AVX-512 VL.
                return unsafe { row_avx512(kernel, y, row, scratch) };
            }
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: the CPU has AVX2.
                return unsafe { row_avx2(kernel, y, row, scratch) };
            }
            kernel.row::<Portable>(y, row, scratch)
        },
    );
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn row_avx2<R, K: RowKernel<R>>(kernel: &K, y: usize, out: R, scratch: &mut K::Scratch) {
    kernel.row::<Avx2>(y, out, scratch)
}

/// The AVX2 kernel compiled with AVX-512 VL enabled: the same 256-bit vectors, but 32
/// vector registers instead of 16, which spares the filters most of their spills.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512vl")]
unsafe fn row_avx512<R, K: RowKernel<R>>(kernel: &K, y: usize, out: R, scratch: &mut K::Scratch) {
    kernel.row::<Avx2>(y, out, scratch)
}

/// The first [`LANES`] entries of `src`, padded with `fill` where it is shorter.
#[inline(always)]
pub fn load<T: Copy>(src: &[T], fill: T) -> [T; LANES] {
    match <&[T; LANES]>::try_from(src) {
        Ok(a) => *a,
        Err(_) => std::array::from_fn(|k| src.get(k).copied().unwrap_or(fill)),
    }
}

/// Writes the first `dst.len()` (at most [`LANES`]) entries of `v` to `dst`.
#[inline(always)]
pub fn store<T: Copy>(dst: &mut [T], v: &[T; LANES]) {
    // A whole chunk is one vector store; only a row's last chunk copies fewer lanes.
    let n = dst.len();
    match <&mut [T; LANES]>::try_from(&mut *dst) {
        Ok(d) => *d = *v,
        Err(_) => dst.copy_from_slice(&v[..n]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values where instruction sets could differ from `f32` arithmetic: signed zeros,
    /// infinities, NaN, subnormals, and ordinary numbers.
    fn awkward() -> [[f32; LANES]; 3] {
        let nan = f32::NAN;
        let tiny = f32::from_bits(1);
        [
            [0.0, -0.0, 1.5, -2.25, f32::INFINITY, f32::NEG_INFINITY, nan, tiny],
            [-0.0, 0.0, 3.0, 0.75, 2.0, f32::INFINITY, 1.0, -tiny],
            [1.0, -1.0, nan, 0.0, -0.0, 4.0, -nan, 1e-30],
        ]
    }

    fn bits(v: [f32; LANES]) -> [u32; LANES] {
        v.map(f32::to_bits)
    }

    /// Every operation of `I` gives the bits `Portable` gives (and so plain f32 code).
    fn matches_portable<I: Isa>() {
        let [a, b, c] = awkward();
        let (va, vb, vc) = (I::load(&a), I::load(&b), I::load(&c));
        let mask = [!0u32, 0, !0, 0, !0, 0, !0, 0].map(f32::from_bits);
        let pairs = [
            (I::add(va, vb), Portable::add(a, b)),
            (I::sub(va, vb), Portable::sub(a, b)),
            (I::mul(va, vb), Portable::mul(a, b)),
            (I::div(va, vb), Portable::div(a, b)),
            (I::positive_part(va), Portable::positive_part(a)),
            (I::and(va, I::load(&mask)), Portable::and(a, mask)),
            (I::if_positive(vc, va, vb), Portable::if_positive(c, a, b)),
            (I::splat(-0.0), Portable::splat(-0.0)),
        ];
        for (k, (got, want)) in pairs.into_iter().enumerate() {
            let (got, want) = (I::to_array(got), want);
            // NaN payloads may differ; NaN-ness may not.
            for (g, w) in got.iter().zip(want) {
                assert!(
                    g.to_bits() == w.to_bits() || (g.is_nan() && w.is_nan()),
                    "op {k}: {got:?} against {want:?}"
                );
            }
        }
        assert_eq!(bits(Portable::positive_part([-0.0; LANES])), bits([0.0; LANES]));
    }

    #[test]
    fn portable_ops_are_f32_arithmetic() {
        matches_portable::<Portable>();
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_ops_match_portable() {
        if !std::is_x86_feature_detected!("avx2") {
            let why = "is_x86_feature_detected!(\"avx2\") is false";
            crate::testing::skip(
                "avx2_ops_match_portable",
                crate::testing::Missing::CpuFeature,
                why,
            );
            return;
        }
        // SAFETY: the CPU has AVX2.
        unsafe { avx2_checks() }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn avx2_checks() {
        matches_portable::<Avx2>();
    }
}
