//! Display encoding of linear colour: exposure, a filmic curve, sRGB.
//!
//! The filmic curve is Narkowicz's fit of the ACES reference rendering transform; the same
//! expressions are in `shaders/remodulate.wgsl` so the GPU path displays the same image.

use glam::Vec3;

/// ACES filmic curve (Narkowicz 2015 fit), clamped to [0, 1].
#[inline]
pub fn aces_filmic(x: Vec3) -> Vec3 {
    let num = x * (x * 2.51 + Vec3::splat(0.03));
    let den = x * (x * 2.43 + Vec3::splat(0.59)) + Vec3::splat(0.14);
    (num / den).clamp(Vec3::ZERO, Vec3::ONE)
}

/// sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
#[inline]
pub fn srgb_encode(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear colour → display-referred sRGB in [0, 1]: exposure, filmic, sRGB.
#[inline]
pub fn tonemap(colour: Vec3, exposure: f32) -> Vec3 {
    let t = aces_filmic((colour * exposure).max(Vec3::ZERO));
    Vec3::new(srgb_encode(t.x), srgb_encode(t.y), srgb_encode(t.z))
}

/// Quantises a value in [0, 1] to 8 bits, rounding to nearest (as a unorm store does).
#[inline]
pub fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Tonemapped 8-bit RGBA of a linear colour.
#[inline]
pub fn to_rgba8(colour: Vec3, exposure: f32) -> [u8; 4] {
    let t = tonemap(colour, exposure);
    [to_u8(t.x), to_u8(t.y), to_u8(t.z), 255]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn black_stays_black_and_bright_saturates() {
        assert_eq!(to_rgba8(Vec3::ZERO, 1.0), [0, 0, 0, 255]);
        assert_eq!(to_rgba8(Vec3::splat(1e4), 1.0), [255, 255, 255, 255]);
    }

    #[test]
    fn curve_is_monotonic_and_exposure_brightens() {
        let mut last = -1.0;
        for k in 0..100 {
            let v = tonemap(Vec3::splat(k as f32 * 0.05), 1.0).x;
            assert!(v >= last);
            last = v;
        }
        assert!(tonemap(Vec3::splat(0.2), 2.0).x > tonemap(Vec3::splat(0.2), 1.0).x);
    }

    #[test]
    fn srgb_matches_known_values() {
        assert!((srgb_encode(0.5) - 0.735_356_9).abs() < 1e-5);
        assert!((srgb_encode(0.001) - 0.012_92).abs() < 1e-7);
    }
}
