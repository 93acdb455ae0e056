//! Zero-configuration discovery between real processes on loopback: masters announce on
//! the loopback broadcast address (127.255.255.255), each test on a UDP port of its own
//! so that tests running at once do not hear each other, and `gridlight worker` without
//! `--master` finds them.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use gridlight_actors::discovery::tag::{now_ms, Sender};
use gridlight_actors::discovery::{Announcement, DISCOVERY_PORT};
use gridlight_actors::protocol::PROTOCOL_VERSION;

mod support;
use support::*;

/// A UDP port free right now, for one test's announcements.
fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

fn announcing_master(dir: &Path, name: &str, port: u16) -> Master {
    let to = format!("127.255.255.255:{port}");
    Master::start(dir, "127.0.0.1:0", &["--name", name, "--announce-to", &to])
}

fn discovering_worker(port: u16, cache: &Path, extra: &[&str]) -> Proc {
    let port = port.to_string();
    let mut args = vec![
        "worker",
        "--discovery-port",
        &port,
        "--threads",
        "1",
        "--name",
        "found",
        "--null-render",
        "--null-render-delay-ms",
        "2",
        "--priority",
        "normal",
        "--cache-dir",
        cache.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    Proc::spawn(&args, &[])
}

#[test]
fn a_worker_without_a_master_address_joins_the_master_it_hears_and_renders() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let master = announcing_master(&dir.path().join("m"), "lab", port);
    let worker = discovering_worker(port, &dir.path().join("cache"), &[]);
    master.wait_more_frames(3);
    eventually("a frame rendered by the discovered worker", || {
        master.stats().iter().any(|s| u(s, "workers") == 1 && u(s, "jobs_back") > 0).then_some(())
    });
    let log = worker.stderr();
    assert!(log.contains("master found") && log.contains("lab"), "{log}");
}

#[test]
fn with_two_masters_the_name_chooses_and_without_it_the_worker_says_how_to_choose() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let a = announcing_master(&dir.path().join("a"), "desk-a", port);
    let b = announcing_master(&dir.path().join("b"), "desk-b", port);
    let cache = dir.path().join("cache");

    let mut unsure = discovering_worker(port, &cache, &["--discover-timeout", "20"]);
    let status = unsure.wait(PATIENCE).expect("the worker gives up");
    assert!(!status.success());
    let err = unsure.stderr();
    assert!(err.contains("several masters"), "{err}");
    assert!(err.contains("\"desk-a\"") && err.contains("\"desk-b\""), "{err}");
    assert!(err.contains("--master-name NAME"), "{err}");

    let _chosen = discovering_worker(port, &cache, &["--master-name", "desk-b"]);
    b.wait_more_frames(3);
    eventually("desk-b's worker rendering", || {
        b.stats().iter().any(|s| u(s, "workers") == 1 && u(s, "jobs_back") > 0).then_some(())
    });
    assert!(!a.proc.stderr().contains("worker joined"), "desk-a got a worker");
}

#[test]
fn with_no_master_announcing_the_worker_fails_saying_how_to_name_one() {
    let dir = tempfile::tempdir().unwrap();
    let started = Instant::now();
    let mut w = discovering_worker(free_udp_port(), dir.path(), &["--discover-timeout", "1"]);
    let status = w.wait(PATIENCE).expect("the worker gives up");
    assert!(!status.success());
    assert!(started.elapsed() < Duration::from_secs(30));
    let err = w.stderr();
    assert!(err.contains("no gridlight master announced itself"), "{err}");
    assert!(err.contains("--master HOST:PORT"), "{err}");
}

/// Names heard on the default discovery port for `wait`; `None` when the port cannot be
/// shared here (then the caller skips).
fn names_heard_on_the_default_port(wait: Duration) -> Option<Vec<String>> {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, None).ok()?;
    socket.set_reuse_address(true).ok()?;
    socket.set_reuse_port(true).ok()?;
    let any: SocketAddr = ([0, 0, 0, 0], DISCOVERY_PORT).into();
    if let Err(e) = socket.bind(&any.into()) {
        let why = format!("cannot share UDP port {DISCOVERY_PORT} here: {e}");
        gridlight::testing::skip("discovery", gridlight::testing::Missing::System, why);
        return None;
    }
    let socket: UdpSocket = socket.into();
    let deadline = Instant::now() + wait;
    let mut names = Vec::new();
    let mut buf = [0u8; 1024];
    while let Some(left) = deadline.checked_duration_since(Instant::now()) {
        socket.set_read_timeout(Some(left.max(Duration::from_millis(1)))).unwrap();
        if let Ok((n, _)) = socket.recv_from(&mut buf) {
            if let Ok(r) = Announcement::decode(&buf[..n]) {
                names.push(r.announcement.name);
            }
        }
    }
    Some(names)
}

#[test]
fn a_loopback_master_announces_on_the_documented_port_unless_told_not_to() {
    let dir = tempfile::tempdir().unwrap();
    let pid = std::process::id();
    let (loud, quiet) = (format!("loud-{pid}"), format!("quiet-{pid}"));
    let _a = Master::start(&dir.path().join("a"), "127.0.0.1:0", &["--name", &loud]);
    let _b =
        Master::start(&dir.path().join("b"), "127.0.0.1:0", &["--name", &quiet, "--no-announce"]);
    let Some(names) = names_heard_on_the_default_port(Duration::from_secs(2)) else { return };
    assert!(names.contains(&loud), "the announcing master was not heard: {names:?}");
    assert!(!names.contains(&quiet), "--no-announce was not honoured");
}

