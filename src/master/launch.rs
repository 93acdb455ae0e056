//! Running a master from a scene file: what `gridlight master` and `gridlight demo` share.
//!
//! [`prepare`] loads the scene through the asset search path, hashes every asset file
//! into the store workers fetch from, and resolves pacing and reconstruction (command
//! line over the scene file over the paper); [`run`] starts the actor system with the
//! headless sink, prints the address it listens on, plays the interaction script and
//! waits until the frame limit or Ctrl-C/SIGTERM, then stops cleanly and returns the
//! report; [`run_window`] does the same with the window as the sink, until the window
//! closes or Ctrl-C/SIGTERM arrives.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use anyhow::{bail, Context};
use gridlight_actors::announcer::AnnounceConfig;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::discovery;
use gridlight_actors::master::{self, MasterConfig, MasterReport};
use gridlight_actors::protocol::SetsConfig;
use gridlight_actors::supervision::PanicInjection;
use tracing::{info, warn};

use crate::assets::Assets;
use crate::cli::master::DisplayArgs;
use crate::cli::resolution::SizeArg;
use crate::master::compose::Composer;
use crate::master::headless::{HeadlessOptions, HeadlessSink};
use crate::reconstruct::ReconstructParams;
use crate::scene::{AssetResolver, PacingOverrides, SceneSource};

/// Address `gridlight master` listens on when `--listen` is not given.
pub const DEFAULT_LISTEN: &str = "0.0.0.0:7840";

/// Line printed on stdout once the master accepts connections; tools and tests parse it.
pub const LISTENING_PREFIX: &str = "gridlight master listening on ";

/// Everything a master run needs.
#[derive(Clone, Debug)]
pub struct MasterOptions {
    pub scene: SceneSource,
    /// `--assets` directories (searched before `GRIDLIGHT_ASSETS` and `scenes/assets/`).
    pub asset_dirs: Vec<PathBuf>,
    pub listen: SocketAddr,
    pub sets: SetsConfig,
    /// Pacing flags; the scene's `[render.display]` and the paper fill in the rest.
    pub pacing: PacingOverrides,
    /// View and reconstruction flags.
    pub display: DisplayArgs,
    /// Jobs a worker may hold (k).
    pub pipeline: u32,
    /// The master's inbound link in Mbit/s (`--link-mbps`), when known.
    pub link_mbps: Option<f64>,
    pub secret: Option<Vec<u8>>,
    /// Announcing the master on the LAN.
    pub announce: AnnounceOptions,
    pub script: Option<PathBuf>,
    /// Stop after this many shown frames (`None`: until Ctrl-C).
    pub frames: Option<u64>,
    /// Keep queued jobs of outdated scene states (the behaviour before stale-job discard;
    /// only to measure what the discard gains).
    pub keep_stale_jobs: bool,
    /// Frames handed to the sink ahead of it (1 by default for `master` and `demo`).
    pub sink_in_flight: usize,
    /// Panics the supervision guard injects (a test hook: `--inject-panic`).
    pub inject_panics: Vec<PanicInjection>,
    pub headless: HeadlessOptions,
}

/// Whether and how the master announces itself (`gridlight_actors::discovery`).
#[derive(Clone, Debug, Default)]
pub struct AnnounceOptions {
    pub enabled: bool,
    /// Destination; default [`discovery::default_target`] of the listen address.
    pub to: Option<SocketAddr>,
    /// Announced name; default the host name.
    pub name: Option<String>,
}

impl AnnounceOptions {
    /// The actors' announce configuration for a master listening on `listen`.
    fn config(&self, listen: SocketAddr, scene: &SceneSource) -> Option<AnnounceConfig> {
        self.enabled.then(|| AnnounceConfig {
            to: self.to.unwrap_or_else(|| discovery::default_target(listen)),
            name: self
                .name
                .clone()
                .or_else(crate::worker::host_name)
                .unwrap_or_else(|| "gridlight".into()),
            scene: scene.name(),
            interval: discovery::ANNOUNCE_INTERVAL,
        })
    }
}

/// A scene loaded and ready to serve.
pub struct Prepared {
    pub config: MasterConfig,
    pub state: gridlight_actors::state::SceneState,
    pub store: AssetStore,
    pub assets: Arc<Assets>,
    /// Reconstruction parameters (command line over scene over paper), checked.
    pub params: ReconstructParams,
}

impl Prepared {
    /// A composer for this run's frames.
    pub fn composer(&self, opts: &MasterOptions) -> anyhow::Result<Composer> {
        Composer::new(Arc::clone(&self.assets), &self.state, self.params, opts.display.reconstruct)
            .map(|c| c.with_gbuffer_ahead(opts.display.gbuffer_ahead))
            .with_context(|| format!("preparing reconstruction for {}", opts.scene))
    }
}

