//! Sine and cosine for the render kernel, in plain IEEE arithmetic.
//!
//! glibc picks its `sincosf` at load time by CPU (an FMA variant where the CPU has FMA),
//! so the same sample could differ in the last bit between two workers of one grid, which
//! the ARCHITECTURE invariant forbids; a libm call also cost 4 % of a Cornell box frame.
//! This is Cephes' `sinf`/`cosf` (Moshier): Cody–Waite reduction by π/2 in three parts,
//! then degree-7 and degree-8 polynomials on |r| ≤ π/4; about 1e-7 absolute error, and
//! the same bits in every build, as every operation is a single IEEE add or multiply.

use super::lanes::{F32s, Isa, U32s};

/// (sin x, cos x) for |x| up to a few thousand (the kernel's angles are within ±2π).
#[inline(always)]
pub fn sin_cos(x: f32) -> (f32, f32) {
    const FRAC_2_PI: f32 = std::f32::consts::FRAC_2_PI;
    // π/2 = P1 + P2 + P3, with P1 and P2 short enough that k·P1 and k·P2 are exact.
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    let k = (x * FRAC_2_PI + if x >= 0.0 { 0.5 } else { -0.5 }) as i32;
    let kf = k as f32;
    let r = ((x - kf * P1) - kf * P2) - kf * P3;
    let z = r * r;
    let s = r + r * z * (-1.666_665_5e-1 + z * (8.332_161e-3 + z * -1.951_529_6e-4));
    let c = 1.0 - 0.5 * z + z * z * (4.166_664_6e-2 + z * (-1.388_731_6e-3 + z * 2.443_315_7e-5));
    // Quadrant k: odd swaps sin and cos, k & 2 negates sin, (k + 1) & 2 negates cos;
    // done on the bits, because the quadrant of a random angle defeats a branch.
    let (sb, cb) = (s.to_bits(), c.to_bits());
    let swap = 0u32.wrapping_sub(k as u32 & 1);
    let sin = (sb & !swap) | (cb & swap);
    let cos = (cb & !swap) | (sb & swap);
    let sin_sign = (k as u32 & 2) << 30;
    let cos_sign = (k.wrapping_add(1) as u32 & 2) << 30;
    (f32::from_bits(sin ^ sin_sign), f32::from_bits(cos ^ cos_sign))
}

/// [`sin_cos`] of sixteen lanes: the same operations lane by lane, so the same bits.
#[inline(always)]
pub fn sin_cos_lanes<I: Isa>(x: F32s<I>) -> (F32s<I>, F32s<I>) {
    const FRAC_2_PI: f32 = std::f32::consts::FRAC_2_PI;
    const P1: f32 = 1.570_312_5;
    const P2: f32 = 4.837_513e-4;
    const P3: f32 = 7.549_79e-8;
    let half = F32s::select(x.ge(F32s::splat(0.0)), F32s::splat(0.5), F32s::splat(-0.5));
    let t = x * F32s::splat(FRAC_2_PI) + half;
    // Lanes whose angle is NaN get another `k` than `as i32` gives; their values are
    // NaN either way.
    let k = t.trunc_i32();
    let kf = F32s::from_i32(k);
    let r = ((x - kf * F32s::splat(P1)) - kf * F32s::splat(P2)) - kf * F32s::splat(P3);
    let z = r * r;
    let c = |x: f32| F32s::splat(x);
    let s = r + r * z * (c(-1.666_665_5e-1) + z * (c(8.332_161e-3) + z * c(-1.951_529_6e-4)));
    let co = c(1.0) - c(0.5) * z
        + z * z * (c(4.166_664_6e-2) + z * (c(-1.388_731_6e-3) + z * c(2.443_315_7e-5)));
    let (sb, cb) = (s.to_bits(), co.to_bits());
    let swap = (k & U32s::splat(1)).eq(U32s::splat(1));
    let sin = (sb & !swap) | (cb & swap);
    let cos = (cb & !swap) | (sb & swap);
    let sin_sign = (k & U32s::splat(2)) << 30;
    let cos_sign = (k.wrapping_add(U32s::splat(1)) & U32s::splat(2)) << 30;
    (F32s::from_bits(sin ^ sin_sign), F32s::from_bits(cos ^ cos_sign))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::lanes::tests::isa_tests;
    use crate::render::lanes::WIDTH;

    #[test]
    fn matches_double_precision_sin_and_cos() {
        let mut worst = 0.0f64;
        for i in -200_000..=200_000 {
            let x = i as f32 * (4.0 * std::f32::consts::PI / 200_000.0);
            let (s, c) = sin_cos(x);
            let (es, ec) = (x as f64).sin_cos();
            worst = worst.max((s as f64 - es).abs()).max((c as f64 - ec).abs());
        }
        assert!(worst < 2e-7, "worst absolute error {worst:e}");
        // Quadrant boundaries and signs.
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        let (s, c) = sin_cos(std::f32::consts::FRAC_PI_2);
        assert!((s - 1.0).abs() < 1e-7 && c.abs() < 1e-7);
        let (s, c) = sin_cos(-std::f32::consts::PI);
        assert!(s.abs() < 1e-7 && (c + 1.0).abs() < 1e-7);
    }

    fn lanes<I: Isa>() {
        for i in -200..200 {
            let x = F32s::<I>::new(std::array::from_fn(|l| {
                (i * WIDTH as i32 + l as i32) as f32 * 0.0123
            }));
            let (s, c) = sin_cos_lanes(x);
            for l in 0..WIDTH {
                let (es, ec) = sin_cos(x.0[l]);
                assert_eq!((s.0[l].to_bits(), c.0[l].to_bits()), (es.to_bits(), ec.to_bits()));
            }
        }
    }

    isa_tests!(lanes: sse2_lanes_give_the_scalar_bits, avx2_lanes_give_the_scalar_bits,
        avx512_lanes_give_the_scalar_bits);
}
