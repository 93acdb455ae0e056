//! Sixteen paths' numbers side by side: `f32` and `u32` lanes with element-wise
//! operators, for the stream kernel ([`super::stream`]), in each kernel build's
//! instructions.
//!
//! The lane types carry the instruction set they compile to as a type parameter
//! ([`Isa`]): [`Avx512`] makes every operator one AVX-512 instruction on a 512-bit
//! register, [`Avx2`] two AVX/AVX2 instructions on 256-bit halves, [`Sse2`] four SSE2
//! instructions on 128-bit quarters (baseline x86-64, so every x86-64 CPU runs it); off
//! x86-64 all are loops over sixteen elements. A parameter, not a compile-time target
//! feature, because one binary holds every build and picks one at run time
//! ([`super::integrator::render_pixels_counted`]): `F32s<Avx512>` may only be used by code
//! inlined into the x86-64-v4 build and `F32s<Avx2>` by code of the v3 build, whose
//! features make their intrinsics inline there (the stream kernel names its lanes
//! through [`super::accel::Lanes::Simd`], which only those builds' tokens map to them).
//!
//! Each operator is one IEEE operation per lane, never fused (Rust does not contract
//! `mul` and `add` into FMA), so a lane's value is exactly what the scalar code computes
//! from the same inputs in the same order, in any instruction set: that is what lets
//! every build of the stream kernel give the one-path kernel's bits. Not `std::simd`
//! (nightly only) nor the `wide` crate (it picks its instructions by compile-time target
//! features, so the run-time dispatched builds would get SSE quarters); LLVM's own
//! vectorisation of eight-element loops gave half-width code with spills in the v3
//! build (0.77× the intrinsics' samples per second on the Cornell box).
//!
//! Why sixteen lanes in every build: the width is a constant of every stage's code
//! (sample draws, light sampling, the BSDFs, roulette), and one width keeps one source
//! for all builds. Sixteen is one AVX-512 register; the narrower builds' two AVX2 halves
//! or four SSE2 quarters measured as fast as their eight lanes did (AMD EPYC Zen 4,
//! paired medians of alternating rounds, Cornell box / bunny / Sponza: v3 build 1.01× /
//! 1.01× / 1.01× and 1.03× / 0.99× / 1.00× in two series of 5; baseline build 1.01× /
//! 0.98× / 0.99× over 12), the parts' independent chains covering the latency that their
//! extra register pressure costs.
//! An earlier x86-64-v4 build of the eight-lane code (EVEX encoding, 32 registers, mask
//! registers, no wider lanes) gave no speed on an Intel Xeon (1.01×, 1.01×, 0.99× the v3
//! build); the speed of the sixteen-lane v4 build is in [`super::stream`].
//!
//! Comparisons return a [`Mask`] of all-ones or all-zero lanes, and [`F32s::select`] picks
//! by bits, so branches of the scalar code become blends of both sides.

use std::fmt::Debug;
use std::marker::PhantomData;
use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Shl, Shr, Sub};

/// Lanes per group.
pub const WIDTH: usize = 16;

/// The register width a lane type's operators compile to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Four 128-bit SSE2 quarters (baseline x86-64).
    Sse2,
    /// Two 256-bit AVX/AVX2 halves (x86-64-v3).
    Avx2,
    /// One 512-bit AVX-512 register (x86-64-v4).
    Avx512,
}

/// The instructions a lane type's operators compile to.
pub trait Isa: Copy + Default + Debug + PartialEq + Eq {
    const LEVEL: Level;
}

/// Two AVX/AVX2 registers per lane group: only in code of the x86-64-v3 build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Avx2;

impl Isa for Avx2 {
    const LEVEL: Level = Level::Avx2;
}

/// One AVX-512 register per lane group: only in code of the x86-64-v4 build.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Avx512;

impl Isa for Avx512 {
    const LEVEL: Level = Level::Avx512;
}

/// Four SSE2 quarters per lane group: every x86-64 CPU.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sse2;

impl Isa for Sse2 {
    const LEVEL: Level = Level::Sse2;
}

/// Sixteen `f32` lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct F32s<I>(pub [f32; WIDTH], PhantomData<I>);

/// Sixteen `u32` lanes (also masks: all ones is true).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C, align(64))]
pub struct U32s<I>(pub [u32; WIDTH], PhantomData<I>);

