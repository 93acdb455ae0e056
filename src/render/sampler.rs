//! Deterministic sample values: Owen-scrambled, shuffled Sobol points.
//!
//! Every random number of the path tracer comes from here, addressed by
//! (scene seed, frame, pixel, sample index, dimension) — never from entropy — so a
//! sample can be replayed bit for bit (STYLE.md item 9). Following Burley,
//! "Practical Hash-based Owen Scrambling" (JCGT 2020), each 4-D draw takes the
//! first four Sobol dimensions, shuffles the sample index and Owen-scrambles each
//! dimension with a hash-based nested uniform scramble seeded per (pixel, draw).
//! Independent draws ("padding") give an unbounded number of dimensions while each
//! 4-D group keeps its low discrepancy.

use super::isa::IsaLevel;
use super::lanes::{F32s, Isa, U32s};

/// Number of bits in a Sobol direction vector.
const BITS: usize = 32;

/// Direction numbers of Sobol dimensions 1..=3 (dimension 0 is bit reversal),
/// from the primitive polynomials of Joe & Kuo: (degree, coefficients, initial m).
const POLYNOMIALS: [(usize, u32, [u32; 3]); 3] =
    [(1, 0, [1, 0, 0]), (2, 1, [1, 3, 0]), (3, 1, [1, 3, 1])];

/// The 32 direction vectors of one Sobol dimension (Bratley & Fox recurrence).
const fn directions(degree: usize, coeffs: u32, initial: [u32; 3]) -> [u32; BITS] {
    let mut m = [0u32; BITS];
    let mut k = 0;
    while k < BITS {
        if k < degree {
            m[k] = initial[k];
        } else {
            let mut value = m[k - degree] ^ (m[k - degree] << degree);
            let mut j = 1;
            while j < degree {
                if (coeffs >> (degree - 1 - j)) & 1 == 1 {
                    value ^= m[k - j] << j;
                }
                j += 1;
            }
            m[k] = value;
        }
        k += 1;
    }
    let mut v = [0u32; BITS];
    let mut k = 0;
    while k < BITS {
        v[k] = m[k] << (BITS - 1 - k);
        k += 1;
    }
    v
}

/// Byte tables: `TABLES[d][b][x]` is the bit reversal of the XOR of the direction
/// vectors of dimension `d + 1` selected by the bits of byte `b` of the index being
/// `x`. Four lookups replace a 32-step loop per dimension; storing them reversed
/// hands the Owen scramble its input directly (reversal commutes with XOR), which
/// saves a bit reversal per dimension and draw.
static TABLES: [[[u32; 256]; 4]; 3] = build_tables();

/// The same by nibble (`NIBBLES[d][n][x]`, eight lookups), for the x86-64-v4 build: a
/// sixteen-entry table fits one AVX-512 register, where one permutation looks up sixteen
/// lanes, while gathers from the byte tables are slow on Zen 4 (1.04× the samples per
/// second on the Cornell box and Sponza there, parity on the bunny).
static NIBBLES: [[[u32; 16]; 8]; 3] = build_tables();

/// Tables of `C` chunks of `BITS / C` index bits, `N` = 2^(BITS / C) entries each.
const fn build_tables<const N: usize, const C: usize>() -> [[[u32; N]; C]; 3] {
    let width = BITS / C;
    let mut tables = [[[0u32; N]; C]; 3];
    let mut d = 0;
    while d < 3 {
        let (degree, coeffs, initial) = POLYNOMIALS[d];
        let v = directions(degree, coeffs, initial);
        let mut b = 0;
        while b < C {
            let mut x = 0;
            while x < N {
                let mut acc = 0u32;
                let mut bit = 0;
                while bit < width {
                    if (x >> bit) & 1 == 1 {
                        acc ^= v[b * width + bit];
                    }
                    bit += 1;
                }
                tables[d][b][x] = acc.reverse_bits();
                x += 1;
            }
            b += 1;
        }
        d += 1;
    }
    tables
}

/// Sobol dimension `dim + 1` (0..3) of point `index`, as a bit-reversed 32-bit
/// fixed-point value.
#[inline(always)]
fn sobol_reversed(index: u32, dim: usize) -> u32 {
    let t = &TABLES[dim];
    t[0][(index & 0xff) as usize]
        ^ t[1][((index >> 8) & 0xff) as usize]
        ^ t[2][((index >> 16) & 0xff) as usize]
        ^ t[3][(index >> 24) as usize]
}

