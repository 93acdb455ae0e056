//! A simulated worker's renderer: real cached pixels after a modelled render time.
//!
//! It stands in the render thread's seat (`worker::render`), so the link, the
//! protocol, the result tags and the master are the real ones. A job is answered with its
//! set's pixels of a cached frame ([`super::frames`]) once the modelled time
//! ([`super::cost`]) has passed; jobs of one connection run one after another, as on one
//! core, and no thread is used: each answer is a timer on the process's tokio runtime, so
//! hundreds of simulated workers fit in one process.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use gridlight_actors::integrity::ResultKey;
use gridlight_actors::protocol::PackedRadiance;
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::{SceneState, StateVersion};
use rand::SeedableRng;
use tokio::sync::mpsc;
use tokio::time::Instant;

use super::frames::{state_key, FrameCache, StateKey};
use crate::worker::render::{Answer, RenderJob};
use crate::worker::WorkerError;

/// What the simulated workers of one process share.
pub struct SimGrid {
    cache: FrameCache,
    /// The newest frame any of them was given a job of (drives the availability curve).
    newest_frame: AtomicU64,
    keys: Mutex<HashMap<StateVersion, StateKey>>,
}

impl std::fmt::Debug for SimGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimGrid")
            .field("states", &self.cache.len())
            .field("cost", &self.cache.cost)
            .finish()
    }
}

impl SimGrid {
    pub fn new(cache: FrameCache) -> Self {
        Self { cache, newest_frame: AtomicU64::new(0), keys: Mutex::new(HashMap::new()) }
    }

    /// The newest frame number seen in a job.
    pub fn newest_frame(&self) -> u64 {
        self.newest_frame.load(Ordering::Relaxed)
    }

    pub fn cache(&self) -> &FrameCache {
        &self.cache
    }

    /// The content key of `state`, computed once per version.
    fn key(&self, state: &SceneState) -> StateKey {
        let mut keys = self.keys.lock().unwrap_or_else(|p| p.into_inner());
        *keys.entry(state.version).or_insert_with(|| state_key(state))
    }
}

/// One simulated worker (one connection): a core that is busy until its last job ends.
pub struct SimConnection {
    grid: Arc<SimGrid>,
    busy_until: Instant,
    rng: rand::rngs::StdRng,
    /// Bumped when the worker pauses: answers still pending are then dropped.
    epoch: Arc<AtomicU64>,
    /// Jobs held and not yet answered, in the order the core takes them.
    held: Vec<Held>,
}

/// A job the simulated core holds: when it starts and ends, and whether it was superseded.
struct Held {
    frame: u64,
    set: u32,
    version: StateVersion,
    starts: Instant,
    ends: Instant,
    dropped: Arc<AtomicBool>,
}

impl SimConnection {
    /// A connection of `grid`; `seed` makes its job times reproducible.
    pub fn new(grid: Arc<SimGrid>, seed: u64) -> Self {
        Self {
            grid,
            busy_until: Instant::now(),
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            epoch: Arc::new(AtomicU64::new(0)),
            held: Vec::new(),
        }
    }

    /// Schedules `job`'s answer after the jobs already held and its modelled time.
    pub fn submit(
        &mut self,
        job: &RenderJob,
        table: &SetTable,
        key: &ResultKey,
        results: &mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    ) -> Result<(), WorkerError> {
        self.grid.newest_frame.fetch_max(job.frame, Ordering::Relaxed);
        self.supersede_older(job.state.version, results);
        let pixels = table.pixels(job.set).ok_or_else(|| {
            WorkerError::Protocol(format!("job names set {} of {}", job.set, table.sets()))
        })?;
        let frame =
            self.grid.cache.frame(&self.grid.key(&job.state), job.frame).ok_or_else(|| {
                WorkerError::Render(format!(
                    "scene state version {} is not in the simulated grid's frame cache \
                 (the run showed a view that was not rendered beforehand)",
                    job.state.version
                ))
            })?;
        if frame.len() != job.state.resolution.pixels() {
            return Err(WorkerError::Render(format!(
                "cached frames are {}×{}, the job's are {}×{}",
                self.grid.cache.width,
                self.grid.cache.height,
                job.state.resolution.width,
                job.state.resolution.height
            )));
        }
        let radiance: Vec<u32> = pixels.iter().map(|&p| frame[p as usize]).collect();
        let took = self.grid.cache.cost.job_time(pixels.len(), job.spp, &mut self.rng);
        let done = self.busy_until.max(Instant::now()) + took;
        self.busy_until = done;
        let result = key.seal(
            job.frame,
            job.set,
            job.state.version,
            PackedRadiance::Rgb9e5(radiance),
            took.as_micros() as u64,
        );
        let (epoch, queued_in) = (Arc::clone(&self.epoch), self.epoch.load(Ordering::Acquire));
        let dropped = Arc::new(AtomicBool::new(false));
        self.held.push(Held {
            frame: job.frame,
            set: job.set,
            version: job.state.version,
            starts: done - took,
            ends: done,
            dropped: Arc::clone(&dropped),
        });
        let results = results.clone();
        tokio::spawn(async move {
            tokio::time::sleep_until(done).await;
            if epoch.load(Ordering::Acquire) == queued_in && !dropped.load(Ordering::Acquire) {
                let _ = results.send(Ok(Answer::Rendered(result)));
            }
        });
        Ok(())
    }

