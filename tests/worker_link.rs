//! The worker runtime against a scripted master over real loopback TCP.
//!
//! The "master" here is a test script speaking the protocol through the real codec
//! (`MasterChannelCodec`), so each phase of the worker can be checked message by
//! message: the encrypted channel's handshake and HMAC with a secret, asset download into
//! the cache, credits, state before job,
//! results of the right size, reconnecting after the master goes away, and the errors
//! that must stop a worker for good.

use std::time::Duration;

use futures::{SinkExt, StreamExt};
use gridlight::worker::idle::Activity;
use gridlight::worker::{self, Priority, RendererKind, WhenIdle, WorkerConfig, WorkerError};
use gridlight_actors::channel::{respond, Psk};
use gridlight_actors::channel_codec::{KeySlot, MasterChannelCodec};
use gridlight_actors::packing::decode_rgb9e5;
use gridlight_actors::protocol::{
    AssetEntry, MasterMsg, Partition, PauseReason, SetsConfig, WorkerMsg, PROTOCOL_VERSION,
};
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::{Camera, Resolution, SceneState};
use sha2::{Digest, Sha256};
use tokio::net::{TcpListener, TcpStream};
use tokio_util::codec::Framed;
use tokio_util::sync::CancellationToken;

type Peer = Framed<TcpStream, MasterChannelCodec>;

/// No step of a scripted exchange may take longer than this.
const STEP: Duration = Duration::from_secs(10);

const SETS: SetsConfig = SetsConfig { sets: 16, partition: Partition::QuasiRandom };

fn state(version: u64) -> SceneState {
    let camera = Camera::pinhole(glam::Vec3::new(0.0, 0.0, 4.0), glam::Vec3::ZERO, 40.0);
    SceneState {
        version,
        seed: 1,
        ..SceneState::empty(Resolution { width: 32, height: 24 }, camera)
    }
}

fn config(master: String, cache: &std::path::Path, secret: Option<&[u8]>) -> WorkerConfig {
    WorkerConfig {
        master,
        threads: 1,
        secret: secret.map(<[u8]>::to_vec),
        cache: gridlight::worker::CacheChoice::Dir(cache.to_path_buf()),
        forget_on_exit: false,
        name: "test".into(),
        pipeline: 2,
        renderer: RendererKind::Null { delay_ms: 0 },
        priority: Priority::Idle,
        when_idle: WhenIdle::Off,
    }
}

async fn recv(peer: &mut Peer) -> WorkerMsg {
    loop {
        let msg = tokio::time::timeout(STEP, peer.next())
            .await
            .expect("worker answered in time")
            .expect("connection open")
            .expect("decodable message");
        if msg != WorkerMsg::Heartbeat {
            return msg;
        }
    }
}

/// The nonce this scripted master challenges with.
const NONCE: [u8; 32] = [7; 32];

async fn accept(listener: &TcpListener) -> Peer {
    let (socket, _) =
        tokio::time::timeout(STEP, listener.accept()).await.expect("worker connected").unwrap();
    Framed::new(socket, MasterChannelCodec::new(KeySlot::new()))
}

/// Answers the worker's encrypted handshake as a master with `secret`: every message
/// after it is a record of the channel.
async fn encrypt(peer: &mut Peer, secret: &[u8]) {
    let WorkerMsg::Handshake { protocol, noise } = recv(peer).await else {
        panic!("a worker with a secret starts with the encrypted handshake")
    };
    assert_eq!(protocol, PROTOCOL_VERSION);
    let (answer, keys) = respond(&Psk::derive(secret), &noise).expect("same secret");
    peer.send(MasterMsg::Handshake { noise: answer }).await.unwrap();
    peer.codec().slot().install(keys, None);
}