/// Hash-based Laine–Karras permutation (Vegdahl's improved constants): a random
/// bijection in which each bit depends only on the bits below it.
#[inline(always)]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x ^= x.wrapping_mul(0x3d20_adea);
    x = x.wrapping_add(seed);
    x = x.wrapping_mul((seed >> 16) | 1);
    x ^= x.wrapping_mul(0x0552_6c56);
    x ^= x.wrapping_mul(0x53a2_2864);
    x
}

/// Nested uniform (Owen) scramble of a 32-bit fixed-point value given bit-reversed.
#[inline(always)]
fn owen_scramble_reversed(reversed: u32, seed: u32) -> u32 {
    laine_karras(reversed, seed).reverse_bits()
}

/// A fast, well-mixing 64-bit hash (splitmix64 finaliser).
#[inline(always)]
pub(crate) fn mix64(mut x: u64) -> u64 {
    x ^= x >> 30;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 27;
    x = x.wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A fast 32-bit hash (Wellons' lowbias32).
#[inline(always)]
fn mix32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^ (x >> 16)
}

/// Converts 32-bit fixed point to a float in [0, 1).
#[inline(always)]
pub(crate) fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The 32-bit seed every sample stream of `pixel` in `frame` starts from: the only part
/// of the sampler that needs 64-bit arithmetic, so the GPU tracer gets it from here.
#[inline(always)]
pub fn pixel_seed(seed: u64, frame: u64, pixel: u32) -> u32 {
    let h = mix64(seed ^ mix64(frame.wrapping_add(0x9e37_79b9_7f4a_7c15) ^ mix64(pixel as u64)));
    (h ^ (h >> 32)) as u32
}

/// The byte tables of Sobol dimensions 1..=3 as the GPU tracer reads them:
/// `[dimension][byte][value]`, flattened.
pub fn sobol_tables() -> &'static [[[u32; 256]; 4]; 3] {
    &TABLES
}

/// The sample stream of one pixel sample: draws 4-D points for consecutive
/// dimension groups of sample `index` of a pixel.
#[derive(Clone, Copy, Debug)]
pub struct SampleStream {
    pub(crate) pixel_seed: u32,
    /// The sample index, bit-reversed once for every draw's index shuffle.
    pub(crate) index_reversed: u32,
    /// Draws taken so far.
    pub(crate) draw: u32,
}

impl SampleStream {
    /// The stream of sample `index` of `pixel` in `frame` under the scene `seed`.
    #[inline(always)]
    pub fn new(seed: u64, frame: u64, pixel: u32, index: u32) -> Self {
        Self {
            pixel_seed: pixel_seed(seed, frame, pixel),
            index_reversed: index.reverse_bits(),
            draw: 0,
        }
    }

    /// The next 4-D point of this sample, every coordinate in [0, 1).
    #[inline(always)]
    pub fn next4(&mut self) -> [f32; 4] {
        let seed =
            mix32(self.pixel_seed ^ mix32(self.draw.wrapping_mul(0x9e37_79b9) ^ 0x68e3_1da4));
        self.draw += 1;
        // Shuffle the point order (an Owen scramble of the index keeps the
        // sequence's stratification over power-of-two prefixes).
        let i = owen_scramble_reversed(self.index_reversed, seed);
        [
            // Dimension 0 is the bit reversal of the index; scrambling it reduces to a
            // Laine–Karras permutation of the index itself.
            to_unit(owen_scramble_reversed(i, mix32(seed ^ 0xa511_e9b3))),
            to_unit(owen_scramble_reversed(sobol_reversed(i, 0), mix32(seed ^ 0x63d8_3595))),
            to_unit(owen_scramble_reversed(sobol_reversed(i, 1), mix32(seed ^ 0x9e1f_4a13))),
            to_unit(owen_scramble_reversed(sobol_reversed(i, 2), mix32(seed ^ 0x2c1b_3c6d))),
        ]
    }
}

