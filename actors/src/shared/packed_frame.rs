//! A frame's accepted results as they arrived: one packed radiance vector per set, moved
//! out of its message, unpacked into per-pixel planes only when the frame is shown. The
//! assembler fills it and closes the frame ([`ClosedFrame`]); the presenter hands it to the
//! sink thread, which unpacks it.
//!
//! Scattering every result into a full-size frame on arrival cost the master's actor
//! thread, which bounds frames per second, about a fifth of its time (`gridlight bench
//! master`); keeping the words costs nothing there. Unpacking happens once per *shown*
//! frame, on the sink thread, and frames passed over are never unpacked at all.

use std::mem::MaybeUninit;
use std::sync::Arc;

use glam::Vec3;

use crate::scene::state::SceneState;
use crate::shared::sets::SetTable;
use crate::wire::packing::decode_rgb9e5;
use crate::wire::protocol::{ConnId, FrameNo, SetNo};

/// A frame taken out of the table for display.
#[derive(Debug)]
pub struct ClosedFrame {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
    /// Samples per pixel of each of its results (the scheduler's job size for it).
    pub spp: u32,
    /// The accepted results.
    pub results: PackedFrame,
    /// Per set, the connection whose result was accepted (`None`: no result).
    pub owners: Vec<Option<ConnId>>,
    pub back: u32,
    pub total: u32,
}

/// The accepted results of one frame, packed (RGB9E5 words in set order).
#[derive(Clone, Debug)]
pub struct PackedFrame {
    sets: Arc<SetTable>,
    /// `results[s]`: set `s`'s words, `None` while it has not been accepted.
    results: Vec<Option<Vec<u32>>>,
}

impl PackedFrame {
    /// A frame with no results yet.
    pub fn new(sets: Arc<SetTable>) -> Self {
        let results = vec![None; sets.sets() as usize];
        Self { sets, results }
    }

    /// Stores set `set`'s words.
    ///
    /// # Panics
    /// When the set does not exist or `words` does not hold one word per pixel of the
    /// set: the frame table checks both before accepting a result.
    pub fn insert(&mut self, set: SetNo, words: Vec<u32>) {
        assert_eq!(words.len(), self.sets.set_len(set), "set {set}: wrong pixel count");
        self.results[set as usize] = Some(words);
    }

    /// The pixel sets the frame is made of.
    pub fn set_table(&self) -> &Arc<SetTable> {
        &self.sets
    }

    /// Whether set `set`'s words are in.
    pub fn contains(&self, set: SetNo) -> bool {
        self.results.get(set as usize).is_some_and(Option::is_some)
    }

    /// Per-pixel radiance (zero where no result covers the pixel) and coverage.
    pub fn unpack(&self) -> (Vec<Vec3>, Vec<bool>) {
        let n = self.sets.resolution().pixels();
        let mut mask = vec![false; n];
        // Not zero-filled first: a complete frame writes every pixel once, so filling
        // 3.7 MB (640×480) would be stores wasted; only holes are zeroed, below.
        let mut radiance: Vec<Vec3> = Vec::with_capacity(n);
        let out = &mut radiance.spare_capacity_mut()[..n];
        // Set by set: each set's words are read in one sequential run, which the
        // hardware prefetches; the words were just written on another core. Cutting the
        // frame into bands that stay in cache measured 15 % faster with warm words
        // (`cargo bench --bench master_path`) but slower in `gridlight bench master`.
        // A gather in pixel order, which interleaves the reads of all S sets, measured
        // several times slower.
        for (s, words) in self.results.iter().enumerate() {
            if let (Some(words), Some(pixels)) = (words, self.sets.pixels(s as SetNo)) {
                scatter(pixels, words, out, &mut mask);
            }
        }
        for (r, covered) in out.iter_mut().zip(&mask) {
            if !covered {
                r.write(Vec3::ZERO);
            }
        }
        // SAFETY: `scatter` writes `out[p]` wherever it sets `mask[p]`, and the loop above
        // wrote every element whose mask is unset: all `n` elements are initialised.
        unsafe { radiance.set_len(n) };
        (radiance, mask)
    }
}

/// Decodes `words` into the pixels `pixels` names (one word per pixel) and marks them.
fn scatter(pixels: &[u32], words: &[u32], out: &mut [MaybeUninit<Vec3>], mask: &mut [bool]) {
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
    let (mut pixels, mut words) = (pixels, words);
    #[cfg(target_arch = "x86_64")]
    {
        let (p4, w4) = (pixels.chunks_exact(4), words.chunks_exact(4));
        (pixels, words) = (p4.remainder(), w4.remainder());
        for (p, w) in p4.zip(w4) {
            let p = [p[0], p[1], p[2], p[3]].map(|p| p as usize);
            // Indexing checks every pixel against the frame before anything is written.
            let dst = p.map(|p| &mut out[p] as *mut MaybeUninit<Vec3>);
            // SAFETY: SSE2 is part of x86_64; each pointer is a valid element of `out`,
            // written with exactly its 12 bytes.
            unsafe { sse2::decode_store4(&[w[0], w[1], w[2], w[3]], dst) };
            for p in p {
                mask[p] = true;
            }
        }
    }
    for (p, w) in pixels.iter().zip(words) {
        out[*p as usize].write(decode_rgb9e5(*w));
        mask[*p as usize] = true;
    }
}

