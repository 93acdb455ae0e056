//! The render thread of one worker connection: turns jobs into packed results.
//!
//! Rendering is CPU-bound and long compared to I/O, so each connection has its own OS
//! thread that owns the render structures (`RenderScene`, its BVHs) and renders one job
//! at a time; the connection's async task only moves messages. The thread applies a new
//! scene state (`RenderScene::set_state`) when a job names a version it has not rendered
//! with yet, derives the job's pixels from the set number (pixel indices never travel),
//! renders them, packs the reflected radiance (not demodulated: the master divides by its
//! own G-buffer's albedo, `crate::master::compose`) as RGB9E5 and tags the result with the
//! connection's key (`gridlight_actors::integrity`).
//!
//! A job whose state is older than the newest one submitted is not rendered but answered
//! [`Answer::Superseded`] (a newer view came while it waited: its pixels would be stale,
//! and the new view's job would wait behind it); the link tells the master.
//!
//! The thread lowers its own priority first (`priority`: `SCHED_IDLE` by default), so
//! that the desk's owner never waits for it. When the worker pauses, jobs still queued
//! are discarded ([`RenderThread::discard_queued`]); the job being rendered finishes and
//! its result is dropped by the link.
//!
//! The null renderer (`--null-render`, for `gridlight bench master`) answers every job
//! with constant radiance at no cost, so a benchmark measures the master alone; without
//! a simulated delay it answers on the connection's task, with no thread at all. The
//! simulated renderer (`gridlight simgrid`, `crate::simgrid::renderer`) answers with cached
//! real pixels after a modelled render time, on a timer rather than a thread.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc as std_mpsc;
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::packing::encode_rgb9e5;
use gridlight_actors::protocol::{FrameNo, JobResult, PackedRadiance, SetNo, SetsConfig};
use gridlight_actors::state::SceneState;
use tokio::sync::mpsc;
use tracing::{debug, error, warn};

use super::cache::CacheView;
use super::priority::{self, Priority};
use super::shared::Shared;
use super::WorkerError;
use crate::render::{render_pixels, PixelSample, RenderScene};

/// Radiance the null renderer returns for every pixel of `frame`: grey, and different
/// for consecutive frames so that tests can tell which frame a pixel came from. Each
/// value (1 + k/256) is exact in RGB9E5.
pub fn null_radiance(frame: FrameNo) -> Vec3 {
    Vec3::splat(1.0 + (frame % 256) as f32 / 256.0)
}

/// Which renderer a worker runs.
#[derive(Clone, Debug)]
pub enum RendererKind {
    /// The path tracer (`crate::render`).
    PathTracer,
    /// Constant radiance ([`null_radiance`]) for benchmarking the master; `delay_ms`
    /// simulates render time for fault-injection tests (0 in benchmarks).
    Null { delay_ms: u32 },
    /// Cached path-traced pixels after a modelled render time (`crate::simgrid`).
    Simulated(Arc<crate::simgrid::SimGrid>),
    /// The GPU path tracer: every connection's jobs go to one device thread
    /// (`super::gpu`), which renders many at once.
    Gpu(Arc<super::gpu::GpuRenderer>),
}

/// One job with the scene state it names and the samples per pixel it asks for.
#[derive(Clone, Debug)]
pub struct RenderJob {
    pub frame: FrameNo,
    pub set: SetNo,
    pub state: Arc<SceneState>,
    pub spp: u32,
}

/// What the renderer says about one job.
#[derive(Debug)]
pub enum Answer {
    Rendered(JobResult),
    /// Not rendered: a job of a newer scene state was submitted before it started.
    Superseded {
        frame: FrameNo,
        set: SetNo,
    },
}

/// Handle to a connection's renderer: its render thread, or the null renderer itself.
///
/// The path tracer (and a null renderer with a delay) runs on its own thread; dropping
/// the handle ends the thread after its current job. The null renderer without delay
/// answers on the connection's task as the job is submitted: its work is nothing, so a
/// thread hand-off each way would be all its cost, and `gridlight bench master`, which
/// runs such workers beside the master, would measure that instead of the master.
pub struct RenderThread {
    inner: Inner,
}

enum Inner {
    /// Jobs go with the epoch they were queued in; the thread skips stale ones, and
    /// answers those older than `newest` (the newest state version submitted) superseded.
    Thread {
        jobs: std_mpsc::Sender<(u64, RenderJob)>,
        epoch: Arc<AtomicU64>,
        newest: Arc<AtomicU64>,
    },
    Inline {
        renderer: Box<Renderer>,
        results: mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    },
    Gpu {
        device: Arc<super::gpu::GpuRenderer>,
        link: Arc<super::gpu::ConnLink>,
    },
    Simulated {
        conn: Box<crate::simgrid::SimConnection>,
        table: Arc<gridlight_actors::sets::SetTable>,
        key: ResultKey,
        results: mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    },
}