/// Lanes of all ones (true) or all zeros (false).
pub type Mask<I> = U32s<I>;

/// Runs SIMD intrinsics on the lanes as registers.
///
/// SAFETY (of every use): the AVX-512 side runs only for `Avx512` lanes and the AVX/AVX2
/// side only for `Avx2` lanes, which only code inlined into the x86-64-v4 and -v3 builds
/// uses, and those builds run only where the CPU has their features; SSE2 is part of
/// baseline x86-64.
#[cfg(target_arch = "x86_64")]
macro_rules! simd {
    ($e:expr) => {{
        #[allow(unused_unsafe, clippy::undocumented_unsafe_blocks)]
        let out = unsafe {
            #[allow(unused_imports)]
            use std::arch::x86_64::*;
            $e
        };
        out
    }};
}

#[cfg(target_arch = "x86_64")]
mod reg {
    //! Reinterpretation between lane arrays and registers (no instructions).
    use std::arch::x86_64::{__m128, __m128i, __m256, __m256i, __m512, __m512i};

    macro_rules! casts {
        ($($name:ident: $from:ty => $to:ty;)*) => {$(
            #[inline(always)]
            pub fn $name(x: $from) -> $to {
                // SAFETY: same size (64 bytes), any bits are a valid value of either.
                unsafe { std::mem::transmute(x) }
            }
        )*};
    }

    casts! {
        f1: [f32; 16] => __m512;
        f2: [f32; 16] => [__m256; 2];
        f4: [f32; 16] => [__m128; 4];
        u1: [u32; 16] => __m512i;
        u2: [u32; 16] => [__m256i; 2];
        u4: [u32; 16] => [__m128i; 4];
        fo1: __m512 => [f32; 16];
        fo2: [__m256; 2] => [f32; 16];
        fo4: [__m128; 4] => [f32; 16];
        uo1: __m512i => [u32; 16];
        uo2: [__m256i; 2] => [u32; 16];
        uo4: [__m128i; 4] => [u32; 16];
    }
}

/// One operation on the registers of two lane arrays (`$a`, `$b`) of kind `f` or `u`,
/// giving lanes of kind `f` or `u`: `$avx512` on the one AVX-512 register, `$avx` on
/// each AVX half, `$sse` on each SSE quarter, by the lanes' [`Level`] (a constant, so
/// only one arm is compiled into a build). Written out per register, not as a closure,
/// so that it is never compiled out of line.
#[cfg(target_arch = "x86_64")]
macro_rules! regs {
    ($I:ty, $in:ident -> $out:ident, $a:expr, $b:expr,
     |$x:ident, $y:ident| sse: $sse:expr, avx: $avx:expr, avx512: $avx512:expr) => {{
        let (a, b) = ($a, $b);
        match <$I as Isa>::LEVEL {
            Level::Avx512 => {
                let ($x, $y) = (regs!(@in1 $in, a), regs!(@in1 $in, b));
                regs!(@out1 $out, simd!($avx512))
            }
            Level::Avx2 => {
                let (a, b) = (regs!(@in2 $in, a), regs!(@in2 $in, b));
                let r0 = { let ($x, $y) = (a[0], b[0]); simd!($avx) };
                let r1 = { let ($x, $y) = (a[1], b[1]); simd!($avx) };
                regs!(@out2 $out, [r0, r1])
            }
            Level::Sse2 => {
                let (a, b) = (regs!(@in4 $in, a), regs!(@in4 $in, b));
                let r0 = { let ($x, $y) = (a[0], b[0]); simd!($sse) };
                let r1 = { let ($x, $y) = (a[1], b[1]); simd!($sse) };
                let r2 = { let ($x, $y) = (a[2], b[2]); simd!($sse) };
                let r3 = { let ($x, $y) = (a[3], b[3]); simd!($sse) };
                regs!(@out4 $out, [r0, r1, r2, r3])
            }
        }
    }};
    (@in1 f, $e:expr) => { reg::f1($e) };
    (@in1 u, $e:expr) => { reg::u1($e) };
    (@in2 f, $e:expr) => { reg::f2($e) };
    (@in2 u, $e:expr) => { reg::u2($e) };
    (@in4 f, $e:expr) => { reg::f4($e) };
    (@in4 u, $e:expr) => { reg::u4($e) };
    (@out1 f, $e:expr) => { reg::fo1($e) };
    (@out1 u, $e:expr) => { reg::uo1($e) };
    (@out2 f, $e:expr) => { reg::fo2($e) };
    (@out2 u, $e:expr) => { reg::uo2($e) };
    (@out4 f, $e:expr) => { reg::fo4($e) };
    (@out4 u, $e:expr) => { reg::uo4($e) };
}