/// Four RGB9E5 words decoded at once: the same arithmetic as [`decode_rgb9e5`] (exact,
/// so the results are identical), with 12-byte stores to scattered pixels.
#[cfg(target_arch = "x86_64")]
mod sse2 {
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    use glam::Vec3;

    /// # Safety
    /// Each pointer must be valid for writing one `Vec3`.
    #[inline(always)]
    pub unsafe fn decode_store4(words: &[u32; 4], dst: [*mut MaybeUninit<Vec3>; 4]) {
        // SAFETY: SSE2 is part of x86_64 (the intrinsics need no other feature); the caller
        // guarantees that each pointer is valid for writing one `Vec3`.
        unsafe {
            let w = _mm_loadu_si128(words.as_ptr() as *const __m128i);
            // 2^(exp - 24) from its bits: (exp - 24 + 127) << 23, as in `decode_rgb9e5`.
            let exp = _mm_srli_epi32::<27>(w);
            let scale =
                _mm_castsi128_ps(_mm_slli_epi32::<23>(_mm_add_epi32(exp, _mm_set1_epi32(103))));
            let m = _mm_set1_epi32(0x1ff);
            let channel = |v: __m128i| _mm_mul_ps(_mm_cvtepi32_ps(_mm_and_si128(v, m)), scale);
            let r = channel(w);
            let g = channel(_mm_srli_epi32::<9>(w));
            let b = channel(_mm_srli_epi32::<18>(w));
            // Pairs (r, g) and the b lanes as 64-bit halves, written unaligned (a `Vec3` is
            // only 4-aligned): lane i of a half is pixel i's.
            let rg01 = _mm_castps_si128(_mm_unpacklo_ps(r, g)); // r0 g0 r1 g1
            let rg23 = _mm_castps_si128(_mm_unpackhi_ps(r, g)); // r2 g2 r3 g3
            let b = _mm_castps_si128(b);
            let lo = |v: __m128i| _mm_cvtsi128_si64(v) as u64;
            let hi = |v: __m128i| _mm_cvtsi128_si64(_mm_unpackhi_epi64(v, v)) as u64;
            let (b01, b23) = (lo(b), hi(b));
            let rg = [lo(rg01), hi(rg01), lo(rg23), hi(rg23)];
            let blue = [b01 as u32, (b01 >> 32) as u32, b23 as u32, (b23 >> 32) as u32];
            for i in 0..4 {
                let p = dst[i] as *mut u8;
                p.cast::<u64>().write_unaligned(rg[i]);
                p.add(8).cast::<u32>().write_unaligned(blue[i]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::state::Resolution;
    use crate::wire::packing::encode_rgb9e5;
    use crate::wire::protocol::{Partition, SetsConfig};

    #[test]
    fn unpacks_each_set_to_its_own_pixels_and_nothing_else() {
        let res = Resolution { width: 211, height: 97 };
        for partition in [Partition::QuasiRandom, Partition::Tiles] {
            let sets = Arc::new(SetTable::new(res, SetsConfig { sets: 5, partition }).unwrap());
            let mut f = PackedFrame::new(sets.clone());
            let word = |s: u32, k: usize| encode_rgb9e5(Vec3::new(s as f32, k as f32, 1.0));
            for s in [0u32, 2, 4] {
                f.insert(s, (0..sets.set_len(s)).map(|k| word(s, k)).collect());
            }
            let (radiance, mask) = f.unpack();
            for s in 0..5u32 {
                for (k, p) in sets.pixels(s).unwrap().iter().enumerate() {
                    let p = *p as usize;
                    let covered = s % 2 == 0;
                    assert_eq!(mask[p], covered, "{partition:?} set {s} pixel {p}");
                    let want = if covered { decode_rgb9e5(word(s, k)) } else { Vec3::ZERO };
                    assert_eq!(radiance[p], want, "{partition:?} set {s} pixel {p}");
                }
            }
        }
    }

    proptest::proptest! {
        /// Every bit pattern, whatever the set sizes (the four-wide path and its rest), unpacks
        /// exactly as the scalar decoder decodes it (the SIMD path included).
        #[test]
        fn any_words_unpack_as_the_scalar_decoder_decodes_them(
            width in 1u32..300, height in 1u32..80, sets in 1u32..9, seed: u64, present: u16,
        ) {
            let res = Resolution { width, height };
            let sets = sets.min(width * height);
            let config = SetsConfig { sets, partition: Partition::QuasiRandom };
            let table = Arc::new(SetTable::new(res, config).unwrap());
            let mut f = PackedFrame::new(table.clone());
            let mut rng = seed | 1;
            let mut word = || {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng as u32
            };
            let mut expected = vec![None; res.pixels()];
            for s in (0..sets).filter(|s| present >> s & 1 == 1) {
                let words: Vec<u32> = (0..table.set_len(s)).map(|_| word()).collect();
                for (p, w) in table.pixels(s).unwrap().iter().zip(&words) {
                    expected[*p as usize] = Some(decode_rgb9e5(*w));
                }
                f.insert(s, words);
            }
            let (radiance, mask) = f.unpack();
            for (p, e) in expected.iter().enumerate() {
                proptest::prop_assert_eq!(mask[p], e.is_some(), "pixel {}", p);
                proptest::prop_assert_eq!(radiance[p].to_array(), e.unwrap_or(Vec3::ZERO).to_array(), "pixel {}", p);
            }
        }
    }
}