/// Runs the handshake up to and including Welcome; returns the worker's name.
async fn handshake(peer: &mut Peer, secret: Option<&[u8]>, assets: Vec<AssetEntry>) -> String {
    if let Some(secret) = secret {
        encrypt(peer, secret).await;
    }
    let WorkerMsg::Hello { protocol, name, .. } = recv(peer).await else {
        panic!("expected Hello")
    };
    assert_eq!(protocol, PROTOCOL_VERSION);
    let nonce = NONCE;
    peer.send(MasterMsg::Challenge { nonce, auth_required: secret.is_some() }).await.unwrap();
    let WorkerMsg::Auth { mac } = recv(peer).await else { panic!("expected Auth") };
    match secret {
        Some(s) => {
            assert_eq!(mac, Some(gridlight_actors::auth::mac(s, &nonce)), "MAC over our nonce")
        }
        None => assert_eq!(mac, None),
    }
    peer.send(MasterMsg::Welcome { worker_id: 1, sets: SETS, assets }).await.unwrap();
    name
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_authenticates_fetches_assets_renders_and_reconnects() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let secret = b"s3cret".as_slice();
    let cancel = CancellationToken::new();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), Some(secret)),
        cancel.clone(),
    ));

    let mut peer = accept(&listener).await;
    let bytes: Vec<u8> = (0..3000u32).map(|i| (i % 251) as u8).collect();
    let entry = AssetEntry {
        path: "meshes/thing.obj".into(),
        hash: Sha256::digest(&bytes).into(),
        len: bytes.len() as u64,
    };
    let name = handshake(&mut peer, Some(secret), vec![entry.clone()]).await;
    assert!(name.starts_with("test#0"), "{name}");

    // The asset is requested by hash and accepted in two chunks.
    assert_eq!(recv(&mut peer).await, WorkerMsg::AssetRequest { hash: entry.hash });
    for (offset, chunk) in [(0usize, &bytes[..1000]), (1000, &bytes[1000..])] {
        let msg = MasterMsg::AssetChunk {
            hash: entry.hash,
            offset: offset as u64,
            len: entry.len,
            data: chunk.to_vec(),
        };
        peer.send(msg).await.unwrap();
    }
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    let blob = cache.path().join("blobs").join(hex::encode(entry.hash));
    assert_eq!(std::fs::read(&blob).unwrap(), bytes, "verified asset in the cache");

    // Two jobs in flight, each answered with its set's size, then a new credit each.
    let st = state(3);
    let table = SetTable::new(st.resolution, SETS).unwrap();
    peer.send(MasterMsg::State(Box::new(st.clone()))).await.unwrap();
    for set in [5, 9] {
        peer.send(MasterMsg::Job { frame: 11, set, state_version: 3, spp: 1 }).await.unwrap();
    }
    let mut answered = vec![];
    while answered.len() < 2 {
        match recv(&mut peer).await {
            WorkerMsg::Result(r) => {
                assert_eq!((r.frame, r.state_version), (11, 3));
                assert_eq!(r.radiance.len(), table.set_len(r.set));
                // The channel authenticates it: no tag of its own.
                let key = gridlight_actors::integrity::ResultKey::Channel;
                assert!(key.verify(&r), "an encrypted connection's result carries a tag");
                let gridlight_actors::protocol::PackedRadiance::Rgb9e5(px) = &r.radiance;
                assert!(px.iter().all(|p| decode_rgb9e5(*p) == worker::render::null_radiance(11)));
                answered.push(r.set);
            }
            WorkerMsg::Ready { credits } => assert_eq!(credits, 1),
            other => panic!("unexpected {other:?}"),
        }
    }
    answered.sort();
    assert_eq!(answered, vec![5, 9]);

    // The master goes away: the worker comes back by itself, and needs no download now.
    drop(peer);
    let mut peer = accept(&listener).await;
    handshake(&mut peer, Some(secret), vec![entry]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });

    cancel.cancel();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker stopped").unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_job_naming_an_unsent_state_ends_the_link() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), None),
        cancel.clone(),
    ));
    let mut peer = accept(&listener).await;
    handshake(&mut peer, None, vec![]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    peer.send(MasterMsg::Job { frame: 1, set: 0, state_version: 42, spp: 1 }).await.unwrap();
    // The worker hangs up on this connection (no result) and reconnects.
    let closed = tokio::time::timeout(STEP, async {
        loop {
            match peer.next().await {
                None | Some(Err(_)) => break,
                Some(Ok(WorkerMsg::Heartbeat)) => {}
                Some(Ok(other)) => panic!("expected the connection to close, got {other:?}"),
            }
        }
    });
    closed.await.expect("worker closed the connection");
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Hello { .. }));
    cancel.cancel();
    assert!(tokio::time::timeout(STEP, worker).await.unwrap().unwrap().is_ok());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_corrupt_asset_is_refused_and_never_cached() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), None),
        cancel.clone(),
    ));
    let mut peer = accept(&listener).await;
    let entry = AssetEntry { path: "a.obj".into(), hash: Sha256::digest(b"good").into(), len: 4 };
    handshake(&mut peer, None, vec![entry.clone()]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::AssetRequest { hash: entry.hash });
    peer.send(MasterMsg::AssetChunk {
        hash: entry.hash,
        offset: 0,
        len: 4,
        data: b"evil".to_vec(),
    })
    .await
    .unwrap();
    // Refused: the worker drops the connection instead of going to work, and retries.
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Hello { .. }));
    assert!(!cache.path().join("blobs").join(hex::encode(entry.hash)).exists());
    cancel.cancel();
    assert!(tokio::time::timeout(STEP, worker).await.unwrap().unwrap().is_ok());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_rejected_handshake_stops_the_worker_with_the_masters_reason() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), Some(b"wrong")),
        CancellationToken::new(),
    ));
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Handshake { .. }));
    let reason = "authentication failed: wrong secret".to_string();
    peer.send(MasterMsg::Rejected { reason: reason.clone() }).await.unwrap();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker gave up").unwrap();
    match outcome {
        Err(err @ WorkerError::Rejected { .. }) => {
            assert!(err.is_fatal());
            assert!(err.to_string().contains(&reason), "{err}");
        }
        other => panic!("expected a fatal rejection, got {other:?}"),
    }
}

