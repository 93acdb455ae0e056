//! Shared-exponent RGB9E5 packing of radiance (docs/design.md, decision 2).
//!
//! Each pixel is one `u32`: three 9-bit mantissas and a 5-bit exponent shared by the
//! three channels (the `EXT_texture_shared_exponent` layout: red in the low bits,
//! exponent in the top five). Every bit pattern decodes to a finite, non-negative
//! colour no larger than [`RGB9E5_MAX`], so a decoded result cannot carry NaN or
//! infinity into an image; the encoder refuses non-finite input instead of hiding it.

use glam::Vec3;
use thiserror::Error;

use crate::wire::protocol::PackedRadiance;

const MANTISSA_BITS: i32 = 9;
const EXP_BIAS: i32 = 15;
const MAX_EXP: i32 = 31;
const MANTISSA_MAX: u32 = (1 << MANTISSA_BITS) - 1;

/// Largest value a channel can hold: (511/512) · 2^16 = 65408.
pub const RGB9E5_MAX: f32 =
    (MANTISSA_MAX as f32 / (1 << MANTISSA_BITS) as f32) * (1u32 << (MAX_EXP - EXP_BIAS)) as f32;

/// Why radiance could not be packed or unpacked.
#[derive(Debug, Error, PartialEq)]
pub enum PackError {
    #[error("pixel {index} of the set has non-finite radiance {value:?}")]
    NonFinite { index: usize, value: [f32; 3] },
    #[error("result holds {got} pixels but the set has {expected}")]
    Length { got: usize, expected: usize },
}

/// Packs one colour. Negative channels (rounding noise of the demodulation) become 0
/// and channels above [`RGB9E5_MAX`] saturate; the caller has checked finiteness.
pub fn encode_rgb9e5(c: Vec3) -> u32 {
    let clamp = |v: f32| if v > 0.0 { v.min(RGB9E5_MAX) } else { 0.0 }; // NaN → 0
    let (r, g, b) = (clamp(c.x), clamp(c.y), clamp(c.z));
    let max = r.max(g).max(b);
    // floor(log2(max)) read exactly from the float's exponent bits (0 and subnormals
    // land far below the smallest shared exponent).
    let floor_log2 = ((max.to_bits() >> 23) & 0xff) as i32 - 127;
    let mut exp = floor_log2.max(-EXP_BIAS - 1) + 1 + EXP_BIAS;
    // 1 / 2^(exp - 24), built from its bits (exp is in 0..=31, so the power is normal);
    // powers of two make the product exact, and `as u32` floors non-negative values.
    let inv_scale = |e: i32| f32::from_bits(((EXP_BIAS + MANTISSA_BITS - e + 127) as u32) << 23);
    // Rounding may carry the largest mantissa to 512: use the next exponent then.
    if (max * inv_scale(exp) + 0.5) as u32 > MANTISSA_MAX {
        exp += 1;
    }
    let inv = inv_scale(exp);
    let m = |v: f32| ((v * inv + 0.5) as u32).min(MANTISSA_MAX);
    m(r) | (m(g) << 9) | (m(b) << 18) | ((exp as u32) << 27)
}

/// Unpacks one colour; total: every `u32` is a valid finite colour.
pub fn decode_rgb9e5(p: u32) -> Vec3 {
    // 2^(exp - 24) built from its bits: exp - 24 is in -24..=7, a normal f32 exponent.
    let exp = (p >> 27) as i32;
    let scale = f32::from_bits(((exp - EXP_BIAS - MANTISSA_BITS + 127) as u32) << 23);
    let m = |shift: u32| ((p >> shift) & MANTISSA_MAX) as f32 * scale;
    Vec3::new(m(0), m(9), m(18))
}

/// Half the step between neighbouring values at the exponent `p` was packed with:
/// the largest error a correctly rounded channel of `p` can have.
pub fn rgb9e5_half_step(p: u32) -> f32 {
    let exp = (p >> 27) as i32;
    0.5 * 2f32.powi(exp - EXP_BIAS - MANTISSA_BITS)
}

