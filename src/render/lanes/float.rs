//! The `f32` lanes' operators: arithmetic, comparisons into masks, blends, and
//! conversions, each one instruction per register of the lanes' instruction set.

use std::marker::PhantomData;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub};

use super::{bits, each, floats, F32s, Isa, Mask, U32s, WIDTH};

lanewise!(F32s, f, Add, add, +, _mm_add_ps, _mm256_add_ps, _mm512_add_ps);
lanewise!(F32s, f, Sub, sub, -, _mm_sub_ps, _mm256_sub_ps, _mm512_sub_ps);
lanewise!(F32s, f, Mul, mul, *, _mm_mul_ps, _mm256_mul_ps, _mm512_mul_ps);
lanewise!(F32s, f, Div, div, /, _mm_div_ps, _mm256_div_ps, _mm512_div_ps);

impl<I: Isa> AddAssign for F32s<I> {
    #[inline(always)]
    fn add_assign(&mut self, o: F32s<I>) {
        *self = *self + o;
    }
}

impl<I: Isa> Neg for F32s<I> {
    type Output = F32s<I>;
    #[inline(always)]
    fn neg(self) -> F32s<I> {
        F32s::from_bits(self.to_bits() ^ U32s::splat(0x8000_0000))
    }
}

/// A comparison: SSE2 comparison, AVX predicate, or AVX-512 predicate into a mask
/// register widened to lanes, on x86-64; the scalar operator elsewhere (all ordered:
/// false where either side is NaN).
macro_rules! compare {
    ($name:ident, $op:tt, $pred:ident, $sse:ident) => {
        #[inline(always)]
        pub fn $name(self, o: Self) -> Mask<I> {
            #[cfg(target_arch = "x86_64")]
            return U32s::new(regs!(I, f -> u, self.0, o.0, |x, y|
                sse: _mm_castps_si128($sse(x, y)),
                avx: _mm256_castps_si256(_mm256_cmp_ps::<$pred>(x, y)),
                avx512: _mm512_movm_epi32(_mm512_cmp_ps_mask::<$pred>(x, y))));
            #[cfg(not(target_arch = "x86_64"))]
            {
                let mut out = U32s::default();
                for i in 0..WIDTH {
                    out.0[i] = if self.0[i] $op o.0[i] { u32::MAX } else { 0 };
                }
                out
            }
        }
    };
}

impl<I: Isa> F32s<I> {
    #[inline(always)]
    pub fn new(lanes: [f32; WIDTH]) -> Self {
        Self(lanes, PhantomData)
    }

    #[inline(always)]
    pub fn splat(x: f32) -> Self {
        Self::new([x; WIDTH])
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Self::new(each(self.0, f))
    }

    /// The entries `i..i + WIDTH` of `s`.
    #[inline(always)]
    pub fn load(s: &[f32], i: usize) -> Self {
        Self::new(s[i..i + WIDTH].try_into().expect("WIDTH entries"))
    }

    /// [`F32s::load`] without the bounds check, for innermost loops whose indices a
    /// layout keeps in bounds.
    ///
    /// # Safety
    /// `i + WIDTH <= s.len()`.
    #[inline(always)]
    pub unsafe fn load_unchecked(s: &[f32], i: usize) -> Self {
        debug_assert!(i + WIDTH <= s.len(), "{i} + WIDTH is past {}", s.len());
        // SAFETY: the caller guarantees that the WIDTH entries are in `s`; `f32` has no
        // alignment beyond its own, which the slice gives.
        Self::new(unsafe { s.as_ptr().add(i).cast::<[f32; WIDTH]>().read_unaligned() })
    }

    /// Writes the lanes to `a`.
    #[inline(always)]
    pub fn store(self, a: &mut [f32; WIDTH]) {
        *a = self.0;
    }

    /// The lanes' sum, added pairwise: lane i + lane i + 8 for i < 8, then i + (i + 4) of
    /// those, and so on (four vector additions rather than fifteen dependent ones).
    #[inline(always)]
    pub fn sum(self) -> f32 {
        let mut x = self.0;
        let mut n = WIDTH;
        while n > 1 {
            n /= 2;
            for i in 0..n {
                x[i] += x[i + n];
            }
        }
        x[0]
    }

