//! Writing rendered images: linear radiance → PNG (exposure, filmic tonemap, sRGB) or EXR.
//!
//! PNGs are for looking at: exposure in stops, then Narkowicz's fit of the ACES filmic
//! curve (it rolls highlights off instead of clipping them), then the sRGB transfer
//! function. EXRs keep the linear f32 radiance untouched, for gold-standard references and
//! error metrics. Non-finite values are written as 0 in both.

use std::path::{Path, PathBuf};

use glam::Vec3;

/// Why an image could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ImageIoError {
    #[error("`{}`: unsupported image format (use .png or .exr)", .0.display())]
    UnsupportedFormat(PathBuf),
    #[error("image is {width}x{height} but {len} pixels were given")]
    SizeMismatch { width: u32, height: u32, len: usize },
    #[error("cannot write `{}`: {source}", path.display())]
    Write { path: PathBuf, source: image::ImageError },
    #[error("cannot write `{}`: {source}", path.display())]
    Unwritable { path: PathBuf, source: std::io::Error },
}

/// An output file checked to be writable before the work that fills it; removed again on
/// drop unless [`ClaimedOutput::keep`] is called and the file did not exist before.
#[derive(Debug)]
pub struct ClaimedOutput {
    path: PathBuf,
    created: bool,
    keep: bool,
}

impl ClaimedOutput {
    /// Checks the format and that `path` can be written, by opening it for writing
    /// (created empty when missing; an existing file is left as it is until written).
    pub fn claim(path: &Path) -> Result<Self, ImageIoError> {
        ImageFormat::from_path(path)?;
        let existed = path.exists();
        std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(path)
            .map_err(|source| ImageIoError::Unwritable { path: path.to_path_buf(), source })?;
        Ok(Self { path: path.to_path_buf(), created: !existed, keep: false })
    }

    /// The image was written: keep the file.
    pub fn keep(mut self) {
        self.keep = true;
    }
}

impl Drop for ClaimedOutput {
    fn drop(&mut self) {
        // Leave no empty file behind when the work failed.
        if self.created && !self.keep {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// The file formats gridlight writes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// Tonemapped 8-bit sRGB.
    Png,
    /// Linear 32-bit float RGB.
    Exr,
}

impl ImageFormat {
    /// The format named by `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, ImageIoError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            _ => Err(ImageIoError::UnsupportedFormat(path.to_path_buf())),
        }
    }
}

/// Narkowicz's ACES filmic fit, per channel; maps [0, ∞) to [0, 1).
pub fn aces_filmic(x: Vec3) -> Vec3 {
    let (a, b, c, d, e) = (2.51, 0.03, 2.43, 0.59, 0.14);
    ((x * (a * x + b)) / (x * (c * x + d) + e)).clamp(Vec3::ZERO, Vec3::ONE)
}

/// The sRGB opto-electronic transfer function on [0, 1].
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// One display pixel: exposure (stops), tonemap, sRGB, quantised.
pub fn display_pixel(radiance: Vec3, exposure_stops: f32) -> [u8; 3] {
    let v = if radiance.is_finite() { radiance.max(Vec3::ZERO) } else { Vec3::ZERO };
    let mapped = aces_filmic(v * exposure_stops.exp2());
    mapped.to_array().map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8)
}

/// Tonemapped 8-bit sRGB bytes (RGB, row-major, top row first) of linear `pixels`.
pub fn to_srgb8(pixels: &[Vec3], exposure_stops: f32) -> Vec<u8> {
    pixels.iter().flat_map(|&p| display_pixel(p, exposure_stops)).collect()
}

fn check_size<T>(width: u32, height: u32, pixels: &[T]) -> Result<(), ImageIoError> {
    if width as usize * height as usize != pixels.len() {
        return Err(ImageIoError::SizeMismatch { width, height, len: pixels.len() });
    }
    Ok(())
}

/// Writes a tonemapped sRGB PNG.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
    exposure_stops: f32,
) -> Result<(), ImageIoError> {
    check_size(width, height, pixels)?;
    let bytes = to_srgb8(pixels, exposure_stops);
    let image = image::RgbImage::from_raw(width, height, bytes).expect("size checked above");
    image
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| ImageIoError::Write { path: path.to_path_buf(), source })
}

