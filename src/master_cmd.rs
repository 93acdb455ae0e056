//! Running a master from a scene file: what `gridlight master` and `gridlight demo` share.
//!
//! [`prepare`] loads the scene through the asset search path, hashes every asset file
//! into the store workers fetch from, and builds the headless frame sink; [`run`] starts
//! the actor system, prints the address it listens on, plays the interaction script and
//! waits until the frame limit or Ctrl-C, then stops cleanly and returns the report.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context};
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::master::{self, MasterConfig, MasterReport, Pacing};
use gridlight_actors::protocol::SetsConfig;
use tracing::{info, warn};

use crate::headless::{GBufferCache, HeadlessOptions, HeadlessSink, HolesVisible};
use crate::scene::{AssetResolver, AssetSearchPath};

/// Address `gridlight master` listens on when `--listen` is not given.
pub const DEFAULT_LISTEN: &str = "0.0.0.0:7840";

/// Line printed on stdout once the master accepts connections; tools and tests parse it.
pub const LISTENING_PREFIX: &str = "gridlight master listening on ";

/// Everything a master run needs.
#[derive(Clone, Debug)]
pub struct MasterOptions {
    pub scene: PathBuf,
    /// `--assets` directories (searched before `GRIDLIGHT_ASSETS` and `scenes/assets/`).
    pub asset_dirs: Vec<PathBuf>,
    pub listen: SocketAddr,
    pub sets: SetsConfig,
    pub pacing: Pacing,
    /// Jobs a worker may hold (k).
    pub pipeline: u32,
    pub secret: Option<Vec<u8>>,
    pub script: Option<PathBuf>,
    /// Stop after this many shown frames (`None`: until Ctrl-C).
    pub frames: Option<u64>,
    pub headless: HeadlessOptions,
}

/// A scene loaded and ready to serve.
pub struct Prepared {
    pub config: MasterConfig,
    pub state: gridlight_actors::state::SceneState,
    pub store: AssetStore,
    pub sink: HeadlessSink,
}

/// Loads the scene and its assets and builds the sink.
pub fn prepare(opts: &MasterOptions) -> anyhow::Result<Prepared> {
    let search = AssetSearchPath::from_env(&opts.asset_dirs, Some(&opts.scene));
    let loaded = crate::scene::load(&opts.scene, &search)?;
    let manifest = crate::scene::manifest(&loaded.state, &search)
        .with_context(|| format!("hashing the assets of {}", opts.scene.display()))?;
    let mut store = AssetStore::new();
    for entry in &manifest {
        let file = search.resolve(&entry.path)?;
        store
            .add_file(&entry.path, &file)
            .with_context(|| format!("serving asset `{}`", entry.path))?;
    }
    let gbuffers = GBufferCache::new(Arc::new(loaded.assets), &loaded.state)
        .with_context(|| format!("preparing the G-buffer of {}", opts.scene.display()))?;
    let sink = HeadlessSink::new(gbuffers, Box::new(HolesVisible), opts.headless.clone())
        .context("creating the output directory or the stats file")?;
    let mut config = MasterConfig::new(opts.listen, opts.sets);
    config.pacing = opts.pacing;
    config.pipeline = opts.pipeline.max(1);
    config.secret = opts.secret.clone();
    config.max_frames = opts.frames;
    Ok(Prepared { config, state: loaded.state, store, sink })
}

/// Runs a master until its frame limit or Ctrl-C; `on_listening` is called with the
/// address workers should use once it accepts connections (the demo starts its
/// workers there).
pub fn run(
    opts: &MasterOptions,
    on_listening: impl FnOnce(SocketAddr) -> anyhow::Result<()>,
) -> anyhow::Result<MasterReport> {
    let prepared = prepare(opts)?;
    let script = match &opts.script {
        Some(path) => Some(gridlight_actors::script::load(path)?),
        None => None,
    };
    if prepared.config.secret.is_none() {
        warn!("no --secret-file: ANY host that can reach this master may join as a worker");
        eprintln!(
            "gridlight master: no --secret-file given, so any host on the network may join as a worker"
        );
    }
    let handle =
        master::start(prepared.config, prepared.state, prepared.store, Box::new(prepared.sink))
            .with_context(|| format!("starting the master on {}", opts.listen))?;
    let addr = handle.local_addr();
    println!("{LISTENING_PREFIX}{addr}");
    let _ = std::io::stdout().flush();
    info!(%addr, "master started");
    on_listening(addr)?;
    if let Some(script) = script {
        handle.play_script(script);
    }
    let interrupted = ctrl_c_flag()?;
    while !handle.wait_finished(Duration::from_millis(200)) {
        if interrupted.load(Ordering::SeqCst) {
            info!("Ctrl-C: stopping the master");
            break;
        }
    }
    let report = handle.stop().context("stopping the master")?;
    if let Some(err) = &report.error {
        bail!("the master stopped on an error: {err}");
    }
    Ok(report)
}

/// A flag set by Ctrl-C (a tokio signal listener on a small thread of its own).
pub fn ctrl_c_flag() -> anyhow::Result<Arc<AtomicBool>> {
    let flag = Arc::new(AtomicBool::new(false));
    let set = Arc::clone(&flag);
    let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    std::thread::Builder::new().name("ctrl-c".into()).spawn(move || {
        runtime.block_on(async {
            if tokio::signal::ctrl_c().await.is_ok() {
                set.store(true, Ordering::SeqCst);
            }
        })
    })?;
    Ok(flag)
}
