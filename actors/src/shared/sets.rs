//! Pixel sets: which pixels one job renders (docs/design.md, decision 1).
//!
//! A set is a pure function of (resolution, [`SetsConfig`], set number), so master and
//! worker derive the same pixel list and pixel indices never travel. Indices are
//! `y * width + x`, and a set lists its pixels in ascending index order ("set order").
//!
//! **Quasi-random** (the default): pixels are ordered along a Z-order (Morton) curve,
//! so every run of `S` consecutive pixels is a compact patch of the image; the curve is
//! cut into such runs and each run deals one pixel to every set, rotated by a scrambled
//! van der Corput offset per run. Every set therefore holds exactly one pixel of each
//! patch — a stratified sample of the whole image — sizes differ by at most one, any
//! subset of sets covers the image evenly, and the scrambling avoids the regular
//! lattice (and its structured noise) that a fixed rotation would give.
//!
//! **Tiles**: a near-square grid of `S` rectangles, for the paper's Figure 3.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use thiserror::Error;

use crate::scene::state::Resolution;
use crate::wire::protocol::{Partition, SetNo, SetsConfig};

/// Why a partition cannot be made.
#[derive(Debug, Error, PartialEq, Eq)]
pub enum SetsError {
    #[error("the image has no pixels ({width}x{height})")]
    EmptyImage { width: u32, height: u32 },
    #[error("{sets} sets requested; it must be between 1 and the {pixels} pixels of the image")]
    BadSetCount { sets: u32, pixels: usize },
    #[error("set {set} does not exist (there are {sets})")]
    NoSuchSet { set: SetNo, sets: u32 },
}

/// The pixel indices of one set, in set order (ascending).
pub fn set_pixels(res: Resolution, config: SetsConfig, set: SetNo) -> Result<Vec<u32>, SetsError> {
    validate(res, config)?;
    if set >= config.sets {
        return Err(SetsError::NoSuchSet { set, sets: config.sets });
    }
    let owner = assignment(res, config);
    Ok(owner.iter().enumerate().filter(|(_, s)| **s == set).map(|(i, _)| i as u32).collect())
}

/// All sets of a partition, computed once (the master and each worker keep one).
#[derive(Clone, Debug)]
pub struct SetTable {
    resolution: Resolution,
    config: SetsConfig,
    /// `sets[s]` lists set `s`'s pixel indices in set order.
    sets: Vec<Vec<u32>>,
}

impl SetTable {
    /// Computes every set of the partition.
    pub fn new(resolution: Resolution, config: SetsConfig) -> Result<Self, SetsError> {
        validate(resolution, config)?;
        let owner = assignment(resolution, config);
        let mut sets = vec![Vec::new(); config.sets as usize];
        for (pixel, set) in owner.iter().enumerate() {
            sets[*set as usize].push(pixel as u32);
        }
        Ok(Self { resolution, config, sets })
    }

    /// The pixel indices of `set`, in set order; `None` for a set that does not exist.
    pub fn pixels(&self, set: SetNo) -> Option<&[u32]> {
        self.sets.get(set as usize).map(Vec::as_slice)
    }

    /// Number of pixels of `set` (0 for a set that does not exist).
    pub fn set_len(&self, set: SetNo) -> usize {
        self.pixels(set).map_or(0, <[u32]>::len)
    }

    /// Number of sets S.
    pub fn sets(&self) -> u32 {
        self.config.sets
    }

    pub fn config(&self) -> SetsConfig {
        self.config
    }

    pub fn resolution(&self) -> Resolution {
        self.resolution
    }
}

/// The partition of every resolution a run has used, made once each: S and the partition
/// stay for the run, the resolution follows the scene state (a resized window). The master
/// keeps one, shared by its actors; frames, jobs and results find their sets by the
/// resolution of the state they belong to.
#[derive(Debug)]
pub struct SetTables {
    config: SetsConfig,
    tables: Mutex<HashMap<Resolution, Arc<SetTable>>>,
}

impl SetTables {
    /// Tables of `config`, starting with `first`'s (refused like [`SetTable::new`]).
    pub fn new(first: Resolution, config: SetsConfig) -> Result<Self, SetsError> {
        let tables = Self { config, tables: Mutex::new(HashMap::new()) };
        tables.get(first)?;
        Ok(tables)
    }

    /// The sets of `res`, computed on first use; an image with fewer pixels than S is
    /// refused.
    pub fn get(&self, res: Resolution) -> Result<Arc<SetTable>, SetsError> {
        // A poisoned lock only means another thread panicked after a complete insert.
        let mut tables = self.tables.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(table) = tables.get(&res) {
            return Ok(Arc::clone(table));
        }
        let table = Arc::new(SetTable::new(res, self.config)?);
        tables.insert(res, Arc::clone(&table));
        Ok(table)
    }

