//! A GPU worker's device: one thread that renders the jobs of all of the worker's
//! connections with the GPU path tracer (`render::gpu`), many at once.
//!
//! Each connection is one worker to the master, holding its `k` jobs, exactly as a CPU
//! worker's render threads are (paper §4.4): the master's scheduler hands out each job
//! once and drops late results as for anyone. What differs is behind the connections:
//! their jobs all go to this thread, which takes every job queued when it becomes free and
//! renders those of one scene state in a single dispatch (each job's pixels seeded by its
//! own frame), so the device stays full while the next jobs arrive. How many connections
//! a GPU worker opens, and so how many jobs it holds, follows its measured speed
//! ([`connections_for`]).
//!
//! Results are the CPU worker's: reflected radiance of the set's pixels in set order,
//! packed RGB9E5 and tagged with the connection's key; a job whose state is older than
//! its connection's newest is answered `Superseded`; jobs queued before a pause are lost.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc as std_mpsc;
use std::sync::Arc;
use std::time::Instant;

use gridlight_actors::integrity::ResultKey;
use gridlight_actors::protocol::{JobResult, SetsConfig};
use tokio::sync::mpsc;
use tracing::{debug, error, info};

use super::cache::CacheView;
use super::render::{bring_scene_to, Answer, RenderJob};
use super::shared::Shared;
use super::WorkerError;
use crate::render::gpu::{GpuScene, GpuTracer, PixelBatch};
use crate::render::{PixelSample, RenderScene, Strategy};

/// Most jobs rendered in one dispatch.
const MAX_BATCH_JOBS: usize = 256;
/// Device time one batch should take: long enough to amortise a dispatch and its
/// read-back, short enough that results come back within a frame or two.
const BATCH_SECONDS: f64 = 0.05;
/// Samples of the job size a master uses by default (640×480 in 64 sets, 4 spp), for
/// sizing before any job has been seen.
const DEFAULT_JOB_SAMPLES: f64 = 640.0 * 480.0 / 64.0 * 4.0;
/// Most connections a GPU worker opens.
pub const MAX_CONNECTIONS: usize = 32;

/// What a connection tells the device thread with each job.
pub(super) struct ConnLink {
    pub view: CacheView,
    pub shared: Arc<Shared>,
    pub sets: SetsConfig,
    pub key: ResultKey,
    pub results: mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    /// Bumped when the worker pauses: jobs queued before are lost.
    pub epoch: Arc<AtomicU64>,
    /// The newest state version submitted on this connection.
    pub newest: Arc<AtomicU64>,
}

/// A job on its way to the device thread.
pub(super) struct Queued {
    pub job: RenderJob,
    pub queued_in: u64,
    pub link: Arc<ConnLink>,
}

/// The device thread's handle, shared by all connections of a GPU worker.
#[derive(Debug)]
pub struct GpuRenderer {
    jobs: std_mpsc::Sender<Queued>,
    adapter: String,
}

impl std::fmt::Debug for Queued {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Queued(frame {}, set {})", self.job.frame, self.job.set)
    }
}

impl GpuRenderer {
    /// Starts the device thread.
    pub fn start(tracer: GpuTracer) -> Result<Arc<Self>, WorkerError> {
        let adapter = tracer.adapter().to_string();
        let (jobs, rx) = std_mpsc::channel();
        std::thread::Builder::new()
            .name("render gpu".into())
            .spawn(move || run(tracer, rx))
            .map_err(|e| WorkerError::Render(format!("cannot start the GPU thread: {e}")))?;
        Ok(Arc::new(Self { jobs, adapter }))
    }

    /// The adapter's name.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    pub(super) fn submit(&self, queued: Queued) -> Result<(), WorkerError> {
        self.jobs.send(queued).map_err(|_| WorkerError::Render("the GPU thread ended".into()))
    }
}

/// Connections (of `pipeline` jobs each) that keep a device of `samples_per_second` full:
/// two batches of [`BATCH_SECONDS`] of default-sized jobs, one rendering while the next
/// arrives, at least one connection and at most [`MAX_CONNECTIONS`].
pub fn connections_for(samples_per_second: f64, pipeline: u32) -> usize {
    let jobs = (2.0 * samples_per_second * BATCH_SECONDS / DEFAULT_JOB_SAMPLES).ceil();
    let jobs = if jobs.is_finite() { jobs.max(1.0) as usize } else { 1 };
    jobs.div_ceil(pipeline.max(1) as usize).clamp(1, MAX_CONNECTIONS)
}

/// Measures the tracer's samples per second on the built-in Cornell box (160×120, 4 spp),
/// after a first dispatch that compiles the pass.
pub fn calibrate(tracer: &GpuTracer) -> Result<f64, WorkerError> {
    let (assets, mut state) = crate::render::testscenes::cornell_box(160, 120);
    state.render.spp = 4;
    let scene = RenderScene::new(assets, &state).map_err(|e| WorkerError::Render(e.to_string()))?;
    let uploaded = tracer.upload(&scene).map_err(|e| WorkerError::Render(e.to_string()))?;
    let pixels: Vec<u32> = (0..160 * 120).collect();
    let mut out = Vec::new();
    let batch = [PixelBatch { frame: 0, pixels: &pixels }];
    let gpu = |e: crate::gpu::GpuError| WorkerError::Render(e.to_string());
    tracer.render(&uploaded, &batch, Strategy::NeeMis, &mut out).map_err(gpu)?;
    let start = Instant::now();
    let stats = tracer.render(&uploaded, &batch, Strategy::NeeMis, &mut out).map_err(gpu)?;
    let rate = stats.samples as f64 / start.elapsed().as_secs_f64().max(1e-9);
    info!(adapter = tracer.adapter(), samples_per_second = rate as u64, "GPU calibrated");
    Ok(rate)
}

