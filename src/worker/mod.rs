//! The worker runtime: `gridlight worker --master HOST:PORT`.
//!
//! Each render thread is one independent worker (paper, section 4.4): its own TCP
//! connection, handshake, scene states and jobs. The connections share one process-wide
//! context ([`shared::Shared`]: the asset cache, pixel-set tables, loaded assets) and one
//! small tokio runtime for their I/O; rendering happens on one OS thread per connection.
//! A connection that ends for any reason but a fatal one (wrong version or secret)
//! reconnects with exponential back-off and jitter; Ctrl-C ends them all cleanly.
//!
//! Render threads run at the lowest CPU priority by default ([`priority`]); with
//! `--when-idle` the worker pauses while its desk's owner is active ([`idle`]). Without
//! `--master` it finds a master that announces itself on the LAN ([`discover`]).
//!
//! - [`cache`]: the hash-keyed asset cache, on disk (owner-only) or in memory.
//! - `channel`: the encrypted channel's handshake, before a link's first message.
//! - [`forget`]: wiping the fetched scenes when the worker leaves (`--forget-on-exit`).
//! - [`backoff`]: reconnect delays.
//! - [`link`]: one connection to the master: its protocol phases.
//! - [`render`]: the render thread (path tracer or null renderer).
//! - [`gpu`]: a GPU worker's device thread, which renders all its connections' jobs.
//! - [`shared`]: what the connections of a process share.
//! - [`resolver`]: loading a scene's assets from the cache.
//! - [`priority`]: the render threads' CPU priority.
//! - [`idle`]: the owner monitor and the pause/resume decision.
//! - [`discover`]: listening for a master's announcements.

pub mod backoff;
pub mod cache;
mod channel;
pub mod discover;
pub mod forget;
pub mod gpu;
pub mod idle;
pub mod link;
pub mod priority;
pub mod render;
pub mod resolver;
pub mod shared;

use std::sync::Arc;
use std::time::Duration;

use gridlight_actors::channel_codec::{KeySlot, WorkerChannelCodec};
use rand::SeedableRng;
use tokio::net::TcpStream;
use tokio_util::codec::Framed;
use tokio_util::sync::CancellationToken;
use tracing::{error, info, warn};

use backoff::Backoff;
use idle::{Activity, IdlePolicy};
use link::{LinkConfig, LinkEnd, LinkProgress};
pub use priority::Priority;
pub use render::RendererKind;
use shared::Shared;
use tokio::sync::watch;

/// Jobs a worker holds at once when not told otherwise (docs/design.md, decision 7).
pub const DEFAULT_PIPELINE: u32 = 2;

/// Bytes the writer may buffer before it must flush (tokio-util's default is 8 KiB, less
/// than one 640×480 result).
const WRITE_BATCH_BYTES: usize = 256 * 1024;

/// Longest wait for a TCP connection to the master.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// How a worker process runs.
#[derive(Clone, Debug)]
pub struct WorkerConfig {
    /// The master's `HOST:PORT`.
    pub master: String,
    /// Render threads, each its own connection.
    pub threads: usize,
    /// Shared secret proved by HMAC, if the master requires one.
    pub secret: Option<Vec<u8>>,
    /// Where fetched assets are kept.
    pub cache: CacheChoice,
    /// Wipe the fetched scenes from the cache when leaving the grid (`--forget-on-exit`).
    pub forget_on_exit: bool,
    /// Base name; connection `i` calls itself `NAME#i`.
    pub name: String,
    /// Jobs held per connection.
    pub pipeline: u32,
    pub renderer: RendererKind,
    /// CPU priority of the render threads.
    pub priority: Priority,
    /// Whether the worker gives way to its desk's owner.
    pub when_idle: WhenIdle,
}

/// Where a worker keeps the assets it fetched.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheChoice {
    /// The on-disk cache in this directory (`--cache-dir`).
    Dir(std::path::PathBuf),
    /// This process's memory only (`--cache none`): nothing is written to disk.
    Memory,
}