/// A binary operator: one instruction per register (AVX-512, AVX2 or SSE2), the scalar
/// `$op` lane by lane off x86-64.
macro_rules! lanewise {
    ($ty:ident, $kind:ident, $trait:ident, $f:ident, $op:tt,
     $sse:ident, $avx:ident, $avx512:ident) => {
        impl<I: Isa> $trait for $ty<I> {
            type Output = $ty<I>;
            #[inline(always)]
            fn $f(self, o: $ty<I>) -> $ty<I> {
                #[cfg(target_arch = "x86_64")]
                return $ty::new(regs!(I, $kind -> $kind, self.0, o.0,
                    |x, y| sse: $sse(x, y), avx: $avx(x, y), avx512: $avx512(x, y)));
                #[cfg(not(target_arch = "x86_64"))]
                {
                    let mut out = self;
                    for i in 0..WIDTH {
                        out.0[i] = self.0[i] $op o.0[i];
                    }
                    out
                }
            }
        }
    };
}

lanewise!(F32s, f, Add, add, +, _mm_add_ps, _mm256_add_ps, _mm512_add_ps);
lanewise!(F32s, f, Sub, sub, -, _mm_sub_ps, _mm256_sub_ps, _mm512_sub_ps);
lanewise!(F32s, f, Mul, mul, *, _mm_mul_ps, _mm256_mul_ps, _mm512_mul_ps);
lanewise!(F32s, f, Div, div, /, _mm_div_ps, _mm256_div_ps, _mm512_div_ps);
lanewise!(U32s, u, BitAnd, bitand, &, _mm_and_si128, _mm256_and_si256, _mm512_and_si512);
lanewise!(U32s, u, BitOr, bitor, |, _mm_or_si128, _mm256_or_si256, _mm512_or_si512);
lanewise!(U32s, u, BitXor, bitxor, ^, _mm_xor_si128, _mm256_xor_si256, _mm512_xor_si512);

impl<I: Isa> Neg for F32s<I> {
    type Output = F32s<I>;
    #[inline(always)]
    fn neg(self) -> F32s<I> {
        F32s::from_bits(self.to_bits() ^ U32s::splat(0x8000_0000))
    }
}

impl<I: Isa> Not for U32s<I> {
    type Output = U32s<I>;
    #[inline(always)]
    fn not(self) -> U32s<I> {
        self ^ U32s::splat(u32::MAX)
    }
}

/// A shift by the same count in every lane.
macro_rules! shift {
    ($trait:ident, $f:ident, $op:tt, $sse:ident, $avx:ident, $avx512:ident) => {
        impl<I: Isa> $trait<u32> for U32s<I> {
            type Output = U32s<I>;
            #[inline(always)]
            fn $f(self, n: u32) -> U32s<I> {
                #[cfg(target_arch = "x86_64")]
                return U32s::new(regs!(I, u -> u, self.0, self.0, |x, _y|
                    sse: $sse(x, _mm_cvtsi32_si128(n as i32)),
                    avx: $avx(x, _mm_cvtsi32_si128(n as i32)),
                    avx512: $avx512(x, _mm_cvtsi32_si128(n as i32))));
                #[cfg(not(target_arch = "x86_64"))]
                self.map(|x| x $op n)
            }
        }
    };
}

shift!(Shr, shr, >>, _mm_srl_epi32, _mm256_srl_epi32, _mm512_srl_epi32);
shift!(Shl, shl, <<, _mm_sll_epi32, _mm256_sll_epi32, _mm512_sll_epi32);

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

/// Shuffle controls of [`U32s::reverse_bits`], per 128-bit lane: each 32-bit lane's
/// bytes in reverse order, and each nibble's bits reversed.
#[cfg(target_arch = "x86_64")]
const REVERSE_BYTES: [u8; 16] = [3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12];
#[cfg(target_arch = "x86_64")]
const REVERSE_NIBBLES: [u8; 16] = [0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15];

/// A 16-byte table as an SSE register.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn table(t: &[u8; 16]) -> std::arch::x86_64::__m128i {
    // SAFETY: same size, any bits are a valid value of either.
    unsafe { std::mem::transmute(*t) }
}

