//! Frames in flight (paper §4.1): pure logic behind the frame assembler actor.
//!
//! A result is accepted only for a frame not yet displayed and a (frame, set) that was
//! handed out to that very connection and not yet answered; everything else is dropped
//! and counted as late (its frame was displayed), duplicate (already answered) or
//! unknown (never handed to that connection, or a frame never scheduled). Accepted
//! radiance is kept packed, as it arrived ([`PackedFrame`]): accepting costs no pixel
//! work, and only shown frames are ever unpacked.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::assembler::packed_frame::PackedFrame;
use crate::scene::state::{SceneState, StateVersion};
use crate::scheduler::sets::SetTable;
use crate::wire::protocol::{FrameNo, PackedRadiance, SetNo};

use crate::wire::protocol::ConnId;

/// What happened to one result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// Scattered into the frame; `back` results of `total` are in.
    Accepted {
        back: u32,
        total: u32,
    },
    Late,
    Duplicate,
    Unknown,
}

/// Counts of dropped results.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dropped {
    pub late: u64,
    pub duplicate: u64,
    pub unknown: u64,
}

/// A frame taken out of the table for display.
#[derive(Debug)]
pub struct ClosedFrame {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
    /// The accepted results.
    pub results: PackedFrame,
    /// Per set, the connection whose result was accepted (`None`: no result).
    pub owners: Vec<Option<ConnId>>,
    pub back: u32,
    pub total: u32,
}

#[derive(Debug)]
struct OpenFrame {
    state: Arc<SceneState>,
    /// Connection each set was handed to.
    holder: Vec<Option<ConnId>>,
    back: u32,
    results: PackedFrame,
}

/// The frames scheduled and not yet displayed.
#[derive(Debug)]
pub struct FrameTable {
    sets: Arc<SetTable>,
    frames: BTreeMap<FrameNo, OpenFrame>,
    /// Frames up to and including this one were displayed.
    closed_upto: Option<FrameNo>,
    dropped: Dropped,
}

impl FrameTable {
    pub fn new(sets: Arc<SetTable>) -> Self {
        Self { sets, frames: BTreeMap::new(), closed_upto: None, dropped: Dropped::default() }
    }

    /// A fresh table that still refuses frames displayed before (used on restart).
    pub fn restarted(&self) -> Self {
        Self {
            closed_upto: self.closed_upto,
            dropped: self.dropped,
            ..Self::new(self.sets.clone())
        }
    }

    /// The scheduler queued all sets of `frame` with `state`.
    pub fn open(&mut self, frame: FrameNo, state: Arc<SceneState>) {
        if self.is_closed(frame) {
            return;
        }
        let s = self.sets.sets() as usize;
        self.frames.entry(frame).or_insert(OpenFrame {
            state,
            holder: vec![None; s],
            back: 0,
            results: PackedFrame::new(self.sets.clone()),
        });
    }

    /// The scheduler handed `(frame, set)` to `conn`. True when that set of that frame
    /// had already been handed out: a job done twice, which the scheduler must never do
    /// (no redundancy: at most S jobs per frame).
    pub fn handed_out(&mut self, frame: FrameNo, set: SetNo, conn: ConnId) -> bool {
        match self.frames.get_mut(&frame).and_then(|s| s.holder.get_mut(set as usize)) {
            Some(h) => h.replace(conn).is_some(),
            None => false,
        }
    }

    /// Judges one result and, when accepted, keeps its radiance.
    pub fn accept(
        &mut self,
        conn: ConnId,
        frame: FrameNo,
        set: SetNo,
        version: StateVersion,
        radiance: PackedRadiance,
    ) -> Admission {
        let admission = self.judge(conn, frame, set, version, radiance);
        match admission {
            Admission::Late => self.dropped.late += 1,
            Admission::Duplicate => self.dropped.duplicate += 1,
            Admission::Unknown => self.dropped.unknown += 1,
            Admission::Accepted { .. } => {}
        }
        admission
    }

    fn judge(
        &mut self,
        conn: ConnId,
        frame: FrameNo,
        set: SetNo,
        version: StateVersion,
        radiance: PackedRadiance,
    ) -> Admission {
        if self.is_closed(frame) {
            return Admission::Late;
        }
        if self.sets.pixels(set).is_none_or(|p| p.len() != radiance.len()) {
            return Admission::Unknown;
        }
        let Some(slot) = self.frames.get_mut(&frame) else { return Admission::Unknown };
        if slot.holder[set as usize] != Some(conn) || slot.state.version != version {
            return Admission::Unknown;
        }
        if slot.results.contains(set) {
            return Admission::Duplicate;
        }
        slot.back += 1;
        let PackedRadiance::Rgb9e5(words) = radiance;
        slot.results.insert(set, words);
        Admission::Accepted { back: slot.back, total: slot.holder.len() as u32 }
    }

    /// Takes `frame` out for display; it and every earlier frame count as displayed
    /// from now on. `None` when the frame was never opened (or already closed).
    pub fn close(&mut self, frame: FrameNo) -> Option<ClosedFrame> {
        if self.is_closed(frame) {
            return None;
        }
        self.closed_upto = Some(frame);
        // Earlier frames still open were passed over: they are displayed too.
        self.frames.retain(|f, _| *f >= frame);
        let slot = self.frames.remove(&frame)?;
        let owners = (0..slot.holder.len())
            .map(|s| slot.holder[s].filter(|_| slot.results.contains(s as SetNo)))
            .collect();
        Some(ClosedFrame {
            frame,
            state: slot.state,
            results: slot.results,
            owners,
            back: slot.back,
            total: slot.holder.len() as u32,
        })
    }