/// True when the worker closes the connection without sending another message.
async fn closes_without_a_word(peer: &mut Peer) -> bool {
    match tokio::time::timeout(STEP, peer.next()).await.expect("worker acted in time") {
        None | Some(Err(_)) => true,
        Some(Ok(msg)) => panic!("the worker sent {msg:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_with_a_secret_sends_nothing_to_a_master_that_cannot_prove_it() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), Some(b"ours")),
        cancel.clone(),
    ));
    // An impostor answers the handshake under another secret: the worker's check of the
    // answer fails, and it closes before its Hello (its name, its cores) is sent.
    let mut peer = accept(&listener).await;
    let WorkerMsg::Handshake { noise, .. } = recv(&mut peer).await else { panic!("no handshake") };
    assert!(respond(&Psk::derive(b"theirs"), &noise).is_err(), "read under another secret");
    // It cannot read the worker's message, so it answers a handshake of its own.
    let (answer, _) = respond(&Psk::derive(b"theirs"), &fake_first_message()).expect("own");
    peer.send(MasterMsg::Handshake { noise: answer }).await.unwrap();
    assert!(closes_without_a_word(&mut peer).await);
    // A master that answers in the clear (one that does not encrypt): nothing either.
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Handshake { .. }));
    peer.send(MasterMsg::Challenge { nonce: [1; 32], auth_required: false }).await.unwrap();
    assert!(closes_without_a_word(&mut peer).await);
    // Neither is the master's word that the secret is wrong: the worker tries again.
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Handshake { .. }));
    cancel.cancel();
    assert!(tokio::time::timeout(STEP, worker).await.unwrap().unwrap().is_ok());
}

