//! `deploy/slurm/gridlight-workers.sbatch` end to end on a real single-node Slurm cluster
//! (`deploy/slurm/local-cluster.sh`: munged, slurmctld and slurmd on loopback, all state in
//! a temporary directory): a headless `gridlight master` runs, the batch script is
//! submitted as a job array of two tasks, both workers join (the master's stats count 2),
//! frames come back rendered, `scancel` ends the job and the master counts the workers
//! gone. Skipped, saying so, where Slurm and munge are not installed (a failure under
//! `CI=true`, where `.ci/run` installs them) or not root.

#![cfg(unix)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use gridlight::testing::Missing;
use serde_json::Value;

const EXE: &str = env!("CARGO_BIN_EXE_gridlight");
const PATIENCE: Duration = Duration::from_secs(90);
const TOOLS: [&str; 7] = ["munged", "slurmctld", "slurmd", "sbatch", "scancel", "squeue", "sinfo"];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Why this machine cannot run the test, if it cannot: the tools `.ci/run` installs
/// (missing ones fail the test under CI), then root (which CI cannot promise).
fn skip_reason() -> Option<(Missing, String)> {
    let path = std::env::var("PATH").unwrap_or_default() + ":/usr/sbin:/sbin";
    let missing: Vec<&str> = TOOLS
        .into_iter()
        .filter(|t| !path.split(':').any(|d| Path::new(d).join(t).is_file()))
        .collect();
    if !missing.is_empty() {
        let why = format!("{} not installed (apt-get install slurm-wlm munge)", missing.join(", "));
        return Some((Missing::Tool, why));
    }
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    (!root).then(|| (Missing::System, "needs root to run slurmd and munged".into()))
}

/// The single-node cluster; stopped (every daemon killed) when dropped, also on panic.
struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
}