    /// The sets of a resolution already checked, by [`SetTables::new`] or by the scene
    /// holder before it made a state of that resolution.
    ///
    /// # Panics
    /// When `res` was refused, which the checks above rule out.
    pub fn checked(&self, res: Resolution) -> Arc<SetTable> {
        self.get(res).expect("the resolution of every scene state is checked against S")
    }

    /// S and the partition.
    pub fn config(&self) -> SetsConfig {
        self.config
    }
}

fn validate(res: Resolution, config: SetsConfig) -> Result<(), SetsError> {
    let pixels = res.pixels();
    if pixels == 0 {
        return Err(SetsError::EmptyImage { width: res.width, height: res.height });
    }
    if config.sets == 0 || config.sets as usize > pixels {
        return Err(SetsError::BadSetCount { sets: config.sets, pixels });
    }
    Ok(())
}

/// The set of every pixel, indexed by pixel.
fn assignment(res: Resolution, config: SetsConfig) -> Vec<SetNo> {
    match config.partition {
        Partition::QuasiRandom => quasi_random(res, config.sets),
        Partition::Tiles => tiles(res, config.sets),
    }
}

/// Scramble constant for the van der Corput offsets; fixed so all peers agree.
const SCRAMBLE: u32 = 0x9e37_79b9;

fn quasi_random(res: Resolution, sets: u32) -> Vec<SetNo> {
    let (w, h) = (res.width, res.height);
    // Pixels along the Z-order curve (sorting by Morton code skips cells outside the image).
    let mut order: Vec<(u64, u32)> =
        (0..h).flat_map(|y| (0..w).map(move |x| (morton(x, y), y * w + x))).collect();
    order.sort_unstable_by_key(|(code, _)| *code);
    let mut owner = vec![0; order.len()];
    let s = sets as u64;
    for (pos, (_, pixel)) in order.iter().enumerate() {
        let run = (pos as u64 / s) as u32;
        // Scrambled radical inverse of the run number, scaled to 0..S.
        let offset = ((radical_inverse_base2(run) ^ SCRAMBLE) as u64 * s) >> 32;
        owner[*pixel as usize] = ((pos as u64 % s + offset) % s) as SetNo;
    }
    owner
}

/// Van der Corput radical inverse in base 2, as a 32-bit fixed-point fraction.
fn radical_inverse_base2(i: u32) -> u32 {
    i.reverse_bits()
}

/// Interleaves the bits of x (even positions) and y (odd positions).
fn morton(x: u32, y: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        v = (v | (v << 1)) & 0x5555_5555_5555_5555;
        v
    }
    spread(x) | (spread(y) << 1)
}

fn tiles(res: Resolution, sets: u32) -> Vec<SetNo> {
    let (cols, rows) = tile_grid(res, sets);
    let (w, h) = (res.width as u64, res.height as u64);
    let mut owner = Vec::with_capacity(res.pixels());
    for y in 0..h {
        let row = (y * rows as u64 / h) as u32;
        for x in 0..w {
            let col = (x * cols as u64 / w) as u32;
            owner.push(row * cols + col);
        }
    }
    owner
}