    /// max(0, x) per lane as `if x > 0 { x } else { 0 }`: NaN and −0 give +0. (`maxps(x,
    /// 0)` returns its second operand where either is NaN or both are zero.)
    #[inline(always)]
    pub fn positive_part(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, f -> f, self.0, self.0, |x, _y|
            sse: _mm_max_ps(x, _mm_setzero_ps()), avx: _mm256_max_ps(x, _mm256_setzero_ps()),
            avx512: _mm512_max_ps(x, _mm512_setzero_ps())));
        #[cfg(not(target_arch = "x86_64"))]
        self.map(|x| if x > 0.0 { x } else { 0.0 })
    }

    /// Each lane where `keep` is true, +0 where it is false (whatever the lane held: NaN
    /// and infinities too).
    #[inline(always)]
    pub fn masked(self, keep: Mask<I>) -> Self {
        F32s::from_bits(self.to_bits() & keep)
    }

    compare!(lt, <, _CMP_LT_OQ, _mm_cmplt_ps);
    compare!(le, <=, _CMP_LE_OQ, _mm_cmple_ps);
    compare!(gt, >, _CMP_GT_OQ, _mm_cmpgt_ps);
    compare!(ge, >=, _CMP_GE_OQ, _mm_cmpge_ps);
    compare!(eq, ==, _CMP_EQ_OQ, _mm_cmpeq_ps);

    /// `mask ? a : b` per lane, by bits.
    #[inline(always)]
    pub fn select(mask: Mask<I>, a: Self, b: Self) -> Self {
        F32s::from_bits(U32s::select(mask, a.to_bits(), b.to_bits()))
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, f -> f, self.0, self.0, |x, _y|
            sse: _mm_sqrt_ps(x), avx: _mm256_sqrt_ps(x), avx512: _mm512_sqrt_ps(x)));
        #[cfg(not(target_arch = "x86_64"))]
        self.map(f32::sqrt)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        F32s::from_bits(self.to_bits() & U32s::splat(0x7fff_ffff))
    }

    /// [`f32::max`] per lane (the non-NaN side wins), as LLVM lowers it on x86:
    /// `maxps(o, self)` (which returns `self` on ties of ±0 and where either is NaN),
    /// then `o` where `self` is NaN.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        self.extreme::<true>(o)
    }

    /// [`f32::min`] per lane, as [`F32s::max`].
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        self.extreme::<false>(o)
    }

    /// `if self > o { self } else { o }` per lane: x86's `maxps(self, o)`, one instruction
    /// (`o` where either is NaN or both are zero), as the BVH's node tests compute.
    #[inline(always)]
    pub fn maxps(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, f -> f, self.0, o.0, |x, y|
            sse: _mm_max_ps(x, y), avx: _mm256_max_ps(x, y), avx512: _mm512_max_ps(x, y)));
        #[cfg(not(target_arch = "x86_64"))]
        F32s::new(std::array::from_fn(|i| if self.0[i] > o.0[i] { self.0[i] } else { o.0[i] }))
    }

    /// `if self < o { self } else { o }` per lane: x86's `minps(self, o)`, as
    /// [`F32s::maxps`].
    #[inline(always)]
    pub fn minps(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, f -> f, self.0, o.0, |x, y|
            sse: _mm_min_ps(x, y), avx: _mm256_min_ps(x, y), avx512: _mm512_min_ps(x, y)));
        #[cfg(not(target_arch = "x86_64"))]
        F32s::new(std::array::from_fn(|i| if self.0[i] < o.0[i] { self.0[i] } else { o.0[i] }))
    }

    /// [`F32s::max`] (`MAX`) or [`F32s::min`]: the two differ only in the instruction.
    #[inline(always)]
    fn extreme<const MAX: bool>(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, f -> f, self.0, o.0, |x, y|
        sse: {
            let nan = _mm_cmpunord_ps(x, x);
            let m = if MAX { _mm_max_ps(y, x) } else { _mm_min_ps(y, x) };
            _mm_or_ps(_mm_and_ps(nan, y), _mm_andnot_ps(nan, m))
        },
        avx: {
            let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(x, x);
            let m = if MAX { _mm256_max_ps(y, x) } else { _mm256_min_ps(y, x) };
            _mm256_blendv_ps(m, y, nan)
        },
        avx512: {
            let nan = _mm512_cmp_ps_mask::<_CMP_UNORD_Q>(x, x);
            let m = if MAX { _mm512_max_ps(y, x) } else { _mm512_min_ps(y, x) };
            _mm512_mask_blend_ps(nan, m, y)
        }));
        #[cfg(not(target_arch = "x86_64"))]
        F32s::new(std::array::from_fn(|i| {
            if MAX {
                self.0[i].max(o.0[i])
            } else {
                self.0[i].min(o.0[i])
            }
        }))
    }

    /// `x as i32` of each lane, for |x| < 2³¹ (truncation towards zero), as bits.
    #[inline(always)]
    pub fn trunc_i32(self) -> U32s<I> {
        #[cfg(target_arch = "x86_64")]
        return U32s::new(regs!(I, f -> u, self.0, self.0, |x, _y|
            sse: _mm_cvttps_epi32(x), avx: _mm256_cvttps_epi32(x),
            avx512: _mm512_cvttps_epi32(x)));
        #[cfg(not(target_arch = "x86_64"))]
        U32s::new(self.0.map(|x| x as i32 as u32))
    }

    /// `x as f32` of each lane read as `i32`.
    #[inline(always)]
    pub fn from_i32(x: U32s<I>) -> Self {
        #[cfg(target_arch = "x86_64")]
        return F32s::new(regs!(I, u -> f, x.0, x.0, |x, _y|
            sse: _mm_cvtepi32_ps(x), avx: _mm256_cvtepi32_ps(x),
            avx512: _mm512_cvtepi32_ps(x)));
        #[cfg(not(target_arch = "x86_64"))]
        F32s::new(x.0.map(|x| x as i32 as f32))
    }

    #[inline(always)]
    pub fn to_bits(self) -> U32s<I> {
        U32s::new(bits(self.0))
    }

    #[inline(always)]
    pub fn from_bits(b: U32s<I>) -> Self {
        F32s::new(floats(b.0))
    }
}