/// Packs a set's radiance in set order; refuses NaN and infinities (a renderer bug that
/// must not be smoothed over), naming the offending pixel.
pub fn pack(radiance: &[Vec3]) -> Result<PackedRadiance, PackError> {
    let mut out = Vec::with_capacity(radiance.len());
    for (index, c) in radiance.iter().enumerate() {
        if !c.is_finite() {
            return Err(PackError::NonFinite { index, value: c.to_array() });
        }
        out.push(encode_rgb9e5(*c));
    }
    Ok(PackedRadiance::Rgb9e5(out))
}

/// Unpacks a result's radiance, checking that it holds exactly `expected` pixels.
pub fn unpack(packed: &PackedRadiance, expected: usize) -> Result<Vec<Vec3>, PackError> {
    if packed.len() != expected {
        return Err(PackError::Length { got: packed.len(), expected });
    }
    match packed {
        PackedRadiance::Rgb9e5(v) => Ok(v.iter().map(|p| decode_rgb9e5(*p)).collect()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn exact_values_roundtrip_exactly() {
        for c in [Vec3::ZERO, Vec3::ONE, Vec3::new(0.5, 2.0, 0.25), Vec3::splat(RGB9E5_MAX)] {
            assert_eq!(decode_rgb9e5(encode_rgb9e5(c)), c, "{c}");
        }
    }

    #[test]
    fn negative_clamps_to_zero_and_huge_saturates() {
        let d = decode_rgb9e5(encode_rgb9e5(Vec3::new(-1.0, 1e9, 1.0)));
        assert_eq!(d.x, 0.0);
        assert_eq!(d.y, RGB9E5_MAX);
        assert!(d.z < 1e-3, "a saturated channel keeps the others small: {d}");
    }

    #[test]
    fn pack_rejects_non_finite_naming_the_pixel() {
        let err = pack(&[Vec3::ONE, Vec3::new(f32::NAN, 0.0, 0.0)]).unwrap_err();
        assert!(matches!(err, PackError::NonFinite { index: 1, .. }));
        assert!(pack(&[Vec3::new(0.0, f32::INFINITY, 0.0)]).is_err());
    }

    #[test]
    fn unpack_checks_the_pixel_count() {
        let p = pack(&[Vec3::ONE; 3]).expect("pack");
        assert_eq!(unpack(&p, 4), Err(PackError::Length { got: 3, expected: 4 }));
        assert_eq!(unpack(&p, 3).expect("unpack"), vec![Vec3::ONE; 3]);
    }

    #[test]
    fn every_bit_pattern_decodes_finite_and_non_negative() {
        for p in [0u32, u32::MAX, 0xffff_ffff >> 5, 1 << 27, 0xdead_beef] {
            let c = decode_rgb9e5(p);
            assert!(c.is_finite() && c.min_element() >= 0.0, "{p:#x} → {c}");
            assert!(c.max_element() <= RGB9E5_MAX);
        }
    }

    proptest! {
        #[test]
        fn roundtrip_error_within_rgb9e5_precision(
            r in 0.0f32..70000.0, g in 0.0f32..70000.0, b in 0.0f32..70000.0,
            shrink in 0i32..40,
        ) {
            // Spread inputs over many octaves, down to values that flush to zero.
            let k = 2f32.powi(-shrink);
            let c = Vec3::new(r * k, g * k, b * k);
            let p = encode_rgb9e5(c);
            let d = decode_rgb9e5(p);
            let clamped = c.min(Vec3::splat(RGB9E5_MAX));
            let tol = rgb9e5_half_step(p) * 1.0001;
            prop_assert!((d - clamped).abs().max_element() <= tol,
                "{c} → {d}, tolerance {tol}");
            // The shared exponent is the smallest that holds the largest channel, so the
            // relative error of that channel is at most 2^-9.
            let m = clamped.max_element();
            if m > 1e-4 {
                prop_assert!((d.max_element() - m).abs() <= m / 512.0 * 1.0001);
            }
        }
    }
}
