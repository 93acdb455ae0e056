//! Display encoding of reconstructed colour, through `crate::image_io` (exposure in
//! stops, Narkowicz's ACES filmic fit, sRGB) so that the window, PNGs and the GPU pass
//! (`shaders/reconstruct/remodulate.wgsl`, same expressions) show the same image.

use glam::Vec3;

use crate::image_io::{aces_filmic, display_pixel, linear_to_srgb};
use crate::render::lanes::WIDTH;

/// The multiplier of an exposure in stops.
#[inline]
pub fn exposure_scale(stops: f32) -> f32 {
    stops.exp2()
}

/// Linear colour → display-referred sRGB in [0, 1] (not quantised; for metrics).
#[inline]
pub fn tonemap(colour: Vec3, exposure_stops: f32) -> Vec3 {
    let v = if colour.is_finite() { colour.max(Vec3::ZERO) } else { Vec3::ZERO };
    aces_filmic(v * exposure_scale(exposure_stops)).to_array().map(linear_to_srgb).into()
}

/// Tonemapped 8-bit RGBA of a linear colour (as `image_io` writes PNGs).
#[inline]
pub fn to_rgba8(colour: Vec3, exposure_stops: f32) -> [u8; 4] {
    let [r, g, b] = display_pixel(colour, exposure_stops);
    [r, g, b, 255]
}

/// The same bytes as [`to_rgba8`] without a `powf` per channel: the filmic curve, then the
/// 8-bit code looked up in a table (built once from `image_io`'s quantisation, so
/// the codes are identical).
#[inline]
pub fn to_rgba8_fast(colour: Vec3, exposure_scale: f32) -> [u8; 4] {
    Srgb8Table::get().rgba8(filmic(colour, exposure_scale))
}

/// [`to_rgba8_fast`] of [`WIDTH`] colours, with the filmic curve evaluated for all of
/// them first, so that it vectorises.
#[inline(always)]
pub fn to_rgba8_lanes(colour: &[Vec3; WIDTH], exposure_scale: f32) -> [[u8; 4]; WIDTH] {
    let mut t = [Vec3::ZERO; WIDTH];
    for (t, &c) in t.iter_mut().zip(colour) {
        *t = filmic(c, exposure_scale);
    }
    let (table, mut rgba) = (Srgb8Table::get(), [[0; 4]; WIDTH]);
    for (rgba, t) in rgba.iter_mut().zip(t) {
        *rgba = table.rgba8(t);
    }
    rgba
}

/// Exposure, then the filmic curve, as `image_io::display_pixel` (non-finite colours are
/// black, negative components 0).
#[inline(always)]
fn filmic(colour: Vec3, exposure_scale: f32) -> Vec3 {
    let v = if colour.is_finite() { colour.max(Vec3::ZERO) } else { Vec3::ZERO };
    aces_filmic(v * exposure_scale)
}

fn quantise(t: f32) -> u8 {
    (linear_to_srgb(t) * 255.0 + 0.5) as u8
}

/// Bins of [0, 1] in [`Srgb8Table`]. A bin (2.4e-4 wide) is narrower than the narrowest
/// sRGB 8-bit step (3.0e-4, in the linear segment near black), so no bin holds two
/// thresholds.
const BINS: usize = 4096;

/// `image_io`'s 8-bit sRGB quantisation of a value in [0, 1] as a table lookup: the value's
/// bin gives the code at the bin's lower end, and one comparison with the next threshold
/// decides whether the value is past it.
struct Srgb8Table {
    /// `steps[k]`: the smallest value in [0, 1] that quantises to code k + 1 or more;
    /// `steps[255]` = ∞, so that code 255 is never exceeded.
    steps: [f32; 256],
    /// `first[b]`: the code of b / BINS, the lower end of bin b (bin BINS holds 1 alone).
    first: [u8; BINS + 1],
}

