//! A connection flood from one host against a real master process, as an attacker on the
//! LAN would try it: connections from 127.0.0.2 (another host, as far as the master can
//! tell), half sending garbage and half silent, reopened as the master closes them. An
//! honest worker from 127.0.0.1 that starts in the middle must be welcomed while the flood
//! goes on, and the master must log refusals as summaries, not one line per peer.
//!
//! The figures of the flood (2 000 connections) come from the same test:
//! `GRIDLIGHT_FLOOD=2000 cargo test --test faults_flood -- --nocapture` prints
//! `flood: ...` with the time the worker took to be welcomed and the master's WARN lines.

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod support;
use support::*;

/// Connections the flood keeps open (`GRIDLIGHT_FLOOD` overrides).
const DEFAULT_FLOOD: usize = 300;
/// Where the flood comes from: another loopback address, so it is another host to the
/// master (Linux routes all of 127/8 to the loopback interface).
const ATTACKER: [u8; 4] = [127, 0, 0, 2];

/// The attacker: keeps `n` connections to `master` open, reopening (at most one per
/// millisecond) those the master closes; even ones send garbage, odd ones nothing.
struct Flood {
    stop: Arc<AtomicBool>,
    opened: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Flood {
    fn start(master: SocketAddr, n: usize) -> Flood {
        let stop = Arc::new(AtomicBool::new(false));
        let opened = Arc::new(AtomicU64::new(0));
        let (done, count) = (Arc::clone(&stop), Arc::clone(&opened));
        let thread = std::thread::spawn(move || {
            let mut open: Vec<Option<TcpStream>> = (0..n).map(|_| None).collect();
            let mut buf = [0u8; 4096];
            while !done.load(Ordering::SeqCst) {
                for (i, slot) in open.iter_mut().enumerate() {
                    if done.load(Ordering::SeqCst) {
                        break;
                    }
                    if let Some(s) = slot {
                        // Closed by the master (or reset): open another.
                        match s.read(&mut buf) {
                            Ok(0) => *slot = None,
                            Err(e) if e.kind() != std::io::ErrorKind::WouldBlock => *slot = None,
                            _ => {}
                        }
                    }
                    if slot.is_none() {
                        *slot = connect_from_attacker(master, i % 2 == 0);
                        count.fetch_add(1, Ordering::SeqCst);
                        std::thread::sleep(Duration::from_millis(1));
                    }
                }
                std::thread::sleep(Duration::from_millis(5));
            }
        });
        Flood { stop, opened, thread: Some(thread) }
    }

    fn opened(&self) -> u64 {
        self.opened.load(Ordering::SeqCst)
    }

    fn running(&self) -> bool {
        self.thread.as_ref().is_some_and(|t| !t.is_finished())
    }
}

impl Drop for Flood {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn connect_from_attacker(master: SocketAddr, garbage: bool) -> Option<TcpStream> {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::STREAM, None).ok()?;
    socket.bind(&SocketAddr::from((ATTACKER, 0)).into()).ok()?;
    socket.connect_timeout(&master.into(), Duration::from_secs(1)).ok()?;
    let mut s: TcpStream = socket.into();
    if garbage {
        let junk: Vec<u8> =
            (0..200u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let _ = s.write_all(&junk);
    }
    s.set_nonblocking(true).ok()?;
    Some(s)
}

fn warn_lines(log: &str) -> Vec<&str> {
    log.lines().filter(|l| l.contains(" WARN ")).collect()
}

#[test]
fn an_honest_worker_is_welcomed_during_a_flood_and_refusals_are_summarised() {
    let n =
        std::env::var("GRIDLIGHT_FLOOD").ok().and_then(|v| v.parse().ok()).unwrap_or(DEFAULT_FLOOD);
    let dir = tempfile::tempdir().unwrap();
    let master = Master::start(&dir.path().join("m"), "127.0.0.1:0", &[]);
    let flood = Flood::start(master.addr, n);
    eventually("half the flood open", || (flood.opened() >= n as u64 / 2).then_some(()));

    let started = Instant::now();
    let honest = worker(master.addr, &dir.path().join("cache"), "honest", 2, &[]);
    eventually("the honest worker welcomed", || honest.stderr().contains("welcomed").then_some(()));
    let welcomed_after = started.elapsed();
    assert!(flood.running(), "the flood ended before the worker was welcomed");
    let opened_by_then = flood.opened();
    assert!(opened_by_then >= n as u64 / 2, "the flood did not happen");
    master.wait_more_frames(3);
    let warns_by_then = warn_lines(&master.proc.stderr()).len();
    eprintln!(
        "flood: {n} connections kept open from 127.0.0.2, {opened_by_then} opened when the honest \
         worker was welcomed {:.2} s after it started; {warns_by_then} master WARN lines over {:.1} s",
        welcomed_after.as_secs_f64(),
        started.elapsed().as_secs_f64()
    );

    // The refusals so far appear as summaries: a count per kind and address.
    let summary = eventually("a summary of the refusals", || {
        let log = master.proc.stderr();
        log.lines()
            .find(|l| l.contains("refused (summary)") && l.contains("127.0.0.2"))
            .map(str::to_owned)
    });
    let log = master.proc.stderr();
    let warns = warn_lines(&log);
    eprintln!(
        "flood: {} master WARN lines over {:.1} s (first summary included), {} connections opened",
        warns.len(),
        started.elapsed().as_secs_f64(),
        flood.opened()
    );
    assert!(field(&summary, "count").is_some_and(|c| c > 1), "{summary}");
    let per_peer = warns.iter().filter(|l| l.contains("127.0.0.2:")).count();
    assert!(
        per_peer == 0,
        "{per_peer} WARN lines name one flooding peer each:\n{}",
        warns.join("\n")
    );
    assert!(warns.len() < 50, "{} WARN lines:\n{}", warns.len(), warns.join("\n"));
}
