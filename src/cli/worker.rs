//! `gridlight worker`: render jobs for a master; each thread is one independent worker.
//!
//! Settings come from the command line, then `GRIDLIGHT_*` environment variables, then
//! `--config FILE` ([`super::worker_file`]), then the defaults. Without a master address
//! the worker listens for a master's announcements (`worker::discover`).

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{bail, Context};
use clap::builder::BoolishValueParser;

use super::worker_file::WorkerFile;
use super::GlobalArgs;
use crate::worker::discover::{self, DiscoverOptions};
use crate::worker::idle::IdlePolicy;
use crate::worker::{
    self, CacheChoice, Priority, RendererKind, WhenIdle, WorkerConfig, WorkerError,
};

/// Arguments of `gridlight worker`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// The master's address, `HOST:PORT`. Without it the worker joins a master that
    /// announces itself on the LAN.
    #[arg(long, value_name = "HOST:PORT", env = "GRIDLIGHT_MASTER")]
    pub master: Option<String>,
    /// With several masters announcing themselves: join the one of this name (`gridlight
    /// master --name`).
    #[arg(long, value_name = "NAME", env = "GRIDLIGHT_MASTER_NAME", conflicts_with = "master")]
    pub master_name: Option<String>,
    /// UDP port to listen on for masters' announcements [default: 7841].
    #[arg(long, value_name = "PORT", env = "GRIDLIGHT_DISCOVERY_PORT")]
    pub discovery_port: Option<u16>,
    /// Seconds to listen for announcements before giving up [default: 10].
    #[arg(long, value_name = "SECONDS")]
    pub discover_timeout: Option<f64>,
    /// Render threads, each its own connection (default: the idle cores).
    #[arg(long, env = "GRIDLIGHT_THREADS")]
    pub threads: Option<usize>,
    /// File holding the shared secret the master requires (its bytes, trailing newline
    /// removed).
    #[arg(long, value_name = "FILE", env = "GRIDLIGHT_SECRET_FILE")]
    pub secret_file: Option<PathBuf>,
    /// Asset cache directory (default: `gridlight` under the user's cache directory). It is
    /// made owner-only (0700, files 0600); an existing one readable by others is tightened.
    #[arg(long, value_name = "DIR")]
    pub cache_dir: Option<PathBuf>,
    /// Where fetched assets are kept: `disk` (the cache directory, reused across runs) or
    /// `none` (this process's memory only: nothing is written to disk, every start fetches
    /// the scene again) [default: disk].
    #[arg(long, value_enum, value_name = "WHERE", env = "GRIDLIGHT_CACHE")]
    pub cache: Option<CacheMode>,
    /// Wipe the scene's assets from the cache when this worker leaves the grid (Ctrl-C,
    /// SIGTERM, a fatal error, or every connection to the master lost); other scenes'
    /// entries stay. For offices that keep no client data on desks.
    #[arg(long, value_name = "BOOL", env = "GRIDLIGHT_FORGET_ON_EXIT", num_args = 0..=1,
        require_equals = true, default_missing_value = "true",
        value_parser = BoolishValueParser::new())]
    pub forget_on_exit: Option<bool>,
    /// Name shown in the master's logs (default: host name and process id).
    #[arg(long)]
    pub name: Option<String>,
    /// Jobs held per connection (pipelining; 1 is the paper's strict request/response).
    #[arg(long, default_value_t = worker::DEFAULT_PIPELINE)]
    pub pipeline: u32,
    /// CPU priority of the render threads: idle (Linux SCHED_IDLE: any other process runs
    /// first) or normal [default: idle].
    #[arg(long, value_enum, env = "GRIDLIGHT_PRIORITY")]
    pub priority: Option<Priority>,
    /// Pause while the desk's owner is active (other processes busy, or keyboard/mouse
    /// used recently); resume once the machine has been idle for a while.
    #[arg(long, value_name = "BOOL", env = "GRIDLIGHT_WHEN_IDLE", num_args = 0..=1,
        require_equals = true, default_missing_value = "true",
        value_parser = BoolishValueParser::new())]
    pub when_idle: Option<bool>,
    /// With --when-idle: the owner is active when other processes use more than this share
    /// of all CPUs [default: 25].
    #[arg(long, value_name = "PERCENT", env = "GRIDLIGHT_IDLE_CPU_PERCENT")]
    pub idle_cpu_percent: Option<f32>,
    /// With --when-idle: over how many seconds that share is measured [default: 10].
    #[arg(long, value_name = "SECONDS", env = "GRIDLIGHT_IDLE_CPU_WINDOW")]
    pub idle_cpu_window: Option<f64>,
    /// With --when-idle: keyboard or mouse input this recent means the owner is active
    /// (where X11 or logind tells) [default: 300].
    #[arg(long, value_name = "SECONDS", env = "GRIDLIGHT_IDLE_INPUT")]
    pub idle_input: Option<f64>,
    /// With --when-idle: seconds of inactivity before a paused worker resumes [default: 30].
    #[arg(long, value_name = "SECONDS", env = "GRIDLIGHT_IDLE_RESUME_AFTER")]
    pub idle_resume_after: Option<f64>,
    /// Render with the GPU path tracer: `--gpu` (or `=on`) on any adapter, software ones
    /// included; `--gpu=auto` only on a hardware adapter, else on CPU threads. Connections
    /// follow the GPU's measured speed unless --threads is given.
    #[arg(long, value_enum, value_name = "WHEN", env = "GRIDLIGHT_GPU", num_args = 0..=1,
        require_equals = true, default_missing_value = "on")]
    pub gpu: Option<super::worker_gpu::GpuChoice>,
    /// Settings file (TOML); the command line and the environment override it.
    #[arg(long, value_name = "FILE", env = "GRIDLIGHT_CONFIG")]
    pub config: Option<PathBuf>,
    /// Answer every job with constant radiance at no cost (for `gridlight bench master`).
    #[arg(long, hide = true)]
    pub null_render: bool,
    /// With `--null-render`: sleep this long per job of the scene's samples per pixel (a job
    /// of more samples proportionally longer), as if rendering (fault-injection tests).
    #[arg(long, hide = true, default_value_t = 0)]
    pub null_render_delay_ms: u32,
}

