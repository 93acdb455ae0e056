//! Bookkeeping of the temporal filter's previous frames.
//!
//! Pure logic shared by the CPU and GPU reconstructors: which ring slot holds which frame
//! and the weights w = 1/(F_i − F_j). The pixel data lives with each implementation
//! (vectors on the CPU, texture-array layers on the GPU). When accumulation restarts is
//! not decided here: it comes with each frame (`FrameInputs::accumulated_frames`).

use gridlight_actors::protocol::FrameNo;

use super::params::MAX_HISTORY;

/// Which frame each history slot holds; slots are reused oldest first.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HistoryRing {
    capacity: usize,
    frames: [Option<FrameNo>; MAX_HISTORY as usize],
    next: usize,
}

impl HistoryRing {
    /// A ring of `capacity` slots (at most `MAX_HISTORY`; 0 disables the temporal filter).
    pub fn new(capacity: u32) -> Self {
        Self { capacity: capacity.min(MAX_HISTORY) as usize, ..Default::default() }
    }

    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Weight of each slot for the current frame: 1/(F_i − F_j), or 0 for an empty slot or
    /// one that is not older than the current frame.
    pub fn weights(&self, current: FrameNo) -> [f32; MAX_HISTORY as usize] {
        let mut w = [0.0; MAX_HISTORY as usize];
        for (slot, frame) in self.frames.iter().enumerate().take(self.capacity) {
            if let Some(f) = *frame {
                if f < current {
                    w[slot] = 1.0 / (current - f) as f32;
                }
            }
        }
        w
    }

    /// Claims the slot for `frame` (the oldest one) and returns its index, or `None` when
    /// the ring has no slots.
    pub fn push(&mut self, frame: FrameNo) -> Option<usize> {
        if self.capacity == 0 {
            return None;
        }
        let slot = self.next;
        self.frames[slot] = Some(frame);
        self.next = (slot + 1) % self.capacity;
        Some(slot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_fall_with_frame_distance_and_slots_are_reused() {
        let mut ring = HistoryRing::new(2);
        assert_eq!(ring.weights(5), [0.0; 4]);
        assert_eq!(ring.push(3), Some(0));
        assert_eq!(ring.push(4), Some(1));
        assert_eq!(ring.weights(5), [0.5, 1.0, 0.0, 0.0]);
        assert_eq!(ring.push(7), Some(0), "the oldest slot is reused");
        assert_eq!(ring.weights(8), [1.0, 0.25, 0.0, 0.0]);
        assert_eq!(HistoryRing::new(0).push(1), None);
    }
}
