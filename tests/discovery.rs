//! Zero-configuration discovery between real processes on loopback: masters announce on
//! the loopback broadcast address (127.255.255.255), each test on a UDP port of its own
//! so that tests running at once do not hear each other, and `gridlight worker` without
//! `--master` finds them.

use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::time::{Duration, Instant};

use gridlight_actors::discovery::{Announcement, DISCOVERY_PORT};

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
            if let Ok(a) = Announcement::decode(&buf[..n]) {
                names.push(a.name);
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
