//! HDR-ꟻLIP (Andersson et al., "Visualizing Errors in Rendered High Dynamic Range
//! Images", Eurographics 2021) beside our LDR-FLIP ([`super::flip`]): path-traced
//! radiance is unbounded, and one display exposure hides errors in the highlights or in
//! the shadows. HDR-FLIP tone-maps both images at a range of exposures and keeps, per
//! pixel, the largest LDR-FLIP.
//!
//! As NVIDIA's reference (`flip-evaluator`, checked by `tests/flip_known_answer.rs`):
//! the ACES fit with its 0.6 pre-exposure cancelled, exposures from the reference's
//! luminance, the first one mapping its maximum and the last its median to 0.85 after
//! tone mapping, `max(2, ⌈stop − start⌉)` of them evenly spaced.

use glam::Vec3;

use super::flip::flip_linear;

/// The ACES fit as `(x·(a·x + b) + c) / (x·(d·x + e) + f)`, pre-exposure 0.6 cancelled.
const ACES: [f32; 6] = [0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14];
/// Tone-mapped value the exposure range's ends map the reference's maximum and median to.
const TARGET: f32 = 0.85;

/// The exposures (in stops) at which LDR-FLIP is evaluated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exposures {
    pub start: f32,
    pub stop: f32,
    pub count: u32,
}

impl Exposures {
    /// The reference's range: `start` maps its largest luminance to [`TARGET`] after
    /// tone mapping, `stop` its median.
    pub fn of(reference: &[Vec3]) -> Self {
        let mut y: Vec<f32> = reference.iter().map(|c| luminance(*c)).collect();
        y.sort_by(f32::total_cmp);
        let n = y.len();
        let (median, max) = match n {
            0 => (0.0, 0.0),
            _ if n % 2 == 1 => (y[n / 2], y[n - 1]),
            _ => ((y[n / 2 - 1] + y[n / 2]) * 0.5, y[n - 1]),
        };
        let x = aces_inverse_of_target();
        let start = (x / max).log2();
        let stop = (x / median).log2();
        let count = ((stop - start).ceil() as i64).max(2) as u32;
        Self { start, stop, count }
    }

    /// Exposure `i` of `count`, in stops.
    pub fn at(&self, i: u32) -> f32 {
        let step = (self.stop - self.start) / (self.count.max(2) - 1) as f32;
        self.start + i as f32 * step
    }
}

/// Per-pixel HDR-FLIP, its mean and the exposures used.
#[derive(Clone, Debug)]
pub struct HdrFlipResult {
    pub mean: f64,
    pub map: Vec<f32>,
    pub exposures: Exposures,
}

/// HDR-FLIP between two linear (unbounded) images.
pub fn hdr_flip(
    reference: &[Vec3],
    test: &[Vec3],
    width: usize,
    height: usize,
    ppd: f32,
) -> HdrFlipResult {
    let exposures = Exposures::of(reference);
    let mut map = vec![0.0f32; reference.len()];
    for i in 0..exposures.count {
        let scale = exposures.at(i).exp2();
        let r = tone_mapped(reference, scale);
        let t = tone_mapped(test, scale);
        let ldr = flip_linear(&r, &t, width, height, ppd);
        for (m, v) in map.iter_mut().zip(&ldr.map) {
            *m = m.max(*v);
        }
    }
    let mean = map.iter().map(|&v| f64::from(v)).sum::<f64>() / map.len().max(1) as f64;
    HdrFlipResult { mean, map, exposures }
}

/// `img` exposed by `scale` and ACES tone-mapped (linear, in [0, 1]).
fn tone_mapped(img: &[Vec3], scale: f32) -> Vec<Vec3> {
    img.iter().map(|c| Vec3::new(aces(c.x * scale), aces(c.y * scale), aces(c.z * scale))).collect()
}

/// The ACES fit, clamped to [0, 1].
pub fn aces(x: f32) -> f32 {
    let [a, b, c, d, e, f] = ACES;
    ((x * (a * x + b) + c) / (x * (d * x + e) + f)).clamp(0.0, 1.0)
}

/// The input that ACES maps to [`TARGET`]: the larger root of
/// `(a − t·d)·x² + (b − t·e)·x + (c − t·f) = 0`.
fn aces_inverse_of_target() -> f32 {
    let [a, b, c, d, e, f] = ACES;
    let (qa, qb, qc) = (a - TARGET * d, b - TARGET * e, c - TARGET * f);
    let d1 = -0.5 * (qb / qa);
    d1 + (d1 * d1 - qc / qa).sqrt()
}

/// Luminance of linear sRGB (Rec. 709 weights), as the reference computes it.
fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exposure_range_maps_the_maximum_and_the_median_to_the_target() {
        // Luminances 1, 2, 8 (grey pixels): median 2, maximum 8.
        let img = [Vec3::splat(1.0), Vec3::splat(8.0), Vec3::splat(2.0)];
        let e = Exposures::of(&img);
        assert!((aces(8.0 * e.start.exp2()) - TARGET).abs() < 1e-5);
        assert!((aces(2.0 * e.stop.exp2()) - TARGET).abs() < 1e-5);
        assert!((e.stop - e.start - 2.0).abs() < 1e-5, "a factor 4 is two stops");
        assert_eq!(e.count, 2, "at least two exposures");
        assert_eq!(e.at(0), e.start);
        assert!((e.at(1) - e.stop).abs() < 1e-6);
    }

    #[test]
    fn an_even_count_takes_the_mean_of_the_middle_two_as_median() {
        let img = [Vec3::splat(1.0), Vec3::splat(3.0), Vec3::splat(16.0), Vec3::splat(2.0)];
        let e = Exposures::of(&img);
        assert!((aces(2.5 * e.stop.exp2()) - TARGET).abs() < 1e-5);
        assert_eq!(e.count, ((16.0f32 / 2.5).log2().ceil()) as u32);
    }

    #[test]
    fn aces_is_zero_at_zero_rises_and_saturates() {
        assert_eq!(aces(0.0), 0.0);
        assert!(aces(0.5) < aces(1.0) && aces(1.0) < aces(4.0));
        assert_eq!(aces(1e6), 1.0);
    }

    #[test]
    fn equal_images_have_no_error_and_a_missing_highlight_has_some() {
        let (w, h) = (16, 12);
        let mut r = vec![Vec3::splat(0.3); w * h];
        assert_eq!(hdr_flip(&r, &r, w, h, 67.0).mean, 0.0);
        r[6 * w + 8] = Vec3::splat(20.0);
        let t = vec![Vec3::splat(0.3); w * h];
        let got = hdr_flip(&r, &t, w, h, 67.0);
        assert!(got.map[6 * w + 8] > 0.5, "the highlight's pixel: {}", got.map[6 * w + 8]);
        // Per pixel the largest over the exposures: never below the first exposure's.
        let scale = got.exposures.start.exp2();
        let first = flip_linear(&tone_mapped(&r, scale), &tone_mapped(&t, scale), w, h, 67.0);
        assert!(got.map.iter().zip(&first.map).all(|(a, b)| a >= b));
    }
}
