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
}
