//! The screenshot key: writes the shown frame as PNG (what the window shows, tonemapped
//! sRGB) or EXR (linear final colour, before tonemapping), numbered so that nothing is
//! overwritten.

use std::path::{Path, PathBuf};

use thiserror::Error;

use glam::Vec3;

use super::panel::ShotFormat;
use super::picture::Picture;

/// What a screenshot writes: the shown frame's number, its picture and, for the final
/// view, its linear colour.
#[derive(Clone, Copy, Debug)]
pub struct Shot<'a> {
    pub frame: u64,
    pub picture: &'a Picture,
    pub linear: Option<&'a [Vec3]>,
}

/// Why a screenshot could not be written.
#[derive(Debug, Error)]
pub enum ScreenshotError {
    #[error("cannot create the screenshot folder {path}: {source}")]
    Folder { path: PathBuf, source: std::io::Error },
    #[error("cannot write {path}: {source}")]
    Write { path: PathBuf, source: image::ImageError },
    #[error("this frame has no linear colour to write as EXR (only the final view has)")]
    NoLinear,
}

/// Writes `shown` into `dir` in `format` and returns the file's path.
pub fn save(dir: &Path, shown: &Shot, format: ShotFormat) -> Result<PathBuf, ScreenshotError> {
    std::fs::create_dir_all(dir)
        .map_err(|source| ScreenshotError::Folder { path: dir.to_path_buf(), source })?;
    let ext = match format {
        ShotFormat::Png => "png",
        ShotFormat::Exr => "exr",
    };
    let path = free_name(dir, shown.frame, ext);
    let (w, h) = (shown.picture.width, shown.picture.height);
    let result = match format {
        ShotFormat::Png => {
            image::save_buffer(&path, &shown.picture.rgba, w, h, image::ExtendedColorType::Rgba8)
        }
        ShotFormat::Exr => {
            let linear = shown.linear.ok_or(ScreenshotError::NoLinear)?;
            let floats: Vec<f32> = linear.iter().flat_map(|c| c.to_array()).collect();
            image::save_buffer(
                &path,
                bytemuck::cast_slice(&floats),
                w,
                h,
                image::ExtendedColorType::Rgb32F,
            )
        }
    };
    result.map_err(|source| ScreenshotError::Write { path: path.clone(), source })?;
    Ok(path)
}

/// `gridlight-frame<N>.<ext>`, or with `-2`, `-3`, … when that exists already.
fn free_name(dir: &Path, frame: u64, ext: &str) -> PathBuf {
    let mut path = dir.join(format!("gridlight-frame{frame}.{ext}"));
    let mut n = 2;
    while path.exists() {
        path = dir.join(format!("gridlight-frame{frame}-{n}.{ext}"));
        n += 1;
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINEAR: [Vec3; 2] = [Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.5, 0.0)];

    fn picture() -> Picture {
        Picture { width: 2, height: 1, rgba: vec![255, 0, 0, 255, 0, 255, 0, 255] }
    }

    fn shot(picture: &Picture, linear: bool) -> Shot<'_> {
        Shot { frame: 7, picture, linear: linear.then_some(&LINEAR[..]) }
    }

    #[test]
    fn png_round_trips_and_names_do_not_collide() {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = picture();
        let a = save(dir.path(), &shot(&p, false), ShotFormat::Png).expect("png");
        let b = save(dir.path(), &shot(&p, false), ShotFormat::Png).expect("png");
        assert_ne!(a, b);
        assert!(a.ends_with("gridlight-frame7.png"));
        let img = image::open(&a).expect("readable").to_rgba8();
        assert_eq!(img.get_pixel(0, 0).0, [255, 0, 0, 255]);
        assert_eq!(img.get_pixel(1, 0).0, [0, 255, 0, 255]);
    }

    #[test]
    fn exr_keeps_linear_values_above_one() {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = picture();
        let path = save(dir.path(), &shot(&p, true), ShotFormat::Exr).expect("exr");
        let img = image::open(&path).expect("readable").to_rgb32f();
        assert_eq!(img.get_pixel(0, 0).0, [2.0, 0.0, 0.0]);
        assert!(matches!(
            save(dir.path(), &shot(&p, false), ShotFormat::Exr),
            Err(ScreenshotError::NoLinear)
        ));
    }
}