/// `--cache`: where fetched assets are kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CacheMode {
    /// The on-disk cache directory.
    #[default]
    Disk,
    /// Memory only.
    None,
}

/// Runs `gridlight worker` until Ctrl-C, SIGTERM or a fatal error.
pub fn run(args: Args, _global: &GlobalArgs) -> anyhow::Result<()> {
    let file = match &args.config {
        Some(path) => WorkerFile::load(path)?,
        None => WorkerFile::default(),
    };
    let secret = match args.secret_file.as_ref().or(file.secret_file.as_ref()) {
        Some(path) => Some(gridlight_actors::auth::read_secret_file(path)?),
        None => None,
    };
    let master = match args.master.clone().or(file.master.clone()) {
        Some(master) => master,
        None => discovered(&args, &file, secret.clone())?,
    };
    let (gpu, threads_given) = (args.gpu.unwrap_or_default(), args.threads.is_some());
    let config = worker_config(args, file, master)?;
    let config = super::worker_gpu::apply(gpu, config, threads_given)?;
    match worker::run(config) {
        Ok(()) => Ok(()),
        Err(err @ WorkerError::Rejected { .. }) | Err(err @ WorkerError::NeedSecret) => {
            // Said plainly on stderr whatever RUST_LOG is: this is why the worker stops.
            eprintln!("gridlight worker: {err}");
            Err(err.into())
        }
        Err(err) => Err(err.into()),
    }
}

/// The master found by listening for announcements (only verified ones with `secret`).
fn discovered(args: &Args, file: &WorkerFile, secret: Option<Vec<u8>>) -> anyhow::Result<String> {
    let opts = DiscoverOptions {
        port: args
            .discovery_port
            .or(file.discovery_port)
            .unwrap_or(DiscoverOptions::default().port),
        master_name: args.master_name.clone().or(file.master_name.clone()),
        timeout: match args.discover_timeout.or(file.discover_timeout_s) {
            Some(s) => seconds("--discover-timeout", s)?,
            None => discover::DEFAULT_TIMEOUT,
        },
        secret,
    };
    Ok(discover::discover(&opts)?.addr.to_string())
}

/// The worker's configuration: command line and environment over file over defaults.
fn worker_config(args: Args, file: WorkerFile, master: String) -> anyhow::Result<WorkerConfig> {
    if args.master.is_none() && file.master.is_some() && args.master_name.is_some() {
        bail!("--master-name chooses among announced masters, but the config file names a master");
    }
    let secret = match args.secret_file.or(file.secret_file) {
        Some(path) => Some(gridlight_actors::auth::read_secret_file(&path)?),
        None => None,
    };
    let when_idle = if args.when_idle.or(file.when_idle).unwrap_or(false) {
        let d = IdlePolicy::default();
        let secs = |flag: &str, v: Option<f64>, default: Duration| match v {
            Some(s) => seconds(flag, s),
            None => Ok(default),
        };
        let policy = IdlePolicy {
            cpu_percent: args.idle_cpu_percent.or(file.idle.cpu_percent).unwrap_or(d.cpu_percent),
            cpu_window: secs(
                "--idle-cpu-window",
                args.idle_cpu_window.or(file.idle.cpu_window_s),
                d.cpu_window,
            )?,
            input_idle: secs(
                "--idle-input",
                args.idle_input.or(file.idle.input_idle_s),
                d.input_idle,
            )?,
            resume_after: secs(
                "--idle-resume-after",
                args.idle_resume_after.or(file.idle.resume_after_s),
                d.resume_after,
            )?,
            sample_every: d.sample_every,
        };
        policy.validate().map_err(anyhow::Error::msg).context("--when-idle settings")?;
        WhenIdle::Monitor(policy)
    } else {
        WhenIdle::Off
    };
    Ok(WorkerConfig {
        master,
        threads: args.threads.or(file.threads).unwrap_or_else(worker::idle_cores).max(1),
        secret,
        cache: cache_choice(args.cache.or(file.cache), args.cache_dir.or(file.cache_dir))?,
        forget_on_exit: args.forget_on_exit.or(file.forget_on_exit).unwrap_or(false),
        name: args.name.or(file.name).unwrap_or_else(worker::default_name),
        pipeline: args.pipeline.max(1),
        renderer: if args.null_render {
            RendererKind::Null { delay_ms: args.null_render_delay_ms }
        } else {
            RendererKind::PathTracer
        },
        priority: args.priority.or(file.priority).unwrap_or_default(),
        when_idle,
    })
}

