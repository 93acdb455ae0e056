//! What the window shows: an 8-bit picture at render resolution (the chosen view of a
//! frame, made by [`crate::master::compose`]), or the final view in the reconstruction's
//! texture on the window's own device ([`FrameImage::Device`]), drawn without a copy.

use std::sync::Arc;

use glam::Vec3;

use crate::master::compose::Image;
use crate::reconstruct::DeviceImage;

/// The pixels of one frame, where they are.
#[derive(Clone, Debug)]
pub enum FrameImage {
    /// On the CPU; the blit pass uploads it.
    Picture {
        picture: Picture,
        /// Final linear colour (albedo · radiance + emission), for EXR screenshots; only
        /// the final view has it.
        linear: Option<Arc<Vec<Vec3>>>,
    },
    /// The final view, left on the window's device by the GPU reconstruction.
    Device(DeviceImage),
}

/// A frame's picture and, for the final view, its linear colour, on the CPU.
pub type HostFrame = (Picture, Option<Arc<Vec<Vec3>>>);

impl FrameImage {
    /// A composed frame's pixels as the window takes them (the sink's hand-over): a host
    /// picture is moved, not copied; `None` when its size does not match its pixels.
    pub fn from_composed(width: u32, height: u32, image: Image) -> Option<Self> {
        Some(match image {
            Image::Host { rgba, linear } => FrameImage::Picture {
                picture: Picture::from_rgba(width, height, rgba)?,
                linear: linear.map(Arc::new),
            },
            Image::Device(image) => FrameImage::Device(image),
        })
    }

    /// The picture and linear colour on the CPU, for screenshots: a device image is read
    /// back here (once per screenshot, never per frame).
    pub fn to_host(&self) -> Result<HostFrame, String> {
        match self {
            FrameImage::Picture { picture, linear } => Ok((picture.clone(), linear.clone())),
            FrameImage::Device(image) => {
                let (rgba, linear) = image.read_back().map_err(|e| e.to_string())?;
                let picture = Picture::from_pixels(image.width, image.height, &rgba)
                    .ok_or("the device image's size does not match its pixels")?;
                Ok((picture, Some(Arc::new(linear))))
            }
        }
    }
}

/// One picture, row-major RGBA8 (display-encoded), y = 0 the top row.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Picture {
    /// A picture from per-pixel RGBA values; `None` when the count does not match the size.
    pub fn from_pixels(width: u32, height: u32, pixels: &[[u8; 4]]) -> Option<Self> {
        (pixels.len() == width as usize * height as usize).then(|| Self {
            width,
            height,
            rgba: pixels.iter().flatten().copied().collect(),
        })
    }

    /// [`Self::from_pixels`] taking the pixels' buffer itself, without a copy.
    pub fn from_rgba(width: u32, height: u32, pixels: Vec<[u8; 4]>) -> Option<Self> {
        (pixels.len() == width as usize * height as usize).then(|| Self {
            width,
            height,
            rgba: bytemuck::allocation::cast_vec(pixels),
        })
    }

    /// The RGBA value of pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = (y as usize * self.width as usize + x as usize) * 4;
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_must_match_the_size() {
        assert!(Picture::from_pixels(3, 1, &[[0; 4]; 2]).is_none());
        let p = Picture::from_pixels(2, 1, &[[1, 2, 3, 4], [5, 6, 7, 8]]).expect("2×1");
        assert_eq!(p.pixel(1, 0), [5, 6, 7, 8]);
        let moved = Picture::from_rgba(2, 1, vec![[1, 2, 3, 4], [5, 6, 7, 8]]).expect("2×1");
        assert_eq!(moved, p);
        assert!(Picture::from_rgba(3, 1, vec![[0; 4]; 2]).is_none());
    }
}