impl Cluster {
    fn start(dir: &Path) -> Cluster {
        let (ctld, slurmd) = (free_port(), free_port());
        let cluster = Cluster { dir: dir.to_path_buf(), conf: dir.join("slurm.conf") };
        let out = Command::new(repo().join("deploy/slurm/local-cluster.sh"))
            .arg("start")
            .arg(dir)
            .args([ctld.to_string(), slurmd.to_string()])
            .output()
            .expect("local-cluster.sh runs");
        assert!(
            out.status.success(),
            "the cluster did not start:\n{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        cluster
    }

    fn slurm(&self, tool: &str, args: &[&str]) -> String {
        let out = Command::new(tool).args(args).env("SLURM_CONF", &self.conf).output().unwrap();
        assert!(out.status.success(), "{tool} {args:?}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(repo().join("deploy/slurm/local-cluster.sh"))
            .arg("stop")
            .arg(&self.dir)
            .status();
    }
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// A child killed when dropped.
struct Killed(Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The Cornell box at 64×48: real path tracing, cheap on two cores.
fn small_scene(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("scenes/cornell-box.toml")).unwrap();
    let small = text.replace("width = 640", "width = 64").replace("height = 480", "height = 48");
    assert_ne!(small, text, "the Cornell box's resolution moved");
    let path = dir.join("cornell-small.toml");
    std::fs::write(&path, small).unwrap();
    path
}

fn stats(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect()
}

/// Waits until the stats file's lines satisfy `done`; panics after [`PATIENCE`].
fn wait_stats(path: &Path, what: &str, done: impl Fn(&[Value]) -> bool) -> Vec<Value> {
    let deadline = Instant::now() + PATIENCE;
    loop {
        let lines = stats(path);
        if done(&lines) {
            return lines;
        }
        assert!(
            Instant::now() < deadline,
            "{what}: not seen in {PATIENCE:?}; last: {:?}",
            lines.last()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}

fn workers(line: &Value) -> u64 {
    line["workers"].as_u64().unwrap()
}

#[test]
fn slurm_job_array_workers_join_render_and_leave() {
    if let Some((missing, why)) = skip_reason() {
        gridlight::testing::skip("Slurm end-to-end test", missing, why);
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let cluster = Cluster::start(&dir.join("cluster"));
    let secret = dir.join("grid.secret");
    std::fs::write(&secret, format!("slurm-test-{}\n", std::process::id())).unwrap();
    let stats_file = dir.join("stats.jsonl");

    let mut master = Command::new(EXE);
    master
        .arg("master")
        .arg(small_scene(dir))
        .args(["--headless", "--listen", "127.0.0.1:0", "--sets", "16", "--fps", "4"])
        // The workers are given the address; nothing goes onto the machine's network.
        .arg("--no-announce")
        .args(["--reconstruct", "cpu", "--stats"])
        .arg(&stats_file)
        .arg("--secret-file")
        .arg(&secret)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    let mut master = Killed(master.spawn().expect("the master starts"));
    let mut stdout = BufReader::new(master.0.stdout.take().unwrap());
    let mut line = String::new();
    let addr = loop {
        line.clear();
        assert!(stdout.read_line(&mut line).unwrap() > 0, "the master exited before listening");
        if let Some(addr) = line.trim().strip_prefix("gridlight master listening on ") {
            break addr.to_string();
        }
    };

    let script = repo().join("deploy/slurm/gridlight-workers.sbatch");
    let out = Command::new("sbatch")
        .args(["--parsable", "--array=0-1", "--chdir"])
        .arg(dir)
        .arg(format!("--output={}/worker-%A_%a.out", dir.display()))
        .arg(&script)
        .arg(&addr)
        .env("SLURM_CONF", &cluster.conf)
        .env("GRIDLIGHT", EXE)
        .env("GRIDLIGHT_SECRET_FILE", &secret)
        .env("TMPDIR", dir)
        .env("RUST_LOG", "info")
        .output()
        .expect("sbatch runs");
    assert!(out.status.success(), "sbatch: {}", String::from_utf8_lossy(&out.stderr));
    let job = String::from_utf8_lossy(&out.stdout).trim().split(';').next().unwrap().to_string();
    eprintln!("submitted job array {job}: {} to master {addr}", script.display());

    let joined = wait_stats(&stats_file, "two Slurm workers counted by the master", |l| {
        l.last().is_some_and(|s| workers(s) == 2)
    });
    let squeue = cluster.slurm("squeue", &["-h", "-j", &job, "-o", "%i %T %N"]);
    eprintln!("squeue:\n{squeue}");
    assert_eq!(squeue.lines().filter(|l| l.contains("RUNNING")).count(), 2, "{squeue}");
    let from = joined.len();
    let rendered = wait_stats(&stats_file, "frames rendered by both workers", |l| {
        l.len() > from + 4
            && l[from..].iter().filter(|s| s["jobs_back"].as_u64() == Some(16)).count() >= 3
    });
    let last = rendered.last().unwrap();
    eprintln!(
        "master: frame {} shown, {} of 16 jobs back, {} workers",
        last["frame"],
        last["jobs_back"],
        workers(last)
    );

    cluster.slurm("scancel", &[&job]);
    let gone = wait_stats(&stats_file, "the workers gone after scancel", |l| {
        l.last().is_some_and(|s| workers(s) == 0)
    });
    eprintln!(
        "after scancel {job}: master frame {} shows 0 workers",
        gone.last().unwrap()["frame"]
    );
    // Completing tasks may show for a moment after their processes are gone.
    let deadline = Instant::now() + PATIENCE;
    while !cluster.slurm("squeue", &["-h", "-j", &job]).trim().is_empty() {
        assert!(Instant::now() < deadline, "the job is still queued after scancel");
        std::thread::sleep(Duration::from_millis(200));
    }
    // Both tasks reached the master: their logs name the master they joined.
    for task in 0..2 {
        let log = std::fs::read_to_string(dir.join(format!("worker-{job}_{task}.out")))
            .unwrap_or_default();
        assert!(!log.contains("ERROR"), "task {task} logged an error:\n{log}");
    }
    assert!(master.0.try_wait().unwrap().is_none(), "the master keeps running without workers");
}
