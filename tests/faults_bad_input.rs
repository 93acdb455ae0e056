//! The bad-input matrix (issue 6) against the master's actor system in-process
//! (`gridlight_actors::master::start`) over real loopback TCP.
//!
//! Every case is a scripted peer doing one wrong thing. For each the test checks: the
//! peer gets a `Rejected` naming the problem (or, when it broke the stream itself, the
//! socket closes), the master's log names the peer's address, that connection is
//! closed, a counter of that kind increased, and a well-behaved worker connected all
//! along keeps getting work and delivering results. The master runs with a shared
//! secret, so authentication failures are part of the matrix.

#[path = "../actors/tests/common.rs"]
mod common;

use std::io::Write;
use std::net::{Shutdown, SocketAddr, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread;
use std::time::{Duration, Instant};

use common::*;
use glam::Vec3;
use gridlight::scene::{manifest, AssetSearchPath};
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::codec::to_frame;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{start, MasterConfig, MasterHandle};
use gridlight_actors::packing::pack;
use gridlight_actors::protocol::*;
use gridlight_actors::state::{Geometry, StateVersion};
use rand::{Rng, SeedableRng};
use serde::Serialize;

const SECRET: &[u8] = b"matrix-secret";
const PEER_TIMEOUT: Duration = Duration::from_millis(800);
const WAIT: Duration = Duration::from_secs(10);

/// Every log line of this test binary, to check that errors name the peer.
fn logs() -> &'static Arc<Mutex<Vec<u8>>> {
    static LOGS: OnceLock<Arc<Mutex<Vec<u8>>>> = OnceLock::new();
    LOGS.get_or_init(|| {
        let buf = Arc::new(Mutex::new(Vec::new()));
        let sink = buf.clone();
        let _ = tracing_subscriber::fmt()
            .with_env_filter("gridlight_actors=info")
            .with_ansi(false)
            .with_writer(move || LogWriter(sink.clone()))
            .try_init();
        buf
    })
}

struct LogWriter(Arc<Mutex<Vec<u8>>>);

