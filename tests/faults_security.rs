//! Security with a shared secret (issue 6): no unauthenticated peer gets a job, the
//! scene, an asset or a pixel on screen, and the secret never crosses the wire.
//!
//! A real worker (the `gridlight::worker` runtime, null renderer) with the secret and
//! several intruders all talk to the in-process master through the fault proxy, which
//! captures every byte both ways; the test then searches the capture for the secret.

#[path = "../actors/tests/common.rs"]
mod common;

use std::sync::{Arc, Mutex};
use std::thread;
use std::time::Duration;

use common::{scene, Peer};
use gridlight::tools::faults::invariants::{lock, Checker, CheckingSink, Limits};
use gridlight::tools::faults::proxy::Proxy;
use gridlight::worker::render::null_radiance;
use gridlight::worker::{run_until, Priority, RendererKind, WhenIdle, WorkerConfig};
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::counters::Counters;
use gridlight_actors::master::start;
use gridlight_actors::protocol::*;
use tokio_util::sync::CancellationToken;

const SECRET: &[u8] = b"correct horse battery staple";

/// Everything an intruder received until the master closed on it.
fn drain(p: &mut Peer) -> Vec<MasterMsg> {
    let mut got = Vec::new();
    while let Ok(m) = p.recv() {
        got.push(m);
    }
    got
}

/// True for messages only an authenticated worker may ever see.
fn privileged(m: &MasterMsg) -> bool {
    matches!(
        m,
        MasterMsg::Welcome { .. }
            | MasterMsg::State(_)
            | MasterMsg::Job { .. }
            | MasterMsg::AssetChunk { .. }
    )
}

fn hello(name: &str) -> WorkerMsg {
    WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: name.into(), cores: 1 }
}

#[test]
fn unauthenticated_peers_get_nothing_and_the_secret_never_crosses_the_wire() {
    let dir = tempfile::tempdir().expect("tempdir");
    let asset = dir.path().join("mesh.obj");
    std::fs::write(&asset, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("asset");
    let mut assets = AssetStore::new();
    let asset_hash = assets.add_file("mesh.obj", &asset).expect("hash").hash;

    let mut config = common::config();
    config.secret = Some(SECRET.to_vec());
    config.peer_timeout = Duration::from_secs(2);
    let checker = Arc::new(Mutex::new(Checker::new(
        Limits { sets: common::S, max_gap: Duration::from_secs(60) },
        Some(null_radiance),
    )));
    let m = start(config, scene(), assets, Box::new(CheckingSink(checker.clone()))).expect("start");
    let proxy = Proxy::start(m.local_addr()).expect("proxy");
    proxy.start_capture();

    // The real worker, with the secret, through the proxy.
    let cancel = CancellationToken::new();
    let worker_config = WorkerConfig {
        master: proxy.local_addr().to_string(),
        threads: 1,
        secret: Some(SECRET.to_vec()),
        cache: gridlight::worker::CacheChoice::Dir(dir.path().join("cache")),
        forget_on_exit: false,
        name: "honest".into(),
        pipeline: 2,
        renderer: RendererKind::Null { delay_ms: 1 },
        priority: Priority::Idle,
        when_idle: WhenIdle::Off,
    };
    let stop = cancel.clone();
    let worker = thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("runtime");
        rt.block_on(run_until(worker_config, stop))
    });
    assert!(m.wait_for_frames(3, Duration::from_secs(20)), "the honest worker got no work");

    // Intruders, each trying another way in.
    let addr = proxy.local_addr();
    let mut no_secret = Peer::connect(addr);
    no_secret.send(&hello("no-secret"));
    no_secret.send(&WorkerMsg::Auth { mac: None });
    no_secret.send(&WorkerMsg::Ready { credits: 2 });
    let mut wrong = Peer::connect(addr);
    wrong.send(&hello("wrong"));
    wrong.send(&WorkerMsg::Auth { mac: Some([0x5a; 32]) });
    wrong.send(&WorkerMsg::AssetRequest { hash: asset_hash });
    let mut skipper = Peer::connect(addr);
    skipper.send(&hello("skipper"));
    skipper.send(&WorkerMsg::AssetRequest { hash: asset_hash });
    let mut pusher = Peer::connect(addr);
    pusher.send(&WorkerMsg::Result(JobResult {
        frame: 1,
        set: 0,
        state_version: 1,
        radiance: PackedRadiance::Rgb9e5(vec![0x7fff_ffff; 96]),
        render_us: 0,
        tag: Some([0; gridlight_actors::integrity::TAG_LEN]),
    }));
    let accepted_before = Counters::get(&m.counters().results_accepted);
    for (name, p) in [
        ("no secret", &mut no_secret),
        ("wrong secret", &mut wrong),
        ("skipped auth", &mut skipper),
        ("pusher", &mut pusher),
    ] {
        let got = drain(p);
        assert!(!got.iter().any(privileged), "{name} received {got:?}");
        assert!(
            matches!(got.last(), Some(MasterMsg::Rejected { .. })),
            "{name} was not told why it was refused: {got:?}"
        );
    }
    assert_eq!(m.worker_counts().live, 1, "an intruder counts as a worker");

    // The honest worker goes on; every pixel shown is from its frame.
    assert!(m.wait_for_frames(m.report().shown + 3, Duration::from_secs(20)));
    assert!(Counters::get(&m.counters().results_accepted) > accepted_before);
    let ck = lock(&checker);
    assert_eq!(ck.violations(), 0, "{:?}", ck.violation_texts());
    drop(ck);

    cancel.cancel();
    let _ = worker.join().expect("worker thread");
    let wire = proxy.captured();
    assert!(wire.len() > 1000, "the capture is too small to mean anything: {} bytes", wire.len());
    assert!(!wire.windows(SECRET.len()).any(|w| w == SECRET), "the shared secret crossed the wire");
    // Nor any 8-byte piece of it (a secret split over fields or frames).
    for piece in SECRET.windows(8) {
        assert!(!wire.windows(8).any(|w| w == piece), "part of the secret crossed the wire");
    }
}
