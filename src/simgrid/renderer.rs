//! A simulated worker's renderer: real cached pixels after a modelled render time.
//!
//! It stands in the render thread's seat (`worker::render`), so the session, the
//! protocol, the result tags and the master are the real ones. A job is answered with its
//! set's pixels of a cached frame ([`super::frames`]) once the modelled time
//! ([`super::cost`]) has passed; jobs of one connection run one after another, as on one
//! core, and no thread is used: each answer is a timer on the process's tokio runtime, so
//! hundreds of simulated workers fit in one process.

use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
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
}

impl SimConnection {
    /// A connection of `grid`; `seed` makes its job times reproducible.
    pub fn new(grid: Arc<SimGrid>, seed: u64) -> Self {
        Self {
            grid,
            busy_until: Instant::now(),
            rng: rand::rngs::StdRng::seed_from_u64(seed),
            epoch: Arc::new(AtomicU64::new(0)),
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
        let pixels = table.pixels(job.set).ok_or_else(|| {
            WorkerError::Protocol(format!("job names set {} of {}", job.set, table.sets()))
        })?;
        let frame =
            self.grid.cache.frame(&self.grid.key(&job.state), job.frame).ok_or_else(|| {
                WorkerError::Render(format!(
                    "scene state version {} is not in the simulated grid's frame cache \
                 (the session showed a view that was not rendered beforehand)",
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
        let took = self.grid.cache.cost.job_time(pixels.len(), &mut self.rng);
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
        let results = results.clone();
        tokio::spawn(async move {
            tokio::time::sleep_until(done).await;
            if epoch.load(Ordering::Acquire) == queued_in {
                let _ = results.send(Ok(Answer::Rendered(result)));
            }
        });
        Ok(())
    }

    /// The worker paused: every job it holds is lost, and its core is free.
    pub fn discard_queued(&mut self) {
        self.epoch.fetch_add(1, Ordering::AcqRel);
        self.busy_until = Instant::now();
    }
}