impl Write for LogWriter {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Waits until the log has a line naming `peer` and containing `what`.
fn log_names(peer: SocketAddr, what: &str) -> bool {
    let needle = format!("peer={peer}");
    let deadline = Instant::now() + WAIT;
    while Instant::now() < deadline {
        let text =
            String::from_utf8_lossy(&logs().lock().unwrap_or_else(|p| p.into_inner())).into_owned();
        if text.lines().any(|l| l.contains(&needle) && l.contains(what)) {
            return true;
        }
        thread::sleep(Duration::from_millis(20));
    }
    false
}

fn config() -> MasterConfig {
    let mut c = common::config();
    c.secret = Some(SECRET.to_vec());
    c.peer_timeout = PEER_TIMEOUT;
    c.heartbeat = Duration::from_millis(200);
    c
}

/// A well-behaved worker answering every job until `stop`; counts its results.
fn bystander(addr: SocketAddr, stop: Arc<AtomicBool>) -> thread::JoinHandle<Result<u64, String>> {
    thread::spawn(move || {
        let table = table();
        let mut p = Peer::connect(addr);
        p.handshake(Some(SECRET))?;
        p.send(&WorkerMsg::Ready { credits: 2 });
        let mut answered = 0;
        while !stop.load(Ordering::Relaxed) {
            let (frame, set, version, _) = p.next_job()?;
            if !p.answer(&table, frame, set, version, frame_value(frame))
                || !p.try_send(&WorkerMsg::Ready { credits: 1 })
            {
                return Err(format!("bystander cut off after {answered} results"));
            }
            answered += 1;
        }
        Ok(answered)
    })
}

/// Waits until `f` holds.
fn eventually(mut f: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + WAIT;
    while Instant::now() < deadline {
        if f() {
            return true;
        }
        thread::sleep(Duration::from_millis(10));
    }
    false
}

fn kind_count(m: &MasterHandle, kind: &str) -> u64 {
    m.counters().rejections().get(kind).copied().unwrap_or(0)
}

/// How one case ends on the wire.
enum Expect {
    /// `Rejected` whose reason contains this, then close.
    Rejected(&'static str),
    /// The peer broke the stream itself: the master just closes.
    Closed,
}

struct Case {
    name: &'static str,
    /// The counter kind that must increase.
    kind: &'static str,
    expect: Expect,
    /// Does the wrong thing on a fresh connection.
    act: fn(&mut Peer, &TcpStream),
}

fn hello() -> WorkerMsg {
    WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "bad-peer".into(), cores: 1 }
}

/// Handshake with the right secret, then one job; answers what the job named.
fn first_job(p: &mut Peer) -> (FrameNo, SetNo, StateVersion) {
    p.handshake(Some(SECRET)).expect("handshake");
    p.send(&WorkerMsg::Ready { credits: 1 });
    let (f, s, v, _) = p.next_job().expect("job");
    (f, s, v)
}

/// A message the worker side does not have: same variants as `WorkerMsg`, one more.
#[derive(Serialize)]
#[allow(dead_code)]
enum FutureWorkerMsg {
    Hello { protocol: u32, name: String, cores: u32 },
    Auth { mac: Option<[u8; 32]> },
    AssetRequest { hash: AssetHash },
    Ready { credits: u32 },
    Result(JobResult),
    Heartbeat,
    Shutdown { now: bool },
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "random bytes",
            kind: "bad_frame",
            expect: Expect::Rejected("bad frame"),
            act: |p, _| {
                let mut rng = rand::rngs::StdRng::seed_from_u64(6);
                let mut bytes = 200u32.to_be_bytes().to_vec();
                bytes.extend((0..200).map(|_| rng.gen::<u8>()));
                p.send_raw(&bytes);
            },
        },
        Case {
            name: "zero length prefix",
            kind: "empty_frame",
            expect: Expect::Rejected("empty frame"),
            act: |p, _| p.send_raw(&[0, 0, 0, 0]),
        },
        Case {
            name: "oversized length prefix",
            kind: "oversized_frame",
            expect: Expect::Rejected("exceeds"),
            act: |p, _| p.send_raw(&u32::MAX.to_be_bytes()),
        },
        Case {
            name: "truncated frame, then EOF",
            kind: "io",
            expect: Expect::Closed,
            act: |p, raw| {
                let frame = to_frame(&hello()).expect("encode");
                p.send_raw(&frame[..frame.len() - 3]);
                raw.shutdown(Shutdown::Write).expect("half-close");
            },
        },
        Case {
            name: "truncated frame, then silence",
            kind: "timeout",
            expect: Expect::Rejected("no message"),
            act: |p, _| {
                let frame = to_frame(&hello()).expect("encode");
                p.send_raw(&frame[..frame.len() - 3]);
            },
        },
        Case {
            name: "valid frame of an unknown message",
            kind: "bad_frame",
            expect: Expect::Rejected("bad frame"),
            act: |p, _| {
                p.send_raw(&to_frame(&FutureWorkerMsg::Shutdown { now: true }).expect("enc"))
            },
        },
        Case {
            name: "message out of phase",
            kind: "phase",
            expect: Expect::Rejected("unexpected Result"),
            act: |p, _| {
                let msg = p.result(1, 0, 1, PackedRadiance::Rgb9e5(vec![0; 4]));
                p.send(&msg)
            },
        },
        Case {
            name: "wrong protocol version",
            kind: "version",
            expect: Expect::Rejected("protocol version"),
            act: |p, _| p.send(&WorkerMsg::Hello { protocol: 0, name: "old".into(), cores: 1 }),
        },
        Case {
            name: "missing secret",
            kind: "auth",
            expect: Expect::Closed, // the handshake below already read the Rejected
            act: |p, _| {
                let err = p.handshake(None).expect_err("welcomed without a secret");
                assert!(err.contains("sent none"), "{err}");
            },
        },
        Case {
            name: "wrong secret",
            kind: "auth",
            expect: Expect::Closed, // the handshake below already read the Rejected
            act: |p, _| {
                let err = p.handshake(Some(b"guess")).expect_err("welcomed with a wrong secret");
                assert!(err.contains("wrong shared secret"), "{err}");
            },
        },
        Case {
            name: "result with the wrong pixel count",
            kind: "pixel_count",
            expect: Expect::Rejected("pixels"),
            act: |p, _| {
                let (frame, set, state_version) = first_job(p);
                let radiance = pack(&[Vec3::ONE; 1]).expect("pack");
                let msg = p.result(frame, set, state_version, radiance);
                p.send(&msg);
            },
        },
        Case {
            name: "result whose record was altered on the wire",
            kind: "decrypt",
            expect: Expect::Rejected("failed authentication"),
            act: |p, _| {
                let (frame, set, state_version) = first_job(p);
                let n = table().set_len(set);
                let radiance = pack(&vec![Vec3::splat(frame_value(frame)); n]).expect("pack");
                let result = p.result(frame, set, state_version, radiance);
                // One bit of the sealed record's ciphertext, as a bad link (or an attacker
                // on the path) would flip it: only the channel's tag can tell.
                let mut bytes = p.encode(&result);
                let middle = bytes.len() / 2;
                bytes[middle] ^= 1 << 3;
                p.send_raw(&bytes);
            },
        },
        Case {
            name: "result for a set never handed to this connection",
            kind: "unknown_result",
            expect: Expect::Rejected("not given"),
            act: |p, _| {
                let (frame, set, version) = first_job(p);
                p.answer(&table(), frame + 1000, set, version, 1.0);
            },
        },
        Case {
            name: "slowloris (connects, says nothing)",
            kind: "timeout",
            expect: Expect::Rejected("no message"),
            act: |_, _| {},
        },
        Case {
            name: "asset request for a hash the scene does not use",
            kind: "asset",
            expect: Expect::Rejected("not in the manifest"),
            act: |p, _| {
                p.handshake(Some(SECRET)).expect("handshake");
                p.send(&WorkerMsg::AssetRequest { hash: [0xab; 32] });
            },
        },
    ]
}

