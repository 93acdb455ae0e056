//! The `u32` lanes' operators (and masks'): bitwise logic, shifts, wrapping arithmetic,
//! integer comparisons, bit reversal, table lookups and conversions to and from masks.

use std::marker::PhantomData;
use std::ops::{BitAnd, BitOr, BitXor, Not, Shl, Shr};

#[cfg(target_arch = "x86_64")]
use super::reg;
use super::{each, F32s, Isa, Mask, U32s, WIDTH};
#[cfg(target_arch = "x86_64")]
use crate::render::isa::IsaLevel;

lanewise!(U32s, u, BitAnd, bitand, &, _mm_and_si128, _mm256_and_si256, _mm512_and_si512);
lanewise!(U32s, u, BitOr, bitor, |, _mm_or_si128, _mm256_or_si256, _mm512_or_si512);
lanewise!(U32s, u, BitXor, bitxor, ^, _mm_xor_si128, _mm256_xor_si256, _mm512_xor_si512);

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
        if I::LEVEL != IsaLevel::Baseline {
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
        if I::LEVEL != IsaLevel::Baseline {
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
        if I::LEVEL != IsaLevel::Baseline {
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
            IsaLevel::V4 => simd!(_mm512_movepi32_mask(reg::u1(self.0))) as u32,
            IsaLevel::V3 => simd!({
                let h = reg::u2(self.0);
                let lo = _mm256_movemask_ps(_mm256_castsi256_ps(h[0])) as u32;
                let hi = _mm256_movemask_ps(_mm256_castsi256_ps(h[1])) as u32;
                lo | (hi << 8)
            }),
            IsaLevel::Baseline => simd!({
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