/// [`SampleStream::next4`] of sixteen streams at once, each at its own draw: the same
/// integer steps lane by lane (so the same values), for the stream kernel.
#[inline(always)]
pub(crate) fn next4_lanes<I: Isa>(
    pixel_seed: U32s<I>,
    index_reversed: U32s<I>,
    draw: U32s<I>,
) -> [F32s<I>; 4] {
    // Functions, not closures: a closure called several times may be outlined, and
    // outside the v3 build's function its lane intrinsics would not inline.
    #[inline(always)]
    fn mix<I: Isa>(x: U32s<I>) -> U32s<I> {
        let x = x ^ (x >> 16);
        let x = x.wrapping_mul(U32s::splat(0x7feb_352d));
        let x = x ^ (x >> 15);
        let x = x.wrapping_mul(U32s::splat(0x846c_a68b));
        x ^ (x >> 16)
    }
    #[inline(always)]
    fn owen<I: Isa>(mut x: U32s<I>, seed: U32s<I>) -> U32s<I> {
        x = x ^ x.wrapping_mul(U32s::splat(0x3d20_adea));
        x = x.wrapping_add(seed);
        x = x.wrapping_mul((seed >> 16) | U32s::splat(1));
        x = x ^ x.wrapping_mul(U32s::splat(0x0552_6c56));
        x = x ^ x.wrapping_mul(U32s::splat(0x53a2_2864));
        x.reverse_bits()
    }
    #[inline(always)]
    fn unit<I: Isa>(x: U32s<I>) -> F32s<I> {
        (x >> 8).to_f32() * F32s::splat(1.0 / 16_777_216.0)
    }
    #[inline(always)]
    fn sobol<I: Isa>(i: U32s<I>, dim: usize) -> U32s<I> {
        if I::LEVEL == IsaLevel::V4 {
            let mut x = U32s::splat(0);
            for (n, table) in NIBBLES[dim].iter().enumerate() {
                x = x ^ U32s::lookup16(table, (i >> (4 * n as u32)) & U32s::splat(15));
            }
            return x;
        }
        let t = &TABLES[dim];
        let byte = U32s::splat(0xff);
        U32s::gather(&t[0], i & byte)
            ^ U32s::gather(&t[1], (i >> 8) & byte)
            ^ U32s::gather(&t[2], (i >> 16) & byte)
            ^ U32s::gather(&t[3], i >> 24)
    }
    let seed =
        mix(pixel_seed
            ^ mix(draw.wrapping_mul(U32s::splat(0x9e37_79b9)) ^ U32s::splat(0x68e3_1da4)));
    let i = owen(index_reversed, seed);
    [
        unit(owen(i, mix(seed ^ U32s::splat(0xa511_e9b3)))),
        unit(owen(sobol(i, 0), mix(seed ^ U32s::splat(0x63d8_3595)))),
        unit(owen(sobol(i, 1), mix(seed ^ U32s::splat(0x9e1f_4a13)))),
        unit(owen(sobol(i, 2), mix(seed ^ U32s::splat(0x2c1b_3c6d)))),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::lanes::tests::isa_tests;
    use crate::render::lanes::WIDTH;

    /// Plain Sobol value by the defining XOR over set bits.
    fn sobol_slow(index: u32, dim: usize) -> u32 {
        let v = if dim == 0 {
            std::array::from_fn(|k| 1u32 << (31 - k))
        } else {
            let (d, c, m) = POLYNOMIALS[dim - 1];
            directions(d, c, m)
        };
        (0..32).filter(|k| index >> k & 1 == 1).fold(0, |acc, k| acc ^ v[k])
    }

    #[test]
    fn direction_numbers_match_published_sobol() {
        // Dimension 2 of the Sobol sequence: m = 1, 3, 5, 15, 17, 51, ...
        let v = directions(1, 0, [1, 0, 0]);
        let m: Vec<u32> = (0..6).map(|k| v[k] >> (31 - k)).collect();
        assert_eq!(m, [1, 3, 5, 15, 17, 51]);
        // Every m_k is odd and below 2^(k+1), the defining property of direction numbers.
        for (d, c, init) in POLYNOMIALS {
            let v = directions(d, c, init);
            for (k, vk) in v.iter().enumerate() {
                let mk = vk >> (31 - k);
                assert_eq!(mk & 1, 1);
                assert!((mk as u64) < 1u64 << (k + 1));
            }
        }
        for dim in 0..3 {
            for i in [0u32, 1, 2, 3, 255, 256, 12345, u32::MAX] {
                assert_eq!(sobol_reversed(i, dim).reverse_bits(), sobol_slow(i, dim + 1));
            }
        }
    }

    #[test]
    fn draws_match_the_reference_definition() {
        // The kernel's reversed tables and hoisted reversals must give exactly the
        // textbook construction: Owen-scramble the index, then each Sobol dimension.
        let owen = |x: u32, seed: u32| laine_karras(x.reverse_bits(), seed).reverse_bits();
        for (pixel, index) in [(0u32, 0u32), (5, 1), (77, 3), (1234, 1023), (9, u32::MAX)] {
            let mut stream = SampleStream::new(42, 7, pixel, index);
            let h =
                mix64(42 ^ mix64(7u64.wrapping_add(0x9e37_79b9_7f4a_7c15) ^ mix64(pixel as u64)));
            let pixel_seed = (h ^ (h >> 32)) as u32;
            for draw in 0..6u32 {
                let seed = mix32(pixel_seed ^ mix32(draw.wrapping_mul(0x9e37_79b9) ^ 0x68e3_1da4));
                let i = owen(index, seed);
                let expected = [
                    owen(sobol_slow(i, 0), mix32(seed ^ 0xa511_e9b3)),
                    owen(sobol_slow(i, 1), mix32(seed ^ 0x63d8_3595)),
                    owen(sobol_slow(i, 2), mix32(seed ^ 0x9e1f_4a13)),
                    owen(sobol_slow(i, 3), mix32(seed ^ 0x2c1b_3c6d)),
                ]
                .map(to_unit);
                assert_eq!(stream.next4(), expected, "pixel {pixel} index {index} draw {draw}");
            }
        }
    }

    fn lanes_draw<I: Isa>() {
        let mut streams: [SampleStream; WIDTH] =
            std::array::from_fn(|l| SampleStream::new(9, 4, 100 + l as u32 * 37, l as u32 * 3));
        for (l, stream) in streams.iter_mut().enumerate() {
            for _ in 0..l {
                stream.next4();
            }
        }
        let lanes =
            |f: fn(&SampleStream) -> u32| U32s::<I>::new(std::array::from_fn(|l| f(&streams[l])));
        let got =
            next4_lanes(lanes(|s| s.pixel_seed), lanes(|s| s.index_reversed), lanes(|s| s.draw));
        for (l, s) in streams.iter_mut().enumerate() {
            let want = s.next4();
            for k in 0..4 {
                assert_eq!(got[k].0[l].to_bits(), want[k].to_bits(), "lane {l} dimension {k}");
            }
        }
    }

    isa_tests!(lanes_draw: sse2_lanes_draw_what_their_streams_draw,
        avx2_lanes_draw_what_their_streams_draw, avx512_lanes_draw_what_their_streams_draw);

    #[test]
    fn sobol_points_are_stratified_in_2d() {
        // The first 16 points of dimensions (0,1) put one point in each 4x4 cell.
        let mut cells = [0u32; 16];
        for i in 0..16u32 {
            let x = sobol_slow(i, 0) >> 30;
            let y = sobol_slow(i, 1) >> 30;
            cells[(y * 4 + x) as usize] += 1;
        }
        assert!(cells.iter().all(|&c| c == 1), "{cells:?}");
    }

    #[test]
    fn scrambled_points_keep_stratification_and_differ_per_pixel() {
        for pixel in 0..4 {
            let mut cells = [[0u32; 4]; 4];
            let mut cells23 = [[0u32; 4]; 4];
            for i in 0..16 {
                let p = SampleStream::new(7, 3, pixel, i).next4();
                cells[(p[0] * 4.0) as usize][(p[1] * 4.0) as usize] += 1;
                cells23[(p[2] * 4.0) as usize][(p[3] * 4.0) as usize] += 1;
            }
            assert!(cells.iter().flatten().all(|&c| c == 1), "pixel {pixel}: {cells:?}");
            assert!(cells23.iter().flatten().all(|&c| c == 1), "pixel {pixel}: {cells23:?}");
        }
        let a = SampleStream::new(7, 3, 0, 0).next4();
        let b = SampleStream::new(7, 3, 1, 0).next4();
        let c = SampleStream::new(7, 4, 0, 0).next4();
        assert_ne!(a, b);
        assert_ne!(a, c);
        assert_eq!(a, SampleStream::new(7, 3, 0, 0).next4());
    }

    #[test]
    fn draws_are_uniform_on_average() {
        let mut sum = [0.0f64; 4];
        let n = 4096;
        for i in 0..n {
            let mut s = SampleStream::new(1, 0, i, 0);
            s.next4();
            let p = s.next4();
            for d in 0..4 {
                assert!((0.0..1.0).contains(&p[d]));
                sum[d] += p[d] as f64;
            }
        }
        for d in sum {
            assert!((d / n as f64 - 0.5).abs() < 0.02, "mean {}", d / n as f64);
        }
    }
}
