//! The job queue (paper §4.2): pure logic behind the scheduler actor.
//!
//! When fewer than `threshold` jobs are queued it adds all `S` jobs of a new frame with
//! the latest scene state; jobs of frames already displayed are discarded; jobs are
//! handed out front first. A job leaves the queue exactly once: nothing lost is ever
//! queued again (STYLE.md item 7). At most `max_frames_open` frames exist between the
//! display and the newest scheduled frame, so fast workers cannot run unboundedly ahead.
//!
//! Each frame's sets are queued in a rotated order ([`first_set`]): the display often shows
//! a frame before its last jobs return, and with one fixed order the same sets (and so the
//! same pixels) would be the ones missing in every frame, so accumulation would never fill
//! them while the view is static.
//!
//! Only a frame's `quota` of sets is queued (all S unless set): the jobs the display can use
//! (`handout_plan`). The frame window can be widened so that a large grid's credits can all
//! be served from frames in flight. Every job of a frame takes the samples per pixel the
//! queue had when the frame was opened (`job_size`): a frame's results are alike.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

use crate::scene::state::SceneState;
use crate::shared::job::Job;
use crate::wire::protocol::{FrameNo, SetNo};

/// A frame that was just added to the queue.
#[derive(Clone, Debug)]
pub struct NewFrame {
    pub frame: FrameNo,
    pub state: Arc<SceneState>,
    /// Samples per pixel of each of its jobs.
    pub spp: u32,
}

/// Frames × sets waiting to be handed out.
#[derive(Debug)]
pub struct JobQueue {
    sets: u32,
    /// Sets queued per frame, `1..=sets`.
    quota: u32,
    threshold: usize,
    /// Frames open at most, from the threshold; `window` may widen it.
    base_frames_open: u64,
    max_frames_open: u64,
    queue: VecDeque<Job>,
    /// Sets queued so far (quota and replacements), the state and the samples per pixel
    /// of every open frame.
    opened: BTreeMap<FrameNo, (u32, Arc<SceneState>, u32)>,
    /// Samples per pixel of the jobs of frames opened from now on.
    spp: u32,
    /// Number the next scheduled frame gets.
    next_frame: FrameNo,
    /// Frames below this were displayed (shown or skipped).
    first_open: FrameNo,
    state: Arc<SceneState>,
}

impl JobQueue {
    /// An empty queue; the first frame gets number `first_frame`.
    pub fn new(sets: u32, threshold: usize, state: Arc<SceneState>, first_frame: FrameNo) -> Self {
        let sets = sets.max(1);
        let threshold = threshold.max(1);
        // Enough frames to keep `threshold` jobs queued, plus the one on display.
        let max_frames_open = threshold.div_ceil(sets as usize) as u64 + 2;
        Self {
            sets,
            quota: sets,
            threshold,
            base_frames_open: max_frames_open,
            max_frames_open,
            queue: VecDeque::new(),
            opened: BTreeMap::new(),
            next_frame: first_frame,
            first_open: first_frame,
            spp: state.render.spp.max(1),
            state,
        }
    }

    /// Frames opened from now on take `spp` samples per pixel per job (at least 1).
    pub fn set_spp(&mut self, spp: u32) {
        self.spp = spp.max(1);
    }

    /// Samples per pixel of the jobs of the next frame opened.
    pub fn spp(&self) -> u32 {
        self.spp
    }

    /// New frames use `state` from now on; queued jobs keep the state they were made with
    /// until [`JobQueue::discard_outdated`].
    pub fn set_state(&mut self, state: Arc<SceneState>) {
        self.state = state;
    }

    /// Discards the queued jobs of frames made with an older state version than the
    /// current one: a view the user has left is not worth rendering (the paper discards
    /// stale jobs), and the new view's frames are queued behind them otherwise. Jobs
    /// already handed out are not recalled; nothing discarded is queued again. Returns
    /// how many were discarded.
    pub fn discard_outdated(&mut self) -> usize {
        let version = self.state.version;
        let before = self.queue.len();
        self.queue.retain(|j| j.state.version >= version);
        // Their frames get no more sets either (`queue_more`).
        self.opened.retain(|_, (_, state, _)| state.version >= version);
        before - self.queue.len()
    }

