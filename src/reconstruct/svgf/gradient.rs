//! Temporal gradients (after A-SVGF, Schied et al. 2018): where this frame's new samples
//! disagree with the reprojected history, the lighting changed there (an edited material
//! or light, a moved shadow, view-dependent shading), and the history is corrected.
//!
//! A first frame after an edit has samples at a few percent of its pixels, each with the
//! noise of one path: a single pixel's difference says little. So the differences are
//! pooled over the neighbourhood: per tile of [`TILE`]² pixels, Σ new luminance,
//! Σ history mean luminance at the same pixels and Σ of their squared differences; each
//! tile pools its neighbours' tiles until it holds [`MIN_SAMPLES`] (at most
//! [`MAX_REACH`] tiles away). The pooled difference in units of its own spread,
//! z = |Σδ| / √Σδ², says whether the change is more than noise (z ~ |N(0, 1)| without
//! one); the ratio Σ new / Σ old says how much. The history is scaled towards that ratio
//! by a confidence rising from 0 at z = [`Z_NOISE`] to 1 at [`Z_SURE`], interpolated
//! bilinearly between tile centres so that tiles leave no seams. Rejecting the history
//! instead (A-SVGF) would leave one sample in thirty pixels to show; rescaling keeps its
//! detail and noise level at the new brightness. Only luminance is compared (the three
//! channels' sums would be three times as noisy): a change of hue is not corrected, and
//! the shortened history after an edit (`SvgfParams::edit_samples`) lets it in.

use glam::Vec3;
use rayon::prelude::*;

use super::reproject::{luminance, Moments};

/// Tile side in pixels.
pub const TILE: usize = 8;
/// Samples a tile's estimate pools before it stops growing.
pub const MIN_SAMPLES: f32 = 24.0;
/// Most tiles a tile pools from in each direction.
pub const MAX_REACH: usize = 4;
/// Below this z the difference is taken for noise.
pub const Z_NOISE: f32 = 1.5;
/// From this z on the ratio is applied fully.
pub const Z_SURE: f32 = 3.0;
/// Largest factor applied (a dark history lit up by a new light).
const MAX_RATIO: f32 = 16.0;

/// One tile's sums over pixels with a new sample and a history.
#[derive(Clone, Copy, Debug, Default)]
struct TileSums {
    new: f32,
    old: f32,
    /// Σ (new − old)².
    d2: f32,
    count: f32,
}

impl TileSums {
    fn add(&mut self, o: &TileSums) {
        self.new += o.new;
        self.old += o.old;
        self.d2 += o.d2;
        self.count += o.count;
    }

    /// The factor the history is scaled by (1 where the difference is noise).
    fn factor(&self) -> f32 {
        if self.count < 2.0 || self.d2 <= 0.0 || self.old <= 0.0 {
            return 1.0;
        }
        let z = (self.new - self.old).abs() / self.d2.sqrt();
        let confidence = ((z - Z_NOISE) / (Z_SURE - Z_NOISE)).clamp(0.0, 1.0);
        let ratio = (self.new / self.old).min(MAX_RATIO);
        1.0 + confidence * (ratio - 1.0)
    }
}

/// The gradient's per-tile buffers for one frame size.
#[derive(Debug)]
pub struct Gradient {
    width: usize,
    height: usize,
    tiles_x: usize,
    tiles_y: usize,
    sums: Vec<TileSums>,
    factor: Vec<f32>,
}

impl Gradient {
    pub fn new(width: u32, height: u32) -> Self {
        let (width, height) = (width as usize, height as usize);
        let (tiles_x, tiles_y) = (width.div_ceil(TILE), height.div_ceil(TILE));
        Self {
            width,
            height,
            tiles_x,
            tiles_y,
            sums: vec![TileSums::default(); tiles_x * tiles_y],
            factor: vec![1.0; tiles_x * tiles_y],
        }
    }

    /// Each tile's factor after [`Gradient::correct`] (row-major tiles).
    pub fn factors(&self) -> &[f32] {
        &self.factor
    }