impl<I: Isa> U32s<I> {
    #[inline(always)]
    pub fn new(lanes: [u32; WIDTH]) -> Self {
        Self(lanes, PhantomData)
    }

    #[inline(always)]
    pub fn splat(x: u32) -> Self {
        Self::new([x; WIDTH])
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(u32) -> u32) -> Self {
        Self::new(each(self.0, f))
    }

    /// `mask ? a : b` per lane, by bits.
    #[inline(always)]
    pub fn select(mask: Mask<I>, a: Self, b: Self) -> Self {
        (mask & a) | (!mask & b)
    }

    #[inline(always)]
    pub fn wrapping_mul(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return U32s::new(regs!(I, u -> u, self.0, o.0, |a, b|
            // SSE2 has no 32-bit low multiply: even and odd lanes' 64-bit products,
            // their low halves interleaved back.
            sse: {
                let even = _mm_mul_epu32(a, b);
                let odd = _mm_mul_epu32(_mm_srli_epi64::<32>(a), _mm_srli_epi64::<32>(b));
                _mm_unpacklo_epi32(
                    _mm_shuffle_epi32::<0b00_00_10_00>(even),
                    _mm_shuffle_epi32::<0b00_00_10_00>(odd),
                )
            },
            avx: _mm256_mullo_epi32(a, b),
            avx512: _mm512_mullo_epi32(a, b)));
        #[cfg(not(target_arch = "x86_64"))]
        U32s::new(std::array::from_fn(|i| self.0[i].wrapping_mul(o.0[i])))
    }

    #[inline(always)]
    pub fn wrapping_add(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return U32s::new(regs!(I, u -> u, self.0, o.0, |a, b|
            sse: _mm_add_epi32(a, b), avx: _mm256_add_epi32(a, b),
            avx512: _mm512_add_epi32(a, b)));
        #[cfg(not(target_arch = "x86_64"))]
        U32s::new(std::array::from_fn(|i| self.0[i].wrapping_add(o.0[i])))
    }

    /// Lanes where `self` and `o` are equal.
    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask<I> {
        #[cfg(target_arch = "x86_64")]
        return U32s::new(regs!(I, u -> u, self.0, o.0, |a, b|
            sse: _mm_cmpeq_epi32(a, b), avx: _mm256_cmpeq_epi32(a, b),
            avx512: _mm512_movm_epi32(_mm512_cmpeq_epi32_mask(a, b))));
        #[cfg(not(target_arch = "x86_64"))]
        U32s::new(std::array::from_fn(|i| if self.0[i] == o.0[i] { u32::MAX } else { 0 }))
    }

    /// Lanes where `self > o`, both read as `i32`.
    #[inline(always)]
    pub fn gt_i32(self, o: Self) -> Mask<I> {
        #[cfg(target_arch = "x86_64")]
        return U32s::new(regs!(I, u -> u, self.0, o.0, |a, b|
            sse: _mm_cmpgt_epi32(a, b), avx: _mm256_cmpgt_epi32(a, b),
            avx512: _mm512_movm_epi32(_mm512_cmpgt_epi32_mask(a, b))));
        #[cfg(not(target_arch = "x86_64"))]
        U32s::new(std::array::from_fn(
            |i| if self.0[i] as i32 > o.0[i] as i32 { u32::MAX } else { 0 },
        ))
    }