/// Writes display-encoded RGBA8 pixels (already tonemapped) as PNG.
pub fn write_png_rgba8(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[u8; 4]],
) -> Result<(), ImageIoError> {
    check_size(width, height, pixels)?;
    let bytes: Vec<u8> = pixels.iter().flatten().copied().collect();
    let image = image::RgbaImage::from_raw(width, height, bytes).expect("size checked above");
    image
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|source| ImageIoError::Write { path: path.to_path_buf(), source })
}

/// Writes linear f32 RGB to an OpenEXR file.
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
) -> Result<(), ImageIoError> {
    check_size(width, height, pixels)?;
    let data: Vec<f32> =
        pixels.iter().flat_map(|&p| if p.is_finite() { p.to_array() } else { [0.0; 3] }).collect();
    let image = image::Rgb32FImage::from_raw(width, height, data).expect("size checked above");
    image::DynamicImage::ImageRgb32F(image)
        .save_with_format(path, image::ImageFormat::OpenExr)
        .map_err(|source| ImageIoError::Write { path: path.to_path_buf(), source })
}

/// Writes `pixels` in the format `path`'s extension names (`exposure_stops` applies to PNG).
pub fn write_image(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[Vec3],
    exposure_stops: f32,
) -> Result<(), ImageIoError> {
    match ImageFormat::from_path(path)? {
        ImageFormat::Png => write_png(path, width, height, pixels, exposure_stops),
        ImageFormat::Exr => write_exr(path, width, height, pixels),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tonemap_is_monotonic_and_bounded() {
        let mut last = -1.0;
        for i in 0..100 {
            let v = aces_filmic(Vec3::splat(i as f32 * 0.2)).x;
            assert!(v >= last && v <= 1.0);
            last = v;
        }
        assert_eq!(display_pixel(Vec3::ZERO, 0.0), [0, 0, 0]);
        assert_eq!(display_pixel(Vec3::splat(f32::NAN), 0.0), [0, 0, 0]);
        assert!(display_pixel(Vec3::splat(1e6), 0.0)[0] >= 254);
    }

    #[test]
    fn srgb_curve_matches_reference_points() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert!((linear_to_srgb(1.0) - 1.0).abs() < 1e-6);
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-3);
    }

    #[test]
    fn format_follows_extension_and_rejects_others() {
        assert_eq!(ImageFormat::from_path(Path::new("a.PNG")).ok(), Some(ImageFormat::Png));
        assert_eq!(ImageFormat::from_path(Path::new("a.exr")).ok(), Some(ImageFormat::Exr));
        let err = ImageFormat::from_path(Path::new("a.jpg")).expect_err("jpg");
        assert!(err.to_string().contains("a.jpg"));
    }

    #[test]
    fn exr_round_trips_linear_values() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("x.exr");
        let pixels = vec![Vec3::new(0.5, 2.0, 100.0), Vec3::new(0.0, 1e-3, 7.25)];
        write_image(&path, 2, 1, &pixels, 0.0).expect("write exr");
        let back = image::open(&path).expect("read exr").to_rgb32f();
        assert_eq!(back.get_pixel(0, 0).0, [0.5, 2.0, 100.0]);
        assert_eq!(back.get_pixel(1, 0).0, [0.0, 1e-3, 7.25]);
    }

    #[test]
    fn png_is_tonemapped_srgb() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("x.png");
        write_image(&path, 1, 2, &[Vec3::ZERO, Vec3::splat(0.18)], 0.0).expect("write png");
        let back = image::open(&path).expect("read png").to_rgb8();
        assert_eq!(back.get_pixel(0, 0).0, [0, 0, 0]);
        assert_eq!(back.get_pixel(0, 1).0, display_pixel(Vec3::splat(0.18), 0.0));
        assert!(write_image(&path, 2, 2, &[Vec3::ZERO], 0.0).is_err());
    }
}