/// The device thread: batches until every connection's handle is gone.
fn run(tracer: GpuTracer, rx: std_mpsc::Receiver<Queued>) {
    let mut scene: Option<RenderScene> = None;
    let mut uploaded: Option<GpuScene> = None;
    let mut samples = Vec::new();
    while let Ok(first) = rx.recv() {
        let mut batch = vec![first];
        while batch.len() < MAX_BATCH_JOBS {
            match rx.try_recv() {
                Ok(q) => batch.push(q),
                Err(_) => break,
            }
        }
        batch.retain(live);
        while !batch.is_empty() {
            // One scene state and samples per pixel per dispatch, the first job's; the
            // others wait their turn.
            let (version, spp) = (batch[0].job.state.version, batch[0].job.spp);
            let (group, rest): (Vec<Queued>, Vec<Queued>) =
                batch.into_iter().partition(|q| q.job.state.version == version && q.job.spp == spp);
            batch = rest;
            if let Err(err) = render_group(&tracer, &group, &mut scene, &mut uploaded, &mut samples)
            {
                error!(version, cause = %err, "GPU render failed");
                scene = None;
                uploaded = None;
                for q in &group {
                    let _ = q.link.results.send(Err(WorkerError::Render(err.to_string())));
                }
            }
        }
    }
    debug!("GPU thread ends");
}

/// Whether a queued job is still to be rendered: not lost to a pause, and not superseded
/// (then its connection is told so).
fn live(q: &Queued) -> bool {
    if q.queued_in != q.link.epoch.load(Ordering::Acquire) {
        return false;
    }
    if q.job.state.version < q.link.newest.load(Ordering::Acquire) {
        let (frame, set) = (q.job.frame, q.job.set);
        let _ = q.link.results.send(Ok(Answer::Superseded { frame, set }));
        return false;
    }
    true
}

fn render_group(
    tracer: &GpuTracer,
    group: &[Queued],
    scene: &mut Option<RenderScene>,
    uploaded: &mut Option<GpuScene>,
    samples: &mut Vec<PixelSample>,
) -> Result<(), WorkerError> {
    let started = Instant::now();
    let first = &group[0];
    let state = &first.job.state;
    bring_scene_to(scene, Some(&first.link.view), &first.link.shared, state)?;
    let scene = scene.as_ref().ok_or_else(|| WorkerError::Render("no render scene".into()))?;
    if uploaded.as_ref().is_none_or(|u| u.version() != state.version) {
        *uploaded = Some(tracer.upload(scene).map_err(|e| WorkerError::Render(e.to_string()))?);
    }
    let uploaded = uploaded.as_mut().ok_or_else(|| WorkerError::Render("no GPU scene".into()))?;
    uploaded.set_spp(first.job.spp);
    let mut tables = Vec::with_capacity(group.len());
    for q in group {
        let table = q.link.shared.set_table(state.resolution, q.link.sets).map_err(|e| {
            WorkerError::Protocol(format!("job (frame {}, set {}): {e}", q.job.frame, q.job.set))
        })?;
        tables.push(table);
    }
    let mut batches = Vec::with_capacity(group.len());
    for (q, table) in group.iter().zip(&tables) {
        let pixels = table.pixels(q.job.set).ok_or_else(|| {
            WorkerError::Protocol(format!(
                "job names set {} but a frame has {} sets",
                q.job.set, q.link.sets.sets
            ))
        })?;
        batches.push(PixelBatch { frame: q.job.frame, pixels });
    }
    tracer
        .render(uploaded, &batches, Strategy::NeeMis, samples)
        .map_err(|e| WorkerError::Render(e.to_string()))?;
    let render_us = started.elapsed().as_micros() as u64;
    debug!(jobs = group.len(), pixels = samples.len(), render_us, "GPU batch rendered");
    let mut at = 0;
    for (q, b) in group.iter().zip(&batches) {
        let part = &samples[at..at + b.pixels.len()];
        at += b.pixels.len();
        let result = seal(q, part, render_us);
        let _ = q.link.results.send(result.map(Answer::Rendered));
    }
    Ok(())
}

/// Packs a job's reflected radiance and tags it with its connection's key.
fn seal(q: &Queued, part: &[PixelSample], render_us: u64) -> Result<JobResult, WorkerError> {
    let reflected: Vec<_> = part.iter().map(|s| s.reflected).collect();
    // A NaN would be a renderer bug: refused here rather than sent (as on the CPU).
    let radiance = gridlight_actors::packing::pack(&reflected).map_err(|e| {
        WorkerError::Render(format!("frame {} set {}: {e}", q.job.frame, q.job.set))
    })?;
    Ok(q.link.key.seal(q.job.frame, q.job.set, q.job.state.version, radiance, render_us))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn connections_follow_the_measured_speed() {
        // A slow device (lavapipe, ~1 M samples/s) holds a few jobs, a fast one many.
        assert_eq!(connections_for(1e6, 2), 3);
        assert_eq!(connections_for(0.0, 2), 1);
        assert_eq!(connections_for(f64::NAN, 2), 1);
        assert!(connections_for(2e7, 2) > connections_for(4e6, 2));
        assert_eq!(connections_for(1e12, 2), MAX_CONNECTIONS);
    }
}
