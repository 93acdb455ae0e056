//! One run of the real master with a simulated grid (`crate::simgrid`): the
//! experiments of `eval paper` are runs with different grids, pacings and views.
//!
//! [`Prepared`] measures the scene's cost and renders the frame cache once (written to a
//! file the simulated-worker processes load); [`run`] starts the master in this
//! process with a sink that records every shown frame (and, for Figure 8, keeps it to be
//! composed after the run and measured against a gold standard), starts the grid as
//! `gridlight simgrid` child processes (a few of them, each holding many connections; on
//! a `tools::lan` testbed, on its worker hosts), plays the camera path if any (at its
//! recorded times, or one edit per shown frame), and returns per-frame records and the
//! useful fraction of the returned results.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use glam::Vec3;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::edit::{CameraEdit, Edit};
use gridlight_actors::master::{self, MasterConfig, Pacing, ShownFrame, SinkError};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sets::SetTable;
use gridlight_actors::sink::FrameSink;
use gridlight_actors::state::SceneState;
use gridlight_actors::stats::useful_fraction;
use serde::Serialize;

use crate::assets::Assets;
use crate::children::Children;
use crate::gpu::Backend;
use crate::master::compose::Composer;
use crate::master::view::View;
use crate::reconstruct::ReconstructParams;
use crate::render::RenderScene;
use crate::simgrid::{Availability, CostModel, FrameCache};
use crate::tools::eval::{flip, hdr_flip::hdr_flip};
use crate::tools::lan::{netns, Testbed};

/// Sets of the jobs timed to measure a scene's cost.
const MEASURE_SETS: u32 = 64;
/// Jobs timed to measure a scene's cost (in `CostModel::measure`'s rounds).
const COST_JOBS: u32 = 40;
/// Simulated workers per child process at most.
const WORKERS_PER_PROCESS: u32 = 128;
/// Longest wait for the grid to connect and the first frames to show.
const WARMUP_TIMEOUT: Duration = Duration::from_secs(60);

/// A scene with its cost model and frame cache on disk.
pub struct Prepared {
    pub name: String,
    pub assets: Arc<Assets>,
    pub state: SceneState,
    pub cost: CostModel,
    pub cache_file: PathBuf,
    pub sets: u32,
}

impl Prepared {
    /// Measures `state`'s cost on this machine (one core, the master's default sets).
    pub fn measure(assets: &Arc<Assets>, state: &SceneState) -> anyhow::Result<CostModel> {
        // Timed on the master's default sets: jobs large enough to time one by one.
        let table = SetTable::new(
            state.resolution,
            SetsConfig { sets: MEASURE_SETS, partition: Partition::QuasiRandom },
        )
        .context("pixel sets")?;
        let scene = RenderScene::new(Arc::clone(assets), state).context("render scene")?;
        Ok(CostModel::measure(&scene, &table, COST_JOBS))
    }

    /// Caches `frames` frames of `state` and `path_frames` of each state along `path`,
    /// with `cost` (measured by [`Prepared::measure`]) timed as `timing` says.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: &str,
        assets: Arc<Assets>,
        state: SceneState,
        sets: u32,
        frames: u32,
        path: &[(Duration, Edit)],
        path_frames: u32,
        dir: &Path,
        timing: Timing,
        mut cost: CostModel,
    ) -> anyhow::Result<Self> {
        cost.time_scale = timing.time_scale(state.resolution.pixels(), cost.samples_per_second);
        let (w, h) = (state.resolution.width, state.resolution.height);
        let mut cache = FrameCache::new(w, h, cost);
        cache.add_state(&assets, &state, frames)?;
        let mut s = state.clone();
        for (_, edit) in path {
            gridlight_actors::edit::apply(&mut s, edit).context("applying the camera path")?;
            cache.add_state(&assets, &s, path_frames)?;
        }
        let cache_file = dir.join(format!("{name}-{w}x{h}.simgrid"));
        cache.save(&cache_file)?;
        Ok(Self { name: name.to_string(), assets, state, cost, cache_file, sets })
    }

    /// Mean modelled time of one job (one set).
    pub fn job_time(&self) -> Duration {
        self.cost.mean_job_time(self.state.resolution.pixels() / self.sets as usize)
    }

    /// Frames per second one worker renders (all S jobs of a frame).
    pub fn frames_per_worker_second(&self) -> f64 {
        1.0 / (self.job_time().as_secs_f64() * f64::from(self.sets))
    }
}

