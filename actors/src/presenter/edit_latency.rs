//! Edit-to-display latency: when each edit happened, until the first shown frame whose
//! scene state includes it.
//!
//! The scene holder logs every edit it applies with the version it made and the instant
//! of the edit (the input event for the window's edits, the scripted time for scripts);
//! the display takes, for each shown frame, the edits its version includes and not yet
//! shown. Versions only grow, so a frame of version `v` includes every edit `≤ v`. The
//! latency itself is stamped by whoever really shows the frame (the headless writer after
//! composing it, the window when it draws it): [`crate::presenter::stats::FrameStats::stamp_edit_latency`].

use std::collections::VecDeque;
use std::sync::Mutex;
use std::time::Instant;

use crate::scene::state::StateVersion;

/// Edits remembered at most while no frame shows them (oldest forgotten first), so that
/// a master whose display stalls cannot grow without bound.
pub const MAX_PENDING_EDITS: usize = 4096;

/// Edits applied and not yet shown, in version order.
#[derive(Debug, Default)]
pub struct EditLog {
    pending: Mutex<VecDeque<(StateVersion, Instant)>>,
}

impl EditLog {
    /// The edit made `version`; it happened at `at`.
    pub fn applied(&self, version: StateVersion, at: Instant) {
        let mut p = self.lock();
        if p.len() == MAX_PENDING_EDITS {
            p.pop_front();
        }
        p.push_back((version, at));
    }

    /// A frame of `version` is shown: the instants of the edits it shows first.
    pub fn shown(&self, version: StateVersion) -> Vec<Instant> {
        let mut p = self.lock();
        let n = p.iter().take_while(|(v, _)| *v <= version).count();
        p.drain(..n).map(|(_, at)| at).collect()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, VecDeque<(StateVersion, Instant)>> {
        self.pending.lock().unwrap_or_else(|p| p.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn a_frame_shows_every_edit_up_to_its_version_once() {
        let log = EditLog::default();
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
        let log = EditLog::default();
        let t0 = Instant::now();
        for v in 0..(MAX_PENDING_EDITS as u64 + 10) {
            log.applied(v, t0);
        }
        assert_eq!(log.shown(u64::MAX).len(), MAX_PENDING_EDITS);
    }
}