    /// Whether any set of an open frame was handed out: its computation has started.
    pub fn started(&self, frame: FrameNo) -> bool {
        self.frames.get(&frame).is_some_and(|s| s.holder.iter().any(Option::is_some))
    }

    /// The state version of an open frame.
    pub fn version(&self, frame: FrameNo) -> Option<StateVersion> {
        self.frames.get(&frame).map(|s| s.state.version)
    }

    /// Jobs back and total of an open frame.
    pub fn progress(&self, frame: FrameNo) -> Option<(u32, u32)> {
        self.frames.get(&frame).map(|s| (s.back, s.holder.len() as u32))
    }

    pub fn dropped(&self) -> Dropped {
        self.dropped
    }

    /// Frames currently in flight.
    pub fn open_frames(&self) -> usize {
        self.frames.len()
    }

    fn is_closed(&self, frame: FrameNo) -> bool {
        self.closed_upto.is_some_and(|c| frame <= c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::state::Resolution;
    use crate::scheduler::job_queue::tests::state;
    use crate::wire::packing::{encode_rgb9e5, pack};
    use crate::wire::protocol::{Partition, SetsConfig};
    use glam::Vec3;

    fn table() -> FrameTable {
        let sets = SetTable::new(
            Resolution { width: 8, height: 8 },
            SetsConfig { sets: 4, partition: Partition::QuasiRandom },
        )
        .expect("sets");
        FrameTable::new(Arc::new(sets))
    }

    fn radiance(v: f32) -> PackedRadiance {
        pack(&[Vec3::splat(v); 16]).expect("pack")
    }

    #[test]
    fn accepts_a_handed_out_set_once() {
        let mut t = table();
        t.open(0, state(3));
        assert!(!t.handed_out(0, 1, 7));
        assert!(!t.handed_out(0, 2, 7), "another set of the same frame is no re-hand-out");
        assert_eq!(t.accept(7, 0, 1, 3, radiance(2.0)), Admission::Accepted { back: 1, total: 4 });
        assert_eq!(t.accept(7, 0, 1, 3, radiance(2.0)), Admission::Duplicate);
        let closed = t.close(0).expect("open frame");
        assert_eq!(closed.back, 1);
        let (radiance, mask) = closed.results.unpack();
        let covered: Vec<usize> = (0..64).filter(|p| mask[*p]).collect();
        assert_eq!(
            covered,
            t.sets.pixels(1).unwrap().iter().map(|p| *p as usize).collect::<Vec<_>>()
        );
        assert!(covered.iter().all(|p| radiance[*p] == Vec3::splat(2.0)));
        assert_eq!(t.dropped(), Dropped { late: 0, duplicate: 1, unknown: 0 });
    }

    #[test]
    fn a_second_hand_out_of_one_set_is_reported() {
        let mut t = table();
        t.open(0, state(3));
        assert!(!t.started(0));
        assert!(!t.handed_out(0, 1, 7));
        assert!(t.started(0) && t.version(0) == Some(3));
        assert!(t.handed_out(0, 1, 8), "a job handed out twice went unnoticed");
        assert!(!t.handed_out(9, 1, 7), "a frame not in the table cannot be judged");
    }

    #[test]
    fn results_not_handed_to_that_connection_are_unknown() {
        let mut t = table();
        t.open(0, state(3));
        t.handed_out(0, 1, 7);
        assert_eq!(t.accept(8, 0, 1, 3, radiance(1.0)), Admission::Unknown, "other connection");
        assert_eq!(t.accept(7, 0, 2, 3, radiance(1.0)), Admission::Unknown, "set not handed out");
        assert_eq!(t.accept(7, 0, 1, 4, radiance(1.0)), Admission::Unknown, "wrong version");
        assert_eq!(t.accept(7, 5, 1, 3, radiance(1.0)), Admission::Unknown, "frame never opened");
        assert_eq!(t.accept(7, 0, 9, 3, radiance(1.0)), Admission::Unknown, "no such set");
        let short = PackedRadiance::Rgb9e5(vec![encode_rgb9e5(Vec3::ONE); 3]);
        assert_eq!(t.accept(7, 0, 1, 3, short.clone()), Admission::Unknown, "wrong pixel count");
        assert_eq!(t.dropped().unknown, 6);
        assert_eq!(t.progress(0), Some((0, 4)));
    }

    #[test]
    fn results_for_displayed_frames_are_late_and_never_reach_an_image() {
        let mut t = table();
        t.open(0, state(1));
        t.open(1, state(1));
        t.handed_out(0, 0, 1);
        t.handed_out(1, 0, 1);
        let closed = t.close(1).expect("frame 1");
        assert!(closed.results.unpack().1.iter().all(|m| !m));
        assert_eq!(t.accept(1, 0, 0, 1, radiance(1.0)), Admission::Late, "passed-over frame");
        assert_eq!(t.accept(1, 1, 0, 1, radiance(1.0)), Admission::Late);
        assert!(t.close(0).is_none() && t.close(1).is_none());
        t.open(1, state(1));
        assert_eq!(t.open_frames(), 0, "a displayed frame was reopened");
        assert_eq!(t.dropped().late, 2);
    }

    #[test]
    fn restart_keeps_the_displayed_boundary() {
        let mut t = table();
        t.open(3, state(1));
        t.close(3);
        let mut r = t.restarted();
        r.open(2, state(1));
        assert_eq!(r.open_frames(), 0);
        r.open(4, state(1));
        assert_eq!(r.progress(4), Some((0, 4)));
    }
}