/// A host on the LAN without the secret, sending announcements until dropped: untagged,
/// tagged under a guessed secret, an old one tagged under the real secret (captured
/// earlier), and genuine datagrams of `genuine_port`'s master captured and sent again.
struct Forger {
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Forger {
    fn start(port: u16, secret: &'static [u8]) -> Forger {
        let stop = Arc::new(AtomicBool::new(false));
        let done = Arc::clone(&stop);
        let to: SocketAddr = ([127, 255, 255, 255], port).into();
        let capture = listen_shared(port);
        let thread = std::thread::spawn(move || {
            let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
            socket.set_broadcast(true).unwrap();
            capture.set_nonblocking(true).unwrap();
            let fake = |name: &str| {
                let at: SocketAddr = "127.0.0.1:9".parse().unwrap();
                Announcement::new(PROTOCOL_VERSION, at, name, "stolen", true)
            };
            let mut untagged = Sender::new(fake("forged-untagged"), None);
            let mut guessed = Sender::new(fake("forged-guessed"), Some(b"password"));
            let mut old = Sender::new(fake("forged-stale"), Some(secret));
            let mut captured: Vec<Vec<u8>> = Vec::new();
            let mut buf = [0u8; 1024];
            while !done.load(Ordering::SeqCst) {
                while let Ok((n, _)) = capture.recv_from(&mut buf) {
                    if captured.len() < 4 {
                        captured.push(buf[..n].to_vec());
                    }
                }
                let now = now_ms();
                let mut datagrams = vec![
                    untagged.next(now).unwrap(),
                    guessed.next(now).unwrap(),
                    old.next(now - 10 * 60 * 1000).unwrap(),
                ];
                datagrams.extend(captured.iter().cloned());
                for d in &datagrams {
                    let _ = socket.send_to(d, to);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        Forger { stop, thread: Some(thread) }
    }
}

impl Drop for Forger {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// A socket on `port` shared with the workers listening there.
fn listen_shared(port: u16) -> UdpSocket {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, None).unwrap();
    socket.set_reuse_address(true).unwrap();
    socket.set_reuse_port(true).unwrap();
    let any: SocketAddr = ([0, 0, 0, 0], port).into();
    socket.bind(&any.into()).unwrap();
    socket.into()
}

const SECRET: &[u8] = b"office secret";

#[test]
fn a_worker_with_a_secret_ignores_forged_announcements_and_joins_the_genuine_master() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let secret_file = dir.path().join("grid.secret");
    std::fs::write(&secret_file, SECRET).unwrap();
    let secret_arg = secret_file.to_str().unwrap();
    let to = format!("127.255.255.255:{port}");
    // An honest master without a secret (its announcements are untagged) ...
    let decoy = announcing_master(&dir.path().join("d"), "decoy", port);
    // ... the grid's own master ...
    let lab = Master::start(
        &dir.path().join("lab"),
        "127.0.0.1:0",
        &["--name", "lab", "--announce-to", &to, "--secret-file", secret_arg],
    );
    // ... and a forger. Believing any of the others would make the choice ambiguous.
    let _forger = Forger::start(port, SECRET);

    let cache = dir.path().join("cache");
    let trusting = discovering_worker(port, &cache, &["--secret-file", secret_arg]);
    eventually("a frame rendered by the worker with the secret", || {
        lab.stats().iter().any(|s| u(s, "workers") == 1 && u(s, "jobs_back") > 0).then_some(())
    });
    let log = strip_ansi(&trusting.stderr());
    assert!(log.contains("master found") && log.contains("lab"), "{log}");
    let warnings = log.lines().filter(|l| l.contains("announcement ignored")).count();
    assert_eq!(warnings, 1, "one warning, not one per datagram:\n{log}");
    assert!(!decoy.proc.stderr().contains("worker joined"), "the decoy got a worker");

    // A worker without a secret cannot check tags and still finds an unauthenticated
    // master, as before.
    let _plain = discovering_worker(port, &dir.path().join("c2"), &["--master-name", "decoy"]);
    eventually("the decoy's worker rendering", || {
        decoy.stats().iter().any(|s| u(s, "workers") == 1 && u(s, "jobs_back") > 0).then_some(())
    });
}

#[test]
fn a_worker_whose_secret_verifies_no_announcement_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_udp_port();
    let to = format!("127.255.255.255:{port}");
    let secret_file = dir.path().join("grid.secret");
    std::fs::write(&secret_file, SECRET).unwrap();
    let other = dir.path().join("other.secret");
    std::fs::write(&other, b"another office").unwrap();
    let _lab = Master::start(
        &dir.path().join("lab"),
        "127.0.0.1:0",
        &["--name", "lab", "--announce-to", &to, "--secret-file", secret_file.to_str().unwrap()],
    );
    let mut w = discovering_worker(
        port,
        dir.path(),
        &["--secret-file", other.to_str().unwrap(), "--discover-timeout", "2"],
    );
    let status = w.wait(PATIENCE).expect("the worker gives up");
    assert!(!status.success());
    let err = strip_ansi(&w.stderr());
    assert!(err.contains("no gridlight master announced itself"), "{err}");
    assert!(err.contains("bad tag") && err.contains("same --secret-file"), "{err}");
}
