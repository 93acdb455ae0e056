//! Progressive refinement while the scene state is unchanged (paper §5): pure logic
//! behind the display actor. Results of every shown frame with the same state version
//! are averaged per pixel; a new version starts over.

use glam::Vec3;

use crate::state::StateVersion;

/// Running per-pixel means since the last state change.
#[derive(Debug)]
pub struct Accumulator {
    version: Option<StateVersion>,
    /// Kept as a mean (updated incrementally) so a shown frame only copies it.
    mean: Vec<Vec3>,
    count: Vec<u32>,
    frames: u32,
}

impl Accumulator {
    pub fn new(pixels: usize) -> Self {
        Self { version: None, mean: vec![Vec3::ZERO; pixels], count: vec![0; pixels], frames: 0 }
    }

    /// Adds one frame's covered pixels; a different version (or pixel count) resets.
    pub fn add(&mut self, version: StateVersion, radiance: &[Vec3], mask: &[bool]) {
        if self.version != Some(version) || self.mean.len() != radiance.len() {
            self.version = Some(version);
            self.mean = vec![Vec3::ZERO; radiance.len()];
            self.count = vec![0; radiance.len()];
            self.frames = 0;
        }
        self.frames += 1;
        for ((m, c), (r, covered)) in
            self.mean.iter_mut().zip(&mut self.count).zip(radiance.iter().zip(mask))
        {
            if *covered {
                *c += 1;
                *m += (*r - *m) / *c as f32;
            }
        }
    }

    /// Mean radiance per pixel (zero where nothing arrived) and the per-pixel counts.
    pub fn mean(&self) -> (Vec<Vec3>, Vec<u32>) {
        (self.mean.clone(), self.count.clone())
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.mean.len()
    }

    /// Frames accumulated since the last state change.
    pub fn frames(&self) -> u32 {
        self.frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn averages_per_pixel_and_resets_on_a_new_version() {
        let mut a = Accumulator::new(2);
        a.add(1, &[Vec3::ONE, Vec3::splat(9.0)], &[true, false]);
        a.add(1, &[Vec3::splat(3.0), Vec3::splat(4.0)], &[true, true]);
        let (mean, count) = a.mean();
        assert_eq!(mean, vec![Vec3::splat(2.0), Vec3::splat(4.0)]);
        assert_eq!(count, vec![2, 1]);
        assert_eq!(a.frames(), 2);
        a.add(2, &[Vec3::splat(5.0), Vec3::ZERO], &[true, false]);
        let (mean, count) = a.mean();
        assert_eq!(mean, vec![Vec3::splat(5.0), Vec3::ZERO]);
        assert_eq!(count, vec![1, 0]);
        assert_eq!(a.frames(), 1);
    }
}
