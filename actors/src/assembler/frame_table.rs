//! Frames in flight (paper §4.1): pure logic behind the frame assembler actor.
//!
//! A frame is opened when the scheduler queues it, marked started at its first hand-out
//! and taken out when it is displayed (shown or skipped); it and every earlier frame
//! count as displayed from then on. The results that reach the table were already
//! checked by the connection that received them (`connection::protocol_state`: set range, the
//! job it answers, its state version, its pixel count, answered once): the table only
//! judges time. A result for a displayed frame is late; one for a frame the table does
//! not hold (lost in a restart of the assembler) is unknown; a second result for one set
//! means the set was handed out twice, which the scheduler must never do. Accepted
//! radiance is kept packed, as it arrived ([`PackedFrame`]): accepting costs no pixel
//! work, and only shown frames are ever unpacked.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use crate::scene::state::{SceneState, StateVersion};
use crate::shared::packed_frame::{ClosedFrame, PackedFrame};
use crate::shared::sets::SetTables;
use crate::wire::protocol::{ConnId, FrameNo, PackedRadiance, SetNo};

/// What happened to one result.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Admission {
    /// Kept in the frame; `back` results of `total` are in.
    Accepted { back: u32, total: u32 },
    /// Its frame was displayed.
    Late,
    /// Its frame is not in the table (lost when the assembler restarted).
    Unknown,
    /// Its set already has a result from another connection: the set was handed out twice.
    HandedTwice,
}

/// How far an open frame is, for the wait heuristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    pub version: StateVersion,
    pub back: u32,
    pub total: u32,
    /// When the scheduler queued it.
    pub scheduled_at: Instant,
    /// Its first hand-out: the start of its computation (paper §4.3).
    pub started_at: Option<Instant>,
}

#[derive(Debug)]
struct OpenFrame {
    state: Arc<SceneState>,
    /// Samples per pixel of each of its jobs.
    spp: u32,
    scheduled_at: Instant,
    started_at: Option<Instant>,
    /// Lost in a restart of the assembler: it accepts nothing and is skipped.
    lost: bool,
    back: u32,
    results: PackedFrame,
    /// Per set, the connection whose result was accepted.
    owners: Vec<Option<ConnId>>,
}

/// The frames scheduled and not yet displayed.
#[derive(Debug)]
pub struct FrameTable {
    sets: Arc<SetTables>,
    frames: BTreeMap<FrameNo, OpenFrame>,
    /// Frames up to and including this one were displayed.
    closed_upto: Option<FrameNo>,
}

impl FrameTable {
    pub fn new(sets: Arc<SetTables>) -> Self {
        Self { sets, frames: BTreeMap::new(), closed_upto: None }
    }

    /// The table after a restart: it still refuses frames displayed before, and the
    /// frames in flight keep their place and time but lose their results and accept
    /// none (their jobs' results count as unknown; the frames are skipped in turn).
    pub fn restarted(&self) -> Self {
        let frames = self
            .frames
            .iter()
            .map(|(f, o)| {
                let lost = OpenFrame {
                    state: o.state.clone(),
                    spp: o.spp,
                    scheduled_at: o.scheduled_at,
                    started_at: o.started_at,
                    lost: true,
                    back: 0,
                    results: PackedFrame::new(o.results.set_table().clone()),
                    owners: vec![None; o.owners.len()],
                };
                (*f, lost)
            })
            .collect();
        Self { sets: self.sets.clone(), frames, closed_upto: self.closed_upto }
    }

    /// The scheduler queued `frame` with `state`, `spp` samples per pixel per job, at `now`.
    pub fn open(&mut self, frame: FrameNo, state: Arc<SceneState>, spp: u32, now: Instant) {
        if self.is_closed(frame) {
            return;
        }
        let sets = self.sets.checked(state.resolution);
        let s = sets.sets() as usize;
        self.frames.entry(frame).or_insert(OpenFrame {
            state,
            spp,
            scheduled_at: now,
            started_at: None,
            lost: false,
            back: 0,
            results: PackedFrame::new(sets),
            owners: vec![None; s],
        });
    }

    /// The first job of `frame` was handed out at `now`.
    pub fn start(&mut self, frame: FrameNo, now: Instant) {
        if let Some(f) = self.frames.get_mut(&frame) {
            f.started_at.get_or_insert(now);
        }
    }

    /// Judges one result in time and, when accepted, keeps its radiance.
    pub fn accept(
        &mut self,
        conn: ConnId,
        frame: FrameNo,
        set: SetNo,
        radiance: PackedRadiance,
    ) -> Admission {
        if self.is_closed(frame) {
            return Admission::Late;
        }
        let Some(open) = self.frames.get_mut(&frame).filter(|f| !f.lost) else {
            return Admission::Unknown;
        };
        if open.results.contains(set) {
            return Admission::HandedTwice;
        }
        open.back += 1;
        let PackedRadiance::Rgb9e5(words) = radiance;
        open.results.insert(set, words);
        open.owners[set as usize] = Some(conn);
        Admission::Accepted { back: open.back, total: open.owners.len() as u32 }
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
        let open = self.frames.remove(&frame)?;
        Some(ClosedFrame {
            frame,
            state: open.state,
            spp: open.spp,
            results: open.results,
            total: open.owners.len() as u32,
            owners: open.owners,
            back: open.back,
        })
    }