    /// [`u32::reverse_bits`] per lane. AVX2 and AVX-512: bytes reversed by a shuffle
    /// within each 128-bit lane, then the bits of each byte through a nibble table. SSE2
    /// has no byte shuffle: bits, pairs and nibbles swapped by masks and shifts, then the
    /// bytes.
    #[inline(always)]
    pub fn reverse_bits(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        if I::LEVEL != Level::Sse2 {
            return U32s::new(regs!(I, u -> u, self.0, self.0, |x, _y|
            sse: x, // never taken: SSE2 lanes take the shifts below
            avx: {
                let bytes = _mm256_broadcastsi128_si256(table(&REVERSE_BYTES));
                let nibbles = _mm256_broadcastsi128_si256(table(&REVERSE_NIBBLES));
                let (low, x) = (_mm256_set1_epi8(0x0f), _mm256_shuffle_epi8(x, bytes));
                let lo = _mm256_shuffle_epi8(nibbles, _mm256_and_si256(x, low));
                let high = _mm256_and_si256(_mm256_srli_epi16::<4>(x), low);
                let hi = _mm256_shuffle_epi8(nibbles, high);
                _mm256_or_si256(_mm256_slli_epi16::<4>(lo), hi)
            },
            avx512: {
                let bytes = _mm512_broadcast_i32x4(table(&REVERSE_BYTES));
                let nibbles = _mm512_broadcast_i32x4(table(&REVERSE_NIBBLES));
                let (low, x) = (_mm512_set1_epi8(0x0f), _mm512_shuffle_epi8(x, bytes));
                let lo = _mm512_shuffle_epi8(nibbles, _mm512_and_si512(x, low));
                let high = _mm512_and_si512(_mm512_srli_epi16::<4>(x), low);
                let hi = _mm512_shuffle_epi8(nibbles, high);
                _mm512_or_si512(_mm512_slli_epi16::<4>(lo), hi)
            }));
        }
        #[inline(always)]
        fn swap<I: Isa>(x: U32s<I>, n: u32, m: u32) -> U32s<I> {
            ((x >> n) & U32s::splat(m)) | ((x & U32s::splat(m)) << n)
        }
        let x = swap(swap(swap(self, 1, 0x5555_5555), 2, 0x3333_3333), 4, 0x0f0f_0f0f);
        (x >> 24)
            | ((x >> 8) & U32s::splat(0xff00))
            | ((x << 8) & U32s::splat(0x00ff_0000))
            | (x << 24)
    }

    /// `table[i]` for each lane's `i` (< 256).
    #[inline(always)]
    pub fn gather(table: &[u32; 256], index: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        if I::LEVEL != Level::Sse2 {
            let t = table.as_ptr() as *const i32;
            return U32s::new(regs!(I, u -> u, index.0, index.0, |i, _y|
                sse: i, // never taken: SSE2 lanes take the loop below
                avx: _mm256_i32gather_epi32::<4>(t, i),
                avx512: _mm512_i32gather_epi32::<4>(i, t)));
        }
        let mut out = [0; WIDTH];
        for (o, &i) in out.iter_mut().zip(&index.0) {
            *o = table[i as usize];
        }
        U32s::new(out)
    }

    /// `table[i]` for each lane's `i` (< 16) from a table held in registers: one
    /// permutation in AVX-512, two and a blend per AVX2 half; loads lane by lane in SSE2,
    /// which has no variable permutation. The register loads read the table's 64 bytes.
    #[inline(always)]
    pub fn lookup16(table: &[u32; 16], index: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        if I::LEVEL != Level::Sse2 {
            let t = table.as_ptr() as *const std::arch::x86_64::__m256i;
            return U32s::new(regs!(I, u -> u, index.0, index.0, |i, _y|
                sse: i, // never taken: SSE2 lanes take the loop below
                avx: {
                    let (lo, hi) = (_mm256_loadu_si256(t), _mm256_loadu_si256(t.add(1)));
                    let (lo, hi) =
                        (_mm256_permutevar8x32_epi32(lo, i), _mm256_permutevar8x32_epi32(hi, i));
                    // Bit 3 of the index, moved to the sign bit, picks the half.
                    let upper = _mm256_castsi256_ps(_mm256_slli_epi32::<28>(i));
                    _mm256_castps_si256(_mm256_blendv_ps(
                        _mm256_castsi256_ps(lo),
                        _mm256_castsi256_ps(hi),
                        upper,
                    ))
                },
                avx512: _mm512_permutexvar_epi32(i, _mm512_loadu_si512(t as *const _))));
        }
        let mut out = [0; WIDTH];
        for (o, &i) in out.iter_mut().zip(&index.0) {
            *o = table[i as usize];
        }
        U32s::new(out)
    }

    /// Each lane read as an integer below 2²⁴, converted exactly to `f32`.
    #[inline(always)]
    pub fn to_f32(self) -> F32s<I> {
        F32s::from_i32(self)
    }

    /// Lane `i` true where bit `i` of `bits` is set.
    #[inline(always)]
    pub fn from_bitmask(bits: u32) -> Mask<I> {
        let lane_bits = U32s::new(std::array::from_fn(|i| 1 << i));
        (U32s::splat(bits) & lane_bits).eq(lane_bits)
    }

