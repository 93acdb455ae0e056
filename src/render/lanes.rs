//! Eight paths' numbers side by side: `f32` and `u32` lanes with element-wise
//! operators, for the stream kernel ([`super::stream`]).
//!
//! On x86-64 every operator is one AVX/AVX2 instruction on a 256-bit register, so these
//! types may only be used by code that runs in the x86-64-v3 build (the stream kernel is
//! inlined into `integrator::v3`, whose features make the intrinsics inline there);
//! elsewhere they are loops over eight elements. Each operator is one IEEE operation per
//! lane, never fused (Rust does not contract `mul` and `add` into FMA), so a lane's
//! value is exactly what the scalar code computes from the same inputs in the same order:
//! that is what lets the stream kernel give the one-path kernel's bits. Not `std::simd`
//! (nightly only) nor the `wide` crate (it picks its instructions by compile-time target
//! features, so the run-time dispatched v3 build would get SSE halves); LLVM's own
//! vectorisation of eight-element loops was tried and gave half-width code with spills.
//!
//! Comparisons return a [`Mask`] of all-ones or all-zero lanes, and [`F8::select`] picks
//! by bits, so branches of the scalar code become blends of both sides.

use std::ops::{Add, BitAnd, BitOr, BitXor, Div, Mul, Neg, Not, Shl, Shr, Sub};

/// Lanes per group.
pub const WIDTH: usize = 8;

/// Eight `f32` lanes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct F8(pub [f32; WIDTH]);

/// Eight `u32` lanes (also masks: all ones is true).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(C, align(32))]
pub struct U8(pub [u32; WIDTH]);

/// Lanes of all ones (true) or all zeros (false).
pub type Mask = U8;

/// Runs an AVX/AVX2 expression on the lanes as registers.
///
/// SAFETY (of every use): the lane types are only used by code inlined into the
/// x86-64-v3 build, which runs only where the CPU has AVX2; `F8`/`U8` are 32 aligned
/// bytes, the layout of `__m256`/`__m256i`.
#[cfg(target_arch = "x86_64")]
macro_rules! avx {
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
    //! Reinterpretation between the lane types and AVX registers (no instructions).
    use super::{F8, U8};
    use std::arch::x86_64::{__m256, __m256i};

    #[inline(always)]
    pub fn f(x: F8) -> __m256 {
        // SAFETY: same size (32 bytes), any bits are a valid value of either.
        unsafe { std::mem::transmute(x) }
    }
    #[inline(always)]
    pub fn u(x: U8) -> __m256i {
        // SAFETY: as `f`.
        unsafe { std::mem::transmute(x) }
    }
    #[inline(always)]
    pub fn fo(x: __m256) -> F8 {
        // SAFETY: as `f`.
        unsafe { std::mem::transmute(x) }
    }
    #[inline(always)]
    pub fn uo(x: __m256i) -> U8 {
        // SAFETY: as `f`.
        unsafe { std::mem::transmute(x) }
    }
}