impl RenderThread {
    /// Starts the renderer; results (or the error that ended it) go to `results`.
    #[allow(clippy::too_many_arguments)]
    pub fn spawn(
        name: &str,
        kind: RendererKind,
        priority: Priority,
        view: Option<CacheView>,
        shared: Arc<Shared>,
        sets: SetsConfig,
        key: ResultKey,
        results: mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    ) -> Result<Self, WorkerError> {
        if let RendererKind::Simulated(grid) = &kind {
            let res = grid.cache().resolution();
            let table = shared
                .set_table(res, sets)
                .map_err(|e| WorkerError::Protocol(format!("the master's sets: {e}")))?;
            let seed =
                name.bytes().fold(0u64, |h, b| h.wrapping_mul(31).wrapping_add(u64::from(b)));
            let conn = Box::new(crate::simgrid::SimConnection::new(Arc::clone(grid), seed));
            return Ok(Self { inner: Inner::Simulated { conn, table, key, results } });
        }
        if let RendererKind::Gpu(device) = &kind {
            let view = view.ok_or_else(|| WorkerError::Render("no asset view".into()))?;
            let link = Arc::new(super::gpu::ConnLink {
                view,
                shared,
                sets,
                key,
                results,
                epoch: Arc::new(AtomicU64::new(0)),
                newest: Arc::new(AtomicU64::new(0)),
            });
            return Ok(Self { inner: Inner::Gpu { device: Arc::clone(device), link } });
        }
        let inline = matches!(kind, RendererKind::Null { delay_ms: 0 });
        let mut renderer =
            Renderer { kind, view, shared, sets, key, scene: None, samples: Vec::new() };
        if inline {
            return Ok(Self { inner: Inner::Inline { renderer: Box::new(renderer), results } });
        }
        let (jobs, rx) = std_mpsc::channel::<(u64, RenderJob)>();
        let epoch = Arc::new(AtomicU64::new(0));
        let current = Arc::clone(&epoch);
        let newest = Arc::new(AtomicU64::new(0));
        let newest_seen = Arc::clone(&newest);
        std::thread::Builder::new()
            .name(format!("render {name}"))
            .spawn(move || {
                match priority::apply_to_current_thread(priority) {
                    Ok(applied) => debug!(%applied, "render thread priority"),
                    Err(e) => warn!(cause = %e, "render thread runs at normal priority"),
                }
                while let Ok((queued_in, job)) = rx.recv() {
                    if queued_in != current.load(Ordering::Acquire) {
                        continue; // held when the worker paused: lost, never rendered
                    }
                    if job.state.version < newest_seen.load(Ordering::Acquire) {
                        let (frame, set) = (job.frame, job.set);
                        if results.send(Ok(Answer::Superseded { frame, set })).is_err() {
                            break;
                        }
                        continue;
                    }
                    if !renderer.answer(&job, &results) {
                        break;
                    }
                }
            })
            .map_err(|e| WorkerError::Render(format!("cannot start a render thread: {e}")))?;
        Ok(Self { inner: Inner::Thread { jobs, epoch, newest } })
    }

    /// Drops every job queued and not yet started (the worker paused).
    pub fn discard_queued(&mut self) {
        match &mut self.inner {
            Inner::Thread { epoch, .. } => {
                epoch.fetch_add(1, Ordering::AcqRel);
            }
            Inner::Gpu { link, .. } => {
                link.epoch.fetch_add(1, Ordering::AcqRel);
            }
            Inner::Simulated { conn, .. } => conn.discard_queued(),
            Inner::Inline { .. } => {}
        }
    }

    /// Queues a job behind the ones already held (or answers it, for the inline renderer).
    pub fn submit(&mut self, job: RenderJob) -> Result<(), WorkerError> {
        match &mut self.inner {
            Inner::Thread { jobs, epoch, newest } => {
                newest.fetch_max(job.state.version, Ordering::AcqRel);
                jobs.send((epoch.load(Ordering::Acquire), job))
                    .map_err(|_| WorkerError::Render("the render thread ended".into()))
            }
            Inner::Inline { renderer, results } => {
                renderer.answer(&job, results);
                Ok(())
            }
            Inner::Gpu { device, link } => {
                link.newest.fetch_max(job.state.version, Ordering::AcqRel);
                let queued_in = link.epoch.load(Ordering::Acquire);
                device.submit(super::gpu::Queued { job, queued_in, link: Arc::clone(link) })
            }
            Inner::Simulated { conn, table, key, results } => {
                if table.resolution() != job.state.resolution {
                    return Err(WorkerError::Render(format!(
                        "the simulated grid's frames are {}×{}, the job's {}×{}",
                        table.resolution().width,
                        table.resolution().height,
                        job.state.resolution.width,
                        job.state.resolution.height
                    )));
                }
                conn.submit(&job, table, key, results)
            }
        }
    }
}

