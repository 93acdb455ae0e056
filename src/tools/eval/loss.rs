//! Figure 3: a complete frame loses a fraction of its jobs; the quasi-random partition
//! plus reconstruction should stay much closer to the complete frame than the tile
//! partition with the same loss.
//!
//! The reference is the complete frame through the same pipeline (the first frame of a
//! state: fill, temporal without history, edge-aware Gaussian), so the error measures only
//! what the lost jobs cost.

use glam::Vec3;
use gridlight_actors::protocol::{Partition, SetNo, SetsConfig};
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::Resolution;
use serde::Serialize;

use super::{compare, Errors, FrameData};
use crate::reconstruct::{CpuReconstructor, FrameInputs, ReconstructParams};

/// The result of one loss level.
#[derive(Clone, Debug, Serialize)]
pub struct LossOutcome {
    pub loss: f64,
    pub sets: u32,
    pub dropped: u32,
    pub quasi_random: Errors,
    pub tiles: Errors,
    #[serde(skip)]
    pub images: LossImages,
}

/// Final linear colour of the reference and the two reconstructions.
#[derive(Clone, Debug, Default)]
pub struct LossImages {
    pub reference: Vec<Vec3>,
    pub quasi_random: Vec<Vec3>,
    pub tiles: Vec<Vec3>,
    pub quasi_random_holes: Vec<Vec3>,
    pub tiles_holes: Vec<Vec3>,
}

/// `round(loss · sets)` distinct set numbers, chosen pseudo-randomly from `seed`.
pub fn dropped_sets(sets: u32, loss: f64, seed: u64) -> Vec<SetNo> {
    let count = ((loss.clamp(0.0, 1.0) * sets as f64).round() as usize).min(sets as usize);
    let mut order: Vec<(u64, SetNo)> = (0..sets).map(|s| (mix(seed, s as u64), s)).collect();
    order.sort_unstable();
    let mut dropped: Vec<SetNo> = order.into_iter().take(count).map(|(_, s)| s).collect();
    dropped.sort_unstable();
    dropped
}

fn mix(seed: u64, v: u64) -> u64 {
    let mut z = seed.wrapping_add(v.wrapping_mul(0x9E37_79B9_7F4A_7C15));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Which pixels have a result when the given sets are lost.
pub fn mask_without(table: &SetTable, dropped: &[SetNo]) -> Vec<bool> {
    let mut mask = vec![false; table.resolution().pixels()];
    for set in (0..table.sets()).filter(|s| dropped.binary_search(s).is_err()) {
        for &p in table.pixels(set).unwrap_or(&[]) {
            mask[p as usize] = true;
        }
    }
    mask
}

/// Runs one frame (a fresh reconstructor: the first frame of a state) with `mask`.
pub fn reconstruct_once(
    frame: &FrameData,
    mask: &[bool],
    params: ReconstructParams,
) -> anyhow::Result<Vec<Vec3>> {
    let g = &frame.gbuffer;
    let mut r = CpuReconstructor::new(g.width, g.height, params)?;
    let out = r.reconstruct(&FrameInputs {
        frame: 1,
        state_version: 1,
        accumulated_frames: 1,
        radiance: &frame.radiance,
        mask,
        gbuffer: g,
        scene: None,
    })?;
    Ok(out.colour)
}

/// Drops `loss` of the `sets` jobs of `frame` under both partitions and measures each
/// reconstruction against the complete frame.
pub fn run(
    frame: &FrameData,
    sets: u32,
    loss: f64,
    params: ReconstructParams,
    exposure: f32,
    seed: u64,
) -> anyhow::Result<LossOutcome> {
    let g = &frame.gbuffer;
    let res = Resolution { width: g.width, height: g.height };
    let dropped = dropped_sets(sets, loss, seed);
    let reference = reconstruct_once(frame, &vec![true; g.len()], params)?;
    let mut images = LossImages { reference, ..Default::default() };
    let mut errors = [Errors::default(); 2];
    for (k, partition) in [Partition::QuasiRandom, Partition::Tiles].into_iter().enumerate() {
        let table = SetTable::new(res, SetsConfig { sets, partition })?;
        let mask = mask_without(&table, &dropped);
        let colour = reconstruct_once(frame, &mask, params)?;
        errors[k] = compare(&images.reference, &colour, g.width, g.height, exposure);
        let holes: Vec<Vec3> = frame
            .colour()
            .iter()
            .zip(&mask)
            .map(|(c, &m)| if m { *c } else { Vec3::ZERO })
            .collect();
        if k == 0 {
            (images.quasi_random, images.quasi_random_holes) = (colour, holes);
        } else {
            (images.tiles, images.tiles_holes) = (colour, holes);
        }
    }
    Ok(LossOutcome {
        loss,
        sets,
        dropped: dropped.len() as u32,
        quasi_random: errors[0],
        tiles: errors[1],
        images,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dropped_sets_are_distinct_deterministic_and_sized() {
        let d = dropped_sets(64, 0.25, 3);
        assert_eq!(d.len(), 16);
        assert_eq!(d, dropped_sets(64, 0.25, 3));
        assert_ne!(d, dropped_sets(64, 0.25, 4));
        assert!(d.windows(2).all(|w| w[0] < w[1]));
        assert!(dropped_sets(64, 0.0, 3).is_empty());
    }

    #[test]
    fn mask_misses_exactly_the_dropped_sets() {
        let res = Resolution { width: 32, height: 24 };
        let table = SetTable::new(res, SetsConfig { sets: 16, partition: Partition::QuasiRandom })
            .expect("sets");
        let dropped = dropped_sets(16, 0.5, 1);
        let mask = mask_without(&table, &dropped);
        let missing: usize = dropped.iter().map(|&s| table.set_len(s)).sum();
        assert_eq!(mask.iter().filter(|m| !**m).count(), missing);
    }
}