    /// Bit `i` set where lane `i` of a mask is true.
    #[inline(always)]
    pub fn bitmask(self) -> u32 {
        #[cfg(target_arch = "x86_64")]
        return match I::LEVEL {
            Level::Avx512 => simd!(_mm512_movepi32_mask(reg::u1(self.0))) as u32,
            Level::Avx2 => simd!({
                let h = reg::u2(self.0);
                let lo = _mm256_movemask_ps(_mm256_castsi256_ps(h[0])) as u32;
                let hi = _mm256_movemask_ps(_mm256_castsi256_ps(h[1])) as u32;
                lo | (hi << 8)
            }),
            Level::Sse2 => simd!({
                let q = reg::u4(self.0);
                let m0 = _mm_movemask_ps(_mm_castsi128_ps(q[0])) as u32;
                let m1 = _mm_movemask_ps(_mm_castsi128_ps(q[1])) as u32;
                let m2 = _mm_movemask_ps(_mm_castsi128_ps(q[2])) as u32;
                let m3 = _mm_movemask_ps(_mm_castsi128_ps(q[3])) as u32;
                m0 | (m1 << 4) | (m2 << 8) | (m3 << 12)
            }),
        };
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut bits = 0;
            for i in 0..WIDTH {
                bits |= (self.0[i] >> 31) << i;
            }
            bits
        }
    }
}

/// `f` of each lane, as a loop: `[T; N]::map` was left out of line in the baseline build.
#[inline(always)]
fn each<T: Copy>(mut x: [T; WIDTH], f: impl Fn(T) -> T) -> [T; WIDTH] {
    for v in &mut x {
        *v = f(*v);
    }
    x
}

/// The bits of sixteen `f32`s ([`f32::to_bits`] of each, with no call that might stay out
/// of line as `[T; N]::map` can).
#[inline(always)]
fn bits(x: [f32; WIDTH]) -> [u32; WIDTH] {
    // SAFETY: same size, and every bit pattern is a valid `u32`.
    unsafe { std::mem::transmute(x) }
}

/// [`f32::from_bits`] of sixteen `u32`s, as [`bits`].
#[inline(always)]
fn floats(x: [u32; WIDTH]) -> [f32; WIDTH] {
    // SAFETY: same size, and every bit pattern is a valid `f32`.
    unsafe { std::mem::transmute(x) }
}

/// Sixteen 3-vectors, component by component, with glam's `Vec3` arithmetic (same
/// operations in the same order, so the same bits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3s<I> {
    pub x: F32s<I>,
    pub y: F32s<I>,
    pub z: F32s<I>,
}

impl<I: Isa> Vec3s<I> {
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self { x: F32s::splat(v.x), y: F32s::splat(v.y), z: F32s::splat(v.z) }
    }

    #[inline(always)]
    pub fn lane(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x.0[i], self.y.0[i], self.z.0[i])
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, v: glam::Vec3) {
        (self.x.0[i], self.y.0[i], self.z.0[i]) = (v.x, v.y, v.z);
    }

    /// `(x·x') + (y·y') + (z·z')`, as glam.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F32s<I> {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn scale(self, s: F32s<I>) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    #[inline(always)]
    pub fn div_by(self, s: F32s<I>) -> Self {
        Self { x: self.x / s, y: self.y / s, z: self.z / s }
    }

    /// glam's `normalize`: the components times `1 / sqrt(self · self)`.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self.scale(F32s::splat(1.0) / self.dot(self).sqrt())
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Self { x: self.x.abs(), y: self.y.abs(), z: self.z.abs() }
    }

    /// glam's `max_element`: `max(x, max(y, z))` with `a > b ? a : b`.
    #[inline(always)]
    pub fn max_element(self) -> F32s<I> {
        #[inline(always)]
        fn gt<I: Isa>(a: F32s<I>, b: F32s<I>) -> F32s<I> {
            F32s::select(a.gt(b), a, b)
        }
        gt(self.x, gt(self.y, self.z))
    }

    /// Lanes where all three components equal `o`'s.
    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask<I> {
        self.x.eq(o.x) & self.y.eq(o.y) & self.z.eq(o.z)
    }

    #[inline(always)]
    pub fn select(mask: Mask<I>, a: Self, b: Self) -> Self {
        Self {
            x: F32s::select(mask, a.x, b.x),
            y: F32s::select(mask, a.y, b.y),
            z: F32s::select(mask, a.z, b.z),
        }
    }
}