impl CacheChoice {
    /// Opens the cache.
    pub fn open(&self) -> Result<cache::AssetCache, cache::CacheError> {
        match self {
            Self::Dir(dir) => cache::AssetCache::open(dir),
            Self::Memory => Ok(cache::AssetCache::in_memory()),
        }
    }
}

impl std::fmt::Display for CacheChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Dir(dir) => write!(f, "{}", dir.display()),
            Self::Memory => f.write_str("memory only"),
        }
    }
}

/// Whether, and how, a worker pauses while its desk's owner is active.
#[derive(Clone, Debug)]
pub enum WhenIdle {
    /// Always take jobs.
    Off,
    /// Watch this machine (`--when-idle`).
    Monitor(IdlePolicy),
    /// Follow decisions made elsewhere (tests, embedders).
    Follow(watch::Receiver<Activity>),
}

/// Why a worker (or one of its connections) stopped.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    #[error("the master rejected this worker: {reason}")]
    Rejected { reason: String, fatal: bool },
    #[error("the master requires a shared secret: pass --secret-file")]
    NeedSecret,
    #[error("connection to the master: {0}")]
    Connection(String),
    #[error("protocol violation by the master: {0}")]
    Protocol(String),
    #[error("encrypted channel: {0}")]
    Channel(#[from] gridlight_actors::channel::ChannelError),
    #[error(transparent)]
    Cache(#[from] cache::CacheError),
    #[error("loading the scene's assets: {0}")]
    Assets(String),
    #[error("rendering: {0}")]
    Render(String),
    #[error("cannot start the worker runtime: {0}")]
    Runtime(std::io::Error),
}

impl WorkerError {
    /// Errors that reconnecting cannot fix: the process should exit non-zero.
    pub fn is_fatal(&self) -> bool {
        matches!(
            self,
            WorkerError::Rejected { fatal: true, .. }
                | WorkerError::NeedSecret
                | WorkerError::Runtime(_)
        )
    }
}

/// Idle cores of this machine: available parallelism minus the 1-minute load, at least 1.
pub fn idle_cores() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().and_then(|l| l.parse::<f64>().ok()))
        .unwrap_or(0.0);
    cores.saturating_sub(load.round() as usize).max(1)
}

/// This machine's name (`/etc/hostname`, else `$HOSTNAME`), if it has one.
pub fn host_name() -> Option<String> {
    std::fs::read_to_string("/etc/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
}

/// A default worker name: the host name and the process id.
pub fn default_name() -> String {
    let host = host_name().unwrap_or_else(|| "worker".into());
    format!("{host}:{}", std::process::id())
}

/// Runs a worker process until Ctrl-C or SIGTERM (`Ok`) or a fatal error.
pub fn run(config: WorkerConfig) -> Result<(), WorkerError> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .thread_name("worker-io")
        .enable_all()
        .build()
        .map_err(WorkerError::Runtime)?;
    let cancel = CancellationToken::new();
    let stop = cancel.clone();
    // Ctrl-C and SIGTERM alike end the connections cleanly (and wipe, with --forget-on-exit).
    crate::signals::on_stop_signal(move |_| stop.cancel()).map_err(WorkerError::Runtime)?;
    runtime.block_on(run_until(config, cancel))
}

