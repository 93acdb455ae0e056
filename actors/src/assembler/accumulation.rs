//! Progressive refinement while the scene state is unchanged (paper §5): how many shown
//! frames share the current state version, decided once per shown frame.
//!
//! The frame assembler decides it as it shows a frame and the count travels with the frame
//! (`FrameStats::accumulated_frames`); the reconstruction obeys it (1 restarts its running
//! average with the filters on, more averages without them) and never counts on its own,
//! so the two cannot disagree (they did when the display kept a count the reconstructor
//! did not, and a display restart reset one of them). Drivers that reconstruct without a
//! master (evaluation, benchmarks) use the same type. The per-pixel average itself is the
//! reconstruction's accumulation pass, on the sink thread, not an actor's work.

use crate::scene::state::StateVersion;

/// The run of shown frames with one scene state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Accumulation {
    version: Option<StateVersion>,
    frames: u32,
}

impl Accumulation {
    /// One more shown frame of `version`: the frames accumulated with it, this one
    /// included (1: a new state, the average starts over).
    pub fn add(&mut self, version: StateVersion) -> u32 {
        if self.version != Some(version) {
            self.version = Some(version);
            self.frames = 0;
        }
        self.frames += 1;
        self.frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_frames_of_one_version_and_starts_over_on_a_new_one() {
        let mut a = Accumulation::default();
        assert_eq!(a.add(1), 1);
        assert_eq!(a.add(1), 2);
        assert_eq!(a.add(1), 3);
        assert_eq!(a.add(2), 1);
    }
}