    /// Scales `history` (reprojected, before this frame's samples are added) where this
    /// frame's samples (`radiance` where `mask`) show that the lighting changed.
    pub fn correct(&mut self, history: &mut [Moments], radiance: &[Vec3], mask: &[bool]) {
        let (w, h, tx) = (self.width, self.height, self.tiles_x);
        assert!(history.len() == w * h && radiance.len() == w * h && mask.len() == w * h);
        self.sums.par_chunks_mut(tx).enumerate().for_each(|(ty, row)| {
            row.fill(TileSums::default());
            for y in ty * TILE..h.min((ty + 1) * TILE) {
                for x in 0..w {
                    let i = y * w + x;
                    let m = &history[i];
                    if mask[i] && m.sum.w > 0.0 {
                        let (new, old) = (luminance(radiance[i]), m.lum.x / m.sum.w);
                        let t = &mut row[x / TILE];
                        (t.new, t.old) = (t.new + new, t.old + old);
                        t.d2 += (new - old) * (new - old);
                        t.count += 1.0;
                    }
                }
            }
        });
        let sums = &self.sums;
        let ty_n = self.tiles_y;
        self.factor.par_iter_mut().enumerate().for_each(|(t, f)| {
            let (cx, cy) = (t % tx, t / tx);
            let mut pooled = TileSums::default();
            for reach in 0..=MAX_REACH {
                pooled = TileSums::default();
                for y in cy.saturating_sub(reach)..(cy + reach + 1).min(ty_n) {
                    for x in cx.saturating_sub(reach)..(cx + reach + 1).min(tx) {
                        pooled.add(&sums[y * tx + x]);
                    }
                }
                if pooled.count >= MIN_SAMPLES {
                    break;
                }
            }
            *f = pooled.factor();
        });
        if self.factor.iter().all(|&f| f == 1.0) {
            return;
        }
        let factor = &self.factor;
        let at = |x: usize, y: usize| factor[y.min(ty_n - 1) * tx + x.min(tx - 1)];
        history.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            // Tile centres at (t + ½)·TILE: the pixel's position among them.
            let fy = ((y as f32 + 0.5) / TILE as f32 - 0.5).max(0.0);
            let (y0, wy) = (fy as usize, fy.fract());
            for (x, m) in row.iter_mut().enumerate() {
                let fx = ((x as f32 + 0.5) / TILE as f32 - 0.5).max(0.0);
                let (x0, wx) = (fx as usize, fx.fract());
                let top = at(x0, y0) * (1.0 - wx) + at(x0 + 1, y0) * wx;
                let bottom = at(x0, y0 + 1) * (1.0 - wx) + at(x0 + 1, y0 + 1) * wx;
                let k = top * (1.0 - wy) + bottom * wy;
                if k != 1.0 {
                    m.sum = (m.sum.truncate() * k).extend(m.sum.w);
                    m.lum.x *= k;
                    m.lum.y *= k * k;
                }
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A history of `n` samples of `v` at every pixel.
    fn history(w: usize, h: usize, v: f32, n: f32) -> Vec<Moments> {
        let mut m = Moments::default();
        for _ in 0..n as usize {
            m.add(Vec3::splat(v));
        }
        vec![m; w * h]
    }

    /// Noise of ±50 % around `v` at one pixel in `every`.
    fn samples(w: usize, h: usize, v: f32, every: usize) -> (Vec<Vec3>, Vec<bool>) {
        let radiance = (0..w * h)
            .map(|i| {
                let hash = ((i as u64 * 2654435761) % 1000) as f32 / 1000.0;
                Vec3::splat(v * (0.5 + hash))
            })
            .collect();
        (radiance, (0..w * h).map(|i| i % every == 0).collect())
    }

    #[test]
    fn a_halved_light_halves_the_history_and_noise_leaves_it() {
        let (w, h) = (96, 64);
        let mut g = Gradient::new(w as u32, h as u32);
        let (radiance, mask) = samples(w, h, 0.5, 31);
        let mut hist = history(w, h, 1.0, 4.0);
        g.correct(&mut hist, &radiance, &mask);
        for m in &hist {
            let mean = m.sum.x / m.sum.w;
            assert!((mean - 0.5).abs() < 0.06, "mean {mean} after halving");
            assert_eq!(m.sum.w, 4.0, "the count is kept");
        }
        // The same light: the samples scatter around the history, which stays.
        let (radiance, _) = samples(w, h, 1.0, 31);
        let mut hist = history(w, h, 1.0, 4.0);
        g.correct(&mut hist, &radiance, &mask);
        let moved = hist.iter().filter(|m| (m.sum.x / m.sum.w - 1.0).abs() > 0.03).count();
        assert!(moved * 10 < hist.len(), "{moved} of {} pixels moved", hist.len());
    }

    #[test]
    fn a_local_change_stays_local() {
        let (w, h) = (128, 64);
        let mut g = Gradient::new(w as u32, h as u32);
        // The left half's light doubled; the right half's unchanged.
        let (mut radiance, mask) = samples(w, h, 1.0, 7);
        for (i, v) in radiance.iter_mut().enumerate() {
            if i % w < w / 2 {
                *v *= 2.0;
            }
        }
        let mut hist = history(w, h, 1.0, 4.0);
        g.correct(&mut hist, &radiance, &mask);
        for y in 0..h {
            let (left, right) = (&hist[y * w + 4], &hist[y * w + w - 5]);
            assert!((left.sum.x / left.sum.w - 2.0).abs() < 0.2, "row {y}: {left:?}");
            assert!((right.sum.x / right.sum.w - 1.0).abs() < 0.1, "row {y}: {right:?}");
        }
    }
}
