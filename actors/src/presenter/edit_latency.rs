//! Edit-to-display latency: when each edit happened, until the first shown frame whose
//! scene state includes it.
//!
//! The scene holder tells the presenter of every edit it applies ([`EditApplied`](super::EditApplied): the
//! version it made and the instant of the edit, the input event for the window's edits,
//! the scripted time for scripts); the presenter keeps them in its [`EditLog`] and takes,
//! for each shown frame, the edits its version includes and not yet shown. Versions only grow, so a frame of version `v` includes every edit `≤ v`. The
//! latency itself is stamped by whoever really shows the frame (the headless writer after
//! composing it, the window when it draws it): [`crate::presenter::stats::FrameStats::stamp_edit_latency`].

use std::collections::VecDeque;
use std::time::Instant;

use crate::scene::state::StateVersion;

/// Edits remembered at most while no frame shows them (oldest forgotten first), so that
/// a master whose display stalls cannot grow without bound.
pub const MAX_PENDING_EDITS: usize = 4096;

/// Edits applied and not yet shown, in version order (the presenter's own).
#[derive(Debug, Default)]
pub struct EditLog {
    pending: VecDeque<(StateVersion, Instant)>,
}

impl EditLog {
    /// The edit made `version`; it happened at `at`.
    pub fn applied(&mut self, version: StateVersion, at: Instant) {
        if self.pending.len() == MAX_PENDING_EDITS {
            self.pending.pop_front();
        }
        self.pending.push_back((version, at));
    }

    /// A frame of `version` is shown: the instants of the edits it shows first.
    pub fn shown(&mut self, version: StateVersion) -> Vec<Instant> {
        let n = self.pending.iter().take_while(|(v, _)| *v <= version).count();
        self.pending.drain(..n).map(|(_, at)| at).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_frame_shows_every_edit_up_to_its_version_once() {
        let mut log = EditLog::default();
        let t0 = Instant::now();
        let at = |ms| t0 + Duration::from_millis(ms);
        log.applied(2, at(0));
        log.applied(3, at(10));
        log.applied(4, at(20));
        assert!(log.shown(1).is_empty(), "an older frame shows none of them");
        assert_eq!(log.shown(3), vec![at(0), at(10)]);
        assert!(log.shown(3).is_empty(), "each edit is shown once");
        assert_eq!(log.shown(9), vec![at(20)]);
    }

    #[test]
    fn the_log_is_bounded() {
        let mut log = EditLog::default();
        let t0 = Instant::now();
        for v in 0..(MAX_PENDING_EDITS as u64 + 10) {
            log.applied(v, t0);
        }
        assert_eq!(log.shown(u64::MAX).len(), MAX_PENDING_EDITS);
    }
}
