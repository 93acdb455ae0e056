//! Sixteen paths' numbers side by side: `f32` and `u32` lanes with element-wise
//! operators, for the stream kernel ([`super::stream`]) and the reconstruction's filters
//! (sixteen pixels of a row: `crate::reconstruct::rows`), in each kernel build's
//! instructions.
//!
//! The lane types carry the instruction set they compile to as a type parameter
//! ([`Isa`]): [`V4`](super::isa::V4) makes every operator one AVX-512 instruction on a
//! 512-bit register, [`V3`](super::isa::V3) two AVX/AVX2 instructions on 256-bit halves,
//! [`Baseline`](super::isa::Baseline) four SSE2 instructions on 128-bit quarters (so every
//! x86-64 CPU runs it); off x86-64 all are loops over sixteen elements. A parameter, not a
//! compile-time target feature, because one binary holds every build and picks one at run
//! time ([`super::integrator::render_pixels_counted`]): `F32s<V4>` may only be used by
//! code inlined into the x86-64-v4 build and `F32s<V3>` by code of the v3 build, whose
//! features make their intrinsics inline there (the kernel reaches them only through a
//! [`super::isa::Cpu`] of that level).
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
//!
//! Files: this one holds the types and the register plumbing every operator is written
//! with; `float.rs` the `f32` lanes' operators, `int.rs` the `u32` lanes' (and masks'),
//! `vec3.rs` three-component vectors of lanes, `tests.rs` the per-instruction-set checks
//! that every operator gives the scalar bits.

use std::marker::PhantomData;

pub use super::isa::Isa;

/// Lanes per group.
pub const WIDTH: usize = 16;

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
/// SAFETY (of every use): the AVX-512 side runs only for `V4` lanes and the AVX/AVX2
/// side only for `V3` lanes, which only code inlined into the x86-64-v4 and -v3 builds
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
/// each AVX half, `$sse` on each SSE quarter, by the lanes'
/// [`IsaLevel`](super::isa::IsaLevel) (a constant, so only one arm is compiled into a
/// build). Written out per register, not as a closure, so that it is never compiled out
/// of line.
#[cfg(target_arch = "x86_64")]
macro_rules! regs {
    ($I:ty, $in:ident -> $out:ident, $a:expr, $b:expr,
     |$x:ident, $y:ident| sse: $sse:expr, avx: $avx:expr, avx512: $avx512:expr) => {{
        let (a, b) = ($a, $b);
        match <$I as $crate::render::isa::Isa>::LEVEL {
            $crate::render::isa::IsaLevel::V4 => {
                let ($x, $y) = (regs!(@in1 $in, a), regs!(@in1 $in, b));
                regs!(@out1 $out, simd!($avx512))
            }
            $crate::render::isa::IsaLevel::V3 => {
                let (a, b) = (regs!(@in2 $in, a), regs!(@in2 $in, b));
                let r0 = { let ($x, $y) = (a[0], b[0]); simd!($avx) };
                let r1 = { let ($x, $y) = (a[1], b[1]); simd!($avx) };
                regs!(@out2 $out, [r0, r1])
            }
            $crate::render::isa::IsaLevel::Baseline => {
                let (a, b) = (regs!(@in4 $in, a), regs!(@in4 $in, b));
                let r0 = { let ($x, $y) = (a[0], b[0]); simd!($sse) };
                let r1 = { let ($x, $y) = (a[1], b[1]); simd!($sse) };
                let r2 = { let ($x, $y) = (a[2], b[2]); simd!($sse) };
                let r3 = { let ($x, $y) = (a[3], b[3]); simd!($sse) };
                regs!(@out4 $out, [r0, r1, r2, r3])
            }
        }
    }};
    (@in1 f, $e:expr) => { $crate::render::lanes::reg::f1($e) };
    (@in1 u, $e:expr) => { $crate::render::lanes::reg::u1($e) };
    (@in2 f, $e:expr) => { $crate::render::lanes::reg::f2($e) };
    (@in2 u, $e:expr) => { $crate::render::lanes::reg::u2($e) };
    (@in4 f, $e:expr) => { $crate::render::lanes::reg::f4($e) };
    (@in4 u, $e:expr) => { $crate::render::lanes::reg::u4($e) };
    (@out1 f, $e:expr) => { $crate::render::lanes::reg::fo1($e) };
    (@out1 u, $e:expr) => { $crate::render::lanes::reg::uo1($e) };
    (@out2 f, $e:expr) => { $crate::render::lanes::reg::fo2($e) };
    (@out2 u, $e:expr) => { $crate::render::lanes::reg::uo2($e) };
    (@out4 f, $e:expr) => { $crate::render::lanes::reg::fo4($e) };
    (@out4 u, $e:expr) => { $crate::render::lanes::reg::uo4($e) };
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

mod float;
mod int;
mod vec3;

pub use vec3::Vec3s;

#[cfg(test)]
pub(crate) mod tests;