/// How the simulated cores are timed.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Timing {
    /// Jobs are timed as jobs of a frame of this many pixels (the paper's 640×480), while
    /// their pixels come from the smaller cached frame: each cached pixel stands for
    /// `paper_pixels / pixels` of them.
    pub paper_pixels: usize,
    /// Modelled cores render this many samples per second on the Cornell box; `None`:
    /// this machine's measured speed.
    pub core_samples_per_second: Option<f64>,
    /// This machine's measured samples per second on the Cornell box, the reference
    /// that makes other scenes' costs relative; `None`: the scene being prepared is it.
    pub reference_samples_per_second: Option<f64>,
}

impl Timing {
    /// The cost model's time scale for a frame of `pixels` pixels whose scene renders
    /// `measured` samples per second here.
    fn time_scale(&self, pixels: usize, measured: f64) -> f64 {
        let size = self.paper_pixels as f64 / pixels.max(1) as f64;
        let reference = self.reference_samples_per_second.unwrap_or(measured);
        let speed = self.core_samples_per_second.map_or(1.0, |target| target / reference);
        size / speed
    }
}

/// One run.
#[derive(Clone, Debug)]
pub struct Run {
    pub availability: Availability,
    pub pacing: Pacing,
    /// Measured time after the warm-up (a camera path plays from its start).
    pub seconds: f64,
    pub path: Vec<(Duration, Edit)>,
    /// How the camera path is played.
    pub path_pacing: PathPacing,
    /// Jobs a worker holds (k).
    pub pipeline: u32,
    /// Hosts of a network testbed (`tools::lan`): the master on one, the grid's processes
    /// on the others, every link rate-limited; `None`: loopback.
    pub network: Option<Arc<Testbed>>,
    /// Compose each shown frame and measure FLIP to this linear image (Figure 8). The
    /// frames are kept during the run and composed after it, so that reconstruction
    /// on this machine's CPU neither slows the display nor takes the cores the grid's
    /// simulation runs on (the paper reconstructed on the master's GPU).
    pub gold: Option<Arc<Vec<Vec3>>>,
}

/// How a run plays its camera path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathPacing {
    /// Each edit at its recorded time, whatever the display shows.
    Timed,
    /// As the paper's interactive sequences: the view holds until the path's first edit
    /// is due, then the next edit is made as soon as a frame of the newest view is shown,
    /// so that each view gets one whole frame period on the grid. Every edit discards the
    /// older view's queued jobs (the master's default, for edit-to-display latency).
    PerFrame,
    /// As the paper renders its sequences (§4.3, §6.1): each frame keeps the scene state
    /// it was scheduled with, since a job carries its absolute state, and only jobs of
    /// frames already shown are discarded; the next edit is made as soon as any frame is
    /// shown, so consecutive frames carry consecutive cameras and every frame has its
    /// period on the grid.
    Sequence,
}

/// One shown frame.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRecord {
    pub frame: u64,
    /// Seconds since every worker of the grid had connected.
    pub t: f64,
    /// Shown inside the measured interval (after the warm-up).
    pub measured: bool,
    pub q: f64,
    pub workers: u64,
    pub paused_workers: u64,
    /// The scene-state version the frame was rendered with.
    pub version: u64,
    /// Whether that was the newest state when the frame was shown (false: an edit had
    /// outdated it, and the display showed it without waiting).
    pub current: bool,
    /// Results of this frame that came back in time (its Q_t × S).
    pub jobs_back: u32,
    /// Samples per pixel of each of them (the scheduler sizes jobs to the grid).
    pub spp: u32,
    /// FLIP to the gold standard, when one was given.
    pub flip: Option<f64>,
    /// HDR-FLIP of the linear image to the gold standard, for some of those frames
    /// ([`HDR_POINTS`] per run).
    pub hdr_flip: Option<f64>,
}

/// What a run measured.
#[derive(Clone, Debug, Serialize)]
pub struct Outcome {
    /// Frames of the measured interval.
    pub frames: Vec<FrameRecord>,
    /// Every frame shown once the grid had connected, warm-up included.
    pub all_frames: Vec<FrameRecord>,
    pub frames_per_second: f64,
    pub mean_q: f64,
    /// Results used in shown frames ÷ results judged (used, unused or late).
    pub useful_fraction: f64,
    pub results_used: u64,
    /// Results that came back: used, accepted into frames not shown, or late.
    pub results_returned: u64,
    pub dropped_late: u64,
    pub frames_skipped: u64,
    pub seconds: f64,
    /// Bytes into and out of the master's host over its link, on a testbed.
    pub link_rx_bytes: Option<u64>,
    pub link_tx_bytes: Option<u64>,
}