/// A first handshake message under the impostor's own secret.
fn fake_first_message() -> Vec<u8> {
    gridlight_actors::channel::initiate(&Psk::derive(b"theirs")).expect("initiate").1
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_with_a_secret_stops_when_the_master_does_not_encrypt() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), Some(b"s")),
        CancellationToken::new(),
    ));
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Handshake { .. }));
    let reason = gridlight_actors::rejection::Rejection::NotEncrypting.to_string();
    peer.send(MasterMsg::Rejected { reason: reason.clone() }).await.unwrap();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker gave up").unwrap();
    match outcome {
        Err(err) => {
            assert!(err.is_fatal(), "{err}");
            assert!(err.to_string().contains("does not encrypt"), "{err}");
        }
        Ok(()) => panic!("the worker went on with a master that does not encrypt"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_without_a_secret_stops_when_the_master_requires_one() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let worker = tokio::spawn(worker::run_until(
        config(listener.local_addr().unwrap().to_string(), cache.path(), None),
        CancellationToken::new(),
    ));
    let mut peer = accept(&listener).await;
    assert!(matches!(recv(&mut peer).await, WorkerMsg::Hello { .. }));
    peer.send(MasterMsg::Challenge { nonce: [1; 32], auth_required: true }).await.unwrap();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker gave up").unwrap();
    assert!(matches!(outcome, Err(WorkerError::NeedSecret)), "{outcome:?}");
}

/// The next message other than a heartbeat within `wait`, if any.
async fn recv_within(peer: &mut Peer, wait: Duration) -> Option<WorkerMsg> {
    let deadline = tokio::time::Instant::now() + wait;
    loop {
        match tokio::time::timeout_at(deadline, peer.next()).await {
            Err(_) => return None,
            Ok(Some(Ok(WorkerMsg::Heartbeat))) => continue,
            Ok(Some(Ok(msg))) => return Some(msg),
            Ok(other) => panic!("connection ended: {other:?}"),
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_pausing_worker_tells_the_master_drops_its_jobs_and_resumes_with_fresh_credits() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let (owner, activity) = tokio::sync::watch::channel(Activity::Working);
    let mut c = config(listener.local_addr().unwrap().to_string(), cache.path(), None);
    // A render thread that takes a while per job, so that jobs are held when it pauses.
    c.renderer = RendererKind::Null { delay_ms: 300 };
    c.when_idle = WhenIdle::Follow(activity);
    let worker = tokio::spawn(worker::run_until(c, cancel.clone()));

    let mut peer = accept(&listener).await;
    handshake(&mut peer, None, vec![]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    peer.send(MasterMsg::State(Box::new(state(1)))).await.unwrap();
    for set in [0, 1] {
        peer.send(MasterMsg::Job { frame: 1, set, state_version: 1, spp: 1 }).await.unwrap();
    }
    // The owner comes back while both jobs are held (one rendering, one queued).
    let reason = PauseReason::OwnerInput { seconds_ago: 1.0 };
    owner.send(Activity::Paused(reason.clone())).unwrap();
    assert_eq!(recv(&mut peer).await, WorkerMsg::Paused { reason });
    // A job that was on its way is dropped too; nothing comes back for any of them.
    peer.send(MasterMsg::Job { frame: 2, set: 0, state_version: 1, spp: 1 }).await.unwrap();
    let sent = recv_within(&mut peer, Duration::from_millis(1500)).await;
    assert!(sent.is_none(), "a paused worker sent {sent:?}");

    owner.send(Activity::Working).unwrap();
    assert_eq!(recv(&mut peer).await, WorkerMsg::Resumed);
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    peer.send(MasterMsg::Job { frame: 3, set: 4, state_version: 1, spp: 1 }).await.unwrap();
    match recv(&mut peer).await {
        WorkerMsg::Result(r) => assert_eq!((r.frame, r.set), (3, 4)),
        other => panic!("expected the new job's result, got {other:?}"),
    }
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 1 });

    cancel.cancel();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker stopped").unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_that_starts_paused_takes_no_job_until_the_owner_leaves() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let reason = PauseReason::OwnerCpu { percent: 90.0, window_s: 10.0 };
    let (owner, activity) = tokio::sync::watch::channel(Activity::Paused(reason.clone()));
    let mut c = config(listener.local_addr().unwrap().to_string(), cache.path(), None);
    c.when_idle = WhenIdle::Follow(activity);
    let worker = tokio::spawn(worker::run_until(c, cancel.clone()));

    let mut peer = accept(&listener).await;
    handshake(&mut peer, None, vec![]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::Paused { reason });
    owner.send(Activity::Working).unwrap();
    assert_eq!(recv(&mut peer).await, WorkerMsg::Resumed);
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    cancel.cancel();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker stopped").unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_held_job_of_an_older_state_is_dropped_when_a_newer_states_job_comes() {
    let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let cache = tempfile::tempdir().unwrap();
    let cancel = CancellationToken::new();
    let mut c = config(listener.local_addr().unwrap().to_string(), cache.path(), None);
    // A render thread that takes a while per job, so that the second job is still queued
    // when the newer state's job arrives.
    c.renderer = RendererKind::Null { delay_ms: 300 };
    let worker = tokio::spawn(worker::run_until(c, cancel.clone()));

    let mut peer = accept(&listener).await;
    handshake(&mut peer, None, vec![]).await;
    assert_eq!(recv(&mut peer).await, WorkerMsg::Ready { credits: 2 });
    peer.send(MasterMsg::State(Box::new(state(1)))).await.unwrap();
    for set in [0, 1] {
        peer.send(MasterMsg::Job { frame: 1, set, state_version: 1, spp: 1 }).await.unwrap();
    }
    // The scene changed: the first job is being rendered, the second is queued.
    peer.send(MasterMsg::State(Box::new(state(2)))).await.unwrap();
    peer.send(MasterMsg::Job { frame: 2, set: 0, state_version: 2, spp: 1 }).await.unwrap();
    let mut got = Vec::new();
    while got.len() < 6 {
        got.push(recv(&mut peer).await);
    }
    let result_of = |frame, set| {
        got.iter()
            .position(|m| matches!(m, WorkerMsg::Result(r) if (r.frame, r.set) == (frame, set)))
    };
    // The first old job is finished when it was started before the new one came, else
    // dropped too; the second was still queued behind it.
    let first_dropped = got.contains(&WorkerMsg::Superseded { frame: 1, set: 0 });
    assert!(result_of(1, 0).is_some() != first_dropped, "rendered or dropped: {got:?}");
    assert!(result_of(1, 1).is_none(), "the queued old job is not rendered: {got:?}");
    let dropped = got
        .iter()
        .position(|m| *m == WorkerMsg::Superseded { frame: 1, set: 1 })
        .expect("the worker says it dropped the old job");
    assert_eq!(got.get(dropped + 1), Some(&WorkerMsg::Ready { credits: 1 }), "{got:?}");
    assert!(result_of(2, 0).is_some(), "the new state's job is rendered: {got:?}");
    assert_eq!(got.iter().filter(|m| **m == WorkerMsg::Ready { credits: 1 }).count(), 3);

    cancel.cancel();
    let outcome = tokio::time::timeout(STEP, worker).await.expect("worker stopped").unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
}