macro_rules! lanewise {
    ($ty:ident, $trait:ident, $f:ident, $op:tt, $avx:expr) => {
        impl $trait for $ty {
            type Output = $ty;
            #[inline(always)]
            fn $f(self, o: $ty) -> $ty {
                #[cfg(target_arch = "x86_64")]
                return $avx(self, o);
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

lanewise!(F8, Add, add, +, |a, b| reg::fo(avx!(_mm256_add_ps(reg::f(a), reg::f(b)))));
lanewise!(F8, Sub, sub, -, |a, b| reg::fo(avx!(_mm256_sub_ps(reg::f(a), reg::f(b)))));
lanewise!(F8, Mul, mul, *, |a, b| reg::fo(avx!(_mm256_mul_ps(reg::f(a), reg::f(b)))));
lanewise!(F8, Div, div, /, |a, b| reg::fo(avx!(_mm256_div_ps(reg::f(a), reg::f(b)))));
lanewise!(U8, BitAnd, bitand, &, |a, b| reg::uo(avx!(_mm256_and_si256(reg::u(a), reg::u(b)))));
lanewise!(U8, BitOr, bitor, |, |a, b| reg::uo(avx!(_mm256_or_si256(reg::u(a), reg::u(b)))));
lanewise!(U8, BitXor, bitxor, ^, |a, b| reg::uo(avx!(_mm256_xor_si256(reg::u(a), reg::u(b)))));

impl Neg for F8 {
    type Output = F8;
    #[inline(always)]
    fn neg(self) -> F8 {
        F8::from_bits(self.to_bits() ^ U8::splat(0x8000_0000))
    }
}

impl Not for U8 {
    type Output = U8;
    #[inline(always)]
    fn not(self) -> U8 {
        self ^ U8::splat(u32::MAX)
    }
}

impl Shr<u32> for U8 {
    type Output = U8;
    #[inline(always)]
    fn shr(self, n: u32) -> U8 {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_srl_epi32(reg::u(self), _mm_cvtsi32_si128(n as i32))));
        #[cfg(not(target_arch = "x86_64"))]
        self.map(|x| x >> n)
    }
}

impl Shl<u32> for U8 {
    type Output = U8;
    #[inline(always)]
    fn shl(self, n: u32) -> U8 {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_sll_epi32(reg::u(self), _mm_cvtsi32_si128(n as i32))));
        #[cfg(not(target_arch = "x86_64"))]
        self.map(|x| x << n)
    }
}

/// A comparison: AVX predicate on x86-64, the scalar operator elsewhere.
macro_rules! compare {
    ($name:ident, $op:tt, $pred:ident) => {
        #[inline(always)]
        pub fn $name(self, o: Self) -> Mask {
            #[cfg(target_arch = "x86_64")]
            return reg::uo(avx!(_mm256_castps_si256(_mm256_cmp_ps::<$pred>(
                reg::f(self),
                reg::f(o)
            ))));
            #[cfg(not(target_arch = "x86_64"))]
            {
                let mut out = U8::default();
                for i in 0..WIDTH {
                    out.0[i] = if self.0[i] $op o.0[i] { u32::MAX } else { 0 };
                }
                out
            }
        }
    };
}

impl F8 {
    #[inline(always)]
    pub fn splat(x: f32) -> Self {
        Self([x; WIDTH])
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        let mut out = self;
        for i in 0..WIDTH {
            out.0[i] = f(self.0[i]);
        }
        out
    }

    compare!(lt, <, _CMP_LT_OQ);
    compare!(le, <=, _CMP_LE_OQ);
    compare!(gt, >, _CMP_GT_OQ);
    compare!(ge, >=, _CMP_GE_OQ);
    compare!(eq, ==, _CMP_EQ_OQ);

    /// `mask ? a : b` per lane, by bits.
    #[inline(always)]
    pub fn select(mask: Mask, a: Self, b: Self) -> Self {
        F8::from_bits(U8::select(mask, a.to_bits(), b.to_bits()))
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return reg::fo(avx!(_mm256_sqrt_ps(reg::f(self))));
        #[cfg(not(target_arch = "x86_64"))]
        self.map(f32::sqrt)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        F8::from_bits(self.to_bits() & U8::splat(0x7fff_ffff))
    }

