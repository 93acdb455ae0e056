//! The encrypted channel as an attacker on the LAN sees it (issue 42): everything a
//! worker and a master with a shared secret exchange goes through the fault proxy,
//! which records each connection's two directions and can change any one byte.
//!
//! - A capture holds no piece of the scene state, of an asset (a mesh and a texture), of
//!   a job or of a result's radiance, and its records look random (entropy per byte),
//!   while the same session without a secret shows all of them (so the search works).
//! - One byte flipped either way, at several places (inside a result, its tag, its
//!   record length, the first record, a job, the scene state) ends that connection with
//!   a typed rejection on the side that reads it; nothing wrong reaches an image and the
//!   master goes on with the worker's next connection.
//! - A recorded session replayed to the master is refused at its first record, and the
//!   replayer reads nothing but a fresh handshake answer and a refusal.
//! - A worker with the wrong secret is refused on its first message: the only thing it
//!   ever reads is the refusal.
//!
//! The master runs in this process (its counters and a checking sink); workers are real
//! `gridlight worker --null-render` processes, whose logs say what they refused.

#[path = "../actors/tests/common.rs"]
mod common;
mod support;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use bytes::BytesMut;
use gridlight::tools::faults::invariants::{lock, Checker, CheckingSink, Limits, SharedChecker};
use gridlight::tools::faults::proxy::{Direction, Proxy, Tamper};
use gridlight::worker::render::null_radiance;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::channel::TAG_LEN;
use gridlight_actors::codec::{to_frame, MasterCodec, WorkerCodec};
use gridlight_actors::counters::Counters;
use gridlight_actors::master::{start, MasterHandle};
use gridlight_actors::protocol::{MasterMsg, PackedRadiance, WorkerMsg};
use support::{eventually, Proc, PATIENCE};
use tokio_util::codec::Decoder;

const SECRET: &str = "9f2c41d07be35a68e1c4f0b2d97a3e55";

/// A master (with or without the secret) behind a capturing proxy, with a mesh and a
/// texture to serve.
struct Grid {
    master: MasterHandle,
    proxy: Proxy,
    checker: SharedChecker,
    dir: tempfile::TempDir,
    secret: bool,
    mesh: Vec<u8>,
    texture: Vec<u8>,
}

impl Grid {
    fn start(secret: bool) -> Grid {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut rng = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let mut mesh = String::new();
        for _ in 0..300 {
            let v = [next(), next(), next()].map(|r| (r % 20_000) as f32 / 1000.0 - 10.0);
            mesh += &format!("v {:.4} {:.4} {:.4}\n", v[0], v[1], v[2]);
        }
        for i in 0..298 {
            mesh += &format!("f {} {} {}\n", i + 1, i + 2, i + 3);
        }
        let texture: Vec<u8> = (0..16 * 1024).map(|_| next() as u8).collect();
        let mut assets = AssetStore::new();
        for (name, bytes) in [("mesh.obj", mesh.as_bytes()), ("wood.png", &texture[..])] {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).expect("asset");
            assets.add_file(name, &path).expect("hash");
        }
        std::fs::write(dir.path().join("secret"), SECRET).expect("secret");
        std::fs::write(dir.path().join("wrong"), "a guess").expect("wrong secret");

        let mut config = common::config();
        config.secret = secret.then(|| SECRET.as_bytes().to_vec());
        let limits = Limits { sets: common::S, max_gap: Duration::from_secs(60) };
        let checker = Arc::new(Mutex::new(Checker::new(limits, Some(null_radiance))));
        let sink = Box::new(CheckingSink(checker.clone()));
        let master = start(config, common::scene(), assets, sink).expect("master");
        let proxy = Proxy::start(master.local_addr()).expect("proxy");
        proxy.start_capture();
        Grid { master, proxy, checker, dir, secret, mesh: mesh.into_bytes(), texture }
    }

    /// A null-render worker process named `name` through the proxy, with the grid's
    /// secret (or `secret_file` instead).
    fn worker(&self, name: &str, secret_file: Option<&str>) -> Proc {
        let file: PathBuf = self.dir.path().join(secret_file.unwrap_or("secret"));
        let file = file.to_str().expect("path");
        let args: &[&str] = if self.secret { &["--secret-file", file] } else { &[] };
        support::worker(self.proxy.local_addr(), &self.dir.path().join("cache"), name, 1, args)
    }

    /// Waits for `n` more frames to be shown.
    fn frames(&self, n: u64) {
        let want = self.master.report().shown + n;
        assert!(self.master.wait_for_frames(want, PATIENCE), "fewer than {want} frames shown");
    }

    fn rejections(&self, kind: &str) -> u64 {
        self.master.counters().rejections().get(kind).copied().unwrap_or(0)
    }

    fn assert_no_violation(&self) {
        let ck = lock(&self.checker);
        assert_eq!(ck.violations(), 0, "{:?}", ck.violation_texts());
    }
}