/// The factorisation cols × rows = S whose tiles are closest to square.
fn tile_grid(res: Resolution, sets: u32) -> (u32, u32) {
    let aspect = res.width as f64 / res.height as f64;
    (1..=sets)
        .filter(|c| sets.is_multiple_of(*c))
        .map(|c| (c, sets / c))
        // A tile never gets fewer than one pixel along an axis.
        .filter(|(c, r)| *c <= res.width && *r <= res.height)
        .min_by(|a, b| {
            let err = |(c, r): (u32, u32)| ((c as f64 / r as f64) / aspect).ln().abs();
            err(*a).total_cmp(&err(*b))
        })
        .unwrap_or((sets, 1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::seq::SliceRandom;
    use rand::SeedableRng;

    fn cfg(sets: u32, partition: Partition) -> SetsConfig {
        SetsConfig { sets, partition }
    }

    fn res(width: u32, height: u32) -> Resolution {
        Resolution { width, height }
    }

    fn assert_partition(table: &SetTable) {
        let n = table.resolution().pixels();
        let mut seen = vec![0u8; n];
        for s in 0..table.sets() {
            let px = table.pixels(s).expect("set exists");
            assert!(px.windows(2).all(|w| w[0] < w[1]), "set {s} not in ascending order");
            for p in px {
                seen[*p as usize] += 1;
            }
        }
        assert!(seen.iter().all(|c| *c == 1), "some pixel is not in exactly one set");
    }

    #[test]
    fn every_pixel_in_exactly_one_set() {
        for (w, h, s) in [(64, 48, 64), (37, 23, 7), (1, 1, 1), (10, 3, 30), (640, 480, 64)] {
            for p in [Partition::QuasiRandom, Partition::Tiles] {
                assert_partition(&SetTable::new(res(w, h), cfg(s, p)).expect("table"));
            }
        }
    }

    #[test]
    fn quasi_random_sizes_differ_by_at_most_one() {
        for (w, h, s) in [(64, 48, 64), (37, 23, 7), (10, 3, 30), (33, 17, 64)] {
            let t = SetTable::new(res(w, h), cfg(s, Partition::QuasiRandom)).expect("table");
            let sizes: Vec<usize> = (0..s).map(|k| t.set_len(k)).collect();
            let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(hi - lo <= 1, "{w}x{h} S={s}: sizes {lo}..{hi}");
        }
    }

    #[test]
    fn pure_function_agrees_with_the_table() {
        let (r, c) = (res(37, 29), cfg(9, Partition::QuasiRandom));
        let t = SetTable::new(r, c).expect("table");
        for s in 0..9 {
            assert_eq!(set_pixels(r, c, s).expect("set"), t.pixels(s).unwrap());
        }
    }

    #[test]
    fn bad_configurations_are_errors() {
        let r = res(4, 4);
        assert!(matches!(
            SetTable::new(r, cfg(0, Partition::QuasiRandom)),
            Err(SetsError::BadSetCount { .. })
        ));
        assert!(matches!(
            SetTable::new(r, cfg(17, Partition::Tiles)),
            Err(SetsError::BadSetCount { .. })
        ));
        assert!(matches!(
            SetTable::new(res(0, 4), cfg(1, Partition::Tiles)),
            Err(SetsError::EmptyImage { .. })
        ));
        assert_eq!(
            set_pixels(r, cfg(4, Partition::QuasiRandom), 4),
            Err(SetsError::NoSuchSet { set: 4, sets: 4 })
        );
    }

    #[test]
    fn tiles_are_compact_rectangles() {
        let t = SetTable::new(res(64, 48), cfg(12, Partition::Tiles)).expect("table");
        // 4x3 grid of 16x16 tiles for a 4:3 image.
        for s in 0..12 {
            assert_eq!(t.set_len(s), 256, "tile {s}");
        }
        let first = t.pixels(0).unwrap();
        assert!(first.iter().all(|p| p % 64 < 16 && p / 64 < 16));
    }

    /// Worst relative deviation of a set's share in a cell of a g×g grid from the
    /// cell's share of the image, over all sets and cells.
    fn worst_coarse_deviation(r: Resolution, sets: &[Vec<u32>], g: u32) -> f64 {
        let mut worst = 0.0f64;
        for set in sets {
            let mut counts = vec![0usize; (g * g) as usize];
            for p in set {
                let (x, y) = (p % r.width, p / r.width);
                counts[((y * g / r.height) * g + x * g / r.width) as usize] += 1;
            }
            let expected = set.len() as f64 / (g * g) as f64;
            for c in counts {
                worst = worst.max((c as f64 - expected).abs() / expected);
            }
        }
        worst
    }

    #[test]
    fn every_set_is_spread_over_the_whole_image() {
        let r = res(128, 96);
        let t = SetTable::new(r, cfg(16, Partition::QuasiRandom)).expect("table");
        let sets: Vec<Vec<u32>> = (0..16).map(|s| t.pixels(s).unwrap().to_vec()).collect();
        // 768 pixels per set over a 4x4 grid: every cell within 10% of its 48.
        let dev = worst_coarse_deviation(r, &sets, 4);
        assert!(dev <= 0.1, "worst coarse-cell deviation {dev}");
    }

    #[test]
    fn quasi_random_is_more_uniform_than_random() {
        let (r, s) = (res(128, 96), 32u32);
        let t = SetTable::new(r, cfg(s, Partition::QuasiRandom)).expect("table");
        let quasi: Vec<Vec<u32>> = (0..s).map(|k| t.pixels(k).unwrap().to_vec()).collect();
        // A random partition with the same set sizes.
        let mut pixels: Vec<u32> = (0..r.pixels() as u32).collect();
        pixels.shuffle(&mut rand::rngs::StdRng::seed_from_u64(7));
        let mut random = vec![Vec::new(); s as usize];
        for (i, p) in pixels.iter().enumerate() {
            random[i % s as usize].push(*p);
        }
        let (q, rnd) =
            (worst_coarse_deviation(r, &quasi, 8), worst_coarse_deviation(r, &random, 8));
        assert!(q * 3.0 < rnd, "quasi-random {q} is not clearly more uniform than random {rnd}");
    }

    #[test]
    fn sets_are_not_a_regular_lattice() {
        // Neighbouring runs use different offsets, so a set's pixel sits at different
        // positions of consecutive patches.
        let r = res(64, 64);
        let t = SetTable::new(r, cfg(16, Partition::QuasiRandom)).expect("table");
        let set0 = t.pixels(0).unwrap();
        let within: std::collections::HashSet<u32> =
            set0.iter().map(|p| (p % 64 % 4) + 4 * (p / 64 % 4)).collect();
        assert!(within.len() > 4, "set 0 uses only {} positions within 4x4 patches", within.len());
    }
}
