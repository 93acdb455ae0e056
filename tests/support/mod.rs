//! What the process-level suites share: the real `gridlight` binary as child processes
//! with their output collected, a headless master on a tiny test scene writing its
//! statistics, and null-render workers.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde_json::Value;

pub mod xvfb;

pub const EXE: &str = env!("CARGO_BIN_EXE_gridlight");
/// Sets per frame in these tests; 64×48 pixels split into 16 sets of 192.
pub const SETS: u32 = 16;
pub const WIDTH: u32 = 64;
pub const HEIGHT: u32 = 48;
/// Upper bound on any wait; tests end far sooner when things work.
pub const PATIENCE: Duration = Duration::from_secs(60);

pub const SCENE: &str = r#"
[camera]
position = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
vfov = 40.0

[resolution]
width = 64
height = 48
"#;

/// A child process whose stdout/stderr are collected in the background; killed on drop.
pub struct Proc {
    pub child: Child,
    pub stdout: Arc<Mutex<String>>,
    pub stderr: Arc<Mutex<String>>,
}

impl Proc {
    pub fn spawn(args: &[&str], env: &[(&str, &str)]) -> Proc {
        let mut cmd = Command::new(EXE);
        cmd.args(args).stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
        cmd.env("RUST_LOG", "info");
        for (k, v) in env {
            cmd.env(k, v);
        }
        let mut child = cmd.spawn().expect("gridlight starts");
        let stdout = collect(child.stdout.take().unwrap());
        let stderr = collect(child.stderr.take().unwrap());
        Proc { child, stdout, stderr }
    }

    pub fn pid(&self) -> i32 {
        self.child.id() as i32
    }

    /// Sends `sig` to the process (POSIX signals: Unix only).
    #[cfg(unix)]
    pub fn signal(&self, sig: i32) {
        // SAFETY: kill takes plain integers; the pid is this test's own child.
        let sent = unsafe { libc::kill(self.pid(), sig) };
        assert_eq!(sent, 0, "signal {sig} delivered");
    }

    pub fn stderr(&self) -> String {
        strip_ansi(&self.stderr.lock().unwrap())
    }