    /// [`f32::max`] per lane (the non-NaN side wins), as LLVM lowers it on x86:
    /// `maxps(o, self)` (which returns `self` on ties of ±0 and where either is NaN),
    /// then `o` where `self` is NaN.
    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return avx!({
            let (x, y) = (reg::f(self), reg::f(o));
            let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(x, x);
            reg::fo(_mm256_blendv_ps(_mm256_max_ps(y, x), y, nan))
        });
        #[cfg(not(target_arch = "x86_64"))]
        self.zip(o, f32::max)
    }

    /// [`f32::min`] per lane, as [`F8::max`].
    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return avx!({
            let (x, y) = (reg::f(self), reg::f(o));
            let nan = _mm256_cmp_ps::<_CMP_UNORD_Q>(x, x);
            reg::fo(_mm256_blendv_ps(_mm256_min_ps(y, x), y, nan))
        });
        #[cfg(not(target_arch = "x86_64"))]
        self.zip(o, f32::min)
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let mut out = self;
        for i in 0..WIDTH {
            out.0[i] = f(self.0[i], o.0[i]);
        }
        out
    }

    /// `x as i32` of each lane, for |x| < 2³¹ (truncation towards zero), as bits.
    #[inline(always)]
    pub fn trunc_i32(self) -> U8 {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_cvttps_epi32(reg::f(self))));
        #[cfg(not(target_arch = "x86_64"))]
        U8(self.0.map(|x| x as i32 as u32))
    }

    /// `x as f32` of each lane read as `i32`.
    #[inline(always)]
    pub fn from_i32(x: U8) -> Self {
        #[cfg(target_arch = "x86_64")]
        return reg::fo(avx!(_mm256_cvtepi32_ps(reg::u(x))));
        #[cfg(not(target_arch = "x86_64"))]
        F8(x.0.map(|x| x as i32 as f32))
    }

    #[inline(always)]
    pub fn to_bits(self) -> U8 {
        U8(self.0.map(f32::to_bits))
    }

    #[inline(always)]
    pub fn from_bits(b: U8) -> Self {
        F8(b.0.map(f32::from_bits))
    }
}

impl U8 {
    #[inline(always)]
    pub fn splat(x: u32) -> Self {
        Self([x; WIDTH])
    }

    #[inline(always)]
    pub fn map(self, f: impl Fn(u32) -> u32) -> Self {
        let mut out = self;
        for i in 0..WIDTH {
            out.0[i] = f(self.0[i]);
        }
        out
    }

    /// `mask ? a : b` per lane, by bits.
    #[inline(always)]
    pub fn select(mask: Mask, a: Self, b: Self) -> Self {
        (mask & a) | (!mask & b)
    }