/// Runs one case against a running master and checks all it must.
fn run_case(m: &MasterHandle, case: &Case) {
    eprintln!("case: {}", case.name);
    let before = kind_count(m, case.kind);
    let mut p = Peer::connect(m.local_addr());
    let peer_addr = p.local_addr();
    let stream = p.stream_clone();
    (case.act)(&mut p, &stream);
    match case.expect {
        Expect::Rejected(needle) => {
            let reason = p.expect_rejected();
            assert!(reason.contains(needle), "{}: reason {reason:?} lacks {needle:?}", case.name);
        }
        Expect::Closed => {}
    }
    let end = p.recv_non_heartbeat();
    assert!(end.is_err(), "{}: connection still open, got {end:?}", case.name);
    assert!(
        eventually(|| kind_count(m, case.kind) > before),
        "{}: counter {:?} did not increase ({:?})",
        case.name,
        case.kind,
        m.counters().rejections()
    );
    let what = match case.expect {
        Expect::Closed if case.kind == "io" => "read failed",
        _ => "rejected",
    };
    assert!(log_names(peer_addr, what), "{}: no log line names peer {peer_addr}", case.name);
}

#[test]
fn every_bad_input_is_rejected_alone_and_the_master_and_other_workers_go_on() {
    logs();
    let (sink, rx) = collect_sink();
    let m = start(config(), scene(), AssetStore::new(), sink).expect("start");
    let stop = Arc::new(AtomicBool::new(false));
    let worker = bystander(m.local_addr(), stop.clone());
    assert!(m.wait_for_frames(2, WAIT), "no frames with a good worker");
    for case in cases() {
        let accepted = Counters::get(&m.counters().results_accepted);
        run_case(&m, &case);
        assert!(
            eventually(|| Counters::get(&m.counters().results_accepted) > accepted + 2),
            "{}: the good worker stopped delivering",
            case.name
        );
    }
    stop.store(true, Ordering::Relaxed);
    let answered = worker.join().expect("bystander thread").expect("bystander was cut off");
    assert!(answered > 0);
    assert!(!m.report().finished, "the master finished on bad input");
    // No pixel of a bad peer reached an image: every shown frame is the good worker's.
    for f in rx.try_iter() {
        let want = frame_value(f.frame);
        for (v, covered) in f.current.iter().zip(&f.current_mask) {
            assert!(
                !covered || (*v - Vec3::splat(want)).abs().max_element() < 1e-3,
                "frame {}",
                f.frame
            );
        }
    }
}