impl Srgb8Table {
    fn get() -> &'static Self {
        static TABLE: std::sync::OnceLock<Srgb8Table> = std::sync::OnceLock::new();
        TABLE.get_or_init(|| {
            let mut steps = [f32::INFINITY; 256];
            for (k, step) in steps.iter_mut().take(255).enumerate() {
                *step = first_reaching(k as u8 + 1);
            }
            let first = std::array::from_fn(|b| {
                let lower = b as f32 / BINS as f32;
                steps.partition_point(|&s| s <= lower) as u8
            });
            Self { steps, first }
        })
    }

    /// The RGBA bytes of a colour on the filmic curve.
    #[inline(always)]
    fn rgba8(&self, t: Vec3) -> [u8; 4] {
        [self.code(t.x), self.code(t.y), self.code(t.z), 255]
    }

    /// The code of `t` in [0, 1] (NaN gives 0, as `quantise` does).
    #[inline]
    fn code(&self, t: f32) -> u8 {
        // The float-to-int cast saturates (NaN → 0); t · BINS is exact (a power of two).
        let bin = ((t * BINS as f32) as usize).min(BINS);
        let code = self.first[bin];
        code + u8::from(t >= self.steps[code as usize])
    }
}

/// The smallest value in [0, 1] that quantises to `code` or more.
fn first_reaching(code: u8) -> f32 {
    // Bisect on the bit pattern: non-negative floats order like their bits.
    let (mut lo_bits, mut hi_bits) = (0.0f32.to_bits(), 1.0f32.to_bits());
    while hi_bits - lo_bits > 1 {
        let mid = lo_bits + (hi_bits - lo_bits) / 2;
        if quantise(f32::from_bits(mid)) >= code {
            hi_bits = mid;
        } else {
            lo_bits = mid;
        }
    }
    let (lo, hi) = (f32::from_bits(lo_bits), f32::from_bits(hi_bits));
    if quantise(lo) >= code {
        lo
    } else {
        hi
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn black_stays_black_and_bright_saturates() {
        assert_eq!(to_rgba8(Vec3::ZERO, 0.0), [0, 0, 0, 255]);
        assert_eq!(to_rgba8(Vec3::splat(1e4), 0.0), [255, 255, 255, 255]);
    }

    #[test]
    fn quantised_and_continuous_agree_and_exposure_brightens() {
        let c = Vec3::new(0.1, 0.5, 2.0);
        let t = tonemap(c, 0.0);
        let q = to_rgba8(c, 0.0);
        for k in 0..3 {
            assert!((t[k] * 255.0 - q[k] as f32).abs() <= 0.5 + 1e-3);
        }
        assert!(tonemap(c, 1.0).x > t.x);
    }

    #[test]
    fn no_table_bin_holds_two_thresholds() {
        // With at most one threshold inside each bin, the lookup and one comparison give
        // the same code as counting every threshold below the value.
        let table = Srgb8Table::get();
        for (b, &code) in table.first.iter().enumerate().take(BINS) {
            let upper = (b + 1) as f32 / BINS as f32;
            let after_next = table.steps.get(code as usize + 1).copied().unwrap_or(f32::INFINITY);
            assert!(after_next >= upper, "bin {b} holds two thresholds");
        }
    }

    /// Every float in [0, 1] (about 10^9, most of them in the linear segment, so this
    /// takes seconds).
    #[test]
    fn table_quantisation_matches_image_io_for_every_float_in_the_unit_interval() {
        use rayon::prelude::*;
        let table = Srgb8Table::get();
        (0..=1.0f32.to_bits()).into_par_iter().for_each(|bits| {
            let t = f32::from_bits(bits);
            assert_eq!(table.code(t), quantise(t), "{t:e}");
        });
    }

    #[test]
    fn fast_quantisation_gives_image_io_bytes() {
        for k in 0..20_000 {
            let v = k as f32 * 1e-3;
            let c = Vec3::new(v, v * 0.37, v * 2.9);
            assert_eq!(to_rgba8_fast(c, exposure_scale(0.5)), to_rgba8(c, 0.5), "{c}");
        }
        for c in [Vec3::splat(f32::NAN), Vec3::splat(f32::INFINITY), Vec3::splat(f32::MAX)] {
            assert_eq!(to_rgba8_fast(c, 1.0), to_rgba8(c, 0.0), "{c}");
        }
    }
}
