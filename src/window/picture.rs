//! What the window shows: an 8-bit picture at render resolution (the chosen view of a
//! frame, made by [`crate::master::compose`]).

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
    }
}
