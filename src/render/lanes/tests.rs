//! Every lane operator against the scalar code's bits, in each instruction set.

use super::*;
use crate::render::isa::IsaLevel;

/// Whether this CPU runs lane types of `level`, reporting a skip where not.
pub(crate) fn runnable(level: IsaLevel, test: &str) -> bool {
    if !level.available() {
        let why = format!("the CPU lacks {}, so its lanes were not checked", level.name());
        crate::testing::skip(test, crate::testing::Missing::CpuFeature, why);
        return false;
    }
    true
}

/// Three tests running the generic check `$check` on the baseline, v3 and v4 lane types
/// (the last two skipped where this CPU lacks their build's features).
macro_rules! isa_tests {
    ($check:ident: $baseline:ident, $v3:ident, $v4:ident) => {
        #[test]
        fn $baseline() {
            $check::<$crate::render::isa::Baseline>();
        }

        #[test]
        fn $v3() {
            use $crate::render::isa::{IsaLevel, V3};
            if $crate::render::lanes::tests::runnable(IsaLevel::V3, stringify!($v3)) {
                $check::<V3>();
            }
        }

        #[test]
        fn $v4() {
            use $crate::render::isa::{IsaLevel, V4};
            if $crate::render::lanes::tests::runnable(IsaLevel::V4, stringify!($v4)) {
                $check::<V4>();
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
            // x86's maxps/minps: the second operand unless the first is strictly beyond.
            let (maxps, minps) = (a.maxps(b).0[i].to_bits(), a.minps(b).0[i].to_bits());
            let want = (if x > y { x } else { y }, if x < y { x } else { y });
            assert_eq!((maxps, minps), (want.0.to_bits(), want.1.to_bits()), "{x} {y}");
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
    let table: [u32; 256] = std::array::from_fn(|i| (i as u32).wrapping_mul(0x0101_0101) ^ 0x55);
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

/// The operations the reconstruction's filters use: loads from planes, stores, sums
/// across lanes, the positive part and masking, against the scalar code's bits.
fn filter_bits<I: Isa>() {
    use std::hint::black_box;
    let awkward = [0.5, -1.25, f32::NAN, -0.0, 0.0, f32::INFINITY, f32::NEG_INFINITY, 1e-30];
    let plane: Vec<f32> = black_box(
        (0..3 * WIDTH + 5)
            .map(|i| awkward[i % 8] * if i % 3 == 0 { 1.0 } else { -3.5 } + (i % 5) as f32)
            .collect(),
    );
    let i = 7;
    let a = F32s::<I>::load(&plane, i);
    // SAFETY: `i + WIDTH` is within the plane.
    let b = unsafe { F32s::<I>::load_unchecked(&plane, i + WIDTH) };
    let keep = U32s::<I>::from_bitmask(0b1011_0010_1110_0101);
    let (pos, masked) = (a.positive_part(), a.masked(keep));
    let mut acc = a;
    acc += b;
    let mut stored = [0.0; WIDTH];
    b.store(&mut stored);
    for k in 0..WIDTH {
        let (x, y) = (plane[i + k], plane[i + WIDTH + k]);
        assert_eq!((a.0[k].to_bits(), stored[k].to_bits()), (x.to_bits(), y.to_bits()));
        let want = if x > 0.0 { x } else { 0.0 };
        assert_eq!(pos.0[k].to_bits(), want.to_bits(), "positive part of {x}");
        let want = if keep.0[k] != 0 { x } else { 0.0 };
        assert_eq!(masked.0[k].to_bits(), want.to_bits(), "lane {k}");
        assert_eq!(acc.0[k].to_bits(), (x + y).to_bits(), "lane {k}");
    }
    // The sum, pairwise in the documented order, of finite values (and of a NaN).
    let finite = F32s::<I>::new(black_box(std::array::from_fn(|k| 1.0 / (k as f32 + 3.0))));
    let mut want = finite.0;
    for n in [8, 4, 2, 1] {
        for k in 0..n {
            want[k] += want[k + n];
        }
    }
    assert_eq!(finite.sum().to_bits(), want[0].to_bits());
    assert!(a.sum().is_nan());
    let planes = [&plane[..], &plane[WIDTH..], &plane[2 * WIDTH..]];
    let v = Vec3s::<I>::load(&planes, 2);
    // SAFETY: each plane holds `2 + WIDTH` entries.
    let u = unsafe { Vec3s::<I>::load_unchecked(&planes, 2) };
    let f = Vec3s::<I> { x: finite, y: finite * finite, z: -finite };
    let (lanes, sum, masked) = (v.to_vec3s(), f.sum(), v.masked(keep));
    let mut acc = f;
    acc += f;
    assert_eq!(
        sum.to_array().map(f32::to_bits),
        [finite.sum(), (finite * finite).sum(), (-finite).sum()].map(f32::to_bits)
    );
    for k in 0..WIDTH {
        let want = glam::Vec3::new(planes[0][2 + k], planes[1][2 + k], planes[2][2 + k]);
        assert_eq!(lanes[k].to_array().map(f32::to_bits), want.to_array().map(f32::to_bits));
        assert_eq!(u.lane(k).to_array().map(f32::to_bits), want.to_array().map(f32::to_bits));
        let kept = if keep.0[k] != 0 { want } else { glam::Vec3::ZERO };
        assert_eq!(masked.lane(k).to_array().map(f32::to_bits), kept.to_array().map(f32::to_bits));
        assert_eq!(acc.lane(k), f.lane(k) + f.lane(k), "lane {k}");
    }
    assert_eq!(v.to_array()[1].to_bits(), v.y.to_bits());
}

isa_tests!(filter_bits: sse2_filter_lanes_give_the_scalar_bits,
    avx2_filter_lanes_give_the_scalar_bits, avx512_filter_lanes_give_the_scalar_bits);
