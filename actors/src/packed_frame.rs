//! A frame's accepted results as they arrived: one packed radiance vector per set, moved
//! out of its message, unpacked into per-pixel planes only when the frame is shown.
//!
//! Scattering every result into a full-size frame on arrival cost the master's actor
//! thread, which bounds frames per second, about a fifth of its time (`gridlight bench
//! master`); keeping the words costs nothing there. Unpacking happens once per *shown*
//! frame, on the sink thread, and frames passed over are never unpacked at all.

use std::sync::Arc;

use glam::Vec3;

use crate::packing::decode_rgb9e5;
use crate::protocol::SetNo;
use crate::sets::SetTable;

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

    /// Whether set `set`'s words are in.
    pub fn contains(&self, set: SetNo) -> bool {
        self.results.get(set as usize).is_some_and(Option::is_some)
    }

    /// Per-pixel radiance (zero where no result covers the pixel) and coverage.
    pub fn unpack(&self) -> (Vec<Vec3>, Vec<bool>) {
        let n = self.sets.resolution().pixels();
        let (mut radiance, mut mask) = (vec![Vec3::ZERO; n], vec![false; n]);
        // Set by set: each set's words are read in one sequential run. A gather in pixel
        // order, which interleaves the reads of all S sets, measured several times slower.
        for (s, words) in self.results.iter().enumerate() {
            let (Some(words), Some(pixels)) = (words, self.sets.pixels(s as SetNo)) else {
                continue;
            };
            for (p, w) in pixels.iter().zip(words) {
                radiance[*p as usize] = decode_rgb9e5(*w);
                mask[*p as usize] = true;
            }
        }
        (radiance, mask)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::packing::encode_rgb9e5;
    use crate::protocol::{Partition, SetsConfig};
    use crate::state::Resolution;

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
}