/// A component-wise operator of `Vec3s`.
macro_rules! componentwise {
    ($trait:ident, $f:ident, $op:tt) => {
        impl<I: Isa> $trait for Vec3s<I> {
            type Output = Vec3s<I>;
            #[inline(always)]
            fn $f(self, o: Vec3s<I>) -> Vec3s<I> {
                Vec3s { x: self.x $op o.x, y: self.y $op o.y, z: self.z $op o.z }
            }
        }
    };
}

componentwise!(Add, add, +);
componentwise!(Sub, sub, -);
componentwise!(Mul, mul, *);

impl<I: Isa> Neg for Vec3s<I> {
    type Output = Vec3s<I>;
    #[inline(always)]
    fn neg(self) -> Vec3s<I> {
        Vec3s { x: -self.x, y: -self.y, z: -self.z }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Whether this CPU runs lane types of `level`, reporting a skip where not.
    pub(crate) fn runnable(level: Level, test: &str) -> bool {
        let (runs, why) = match level {
            Level::Sse2 => return true,
            Level::Avx2 => (
                crate::render::integrator::v3::available(),
                "the CPU lacks x86-64-v3, so the AVX2 lanes were not checked",
            ),
            Level::Avx512 => (
                crate::render::integrator::v4::available(),
                "the CPU lacks x86-64-v4, so the AVX-512 lanes were not checked",
            ),
        };
        if !runs {
            crate::testing::skip(test, crate::testing::Missing::CpuFeature, why);
        }
        runs
    }

    /// Three tests running the generic check `$check` on the SSE2, AVX2 and AVX-512 lane
    /// types (the last two skipped where this CPU lacks their build's features).
    macro_rules! isa_tests {
        ($check:ident: $sse2:ident, $avx2:ident, $avx512:ident) => {
            #[test]
            fn $sse2() {
                $check::<$crate::render::lanes::Sse2>();
            }

            #[test]
            fn $avx2() {
                use $crate::render::lanes::{tests::runnable, Avx2, Level};
                if runnable(Level::Avx2, stringify!($avx2)) {
                    $check::<Avx2>();
                }
            }

            #[test]
            fn $avx512() {
                use $crate::render::lanes::{tests::runnable, Avx512, Level};
                if runnable(Level::Avx512, stringify!($avx512)) {
                    $check::<Avx512>();
                }
            }
        };
    }
    pub(crate) use isa_tests;

    fn scalar_bits<I: Isa>() {
        // Opaque inputs: LLVM folds constant NaN-making operations (0/0, √-x) to a NaN
        // other than the one the hardware makes, and Rust leaves NaN bits unspecified.
        use std::hint::black_box;
        let a = F32s::<I>::new(black_box([
            0.5,
            -1.25,
            3.0,
            f32::NAN,
            0.0,
            -0.0,
            1e-30,
            7.5,
            -0.0,
            f32::INFINITY,
            2.5,
            -1e20,
            f32::NAN,
            1.0,
            -3.0,
            0.25,
        ]));
        let b = F32s::<I>::new(black_box([
            2.0,
            4.0,
            -3.0,
            1.0,
            f32::NAN,
            0.0,
            3.0,
            -7.5,
            -0.0,
            f32::INFINITY,
            -2.5,
            1e20,
            f32::NAN,
            0.0,
            -3.0,
            8.0,
        ]));
        for (a, b) in [(a, b), (b, a)] {
            for i in 0..WIDTH {
                let (x, y) = (a.0[i], b.0[i]);
                let (max, min) = (a.max(b).0[i].to_bits(), a.min(b).0[i].to_bits());
                assert_eq!((max, min), (x.max(y).to_bits(), x.min(y).to_bits()), "{x} {y}");
            }
        }
        for i in 0..WIDTH {
            let (x, y) = (a.0[i], b.0[i]);
            assert_eq!((a + b).0[i].to_bits(), (x + y).to_bits());
            assert_eq!((a - b).0[i].to_bits(), (x - y).to_bits());
            assert_eq!((a * b).0[i].to_bits(), (x * y).to_bits());
            assert_eq!((a / b).0[i].to_bits(), (x / y).to_bits());
            assert_eq!((-a).0[i].to_bits(), (-x).to_bits());
            assert_eq!(a.sqrt().0[i].to_bits(), x.sqrt().to_bits());
            assert_eq!(a.lt(b).0[i] != 0, x < y);
            assert_eq!(a.le(b).0[i] != 0, x <= y);
            assert_eq!(a.gt(b).0[i] != 0, x > y);
            assert_eq!(a.eq(b).0[i] != 0, x == y);
            let sel = F32s::select(a.ge(b), a, b).0[i];
            assert_eq!(sel.to_bits(), if x >= y { x } else { y }.to_bits());
        }
        let v = Vec3s { x: a, y: b, z: a * b };
        for i in 0..WIDTH {
            let s = v.lane(i);
            assert_eq!(v.dot(v).0[i].to_bits(), s.dot(s).to_bits(), "lane {i}");
            assert_eq!(v.max_element().0[i].to_bits(), s.max_element().to_bits(), "lane {i}");
        }
        let m = U32s::<I>::from_bitmask(0b1100_0101_1010_0110);
        assert_eq!(m.bitmask(), 0b1100_0101_1010_0110);
        assert_eq!(U32s::<I>::splat(0x0000_0001).reverse_bits(), U32s::splat(0x8000_0000));
        let x = U32s::<I>::new([
            0,
            1,
            0x8000_0000,
            0xdead_beef,
            0x1234_5678,
            u32::MAX,
            7,
            0x0f0f_00f1,
            0x0102_0408,
            0x7fff_ffff,
            0xffff_0000,
            0x0000_ffff,
            42,
            0xcafe_f00d,
            0x8000_0001,
            0x5555_aaaa,
        ]);
        let y = U32s::<I>::new(std::array::from_fn(|i| {
            [3, 0x9e37_79b9, 2, 0x7feb_352d, 0xffff_fffe, 5, 0x8000_0001, 11][i % 8] ^ (i as u32)
        }));
        let table: [u32; 256] =
            std::array::from_fn(|i| (i as u32).wrapping_mul(0x0101_0101) ^ 0x55);
        let (rev, mul, add) = (x.reverse_bits(), x.wrapping_mul(y), x.wrapping_add(y));
        let (shr, shl, gather) = (x >> 8, x << 3, U32s::gather(&table, x & U32s::splat(0xff)));
        let lane = U32s::<I>::new(std::array::from_fn(|i| i as u32));
        let table16: [u32; 16] = std::array::from_fn(|i| table[i * 7]);
        let look = U32s::lookup16(&table16, (x ^ lane) & U32s::splat(15));
        let (eq, gt) =
            (x.eq(U32s::select(U32s::from_bitmask(0b0100_0000_0010_0000), x, !x)), x.gt_i32(y));
        let unit = (x >> 8).to_f32();
        for i in 0..WIDTH {
            let (a, b) = (x.0[i], y.0[i]);
            assert_eq!(rev.0[i], a.reverse_bits(), "lane {i}");
            assert_eq!(mul.0[i], a.wrapping_mul(b), "lane {i}");
            assert_eq!(add.0[i], a.wrapping_add(b), "lane {i}");
            assert_eq!((shr.0[i], shl.0[i]), (a >> 8, a << 3), "lane {i}");
            assert_eq!(gather.0[i], table[(a & 0xff) as usize], "lane {i}");
            assert_eq!(look.0[i], table16[((a ^ i as u32) & 15) as usize], "lane {i}");
            assert_eq!(gt.0[i] != 0, a as i32 > b as i32, "lane {i}");
            assert_eq!(unit.0[i].to_bits(), ((a >> 8) as f32).to_bits(), "lane {i}");
        }
        assert_eq!(eq.bitmask(), 0b0100_0000_0010_0000);
        let t = F32s::<I>::new(std::array::from_fn(|i| {
            [0.4, -0.6, 2.9, -3.5, 1e6, -0.0, 7.0, -1e-3][i % 8] * if i < 8 { 1.0 } else { -3.0 }
        }));
        let k = t.trunc_i32();
        for i in 0..WIDTH {
            assert_eq!(k.0[i] as i32, t.0[i] as i32, "lane {i}");
            assert_eq!(F32s::<I>::from_i32(k).0[i], (t.0[i] as i32) as f32, "lane {i}");
        }
    }

    isa_tests!(scalar_bits: sse2_lanes_give_the_scalar_bits, avx2_lanes_give_the_scalar_bits,
        avx512_lanes_give_the_scalar_bits);
}