/// `--cache` and `--cache-dir` together.
fn cache_choice(mode: Option<CacheMode>, dir: Option<PathBuf>) -> anyhow::Result<CacheChoice> {
    match (mode.unwrap_or_default(), dir) {
        (CacheMode::None, Some(dir)) => bail!(
            "--cache none keeps assets in memory only, but a cache directory is given ({}): \
             drop one of the two",
            dir.display()
        ),
        (CacheMode::None, None) => Ok(CacheChoice::Memory),
        (CacheMode::Disk, dir) => {
            Ok(CacheChoice::Dir(dir.unwrap_or_else(worker::cache::AssetCache::default_dir)))
        }
    }
}

/// A non-negative, finite number of seconds.
fn seconds(flag: &str, s: f64) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s)
        .map_err(|_| anyhow::anyhow!("{flag}: {s} is not a number of seconds (finite, >= 0)"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    fn parse(args: &[&str]) -> Args {
        let cli =
            crate::cli::Cli::try_parse_from(["gridlight", "worker"].iter().chain(args).copied())
                .expect("valid command line");
        match cli.command {
            crate::cli::Command::Worker(a) => a,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn the_command_line_wins_over_the_file_which_wins_over_the_defaults() {
        let file = WorkerFile {
            threads: Some(3),
            priority: Some(Priority::Normal),
            when_idle: Some(true),
            idle: super::super::worker_file::IdleFile {
                cpu_percent: Some(40.0),
                ..Default::default()
            },
            ..Default::default()
        };
        let c = worker_config(parse(&["--threads", "2"]), file, "m:1".into()).unwrap();
        assert_eq!((c.threads, c.priority), (2, Priority::Normal));
        let WhenIdle::Monitor(p) = c.when_idle else { panic!("when idle is on") };
        assert_eq!(p.cpu_percent, 40.0);
        assert_eq!(p.resume_after, IdlePolicy::default().resume_after);
    }

    #[test]
    fn render_threads_are_idle_priority_and_always_on_unless_told() {
        let c = worker_config(parse(&[]), WorkerFile::default(), "m:1".into()).unwrap();
        assert_eq!(c.priority, Priority::Idle);
        assert!(matches!(c.when_idle, WhenIdle::Off));
        let args = parse(&["--priority", "normal", "--when-idle=false"]);
        let file = WorkerFile { when_idle: Some(true), ..Default::default() };
        let c = worker_config(args, file, "m:1".into()).unwrap();
        assert_eq!(c.priority, Priority::Normal);
        assert!(matches!(c.when_idle, WhenIdle::Off), "--when-idle=false overrides the file");
    }

    #[test]
    fn bad_idle_settings_name_the_flag() {
        let err = worker_config(
            parse(&["--when-idle", "--idle-cpu-window=-1"]),
            WorkerFile::default(),
            "m:1".into(),
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("--idle-cpu-window"), "{err}");
        let err = worker_config(
            parse(&["--when-idle", "--idle-cpu-percent", "150"]),
            WorkerFile::default(),
            "m:1".into(),
        )
        .unwrap_err();
        assert!(format!("{err:#}").contains("percent"), "{err:#}");
    }

    #[test]
    fn the_cache_is_on_disk_unless_told_none_and_none_takes_no_directory() {
        let c = worker_config(parse(&["--cache-dir", "/x"]), WorkerFile::default(), "m:1".into());
        assert_eq!(c.unwrap().cache, CacheChoice::Dir("/x".into()));
        let c = worker_config(parse(&["--cache", "none"]), WorkerFile::default(), "m:1".into());
        let c = c.unwrap();
        assert_eq!((c.cache, c.forget_on_exit), (CacheChoice::Memory, false));
        let file = WorkerFile { cache_dir: Some("/y".into()), ..Default::default() };
        let err = worker_config(parse(&["--cache", "none"]), file, "m:1".into()).unwrap_err();
        assert!(
            err.to_string().contains("--cache none") && err.to_string().contains("/y"),
            "{err}"
        );
        let c = worker_config(parse(&["--forget-on-exit"]), WorkerFile::default(), "m:1".into());
        assert!(c.unwrap().forget_on_exit);
    }

    #[test]
    fn master_and_master_name_exclude_each_other() {
        let r = crate::cli::Cli::try_parse_from([
            "gridlight",
            "worker",
            "--master",
            "m:1",
            "--master-name",
            "lab",
        ]);
        assert!(r.is_err());
    }
}