/// Runs `run` on `prepared`'s scene; `exe` is the `gridlight` binary.
pub fn run(exe: &Path, prepared: &Prepared, run: &Run) -> anyhow::Result<Outcome> {
    let listen = match &run.network {
        Some(bed) => SocketAddr::new(bed.master().address.into(), 0),
        None => SocketAddr::from(([127, 0, 0, 1], 0)),
    };
    let mut config = MasterConfig::new(
        listen,
        SetsConfig { sets: prepared.sets, partition: Partition::QuasiRandom },
    );
    config.pacing = run.pacing;
    config.pipeline = run.pipeline.max(1);
    config.discard_stale_jobs = run.path_pacing != PathPacing::Sequence;
    let peak = run.availability.peak();
    config.max_connections = config.max_connections.max(peak as usize + 8);
    let records = Arc::new(Mutex::new(Vec::new()));
    let kept = Arc::new(Mutex::new(Vec::new()));
    let clock = Arc::new(Mutex::new(Clock::default()));
    let newest = Arc::new(AtomicU64::new(prepared.state.version));
    let (shown_tx, shown_rx) = mpsc::channel();
    let sink = RecordingSink {
        records: Arc::clone(&records),
        kept: run.gold.as_ref().map(|_| Arc::clone(&kept)),
        clock: Arc::clone(&clock),
        newest: Arc::clone(&newest),
        shown: shown_tx,
    };
    let start = || master::start(config, prepared.state.clone(), AssetStore::new(), Box::new(sink));
    let handle = match &run.network {
        // The master's threads inherit the namespace of the thread that starts them.
        Some(bed) => netns::run_in(&bed.master().namespace, start)
            .context("entering the master's network namespace")?,
        None => start(),
    }
    .context("starting the master")?;
    let _grid = spawn_grid(exe, handle.local_addr(), prepared, run)?;

    let deadline = Instant::now() + WARMUP_TIMEOUT;
    let want = u64::from(run.availability.at(0).min(peak));
    while handle.worker_counts().live < want {
        if Instant::now() >= deadline {
            bail!("only {} of {want} simulated workers connected", handle.worker_counts().live);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if run.gold.is_some() {
        // Converging starts when the grid is there: an edit that changes nothing but the
        // version restarts the display's accumulation (the cached frames are found by
        // content, so the workers answer it as before).
        let v = handle.edit(Edit::Camera(CameraEdit::default())).context("restarting the view")?;
        newest.fetch_max(v, Ordering::AcqRel);
    }
    clock.lock().unwrap_or_else(|p| p.into_inner()).connected = Some(Instant::now());
    if !handle.wait_for_frames(handle.report().shown + 2, WARMUP_TIMEOUT) {
        bail!("no frames shown with {want} simulated workers");
    }
    let link = |bed: &Arc<Testbed>| bed.counters(bed.master()).ok();
    let link_before = run.network.as_ref().and_then(link);
    let before = Sample::take(&handle);
    clock.lock().unwrap_or_else(|p| p.into_inner()).measuring = true;
    match run.path_pacing {
        PathPacing::Timed => {
            if !run.path.is_empty() {
                handle.play_script(run.path.clone());
            }
            std::thread::sleep(Duration::from_secs_f64(run.seconds));
        }
        PathPacing::PerFrame | PathPacing::Sequence => {
            // Frames shown during the warm-up are not the path's.
            while shown_rx.try_recv().is_ok() {}
            let newest_only = run.path_pacing == PathPacing::PerFrame;
            play_per_frame(&handle, &run.path, run.seconds, &shown_rx, &newest, newest_only)?;
        }
    }
    let after = Sample::take(&handle);
    let link_after = run.network.as_ref().and_then(link);
    clock.lock().unwrap_or_else(|p| p.into_inner()).measuring = false;
    drop(_grid);
    handle.stop().context("stopping the master")?;

    let mut all_frames: Vec<FrameRecord> =
        std::mem::take(&mut *records.lock().unwrap_or_else(|p| p.into_inner()));
    if let Some(gold) = &run.gold {
        let kept = std::mem::take(&mut *kept.lock().unwrap_or_else(|p| p.into_inner()));
        measure_flip(prepared, gold, &kept, &mut all_frames)?;
    }
    let frames: Vec<FrameRecord> = all_frames.iter().filter(|f| f.measured).cloned().collect();
    let seconds = after.at.duration_since(before.at).as_secs_f64();
    let (used, unused, late) =
        (after.used - before.used, after.unused - before.unused, after.late - before.late);
    Ok(Outcome {
        frames_per_second: frames.len() as f64 / seconds,
        mean_q: mean(frames.iter().map(|f| f.q)),
        frames,
        all_frames,
        useful_fraction: useful_fraction(used, used + unused, late).unwrap_or(0.0),
        results_used: used,
        results_returned: used + unused + late,
        dropped_late: late,
        frames_skipped: after.skipped - before.skipped,
        seconds,
        link_rx_bytes: link_before.zip(link_after).map(|(b, a)| a.rx_bytes - b.rx_bytes),
        link_tx_bytes: link_before.zip(link_after).map(|(b, a)| a.tx_bytes - b.tx_bytes),
    })
}

/// Plays `path` one edit per shown frame, from the path's first edit time on, for
/// `seconds` in all: per frame of the newest view when `newest_only`
/// ([`PathPacing::PerFrame`]), else per frame of any view ([`PathPacing::Sequence`]).
fn play_per_frame(
    handle: &master::MasterHandle,
    path: &[(Duration, Edit)],
    seconds: f64,
    shown: &mpsc::Receiver<u64>,
    newest: &AtomicU64,
    newest_only: bool,
) -> anyhow::Result<()> {
    let started = Instant::now();
    let end = started + Duration::from_secs_f64(seconds);
    let hold = path.first().map_or(Duration::ZERO, |(at, _)| *at);
    std::thread::sleep(hold.min(end.saturating_duration_since(started)));
    let mut edits = path.iter().map(|(_, e)| e);
    let mut next = edits.next();
    while let Some(edit) = next {
        // A frame shown before this edit does not answer it.
        while shown.try_recv().is_ok() {}
        let version = handle.edit(edit.clone()).context("editing the camera")?;
        newest.fetch_max(version, Ordering::AcqRel);
        next = edits.next();
        // Wait for a frame of this view (frames of older views are shown without waiting),
        // or for any frame in a sequence.
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match shown.recv_timeout(left) {
                Ok(v) if v >= version || !newest_only => break,
                Ok(_) => continue,
                Err(_) => return Ok(()),
            }
        }
    }
    std::thread::sleep(end.saturating_duration_since(Instant::now()));
    Ok(())
}

/// Frames per run whose HDR-FLIP is measured (it costs one LDR-FLIP per exposure).
pub const HDR_POINTS: usize = 24;

/// Composes the kept frames in order, as the display would have, and sets each record's
/// FLIP to `gold` (and HDR-FLIP for [`HDR_POINTS`] of them, evenly spaced, the last
/// included).
fn measure_flip(
    prepared: &Prepared,
    gold: &[Vec3],
    kept: &[ShownFrame],
    records: &mut [FrameRecord],
) -> anyhow::Result<()> {
    let mut composer = Composer::new(
        Arc::clone(&prepared.assets),
        &prepared.state,
        ReconstructParams::default(),
        Backend::Cpu,
    )
    .context("preparing reconstruction")?;
    let every = kept.len().div_ceil(HDR_POINTS).max(1);
    for (i, frame) in kept.iter().enumerate() {
        let composed = composer.compose(frame, View::Final).context("composing a shown frame")?;
        let Some(r) = records.iter_mut().find(|r| r.frame == frame.frame) else { continue };
        let linear = composed.image.into_host()?.1.unwrap_or_default();
        let (w, h) = (frame.state.resolution.width, frame.state.resolution.height);
        r.flip = Some(super::super::compare(gold, &linear, w, h, 0.0).flip);
        if i % every == 0 || i + 1 == kept.len() {
            let hdr = hdr_flip(gold, &linear, w as usize, h as usize, flip::DEFAULT_PPD);
            r.hdr_flip = Some(hdr.mean);
        }
    }
    Ok(())
}

impl Outcome {
    /// Results used per second over whole frames: the results of the measured frames
    /// after the first, over the time from the first one's display to the last one's.
    /// A window that cut a frame would count all or none of its results (a quarter of
    /// the rate with one worker and four frames in the window).
    pub fn used_per_second(&self) -> Option<f64> {
        self.per_second_over_whole_frames(|f| f64::from(f.jobs_back))
    }

    /// As [`Outcome::used_per_second`], each result weighed by its samples per pixel:
    /// samples per pixel of a set used per second, whatever size the scheduler gave jobs.
    pub fn used_samples_per_second(&self) -> Option<f64> {
        self.per_second_over_whole_frames(|f| f64::from(f.jobs_back) * f64::from(f.spp))
    }

    /// `count` of the measured frames after the first, over the time from the first
    /// one's display to the last one's.
    fn per_second_over_whole_frames(&self, count: impl Fn(&FrameRecord) -> f64) -> Option<f64> {
        let (first, last) = (self.frames.first()?, self.frames.last()?);
        let span = last.t - first.t;
        (span > 0.0).then(|| self.frames[1..].iter().map(count).sum::<f64>() / span)
    }
}

/// Mean of `values` (0 when empty).
pub fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Starts the grid's processes; they are killed when the returned value is dropped.
fn spawn_grid(
    exe: &Path,
    master: SocketAddr,
    prepared: &Prepared,
    run: &Run,
) -> anyhow::Result<Children> {
    let mut children = Children::new();
    let peak = run.availability.peak();
    let mut first = 0;
    while first < peak {
        let count = WORKERS_PER_PROCESS.min(peak - first);
        // One process per worker host, round robin, when the grid is on a testbed.
        let mut cmd = match &run.network {
            Some(bed) => {
                let hosts = bed.workers();
                bed.command(&hosts[(first / WORKERS_PER_PROCESS) as usize % hosts.len()], exe)
            }
            None => Command::new(exe),
        };
        cmd.args(["simgrid", "--master", &master.to_string(), "--cache"])
            .arg(&prepared.cache_file)
            .args(["--grid", &run.availability.n.to_string()])
            .args(["--availability", curve_name(run.availability.curve)])
            .args(["--period", &run.availability.period.to_string()])
            .args(["--first", &first.to_string(), "--count", &count.to_string()])
            .args(["--pipeline", &run.pipeline.max(1).to_string()])
            .args(match run.pacing {
                Pacing::FixedFps(fps) => vec!["--fps".to_string(), fps.to_string()],
                Pacing::Heuristic(_) => Vec::new(),
            })
            .env("RUST_LOG", "error")
            .stdout(Stdio::null());
        children.spawn(cmd).context("starting a simulated-grid process")?;
        first += count;
    }
    Ok(children)
}

fn curve_name(curve: crate::simgrid::Curve) -> &'static str {
    match curve {
        crate::simgrid::Curve::Constant => "constant",
        crate::simgrid::Curve::Sine => "sine",
        crate::simgrid::Curve::Square => "square",
    }
}