    /// Frames queued from now on get only `quota` of their sets (at least 1, at most S).
    pub fn set_quota(&mut self, quota: u32) {
        self.quota = quota.clamp(1, self.sets);
    }

    /// Lets up to `frames` frames be open at once (never fewer than the threshold needs).
    pub fn set_frame_window(&mut self, frames: u64) {
        self.max_frames_open = frames.max(self.base_frames_open);
    }

    /// The state new frames get.
    pub fn state(&self) -> &Arc<SceneState> {
        &self.state
    }

    /// Adds whole frames while fewer than `threshold` jobs are queued (and the frame
    /// window allows); returns the frames added.
    pub fn top_up(&mut self) -> Vec<NewFrame> {
        let mut added = Vec::new();
        while self.queue.len() < self.threshold {
            let Some(f) = self.open_frame() else { break };
            added.push(f);
        }
        added
    }

    /// Adds one frame whatever the threshold, if the frame window allows (a worker whose
    /// result would be late for every queued frame can be in time for a later one).
    pub fn open_frame(&mut self) -> Option<NewFrame> {
        if self.next_frame - self.first_open >= self.max_frames_open {
            return None;
        }
        let frame = self.next_frame;
        self.next_frame += 1;
        let (first, spp) = (first_set(frame, self.sets), self.spp);
        for i in 0..self.quota {
            let set = (first + i) % self.sets;
            self.queue.push_back(Job { frame, set, state: self.state.clone(), spp });
        }
        self.opened.insert(frame, (self.quota, self.state.clone(), spp));
        Some(NewFrame { frame, state: self.state.clone(), spp })
    }

    /// Queues up to `n` more sets of an open frame, ones never queued before (a worker left
    /// holding jobs of it: other sets take their place, the lost ones are never redone);
    /// returns how many were queued. A frame never gets more than S sets.
    pub fn queue_more(&mut self, frame: FrameNo, n: u32) -> u32 {
        let sets = self.sets;
        let Some((queued, state, spp)) = self.opened.get_mut(&frame) else { return 0 };
        let more = n.min(sets - *queued);
        let first = first_set(frame, sets);
        // Behind the frame's own jobs, before later frames'.
        let at = self.queue.iter().position(|j| j.frame > frame).unwrap_or(self.queue.len());
        for i in 0..more {
            let set = (first + *queued + i) % sets;
            let job = Job { frame, set, state: state.clone(), spp: *spp };
            self.queue.insert(at + i as usize, job);
        }
        *queued += more;
        more
    }

    /// Takes up to `n` jobs from the front.
    pub fn take(&mut self, n: usize) -> Vec<Job> {
        let n = n.min(self.queue.len());
        self.queue.drain(..n).collect()
    }

    /// The frames that have queued jobs, oldest first.
    pub fn frames(&self) -> Vec<FrameNo> {
        let mut frames: Vec<FrameNo> = self.queue.iter().map(|j| j.frame).collect();
        frames.dedup(); // jobs are queued frame after frame
        frames
    }

    /// Takes the first queued job of `frame`.
    pub fn take_from(&mut self, frame: FrameNo) -> Option<Job> {
        let i = self.queue.iter().position(|j| j.frame == frame)?;
        self.queue.remove(i)
    }

    /// `frame` was displayed (shown or skipped): its queued jobs and those of every
    /// earlier frame are discarded. Returns how many were dropped.
    pub fn frame_displayed(&mut self, frame: FrameNo) -> usize {
        self.first_open = self.first_open.max(frame + 1);
        self.opened.retain(|f, _| *f > frame);
        let before = self.queue.len();
        self.queue.retain(|j| j.frame > frame);
        before - self.queue.len()
    }

    /// Jobs waiting to be handed out.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// The number the next scheduled frame will get (frames are never renumbered,
    /// so a restarted scheduler continues from here).
    pub fn next_frame(&self) -> FrameNo {
        self.next_frame
    }

    /// The first frame not yet displayed.
    pub fn first_open(&self) -> FrameNo {
        self.first_open
    }
}