    #[inline(always)]
    pub fn wrapping_mul(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_mullo_epi32(reg::u(self), reg::u(o))));
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut out = self;
            for i in 0..WIDTH {
                out.0[i] = self.0[i].wrapping_mul(o.0[i]);
            }
            out
        }
    }

    #[inline(always)]
    pub fn wrapping_add(self, o: Self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_add_epi32(reg::u(self), reg::u(o))));
        #[cfg(not(target_arch = "x86_64"))]
        {
            let mut out = self;
            for i in 0..WIDTH {
                out.0[i] = self.0[i].wrapping_add(o.0[i]);
            }
            out
        }
    }

    /// Lanes where `self` and `o` are equal.
    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_cmpeq_epi32(reg::u(self), reg::u(o))));
        #[cfg(not(target_arch = "x86_64"))]
        self.map2(o, |a, b| if a == b { u32::MAX } else { 0 })
    }

    /// Lanes where `self > o`, both read as `i32`.
    #[inline(always)]
    pub fn gt_i32(self, o: Self) -> Mask {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_cmpgt_epi32(reg::u(self), reg::u(o))));
        #[cfg(not(target_arch = "x86_64"))]
        self.map2(o, |a, b| if a as i32 > b as i32 { u32::MAX } else { 0 })
    }

    #[cfg(not(target_arch = "x86_64"))]
    #[inline(always)]
    fn map2(self, o: Self, f: impl Fn(u32, u32) -> u32) -> Self {
        let mut out = self;
        for i in 0..WIDTH {
            out.0[i] = f(self.0[i], o.0[i]);
        }
        out
    }

    /// [`u32::reverse_bits`] per lane: bytes reversed by a shuffle, then the bits of
    /// each byte through a nibble table.
    #[inline(always)]
    pub fn reverse_bits(self) -> Self {
        #[cfg(target_arch = "x86_64")]
        return avx!({
            let bytes = _mm256_setr_epi8(
                3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 3, 2, 1, 0, 7, 6, 5, 4, 11,
                10, 9, 8, 15, 14, 13, 12,
            );
            let nibbles = _mm256_setr_epi8(
                0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf,
                0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf,
            );
            let low = _mm256_set1_epi8(0x0f);
            let x = _mm256_shuffle_epi8(reg::u(self), bytes);
            let lo = _mm256_shuffle_epi8(nibbles, _mm256_and_si256(x, low));
            let hi = _mm256_shuffle_epi8(nibbles, _mm256_and_si256(_mm256_srli_epi16::<4>(x), low));
            reg::uo(_mm256_or_si256(_mm256_slli_epi16::<4>(lo), hi))
        });
        #[cfg(not(target_arch = "x86_64"))]
        self.map(u32::reverse_bits)
    }

    /// `table[i]` for each lane's `i` (< 256).
    #[inline(always)]
    pub fn gather(table: &[u32; 256], index: U8) -> Self {
        #[cfg(target_arch = "x86_64")]
        return reg::uo(avx!(_mm256_i32gather_epi32::<4>(
            table.as_ptr() as *const i32,
            reg::u(index)
        )));
        #[cfg(not(target_arch = "x86_64"))]
        index.map(|i| table[i as usize])
    }

    /// Each lane read as an integer below 2²⁴, converted exactly to `f32`.
    #[inline(always)]
    pub fn to_f32(self) -> F8 {
        F8::from_i32(self)
    }

    /// Lane `i` true where bit `i` of `bits` is set.
    #[inline(always)]
    pub fn from_bitmask(bits: u32) -> Mask {
        let lane_bits = U8([1, 2, 4, 8, 16, 32, 64, 128]);
        (U8::splat(bits) & lane_bits).eq(lane_bits)
    }

    /// Bit `i` set where lane `i` of a mask is true.
    #[inline(always)]
    pub fn bitmask(self) -> u32 {
        #[cfg(target_arch = "x86_64")]
        return avx!(_mm256_movemask_ps(_mm256_castsi256_ps(reg::u(self))) as u32);
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

/// Eight 3-vectors, component by component, with glam's `Vec3` arithmetic (same
/// operations in the same order, so the same bits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V8 {
    pub x: F8,
    pub y: F8,
    pub z: F8,
}

impl V8 {
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self { x: F8::splat(v.x), y: F8::splat(v.y), z: F8::splat(v.z) }
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
    pub fn dot(self, o: Self) -> F8 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn scale(self, s: F8) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    #[inline(always)]
    pub fn div_by(self, s: F8) -> Self {
        Self { x: self.x / s, y: self.y / s, z: self.z / s }
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Self { x: self.x.abs(), y: self.y.abs(), z: self.z.abs() }
    }

    /// glam's `max_element`: `max(x, max(y, z))` with `a > b ? a : b`.
    #[inline(always)]
    pub fn max_element(self) -> F8 {
        #[inline(always)]
        fn gt(a: F8, b: F8) -> F8 {
            F8::select(a.gt(b), a, b)
        }
        gt(self.x, gt(self.y, self.z))
    }

    /// Lanes where all three components equal `o`'s.
    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask {
        self.x.eq(o.x) & self.y.eq(o.y) & self.z.eq(o.z)
    }

    #[inline(always)]
    pub fn select(mask: Mask, a: Self, b: Self) -> Self {
        Self {
            x: F8::select(mask, a.x, b.x),
            y: F8::select(mask, a.y, b.y),
            z: F8::select(mask, a.z, b.z),
        }
    }
}

