//! Display encoding of reconstructed colour, through `crate::image_io` (exposure in
//! stops, Narkowicz's ACES filmic fit, sRGB) so that the window, PNGs and the GPU pass
//! (`shaders/remodulate.wgsl`, same expressions) show the same image.

use glam::Vec3;

use crate::image_io::{aces_filmic, display_pixel, linear_to_srgb};

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
/// 8-bit code found among the 255 thresholds where `image_io`'s sRGB quantisation steps
/// (found once by bisection on that very function, so the codes are identical).
#[inline]
pub fn to_rgba8_fast(colour: Vec3, exposure_scale: f32) -> [u8; 4] {
    let v = if colour.is_finite() { colour.max(Vec3::ZERO) } else { Vec3::ZERO };
    let t = aces_filmic(v * exposure_scale);
    let steps = srgb8_steps();
    let q = |c: f32| steps.partition_point(|&s| s <= c) as u8;
    [q(t.x), q(t.y), q(t.z), 255]
}

fn quantise(t: f32) -> u8 {
    (linear_to_srgb(t) * 255.0 + 0.5) as u8
}

/// `steps[k]`: the smallest value in [0, 1] that quantises to code k + 1 or more.
fn srgb8_steps() -> &'static [f32; 255] {
    static STEPS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    STEPS.get_or_init(|| {
        let mut steps = [0.0f32; 255];
        for (k, step) in steps.iter_mut().enumerate() {
            let code = k as u8 + 1;
            let (mut lo, mut hi) = (0.0f32, 1.0f32);
            // Bisect on the bit pattern: non-negative floats order like their bits.
            let (mut lo_bits, mut hi_bits) = (lo.to_bits(), hi.to_bits());
            while hi_bits - lo_bits > 1 {
                let mid = lo_bits + (hi_bits - lo_bits) / 2;
                if quantise(f32::from_bits(mid)) >= code {
                    hi_bits = mid;
                } else {
                    lo_bits = mid;
                }
            }
            (lo, hi) = (f32::from_bits(lo_bits), f32::from_bits(hi_bits));
            *step = if quantise(lo) >= code { lo } else { hi };
        }
        steps
    })
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
    fn fast_quantisation_gives_image_io_bytes() {
        for k in 0..20_000 {
            let v = k as f32 * 1e-3;
            let c = Vec3::new(v, v * 0.37, v * 2.9);
            assert_eq!(to_rgba8_fast(c, exposure_scale(0.5)), to_rgba8(c, 0.5), "{c}");
        }
    }
}