    /// A job of `version` came: jobs of older versions held and not yet started are
    /// answered superseded and free the core, as a real worker's render thread does
    /// (their pixels would show a view the user has left).
    fn supersede_older(
        &mut self,
        version: StateVersion,
        results: &mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    ) {
        let now = Instant::now();
        self.held.retain(|h| h.ends > now);
        let mut kept = Vec::with_capacity(self.held.len());
        let mut busy_until = now;
        // Jobs come in version order, so the dropped ones are the last held: the kept ones
        // keep their times.
        for h in self.held.drain(..) {
            if h.version < version && h.starts > now {
                h.dropped.store(true, Ordering::Release);
                let _ = results.send(Ok(Answer::Superseded { frame: h.frame, set: h.set }));
            } else {
                busy_until = busy_until.max(h.ends);
                kept.push(h);
            }
        }
        self.busy_until = busy_until;
        self.held = kept;
    }

    /// The worker paused: every job it holds is lost, and its core is free.
    pub fn discard_queued(&mut self) {
        self.epoch.fetch_add(1, Ordering::AcqRel);
        self.busy_until = Instant::now();
        self.held.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes;
    use gridlight_actors::protocol::{Partition, SetsConfig};

    /// A grid with two views of an 8×8 Cornell box, jobs of 200 ms.
    fn grid() -> (Arc<SimGrid>, SceneState, SceneState, SetTable) {
        let (assets, mut state) = testscenes::cornell_box(8, 8);
        state.render.spp = 1;
        let mut moved = state.clone();
        moved.camera.position.x += 0.1;
        moved.version += 1;
        let cost = crate::simgrid::CostModel {
            samples_per_second: 16.0 / 0.2,
            spread: 0.0,
            spp: 1,
            jobs_measured: 2,
            time_scale: 1.0,
        };
        let mut cache = FrameCache::new(8, 8, cost);
        cache.add_state(&assets, &state, 1).expect("rendered");
        cache.add_state(&assets, &moved, 1).expect("rendered");
        let sets = SetsConfig { sets: 4, partition: Partition::QuasiRandom };
        let table = SetTable::new(state.resolution, sets).expect("sets");
        (Arc::new(SimGrid::new(cache)), state, moved, table)
    }

    #[tokio::test]
    async fn a_newer_views_job_supersedes_the_held_jobs_not_yet_started() {
        let (grid, old, new, table) = grid();
        let key = ResultKey::checksum(&[0; gridlight_actors::auth::NONCE_LEN]);
        let (tx, mut rx) = mpsc::unbounded_channel();
        let mut conn = SimConnection::new(grid, 1);
        let job = |frame, set, state: &SceneState| RenderJob {
            frame,
            set,
            state: Arc::new(state.clone()),
            spp: 1,
        };
        let t0 = Instant::now();
        conn.submit(&job(1, 0, &old), &table, &key, &tx).expect("held");
        conn.submit(&job(1, 1, &old), &table, &key, &tx).expect("held");
        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
        conn.submit(&job(2, 2, &new), &table, &key, &tx).expect("held");
        // The second old job had not started: answered at once, never rendered.
        match rx.recv().await {
            Some(Ok(Answer::Superseded { frame: 1, set: 1 })) => {}
            other => panic!("expected the held old job superseded, got {other:?}"),
        }
        // The job in progress finishes; the new view's job follows it, not the dropped one.
        let mut done = Vec::new();
        while done.len() < 2 {
            match rx.recv().await {
                Some(Ok(Answer::Rendered(r))) => done.push((r.set, t0.elapsed())),
                other => panic!("unexpected {other:?}"),
            }
        }
        assert_eq!(done.iter().map(|d| d.0).collect::<Vec<_>>(), [0, 2]);
        // Two jobs' time (400 ms), not three: timers are absolute, so a loaded machine
        // delays an answer but does not add the dropped job's 200 ms.
        let new_done = done[1].1.as_millis();
        assert!((400..550).contains(&new_done), "the new view's job ended at {new_done} ms");
    }
}