impl Add for V8 {
    type Output = V8;
    #[inline(always)]
    fn add(self, o: V8) -> V8 {
        V8 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}

impl Sub for V8 {
    type Output = V8;
    #[inline(always)]
    fn sub(self, o: V8) -> V8 {
        V8 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}

impl Mul for V8 {
    type Output = V8;
    #[inline(always)]
    fn mul(self, o: V8) -> V8 {
        V8 { x: self.x * o.x, y: self.y * o.y, z: self.z * o.z }
    }
}

impl Neg for V8 {
    type Output = V8;
    #[inline(always)]
    fn neg(self) -> V8 {
        V8 { x: -self.x, y: -self.y, z: -self.z }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Whether this CPU runs the lane types (AVX2), reporting a skip where not.
    pub(crate) fn runnable(test: &str) -> bool {
        if crate::render::integrator::v3::available() {
            return true;
        }
        let why = "the lane types are AVX2 registers";
        crate::testing::skip(test, crate::testing::Missing::CpuFeature, why);
        false
    }

    #[test]
    fn lanes_give_the_scalar_bits() {
        if !runnable("lanes_give_the_scalar_bits") {
            return;
        }
        let a = F8([0.5, -1.25, 3.0, f32::NAN, 0.0, -0.0, 1e-30, 7.5]);
        let b = F8([2.0, 4.0, -3.0, 1.0, f32::NAN, 0.0, 3.0, -7.5]);
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
            assert_eq!((a / b).0[i].to_bits(), (x / y).to_bits());
            assert_eq!(a.lt(b).0[i] != 0, x < y);
            let sel = F8::select(a.ge(b), a, b).0[i];
            assert_eq!(sel.to_bits(), if x >= y { x } else { y }.to_bits());
        }
        let v = V8 { x: a, y: b, z: a * b };
        for i in 0..WIDTH {
            let s = v.lane(i);
            assert_eq!(v.dot(v).0[i].to_bits(), s.dot(s).to_bits(), "lane {i}");
            assert_eq!(v.max_element().0[i].to_bits(), s.max_element().to_bits(), "lane {i}");
        }
        let m = U8::from_bitmask(0b1010_0110);
        assert_eq!(m.bitmask(), 0b1010_0110);
        assert_eq!(U8::splat(0x0000_0001).reverse_bits(), U8::splat(0x8000_0000));
        let x = U8([0, 1, 0x8000_0000, 0xdead_beef, 0x1234_5678, u32::MAX, 7, 0x0f0f_00f1]);
        let y = U8([3, 0x9e37_79b9, 2, 0x7feb_352d, 0xffff_fffe, 5, 0x8000_0001, 11]);
        let table: [u32; 256] =
            std::array::from_fn(|i| (i as u32).wrapping_mul(0x0101_0101) ^ 0x55);
        let (rev, mul, add) = (x.reverse_bits(), x.wrapping_mul(y), x.wrapping_add(y));
        let (shr, shl, gather) = (x >> 8, x << 3, U8::gather(&table, x & U8::splat(0xff)));
        let unit = (x >> 8).to_f32();
        for i in 0..WIDTH {
            let (a, b) = (x.0[i], y.0[i]);
            assert_eq!(rev.0[i], a.reverse_bits(), "lane {i}");
            assert_eq!(mul.0[i], a.wrapping_mul(b), "lane {i}");
            assert_eq!(add.0[i], a.wrapping_add(b), "lane {i}");
            assert_eq!((shr.0[i], shl.0[i]), (a >> 8, a << 3), "lane {i}");
            assert_eq!(gather.0[i], table[(a & 0xff) as usize], "lane {i}");
            assert_eq!(unit.0[i].to_bits(), ((a >> 8) as f32).to_bits(), "lane {i}");
        }
        let t = F8([0.4, -0.6, 2.9, -3.5, 1e6, -0.0, 7.0, -1e-3]);
        let k = t.trunc_i32();
        for i in 0..WIDTH {
            assert_eq!(k.0[i] as i32, t.0[i] as i32, "lane {i}");
            assert_eq!(F8::from_i32(k).0[i], (t.0[i] as i32) as f32, "lane {i}");
        }
    }
}
