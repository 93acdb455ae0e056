//! The presenter's rule for the frames around a change of the scene state: the new view is
//! shown as soon as any of it came back, and no frame of an older view is composed once a
//! newer frame has results (issue 18, edit-to-display latency).
//!
//! The wait heuristic (paper §4.3) judges a frame by how much of it came back; right
//! after an edit that would keep the user's new view waiting behind jobs the grid is
//! still rendering, or behind frames of the view the user has left. So, until a frame of
//! the new state has been shown:
//! - a frame of an outdated state is never waited for: skipped if a later frame has
//!   results (composing it would only delay the newer one by a compose), else shown with
//!   what it has (skipped when empty);
//! - a frame of the new state is shown as soon as it has a result, and skipped when it has
//!   none while a later frame has some.
//!
//! Once it has been shown the heuristic decides again, and the frames of that state
//! accumulate (progressive refinement). Frames decided by this rule are left out of the
//! heuristic's frame time, like abandoned ones: their time is the edit's, not the grid's.

use crate::assembler::wait_heuristic::Decision;
use crate::wire::protocol::FrameNo;

/// Where the frames stand against the last change of the scene state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NewView {
    /// Frames below this one have an outdated state (0: the state never changed).
    pub outdated_before: FrameNo,
    /// The last frame shown, if any.
    pub last_shown: Option<FrameNo>,
}

impl NewView {
    /// The decision about `frame` (with `back` results; `later_has_results`: a frame after
    /// it has some), or `None` when the wait heuristic decides.
    pub fn decide(&self, frame: FrameNo, back: u32, later_has_results: bool) -> Option<Decision> {
        if frame < self.outdated_before {
            return Some(if back > 0 && !later_has_results {
                Decision::Show
            } else {
                Decision::Skip
            });
        }
        let new_view_shown = self.last_shown.is_some_and(|s| s >= self.outdated_before);
        if self.outdated_before == 0 || new_view_shown {
            return None;
        }
        match (back > 0, later_has_results) {
            (true, _) => Some(Decision::Show),
            (false, true) => Some(Decision::Skip),
            (false, false) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SHOW: Option<Decision> = Some(Decision::Show);
    const SKIP: Option<Decision> = Some(Decision::Skip);

    #[test]
    fn before_any_edit_the_heuristic_decides() {
        let v = NewView { outdated_before: 0, last_shown: Some(3) };
        assert_eq!(v.decide(4, 0, true), None);
        assert_eq!(v.decide(4, 9, false), None);
    }

    #[test]
    fn an_outdated_frame_is_shown_with_what_it_has_unless_a_later_frame_has_results() {
        let v = NewView { outdated_before: 10, last_shown: Some(5) };
        assert_eq!(v.decide(7, 3, false), SHOW, "the newest view the grid has");
        assert_eq!(v.decide(7, 3, true), SKIP, "a newer frame has results: no compose of this");
        assert_eq!(v.decide(7, 0, false), SKIP, "nothing to show");
    }

    #[test]
    fn the_new_states_first_frame_is_shown_with_its_first_result_then_the_heuristic_decides() {
        let v = NewView { outdated_before: 10, last_shown: Some(5) };
        assert_eq!(v.decide(10, 1, false), SHOW);
        assert_eq!(v.decide(10, 0, true), SKIP, "a later frame of it came back first");
        assert_eq!(v.decide(10, 0, false), None, "nothing yet: the heuristic waits");
        let shown = NewView { outdated_before: 10, last_shown: Some(10) };
        assert_eq!(shown.decide(11, 1, false), None, "the new view is shown: it accumulates");
    }
}