/// Loads the scene and its assets and resolves the settings.
pub fn prepare(opts: &MasterOptions) -> anyhow::Result<Prepared> {
    let search = opts.scene.search_path(&opts.asset_dirs);
    let mut loaded = crate::scene::load_source(&opts.scene, &search)?;
    let size = &mut loaded.state.resolution;
    let fixed = opts.display.resolution.and_then(SizeArg::fixed);
    crate::cli::resolution::apply(size, fixed, opts.display.scale)?;
    // The store hashes each file as it adds it: the only hashing at start.
    let paths = crate::scene::asset_paths(&loaded.state, &loaded.assets)
        .with_context(|| format!("listing the assets of {}", opts.scene))?;
    let mut store = AssetStore::new();
    for path in &paths {
        let file = search.resolve(path)?;
        store.add_file(path, &file).with_context(|| format!("serving asset `{path}`"))?;
    }
    let params = opts.display.params(loaded.reconstruction);
    params.validate().context("reconstruction parameters")?;
    let mut config = MasterConfig::new(opts.listen, opts.sets);
    config.pacing = crate::scene::display_pacing(&loaded.display, &opts.pacing);
    if let Err(why) = config.pacing.validate() {
        bail!("pacing: {why}");
    }
    config.pipeline = opts.pipeline.max(1);
    config.link_bytes_per_second = opts.link_mbps.map(mbps_to_bytes_per_second);
    config.secret = opts.secret.clone();
    config.max_frames = opts.frames;
    config.announce = opts.announce.config(opts.listen, &opts.scene);
    config.discard_stale_jobs = !opts.keep_stale_jobs;
    // A person watches these frames: the newest view decided when the sink is free beats
    // a frame decided earlier and queued behind another (edit-to-display latency).
    config.sink_in_flight = opts.sink_in_flight;
    config.inject_panics = opts.inject_panics.clone();
    Ok(Prepared { config, state: loaded.state, store, assets: Arc::new(loaded.assets), params })
}

/// Runs a master until its frame limit or Ctrl-C; `on_listening` is called with the
/// address workers should use once it accepts connections (the demo starts its
/// workers there).
pub fn run(
    opts: &MasterOptions,
    on_listening: impl FnOnce(SocketAddr) -> anyhow::Result<()>,
) -> anyhow::Result<MasterReport> {
    let prepared = prepare(opts)?;
    let script = load_script(opts)?;
    let sink = HeadlessSink::new(prepared.composer(opts)?, opts.headless.clone())
        .context("creating the output directory or the stats file")?;
    warn_if_open(&prepared.config);
    let handle = master::start(prepared.config, prepared.state, prepared.store, Box::new(sink))
        .with_context(|| format!("starting the master on {}", opts.listen))?;
    announce(handle.local_addr());
    on_listening(handle.local_addr())?;
    if let Some(script) = script {
        handle.play_script(script);
    }
    let interrupted = crate::signals::stop_flag().context("installing the Ctrl-C handler")?;
    while !handle.wait_finished(Duration::from_millis(100)) {
        if interrupted.load(Ordering::SeqCst) {
            info!("Ctrl-C or SIGTERM: stopping the master");
            break;
        }
    }
    let report = handle.stop().context("stopping the master")?;
    if let Some(err) = &report.error {
        bail!("the master stopped on an error: {err}");
    }
    Ok(report)
}

/// Runs a master whose frames go to a window on this thread, until the window closes
/// (or the frame limit, Ctrl-C or SIGTERM); then `on_shutdown` runs (the demo stops its
/// workers there). Returns the master's report, as [`run`] does.
pub fn run_window(
    opts: &MasterOptions,
    window: crate::window::WindowOptions,
    on_listening: impl FnOnce(SocketAddr) -> anyhow::Result<()> + 'static,
    on_shutdown: Option<Box<dyn FnOnce()>>,
) -> anyhow::Result<MasterReport> {
    let prepared = prepare(opts)?;
    let script = load_script(opts)?;
    let composer = prepared.composer(opts)?;
    warn_if_open(&prepared.config);
    let start = crate::window::master_control::MasterStart {
        config: prepared.config,
        state: prepared.state,
        store: prepared.store,
        composer,
        script,
        on_listening: Box::new(move |addr| {
            announce(addr);
            on_listening(addr).map_err(|e| format!("{e:#}"))
        }),
        on_shutdown,
    };
    let report = crate::window::master_control::run_master_window(window, start)
        .context("running the window (use --headless to run without one)")?;
    if let Some(err) = &report.error {
        bail!("the master stopped on an error: {err}");
    }
    Ok(report)
}

/// Mbit/s (a link's rate as its operator states it) in bytes per second.
pub fn mbps_to_bytes_per_second(mbps: f64) -> f64 {
    mbps * 1e6 / 8.0
}

fn load_script(
    opts: &MasterOptions,
) -> anyhow::Result<Option<Vec<(Duration, gridlight_actors::edit::Edit)>>> {
    opts.script.as_ref().map(|path| Ok(gridlight_actors::script::load(path)?)).transpose()
}

fn warn_if_open(config: &MasterConfig) {
    if config.secret.is_none() {
        warn!("no --secret-file: ANY host that can reach this master may join as a worker, and nothing is encrypted");
        eprintln!(
            "gridlight master: no --secret-file given, so any host on the network may join as a worker, and the scene and its pixels cross the network unencrypted"
        );
    }
}

/// Prints the line tools and tests wait for.
fn announce(addr: SocketAddr) {
    println!("{LISTENING_PREFIX}{addr}");
    let _ = std::io::stdout().flush();
    info!(%addr, "master started");
}