/// Records shown frames while the clock runs; keeps them for Figure 8's FLIP.
struct RecordingSink {
    records: Arc<Mutex<Vec<FrameRecord>>>,
    /// Where shown frames are kept (without their owners) to be composed afterwards.
    kept: Option<Arc<Mutex<Vec<ShownFrame>>>>,
    clock: Arc<Mutex<Clock>>,
    /// The newest scene-state version the run made.
    newest: Arc<AtomicU64>,
    /// Each shown frame's state version, for [`PathPacing::PerFrame`].
    shown: mpsc::Sender<u64>,
}

/// When the grid had connected, and whether the measured interval runs.
#[derive(Default)]
struct Clock {
    connected: Option<Instant>,
    measuring: bool,
}

impl FrameSink for RecordingSink {
    fn show(&mut self, mut frame: ShownFrame) -> Result<(), SinkError> {
        let version = frame.state.version;
        let current = version >= self.newest.load(Ordering::Acquire);
        let _ = self.shown.send(version);
        let (frame_no, stats) = (frame.frame, frame.stats.clone());
        if let Some(kept) = &self.kept {
            // Every frame, warm-up included: the display's accumulation starts with the first.
            frame.owners = Default::default();
            kept.lock().unwrap_or_else(|p| p.into_inner()).push(frame);
        }
        let (connected, measured) = {
            let clock = self.clock.lock().unwrap_or_else(|p| p.into_inner());
            (clock.connected, clock.measuring)
        };
        let Some(start) = connected else { return Ok(()) };
        let s = &stats;
        self.records.lock().unwrap_or_else(|p| p.into_inner()).push(FrameRecord {
            frame: frame_no,
            t: start.elapsed().as_secs_f64(),
            measured,
            q: s.q,
            workers: s.workers,
            paused_workers: s.paused_workers,
            version,
            current,
            jobs_back: s.jobs_back,
            spp: s.spp,
            flip: None,
            hdr_flip: None,
        });
        Ok(())
    }
}

/// Counters at one instant.
struct Sample {
    at: Instant,
    skipped: u64,
    used: u64,
    unused: u64,
    late: u64,
}

impl Sample {
    fn take(handle: &master::MasterHandle) -> Self {
        let c = handle.counters();
        Self {
            at: Instant::now(),
            skipped: handle.report().skipped,
            used: Counters::get(&c.results_used),
            unused: Counters::get(&c.results_unused),
            late: Counters::get(&c.dropped_late),
        }
    }
}