/// What the render thread owns.
struct Renderer {
    kind: RendererKind,
    /// Where the scene's assets are (path tracer only).
    view: Option<CacheView>,
    shared: Arc<Shared>,
    sets: SetsConfig,
    /// This connection's result key: every result leaves tagged (protocol integrity).
    key: ResultKey,
    /// Built on the first job, updated on each new state version.
    scene: Option<RenderScene>,
    /// Reused between jobs: no allocation per job once warm.
    samples: Vec<PixelSample>,
}

impl Renderer {
    /// Renders `job` and sends the result or the error; false when rendering cannot go
    /// on (an error, or nobody listening).
    fn answer(
        &mut self,
        job: &RenderJob,
        results: &mpsc::UnboundedSender<Result<Answer, WorkerError>>,
    ) -> bool {
        let result = self.render(job).map(Answer::Rendered);
        let failed = result.is_err();
        if let Err(err) = &result {
            error!(frame = job.frame, set = job.set, cause = %err, "render failed");
        }
        results.send(result).is_ok() && !failed
    }

    fn render(&mut self, job: &RenderJob) -> Result<JobResult, WorkerError> {
        let started = Instant::now();
        let res = job.state.resolution;
        let table = self.shared.set_table(res, self.sets).map_err(|e| {
            WorkerError::Protocol(format!("job (frame {}, set {}): {e}", job.frame, job.set))
        })?;
        let pixels = table.pixels(job.set).ok_or_else(|| {
            WorkerError::Protocol(format!(
                "job names set {} but a frame has {} sets",
                job.set, self.sets.sets
            ))
        })?;
        let radiance = match self.kind {
            RendererKind::Null { delay_ms } => {
                if delay_ms > 0 {
                    // The delay is a job of the state's samples per pixel: a job of more
                    // takes proportionally longer, as a renderer's would.
                    let scale = f64::from(job.spp) / f64::from(job.state.render.spp.max(1));
                    let delay = std::time::Duration::from_millis(delay_ms.into());
                    std::thread::sleep(delay.mul_f64(scale));
                }
                vec![encode_rgb9e5(null_radiance(job.frame)); pixels.len()]
            }
            RendererKind::Simulated(_) | RendererKind::Gpu(_) => {
                return Err(WorkerError::Render("this renderer has no render thread".into()))
            }
            RendererKind::PathTracer => {
                self.update_scene(&job.state)?;
                let scene = self
                    .scene
                    .as_mut()
                    .ok_or_else(|| WorkerError::Render("no render scene".into()))?;
                scene.set_spp(job.spp);
                render_pixels(scene, job.frame, pixels, &mut self.samples);
                // A NaN would be a renderer bug: refuse it here rather than send it.
                match gridlight_actors::packing::pack(
                    &self.samples.iter().map(|s| s.reflected).collect::<Vec<_>>(),
                ) {
                    Ok(PackedRadiance::Rgb9e5(v)) => v,
                    Err(e) => {
                        return Err(WorkerError::Render(format!(
                            "frame {} set {}: {e}",
                            job.frame, job.set
                        )))
                    }
                }
            }
        };
        // Tagged here, off the connection's async task; the tag's cost is not render time.
        let render_us = started.elapsed().as_micros() as u64;
        Ok(self.key.seal(
            job.frame,
            job.set,
            job.state.version,
            PackedRadiance::Rgb9e5(radiance),
            render_us,
        ))
    }

    /// Brings the render scene to `state`'s version (see [`bring_scene_to`]).
    fn update_scene(&mut self, state: &SceneState) -> Result<(), WorkerError> {
        bring_scene_to(&mut self.scene, self.view.as_ref(), &self.shared, state)
    }
}

/// Brings `scene` to `state`'s version, building or updating it as needed (the CPU render
/// threads and the GPU device thread alike).
pub(super) fn bring_scene_to(
    scene: &mut Option<RenderScene>,
    view: Option<&CacheView>,
    shared: &Shared,
    state: &SceneState,
) -> Result<(), WorkerError> {
    let stale = scene.as_ref().map(|s| s.state().version != state.version);
    match stale {
        None => {
            let view = view.ok_or_else(|| WorkerError::Render("no asset view".into()))?;
            let assets = shared.assets_for(view, state)?;
            debug!(version = state.version, "building the render scene");
            *scene = Some(
                RenderScene::new(assets, state).map_err(|e| WorkerError::Render(e.to_string()))?,
            );
        }
        Some(true) => {
            let current =
                scene.as_mut().ok_or_else(|| WorkerError::Render("no render scene".into()))?;
            if let Err(err) = current.set_state(state) {
                // New geometry or textures: load them and rebuild from scratch.
                debug!(version = state.version, cause = %err, "rebuilding the render scene");
                let view = view.ok_or_else(|| WorkerError::Render("no asset view".into()))?;
                let assets = shared.assets_for(view, state)?;
                *current = RenderScene::new(assets, state)
                    .map_err(|e| WorkerError::Render(e.to_string()))?;
            }
        }
        Some(false) => {}
    }
    Ok(())
}