#[test]
fn one_byte_a_second_is_cut_off_by_the_silence_timeout() {
    logs();
    let (sink, _rx) = collect_sink();
    let m = start(config(), scene(), AssetStore::new(), sink).expect("start");
    let mut p = Peer::connect(m.local_addr());
    let peer_addr = p.local_addr();
    let mut stream = p.stream_clone();
    let frame = to_frame(&hello()).expect("encode");
    // One byte per PEER_TIMEOUT/3 (one a second, scaled): a frame never completes in time.
    let trickle = thread::spawn(move || {
        for b in frame {
            if stream.write_all(&[b]).is_err() {
                return true;
            }
            thread::sleep(PEER_TIMEOUT / 3);
        }
        false
    });
    let reason = p.expect_rejected();
    assert!(reason.contains("no message"), "{reason}");
    assert!(p.recv().is_err(), "connection still open");
    assert!(trickle.join().expect("trickle thread"), "the whole frame went through");
    assert!(eventually(|| kind_count(&m, "timeout") == 1));
    assert!(log_names(peer_addr, "rejected"));
    assert!(
        Peer::connect(m.local_addr()).handshake(Some(SECRET)).is_ok(),
        "master stopped serving"
    );
}

#[test]
fn connections_beyond_the_cap_are_refused_counted_and_served_once_room_is_free() {
    logs();
    let mut c = config();
    c.max_connections = 3;
    let (sink, _rx) = collect_sink();
    let m = start(c, scene(), AssetStore::new(), sink).expect("start");
    let mut held: Vec<Peer> = (0..3).map(|_| Peer::connect(m.local_addr())).collect();
    for p in &mut held {
        p.handshake(Some(SECRET)).expect("within the cap");
    }
    let mut extra = Peer::connect(m.local_addr());
    let reason = extra.expect_rejected();
    assert!(reason.contains("full"), "{reason}");
    assert!(extra.recv().is_err(), "refused connection still open");
    assert!(eventually(|| kind_count(&m, "full") == 1));
    drop(held.pop());
    assert!(
        eventually(|| Peer::connect(m.local_addr()).handshake(Some(SECRET)).is_ok()),
        "a freed slot was not served"
    );
    for p in &mut held {
        p.send(&WorkerMsg::Ready { credits: 1 });
        assert!(p.next_job().is_ok(), "a connection within the cap lost its service");
    }
}

#[test]
fn a_duplicate_result_is_dropped_and_counted_and_never_doubles_a_pixel() {
    let (sink, _rx) = collect_sink();
    let m = start(config(), scene(), AssetStore::new(), sink).expect("start");
    let mut p = Peer::connect(m.local_addr());
    let (frame, set, version) = first_job(&mut p);
    assert!(p.answer(&table(), frame, set, version, frame_value(frame)));
    assert!(p.answer(&table(), frame, set, version, frame_value(frame)));
    assert!(eventually(|| Counters::get(&m.counters().dropped_duplicate) == 1));
    assert_eq!(Counters::get(&m.counters().results_accepted), 1);
    // A duplicate is a stale message, not an attack: the worker keeps its link and work.
    p.send(&WorkerMsg::Ready { credits: 1 });
    assert!(p.next_job().is_ok(), "the worker was not served after a duplicate");
}

#[test]
fn asset_paths_outside_the_asset_folders_never_reach_the_manifest() {
    let dir = tempfile::tempdir().expect("tempdir");
    let inside = dir.path().join("assets");
    std::fs::create_dir_all(&inside).expect("mkdir");
    std::fs::write(dir.path().join("secret.obj"), "v 0 0 0\n").expect("write");
    let resolver = AssetSearchPath::from_dirs(vec![inside]);
    for path in ["../secret.obj", "/etc/passwd", "a/../../secret.obj", ""] {
        let mut state = scene();
        state.objects[0].geometry = Geometry::Obj { path: path.into() };
        let err = manifest(&state, &resolver).expect_err("a path outside the folders was listed");
        assert!(err.to_string().contains("must be relative"), "{path:?}: {err}");
    }
}
