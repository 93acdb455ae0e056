//! Progressive refinement while the scene state is unchanged (paper §5), as the display
//! actor tracks it: how many shown frames share the current state version.
//!
//! The per-pixel average itself is the reconstruction's accumulation pass, run by the
//! frame sink off the actors' threads (`gridlight::reconstruct`, step 4): averaging here
//! too would be the same logic twice and would cost the display actor a pass over every
//! pixel and a copy of the image per shown frame.

use crate::scene::state::StateVersion;

/// Frames shown since the last state change.
#[derive(Debug, Default)]
pub struct Accumulator {
    version: Option<StateVersion>,
    frames: u32,
}

impl Accumulator {
    /// Counts one shown frame of `version`; a different version starts over.
    pub fn add(&mut self, version: StateVersion) {
        if self.version != Some(version) {
            self.version = Some(version);
            self.frames = 0;
        }
        self.frames += 1;
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
    fn counts_frames_of_one_version_and_resets_on_a_new_one() {
        let mut a = Accumulator::default();
        a.add(1);
        a.add(1);
        assert_eq!(a.frames(), 2);
        a.add(2);
        assert_eq!(a.frames(), 1);
    }
}