    /// Waits for the process to exit; its status, or `None` after `timeout`.
    pub fn wait(&mut self, timeout: Duration) -> Option<std::process::ExitStatus> {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    /// (frame, set) of every job this worker was handed, in order (its debug log's
    /// `job received` lines).
    pub fn jobs_received(&self) -> Vec<(u64, u64)> {
        self.stderr()
            .lines()
            .filter(|l| l.contains("job received"))
            .filter_map(|l| Some((field(l, "frame")?, field(l, "set")?)))
            .collect()
    }

    /// Frames this worker sent results for, in order (from its debug log).
    pub fn results_sent(&self) -> Vec<u64> {
        self.stderr()
            .lines()
            .filter(|l| l.contains("result sent"))
            .filter_map(|l| field(l, "frame"))
            .collect()
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub fn collect(mut pipe: impl Read + Send + 'static) -> Arc<Mutex<String>> {
    let buf = Arc::new(Mutex::new(String::new()));
    let sink = Arc::clone(&buf);
    std::thread::spawn(move || {
        let mut reader = BufReader::new(&mut pipe);
        let mut line = String::new();
        while reader.read_line(&mut line).map(|n| n > 0).unwrap_or(false) {
            sink.lock().unwrap().push_str(&line);
            line.clear();
        }
    });
    buf
}

pub fn strip_ansi(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        if c == '\x1b' {
            for d in chars.by_ref() {
                if d.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// The value of `name=N` in a log line.
pub fn field(line: &str, name: &str) -> Option<u64> {
    let at = line.find(&format!("{name}="))? + name.len() + 1;
    line[at..].split(|c: char| !c.is_ascii_digit()).next()?.parse().ok()
}

/// Polls `f` until it returns `Some`, panicking with `what` after [`PATIENCE`].
pub fn eventually<T>(what: &str, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + PATIENCE;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for: {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A master process and where it writes.
pub struct Master {
    pub proc: Proc,
    pub addr: SocketAddr,
    pub dir: PathBuf,
}

impl Master {
    /// Starts `gridlight master` on the test scene; `extra` adds options.
    pub fn start(dir: &Path, listen: &str, extra: &[&str]) -> Master {
        Self::start_scene(dir, SCENE, listen, extra)
    }

    /// Starts `gridlight master` on the scene `text` (its assets go in `dir/assets/`).
    pub fn start_scene(dir: &Path, text: &str, listen: &str, extra: &[&str]) -> Master {
        std::fs::create_dir_all(dir).unwrap();
        let scene = dir.join("scene.toml");
        std::fs::write(&scene, text).unwrap();
        Self::start_file(dir, &scene, listen, extra)
    }

    /// Starts `gridlight master` on the scene file `scene` (TOML or glTF), writing into
    /// `dir`.
    pub fn start_file(dir: &Path, scene: &Path, listen: &str, extra: &[&str]) -> Master {
        let out = dir.join("frames");
        let stats = dir.join("stats.jsonl");
        let sets = SETS.to_string();
        let mut args = vec![
            "master",
            scene.to_str().unwrap(),
            "--listen",
            listen,
            "--sets",
            &sets,
            "--headless",
            "--out",
            out.to_str().unwrap(),
            "--stats",
            stats.to_str().unwrap(),
            "--dump-current",
        ];
        args.extend_from_slice(extra);
        let proc = Proc::spawn(&args, &[]);
        let addr = eventually("the master's listening line", || {
            let out = proc.stdout.lock().unwrap().clone();
            out.lines()
                .find_map(|l| l.strip_prefix(gridlight::master::launch::LISTENING_PREFIX))
                .map(|a| a.trim().parse::<SocketAddr>().expect("a socket address"))
        });
        Master { proc, addr, dir: dir.to_path_buf() }
    }

    /// Every stats line written so far.
    pub fn stats(&self) -> Vec<Value> {
        let text = std::fs::read_to_string(self.dir.join("stats.jsonl")).unwrap_or_default();
        // The last line may be half written.
        text.lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
    }

    pub fn shown(&self) -> usize {
        self.stats().len()
    }

    /// Waits until `n` more frames than now were shown.
    pub fn wait_more_frames(&self, n: usize) {
        let start = self.shown();
        eventually(&format!("{n} more frames"), || (self.shown() >= start + n).then_some(()));
    }
}

pub fn worker(master: SocketAddr, cache: &Path, name: &str, delay_ms: u32, extra: &[&str]) -> Proc {
    let addr = master.to_string();
    let delay = delay_ms.to_string();
    let mut args = vec![
        "worker",
        "--master",
        &addr,
        "--threads",
        "1",
        "--name",
        name,
        "--null-render",
        "--null-render-delay-ms",
        &delay,
        // A stand-in for another machine: at idle priority its simulated renders would
        // wait behind every process of this (loaded) test host.
        "--priority",
        "normal",
        "--cache-dir",
        cache.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    Proc::spawn(&args, &[("RUST_LOG", "info,gridlight::worker=debug")])
}

/// Checks the no-redundancy invariant from the workers' side: no (frame, set) was handed
/// out twice, to one worker or to two, during one master run (frame numbers restart with
/// the master). Returns how many jobs were handed out; panics on a repeat or on none.
pub fn assert_nothing_handed_out_twice(workers: &[&Proc]) -> usize {
    let mut seen = std::collections::BTreeMap::new();
    for (w, proc) in workers.iter().enumerate() {
        for job in proc.jobs_received() {
            if let Some(first) = seen.insert(job, w) {
                panic!("job (frame, set) = {job:?} was handed to worker {first} and again to worker {w}");
            }
        }
    }
    assert!(!seen.is_empty(), "no worker logged a job: the check would have seen nothing");
    seen.len()
}

pub fn u(v: &Value, key: &str) -> u64 {
    v[key].as_u64().unwrap_or_else(|| panic!("stats key `{key}` missing or not a count: {v}"))
}