/// The records of one direction of an encrypted connection, after its first (plain,
/// handshake) frame: each record's offset in the stream and its ciphertext.
fn records(stream: &[u8]) -> Vec<(usize, &[u8])> {
    let mut out = Vec::new();
    let Some(prefix) = stream.get(..4) else { return out };
    let mut at = 4 + u32::from_be_bytes(prefix.try_into().expect("4 bytes")) as usize;
    while at + 2 <= stream.len() {
        let n = u16::from_be_bytes([stream[at], stream[at + 1]]) as usize;
        let Some(record) = stream.get(at + 2..at + 2 + n) else { break };
        out.push((at, record));
        at += 2 + n;
    }
    out
}

/// Shannon entropy of `bytes`, in bits per byte.
fn entropy(bytes: &[u8]) -> f64 {
    let mut counts = [0u64; 256];
    bytes.iter().for_each(|&b| counts[b as usize] += 1);
    let n = bytes.len() as f64;
    counts.iter().filter(|&&c| c > 0).map(|&c| -(c as f64 / n) * (c as f64 / n).log2()).sum()
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

/// Every message of a plain stream, decoded.
fn decode_all<D: Decoder>(mut codec: D, stream: &[u8]) -> Vec<D::Item> {
    let mut buf = BytesMut::from(stream);
    let mut out = Vec::new();
    while let Ok(Some(m)) = codec.decode(&mut buf) {
        out.push(m);
    }
    out
}

/// A session of one worker for `frames` frames; the proxy's capture of it, per
/// connection `[up, down]`.
fn session(grid: &Grid, frames: u64) -> Vec<[Vec<u8>; 2]> {
    let w = grid.worker("captured", None);
    grid.frames(frames);
    drop(w);
    grid.proxy.captured_connections()
}

#[test]
fn a_capture_holds_none_of_the_scene_its_assets_jobs_or_pixels_and_looks_random() {
    let open = Grid::start(false);
    let plain = session(&open, 6);
    let (up, down): (Vec<u8>, Vec<u8>) =
        (plain.iter().flat_map(|c| c[0].clone()).collect(), plain[0][1].clone());
    // What travels, as the open session shows it: 32-byte slices of the scene state, of
    // both assets and of a result's radiance; jobs whole (a job's frame is shorter).
    let mut needles: Vec<(String, Vec<u8>)> = Vec::new();
    for (what, bytes) in [("mesh", &open.mesh), ("texture", &open.texture)] {
        for at in [0, bytes.len() / 2, bytes.len() - 32] {
            needles.push((format!("{what} at {at}"), bytes[at..at + 32].to_vec()));
        }
    }
    for msg in decode_all(WorkerCodec::new(), &down) {
        let frame = to_frame(&msg).expect("encode");
        match msg {
            MasterMsg::State(_) => {
                let mid = frame.len() / 2;
                needles.push(("scene state".into(), frame[mid - 16..mid + 16].to_vec()));
            }
            MasterMsg::Job { frame: f, set, .. } => needles.push((format!("job {f}/{set}"), frame)),
            _ => {}
        }
    }
    for msg in decode_all(MasterCodec::new(), &plain[0][0]) {
        if let WorkerMsg::Result(r) = msg {
            let PackedRadiance::Rgb9e5(words) = &r.radiance;
            let bytes: &[u8] = bytemuck::cast_slice(&words[..8]);
            needles.push((format!("radiance of frame {}", r.frame), bytes.to_vec()));
        }
    }
    let kinds = ["mesh", "texture", "scene state", "job", "radiance"];
    for kind in kinds {
        assert!(needles.iter().any(|(n, _)| n.starts_with(kind)), "no {kind} in the open session");
    }
    let plain_all = open.proxy.captured();
    for (what, needle) in &needles {
        assert!(contains(&plain_all, needle), "{what} is not where the search looks");
    }
    let plain_entropy = entropy(&up);
    drop(open);

    let sealed = Grid::start(true);
    let capture = session(&sealed, 6);
    let all = sealed.proxy.captured();
    for (what, needle) in &needles {
        assert!(!contains(&all, needle), "{what} crossed the wire readable");
    }
    assert!(!contains(&all, SECRET.as_bytes()), "the secret crossed the wire");
    // Past each direction's handshake frame, everything is records; their ciphertext is
    // as random as bytes go (a measured 7.99+ bits/byte over the ~100 KB of a session).
    let mut payload = Vec::new();
    for conn in &capture {
        for stream in conn {
            let recs = records(stream);
            let used: usize = recs.iter().map(|(_, r)| 2 + r.len()).sum();
            let first = stream.len() - used;
            assert!(first <= 128, "{} bytes are not records", first);
            recs.iter().for_each(|(_, r)| payload.extend_from_slice(r));
        }
    }
    assert!(payload.len() >= 32 * 1024, "only {} bytes of records", payload.len());
    let sealed_entropy = entropy(&payload);
    assert!(
        sealed_entropy >= 7.9,
        "records carry {sealed_entropy:.3} bits/byte over {} bytes",
        payload.len()
    );
    assert!(plain_entropy < 7.9, "the open session already looked random: {plain_entropy:.3}");
    sealed.assert_no_violation();
}

/// The bit each flip inverts: the lowest, so that a flip meant for a length's low byte
/// that lands on its high byte lengthens the record by 256 bytes, not 4 KiB.
const FLIP_BITS: u8 = 0x01;

/// Where a byte is flipped: a direction, an offset in a connection's stream, and what
/// the side reading it must say.
struct Flip {
    what: &'static str,
    dir: Direction,
    at: usize,
}

/// Places worth flipping, from a clean connection made with the same (warm) cache and a
/// worker name of the same length: the next one's records have the same lengths up to
/// the first timing difference (a heartbeat, a longer render time).
fn flip_places(conn: &[Vec<u8>; 2]) -> Vec<Flip> {
    let up = records(&conn[0]);
    let down = records(&conn[1]);
    let job_len =
        to_frame(&MasterMsg::Job { frame: 1, set: 0, state_version: 1, spp: 4 }).expect("job");
    let results: Vec<_> = up.iter().filter(|(_, r)| r.len() > 300).collect();
    // Down: Challenge, Welcome, the state (the largest record: the cache is warm, no
    // asset), then jobs. Since protocol 10 a heartbeat has a job's length; the master sends
    // one only after an idle interval, and a flipped heartbeat must be refused as surely
    // as a flipped job, so the records of a job's length after the state are taken as jobs.
    let state_at = (0..down.len()).max_by_key(|&i| down[i].1.len()).expect("records down");
    let state = &down[state_at];
    let jobs: Vec<_> =
        down[state_at + 1..].iter().filter(|(_, r)| r.len() == job_len.len() + TAG_LEN).collect();
    assert!(
        results.len() >= 4 && jobs.len() >= 2,
        "{} results, {} jobs",
        results.len(),
        jobs.len()
    );
    let mid = |(at, r): &(usize, &[u8])| at + 2 + r.len() / 2;
    vec![
        Flip { what: "inside a result", dir: Direction::Up, at: mid(results[2]) },
        // The tag's middle byte, not its last: the worker's Hello differs by a few bytes
        // between connections (it carries measured figures), so every later offset moves.
        Flip {
            what: "a result's tag",
            dir: Direction::Up,
            at: results[1].0 + 2 + results[1].1.len() - TAG_LEN / 2,
        },
        // The length's low byte: the record ends a byte off. Should the shift above land
        // the flip on a high byte instead, FLIP_BITS keeps the error to 256 bytes, which
        // the worker's next result supplies (0x10 there would wait for 4 KiB forever).
        Flip { what: "a result's record length", dir: Direction::Up, at: results[3].0 + 1 },
        Flip { what: "the first record (Hello)", dir: Direction::Up, at: mid(&up[0]) },
        Flip { what: "inside a job", dir: Direction::Down, at: mid(jobs[1]) },
        Flip { what: "inside the scene state", dir: Direction::Down, at: mid(state) },
    ]
}

#[test]
fn a_flipped_byte_either_way_ends_that_connection_and_nothing_reaches_an_image() {
    let grid = Grid::start(true);
    // Warm the cache, then record a clean connection to find the places.
    drop(session(&grid, 3));
    let probe = grid.worker("probe", None);
    grid.frames(4);
    drop(probe);
    let conns = grid.proxy.captured_connections();
    let places = flip_places(conns.last().expect("the probe's connection"));

    for (i, flip) in places.iter().enumerate() {
        let decrypt_before = grid.rejections("decrypt");
        let connections = grid.proxy.stats().connections.load(std::sync::atomic::Ordering::Relaxed);
        grid.proxy.tamper_next(Tamper { dir: flip.dir, at: flip.at as u64, xor: FLIP_BITS });
        let w = grid.worker(&format!("flip{i}"), None);
        match flip.dir {
            // The master reads it: a typed rejection, counted by kind.
            Direction::Up => eventually(flip.what, || {
                (grid.rejections("decrypt") > decrypt_before).then_some(())
            }),
            // The worker reads it: it ends the connection, naming the cause.
            Direction::Down => eventually(flip.what, || {
                w.stderr().contains("a record failed authentication").then_some(())
            }),
        }
        // The worker's next connection works, and the master went on all along.
        eventually("a reconnection", || {
            let now = grid.proxy.stats().connections.load(std::sync::atomic::Ordering::Relaxed);
            (now >= connections + 2).then_some(())
        });
        grid.frames(2);
        drop(w);
    }
    assert!(Counters::get(&grid.master.counters().results_accepted) > 0);
    grid.assert_no_violation();
}

#[test]
fn a_replayed_session_is_refused_at_its_first_record() {
    use std::io::{Read, Write};
    let grid = Grid::start(true);
    let conns = session(&grid, 3);
    let recorded = &conns[0];
    let accepted = Counters::get(&grid.master.counters().results_accepted);
    let decrypt_before = grid.rejections("decrypt");

    let mut replay = std::net::TcpStream::connect(grid.master.local_addr()).expect("connect");
    replay.set_read_timeout(Some(Duration::from_secs(20))).expect("timeout");
    // Everything the worker sent, as it was sent; the master may close while it is
    // being written.
    let _ = replay.write_all(&recorded[0]);
    let mut answer = Vec::new();
    let _ = replay.read_to_end(&mut answer);

    eventually("the replay's refusal", || {
        (grid.rejections("decrypt") > decrypt_before).then_some(())
    });
    assert_eq!(Counters::get(&grid.master.counters().results_accepted), accepted);
    // A fresh handshake answer (not the recorded one), then at most one record: the
    // refusal. No challenge, manifest, state, asset or job.
    let first = 4 + u32::from_be_bytes(answer[..4].try_into().expect("prefix")) as usize;
    let Some(MasterMsg::Handshake { noise }) =
        decode_all(WorkerCodec::new(), &answer[..first]).pop()
    else {
        panic!("the master did not answer the replayed handshake: {answer:?}")
    };
    assert!(!contains(&recorded[1], &noise), "the master answered with recorded keys");
    assert!(records(&answer).len() <= 1, "the replayer read {} records", records(&answer).len());
    assert!(answer.len() < 256, "the replayer read {} bytes", answer.len());
    grid.assert_no_violation();
}

#[test]
fn a_worker_with_the_wrong_secret_reads_nothing_but_its_refusal() {
    let grid = Grid::start(true);
    let mut w = grid.worker("guesser", Some("wrong"));
    let status = w.wait(PATIENCE).expect("the worker gives up");
    assert!(!status.success());
    assert!(w.stderr().contains("wrong shared secret"), "{}", w.stderr());
    let conns = grid.proxy.captured_connections();
    let down = &conns[0][1];
    let got = decode_all(WorkerCodec::new(), down);
    assert!(
        matches!(&got[..], [MasterMsg::Rejected { .. }]),
        "the worker read more than its refusal: {got:?}"
    );
    assert_eq!(to_frame(&got[0]).expect("encode").len(), down.len(), "bytes beside the refusal");
    assert_eq!(grid.rejections("auth"), 1);
    assert_eq!(grid.master.report().shown, 0, "a frame was shown");
}