/// Runs the worker's connections until `cancel` fires (`Ok`) or one fails fatally.
pub async fn run_until(config: WorkerConfig, cancel: CancellationToken) -> Result<(), WorkerError> {
    let shared = Arc::new(Shared::forgetting(config.cache.open()?, config.forget_on_exit));
    info!(master = %config.master, threads = config.threads, cache = %config.cache,
        forget_on_exit = config.forget_on_exit, priority = ?config.priority, "worker starting");
    let activity = match config.when_idle.clone() {
        WhenIdle::Off => watch::channel(Activity::Working).1,
        WhenIdle::Follow(rx) => rx,
        WhenIdle::Monitor(policy) => {
            idle::spawn_monitor(policy, Box::new(idle::input::FirstKnown::detect()), cancel.clone())
                .map_err(WorkerError::Runtime)?
        }
    };
    let mut tasks = tokio::task::JoinSet::new();
    for i in 0..config.threads.max(1) {
        let link = LinkConfig {
            name: format!("{}#{i}", config.name),
            secret: config.secret.clone().map(Arc::new),
            pipeline: config.pipeline,
            renderer: config.renderer.clone(),
            priority: config.priority,
        };
        tasks.spawn(connection_loop(
            config.master.clone(),
            link,
            Arc::clone(&shared),
            cancel.clone(),
            activity.clone(),
        ));
    }
    let mut outcome = Ok(());
    while let Some(done) = tasks.join_next().await {
        let result = done.unwrap_or_else(|e| {
            Err(WorkerError::Connection(format!("connection task failed: {e}")))
        });
        if let Err(err) = result {
            // A fatal error of one connection is the same for all: stop them.
            cancel.cancel();
            if outcome.is_ok() {
                outcome = Err(err);
            }
        }
    }
    shared.forget_if_idle("the worker stops").await;
    outcome
}

/// Connects, runs a link, and reconnects with back-off until shutdown or a fatal error.
pub(crate) async fn connection_loop(
    master: String,
    config: LinkConfig,
    shared: Arc<Shared>,
    cancel: CancellationToken,
    mut activity: watch::Receiver<Activity>,
) -> Result<(), WorkerError> {
    let mut backoff = Backoff::default();
    let mut rng = rand::rngs::StdRng::from_entropy();
    loop {
        let mut progress = LinkProgress::default();
        // Connecting (and the channel's handshake) gives way to a shutdown at once.
        let connected = tokio::select! {
            c = connect(&master, config.secret.as_deref()) => c,
            () = cancel.cancelled() => return Ok(()),
        };
        let outcome = match connected {
            Ok(transport) => {
                link::run(transport, &config, &shared, &cancel, &mut activity, &mut progress).await
            }
            Err(err) => Err(err),
        };
        if progress.welcomed
            && shared.forget.connection_ended()
            && !cancel.is_cancelled()
            && !matches!(outcome, Ok(LinkEnd::Shutdown))
        {
            shared.forget_if_idle("every connection to the master is gone").await;
        }
        match outcome {
            Ok(LinkEnd::Shutdown) => return Ok(()),
            Ok(LinkEnd::Closed) => info!(worker = %config.name, "master closed the connection"),
            Err(err) if err.is_fatal() => {
                error!(worker = %config.name, cause = %err, "giving up");
                return Err(err);
            }
            Err(err) => warn!(worker = %config.name, cause = %err, "connection lost"),
        }
        if cancel.is_cancelled() {
            return Ok(());
        }
        if progress.welcomed {
            backoff.reset();
        }
        let delay = backoff.next_delay(&mut rng);
        info!(worker = %config.name, delay_ms = delay.as_millis() as u64, "reconnecting");
        tokio::select! {
            () = tokio::time::sleep(delay) => {}
            () = cancel.cancelled() => return Ok(()),
        }
    }
}

/// Opens a framed connection to the master, encrypted when there is a secret.
async fn connect(
    master: &str,
    secret: Option<&Vec<u8>>,
) -> Result<Framed<TcpStream, WorkerChannelCodec>, WorkerError> {
    let stream = tokio::time::timeout(CONNECT_TIMEOUT, TcpStream::connect(master))
        .await
        .map_err(|_| WorkerError::Connection(format!("connecting to {master}: timed out")))?
        .map_err(|e| WorkerError::Connection(format!("connecting to {master}: {e}")))?;
    // Results are small and latency matters more than packet count.
    let _ = stream.set_nodelay(true);
    let mut framed = Framed::new(stream, WorkerChannelCodec::new(KeySlot::new()));
    // Room for a result and the credit after it, so that the writer's batch is one write.
    framed.set_backpressure_boundary(WRITE_BATCH_BYTES);
    if let Some(secret) = secret {
        channel::encrypt(&mut framed, secret).await?;
    }
    Ok(framed)
}