    /// The oldest frame not yet displayed and how far it is.
    pub fn oldest(&self) -> Option<(FrameNo, Progress)> {
        self.frames.iter().next().map(|(f, o)| {
            let progress = Progress {
                version: o.state.version,
                back: o.back,
                total: o.owners.len() as u32,
                scheduled_at: o.scheduled_at,
                started_at: o.started_at,
            };
            (*f, progress)
        })
    }

    /// The newest frame in flight.
    pub fn newest(&self) -> Option<FrameNo> {
        self.frames.keys().next_back().copied()
    }

    /// Whether a frame after `frame` has results.
    pub fn later_has_results(&self, frame: FrameNo) -> bool {
        self.frames.range(frame + 1..).any(|(_, o)| o.back > 0)
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
    use crate::wire::packing::pack;
    use crate::wire::protocol::{Partition, SetsConfig};
    use glam::Vec3;

    fn table() -> FrameTable {
        let sets = SetTables::new(
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
    fn keeps_each_accepted_set_with_the_connection_that_sent_it() {
        let mut t = table();
        let now = Instant::now();
        t.open(0, state(3), 4, now);
        assert_eq!(t.accept(7, 0, 1, radiance(2.0)), Admission::Accepted { back: 1, total: 4 });
        assert_eq!(t.oldest().map(|(f, p)| (f, p.back, p.total, p.version)), Some((0, 1, 4, 3)));
        let closed = t.close(0).expect("open frame");
        assert_eq!((closed.back, closed.total, closed.spp), (1, 4, 4));
        assert_eq!(closed.owners, [None, Some(7), None, None]);
        let (radiance, mask) = closed.results.unpack();
        let covered: Vec<usize> = (0..64).filter(|p| mask[*p]).collect();
        assert_eq!(
            covered,
            t.sets
                .checked(Resolution { width: 8, height: 8 })
                .pixels(1)
                .unwrap()
                .iter()
                .map(|p| *p as usize)
                .collect::<Vec<_>>()
        );
        assert!(covered.iter().all(|p| radiance[*p] == Vec3::splat(2.0)));
    }

    #[test]
    fn a_second_result_for_one_set_means_it_was_handed_out_twice() {
        let mut t = table();
        t.open(0, state(3), 4, Instant::now());
        t.accept(7, 0, 1, radiance(2.0));
        assert_eq!(t.accept(8, 0, 1, radiance(3.0)), Admission::HandedTwice);
        assert_eq!(t.close(0).expect("open").owners[1], Some(7), "the first result stays");
    }

    #[test]
    fn a_frame_starts_at_its_first_hand_out() {
        let mut t = table();
        let (t0, t1) = (Instant::now(), Instant::now() + std::time::Duration::from_millis(5));
        t.open(0, state(1), 4, t0);
        assert_eq!(t.oldest().map(|(_, p)| p.started_at), Some(None));
        t.start(0, t1);
        t.start(0, t1 + std::time::Duration::from_millis(5));
        assert_eq!(t.oldest().map(|(_, p)| (p.scheduled_at, p.started_at)), Some((t0, Some(t1))));
    }

    #[test]
    fn results_for_displayed_frames_are_late_and_never_reach_an_image() {
        let mut t = table();
        let now = Instant::now();
        t.open(0, state(1), 4, now);
        t.open(1, state(1), 4, now);
        t.open(2, state(1), 4, now);
        assert_eq!(t.accept(1, 2, 0, radiance(1.0)), Admission::Accepted { back: 1, total: 4 });
        assert!(t.later_has_results(1) && !t.later_has_results(2));
        let closed = t.close(1).expect("frame 1");
        assert!(closed.results.unpack().1.iter().all(|m| !m));
        assert_eq!(t.accept(1, 0, 0, radiance(1.0)), Admission::Late, "passed-over frame");
        assert_eq!(t.accept(1, 1, 0, radiance(1.0)), Admission::Late);
        assert!(t.close(0).is_none() && t.close(1).is_none());
        t.open(1, state(1), 4, now);
        assert_eq!(t.open_frames(), 1, "a displayed frame was reopened");
        assert_eq!(t.accept(1, 5, 0, radiance(1.0)), Admission::Unknown, "never opened");
    }

    #[test]
    fn a_restart_keeps_the_displayed_boundary_and_loses_the_frames_in_flight() {
        let mut t = table();
        let now = Instant::now();
        t.open(3, state(1), 4, now);
        t.open(4, state(1), 4, now);
        t.accept(1, 4, 0, radiance(1.0));
        t.close(3);
        let mut r = t.restarted();
        r.open(2, state(1), 4, now);
        assert_eq!(r.oldest().map(|(f, p)| (f, p.back)), Some((4, 0)), "frame 4 kept, empty");
        assert_eq!(r.accept(1, 4, 1, radiance(1.0)), Admission::Unknown, "lost frames take none");
        r.open(5, state(1), 4, now);
        assert_eq!(r.accept(1, 5, 1, radiance(1.0)), Admission::Accepted { back: 1, total: 4 });
    }
}