/// The set a frame's jobs start with: a Weyl sequence over the golden ratio, so that the
/// starts of consecutive frames spread evenly over all `sets` and every set is early in
/// some frames and late in others.
pub fn first_set(frame: FrameNo, sets: u32) -> SetNo {
    const PHI_FRACTION: f64 = 0.618_033_988_749_894_9;
    let t = (frame as f64 * PHI_FRACTION).fract();
    ((t * f64::from(sets)) as u32).min(sets.saturating_sub(1))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::scene::state::*;
    use glam::Vec3;
    use std::collections::HashMap;

    pub(crate) fn state(version: u64) -> Arc<SceneState> {
        let camera = Camera::pinhole(Vec3::Z, Vec3::ZERO, 45.0);
        let resolution = Resolution { width: 8, height: 8 };
        Arc::new(SceneState { version, seed: 1, ..SceneState::empty(resolution, camera) })
    }

    #[test]
    fn tops_up_whole_frames_below_the_threshold() {
        let mut q = JobQueue::new(4, 8, state(1), 0);
        let added = q.top_up();
        assert_eq!(added.iter().map(|f| f.frame).collect::<Vec<_>>(), vec![0, 1]);
        assert_eq!(q.queued(), 8);
        assert!(q.top_up().is_empty(), "added a frame at the threshold");
        q.take(1);
        assert_eq!(q.top_up().len(), 1, "one job below the threshold adds a whole frame");
        assert_eq!(q.queued(), 11);
    }

    #[test]
    fn never_more_than_s_jobs_per_frame() {
        let mut q = JobQueue::new(5, 10, state(1), 0);
        let mut per_frame: HashMap<FrameNo, Vec<SetNo>> = HashMap::new();
        for round in 0..50 {
            q.top_up();
            for j in q.take(3) {
                per_frame.entry(j.frame).or_default().push(j.set);
            }
            if round % 4 == 3 {
                let f = q.first_open();
                q.frame_displayed(f);
            }
        }
        for (frame, sets) in per_frame {
            let mut s = sets.clone();
            s.sort_unstable();
            s.dedup();
            assert_eq!(s.len(), sets.len(), "frame {frame} handed a set twice");
            assert!(sets.len() <= 5);
        }
    }

    #[test]
    fn every_set_is_among_the_first_half_of_some_frame_within_a_few_frames() {
        // Frames shown at Q = 0.5 get their first half of jobs back: over a few frames
        // every pixel must have had results, or accumulation leaves holes for ever.
        let sets = 64;
        let mut q = JobQueue::new(sets, sets as usize, state(1), 0);
        let mut seen = vec![false; sets as usize];
        for _ in 0..6 {
            q.top_up();
            let frame = q.take(sets as usize);
            assert!(frame.iter().all(|j| j.frame == frame[0].frame), "one whole frame");
            for j in &frame[..sets as usize / 2] {
                seen[j.set as usize] = true;
            }
            q.frame_displayed(frame[0].frame);
        }
        let missing: Vec<usize> = (0..seen.len()).filter(|&s| !seen[s]).collect();
        assert!(missing.is_empty(), "sets never early in 6 frames: {missing:?}");
        assert!((0..1000).all(|f| first_set(f, sets) < sets));
    }

    #[test]
    fn displayed_frames_are_discarded_and_new_state_used() {
        let mut q = JobQueue::new(2, 4, state(1), 10);
        q.top_up();
        assert_eq!(q.frame_displayed(10), 2);
        assert!(q.take(10).iter().all(|j| j.frame == 11));
        q.set_state(state(7));
        let added = q.top_up();
        assert!(added.iter().all(|f| f.state.version == 7 && f.frame >= 12));
    }

    #[test]
    fn a_new_state_discards_the_queued_jobs_of_older_versions_at_once() {
        let mut q = JobQueue::new(4, 8, state(1), 0);
        q.top_up();
        let held = q.take(3); // frame 0: three sets handed out, one still queued
        assert_eq!(q.queued(), 5);
        q.set_state(state(2));
        assert_eq!(q.discard_outdated(), 5, "every queued job of version 1 goes");
        assert_eq!(q.queued(), 0);
        // The new view's frames come next; the discarded sets are never queued again.
        let added = q.top_up();
        assert!(!added.is_empty() && added.iter().all(|f| f.state.version == 2 && f.frame >= 2));
        let jobs = q.take(100);
        assert!(jobs.iter().all(|j| j.state.version == 2 && j.frame >= 2));
        assert!(held.iter().all(|j| j.frame == 0));
        // Discarding again finds nothing: the current version's jobs stay.
        q.top_up();
        assert_eq!(q.discard_outdated(), 0);
        assert_eq!(q.queue_more(0, 1), 0, "a frame of the old state gets no more sets");
    }

    #[test]
    fn a_quota_queues_that_many_different_sets_of_each_frame() {
        let mut q = JobQueue::new(8, 8, state(1), 0);
        q.set_quota(3);
        q.top_up();
        assert_eq!(q.frames(), vec![0, 1, 2]);
        let first: Vec<Job> = (0..3).filter_map(|_| q.take_from(0)).collect();
        assert_eq!(first.len(), 3);
        assert!(q.take_from(0).is_none(), "a fourth set of frame 0 was queued");
        let mut sets: Vec<SetNo> = first.iter().map(|j| j.set).collect();
        sets.dedup();
        assert_eq!(sets.len(), 3);
        assert_eq!(q.take_from(2).map(|j| j.frame), Some(2), "a later frame can be served first");
        q.set_quota(99);
        assert_eq!(q.quota, 8, "never more than S");
    }

    #[test]
    fn sets_lost_with_a_worker_are_replaced_by_sets_never_queued() {
        let mut q = JobQueue::new(4, 4, state(1), 0);
        q.set_quota(2);
        q.top_up();
        let mut sets: Vec<SetNo> = (0..2).filter_map(|_| q.take_from(0)).map(|j| j.set).collect();
        assert_eq!(q.queue_more(0, 1), 1);
        let next = q.take(1);
        assert_eq!(next[0].frame, 0, "the replacement comes before later frames");
        assert_eq!(q.queue_more(0, 5), 1, "only S sets per frame");
        sets.extend(next.iter().map(|j| j.set));
        sets.extend(q.take_from(0).map(|j| j.set));
        sets.sort_unstable();
        assert_eq!(sets, vec![0, 1, 2, 3], "every set once");
        q.frame_displayed(0);
        assert_eq!(q.queue_more(0, 1), 0, "a displayed frame gets nothing");
    }

    #[test]
    fn every_job_of_a_frame_takes_the_samples_per_pixel_it_was_opened_with() {
        let mut q = JobQueue::new(4, 4, state(1), 0);
        q.set_quota(2);
        assert_eq!(q.spp(), 4, "the state's own samples per pixel at first");
        assert_eq!(
            q.top_up().iter().map(|f| (f.frame, f.spp)).collect::<Vec<_>>(),
            [(0, 4), (1, 4)]
        );
        q.set_spp(16);
        assert_eq!(q.open_frame().map(|f| (f.frame, f.spp)), Some((2, 16)));
        assert!(q.take_from(0).is_some_and(|j| j.spp == 4), "an open frame keeps its own");
        assert_eq!(q.queue_more(0, 1), 1);
        let jobs = q.take(100);
        assert_eq!(jobs.len(), 6);
        assert!(jobs.iter().all(|j| j.spp == if j.frame == 2 { 16 } else { 4 }));
        q.set_spp(0);
        assert_eq!(q.spp(), 1, "never less than one sample");
    }

    #[test]
    fn the_frame_window_widens_for_a_large_grid_but_never_narrows() {
        let mut q = JobQueue::new(2, 4, state(1), 0);
        q.set_frame_window(10);
        for _ in 0..100 {
            q.top_up();
            q.take(100);
        }
        assert_eq!(q.next_frame(), 10);
        q.set_frame_window(1);
        q.frame_displayed(9);
        for _ in 0..100 {
            q.top_up();
            q.take(100);
        }
        assert_eq!(q.next_frame() - q.first_open(), 4, "the threshold's window stays");
    }

    #[test]
    fn frame_window_bounds_how_far_the_queue_runs_ahead() {
        let mut q = JobQueue::new(2, 4, state(1), 0);
        // Workers drain everything but the display never moves.
        for _ in 0..100 {
            q.top_up();
            q.take(100);
        }
        assert!(q.next_frame() <= 4, "scheduled {} frames with none displayed", q.next_frame());
        q.frame_displayed(0);
        q.top_up();
        assert_eq!(q.next_frame(), 5);
    }
}
