//! The protocol rules of one connection, case by case, without a socket.

use super::*;
use crate::scene::asset_store::AssetStore;
use crate::scene::state::{Camera, Resolution, SceneState};
use crate::shared::holdings::HeldJobs;
use crate::shared::job::Job;
use crate::shared::sets::SetTables;
use crate::shared::workers::WorkerTable;
use crate::wire::auth;
use crate::wire::channel::{initiate, ChannelError, Psk};
use crate::wire::protocol::PROTOCOL_VERSION;
use crate::wire::protocol::{PackedRadiance, Partition, SetsConfig};
use glam::Vec3;

const SECRET: &[u8] = b"shared";
/// The image size of every job's state here.
const RES: Resolution = Resolution { width: 8, height: 4 };

fn config(secret: Option<&[u8]>) -> Arc<ConnectionConfig> {
    let sets = SetsConfig { sets: 4, partition: Partition::QuasiRandom };
    Arc::new(ConnectionConfig {
        secret: secret.map(<[u8]>::to_vec),
        sets: Arc::new(SetTables::new(RES, sets).expect("sets")),
        assets: Arc::new(AssetStore::new()),
        pipeline: 2,
        heartbeat: Duration::from_secs(1),
        peer_timeout: Duration::from_secs(10),
        workers: Arc::new(WorkerTable::default()),
        held: Arc::new(HeldJobs::default()),
        refusal_lines: Default::default(),
    })
}

fn hello() -> WorkerMsg {
    WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: "w".into(), cores: 2 }
}

fn rejection(actions: &[Action]) -> Option<&Rejection> {
    actions.iter().find_map(|a| match a {
        Action::Reject(r) => Some(r),
        _ => None,
    })
}

/// A connection through the handshake, with the key its results must carry.
fn welcomed(now: Instant) -> (ProtocolState, ResultKey) {
    let mut s = ProtocolState::new(7, config(None), now);
    let out = s.on_message(hello(), now);
    let Some(Action::Send(MasterMsg::Challenge { nonce, auth_required: false })) = out.first()
    else {
        panic!("no challenge: {out:?}");
    };
    let key = ResultKey::checksum(nonce);
    let out = s.on_message(WorkerMsg::Auth { mac: None }, now);
    assert_eq!(out[0], Action::Joined);
    assert!(matches!(&out[1], Action::Send(MasterMsg::Welcome { worker_id: 7, .. })));
    (s, key)
}

fn job(frame: FrameNo, set: SetNo, version: StateVersion) -> Job {
    let camera = Camera::pinhole(Vec3::Z, Vec3::ZERO, 40.0);
    let state = SceneState { version, ..SceneState::empty(RES, camera) };
    Job { frame, set, state: Arc::new(state), spp: 3 }
}

fn answer(
    s: &ProtocolState,
    key: &ResultKey,
    frame: FrameNo,
    set: SetNo,
    v: StateVersion,
) -> WorkerMsg {
    let pixels = s.config.sets.checked(RES).set_len(set);
    let radiance = PackedRadiance::Rgb9e5(vec![0; pixels]);
    WorkerMsg::Result(key.seal(frame, set, v, radiance, 10))
}

#[test]
fn a_wrong_protocol_version_is_rejected_as_final() {
    let now = Instant::now();
    let mut s = ProtocolState::new(1, config(None), now);
    let out = s.on_message(
        WorkerMsg::Hello { protocol: PROTOCOL_VERSION + 1, name: "w".into(), cores: 1 },
        now,
    );
    let why = rejection(&out).expect("rejected");
    assert_eq!(why.kind(), RejectionKind::Version);
    assert!(crate::wire::rejection::is_final(&why.to_string()));
    assert!(s.closing());
    assert!(s.on_message(hello(), now).is_empty(), "a closing connection reads nothing");
}

/// A connection with a secret through the channel's handshake (as a worker with
/// `worker_secret` starts it): the actions, and the worker's keys when it worked.
fn channel(
    s: &mut ProtocolState,
    worker_secret: &[u8],
    now: Instant,
) -> (Vec<Action>, Option<Keys>) {
    let (init, noise) = initiate(&Psk::derive(worker_secret)).expect("initiate");
    let out = s.on_message(WorkerMsg::Handshake { protocol: PROTOCOL_VERSION, noise }, now);
    let keys = match out.first() {
        Some(Action::Send(MasterMsg::Handshake { noise })) => init.finish(noise).ok(),
        _ => None,
    };
    (out, keys)
}

#[test]
fn with_a_secret_only_the_encrypted_channel_under_the_same_secret_is_welcomed() {
    let now = Instant::now();
    // The same secret: the answer, then the keys (both sides name the same handshake);
    // inside the channel the HMAC challenge is checked as before.
    let mut s = ProtocolState::new(1, config(Some(SECRET)), now);
    let (out, keys) = channel(&mut s, SECRET, now);
    assert_eq!(out.len(), 2, "{out:?}");
    assert_eq!(Some(&out[1]), keys.map(Action::Encrypt).as_ref(), "the worker's keys differ");
    let out = s.on_message(hello(), now);
    let Some(Action::Send(MasterMsg::Challenge { nonce, auth_required: true })) = out.first()
    else {
        panic!("no challenge: {out:?}");
    };
    let nonce = *nonce;
    let out = s.on_message(WorkerMsg::Auth { mac: Some(auth::mac(SECRET, &nonce)) }, now);
    assert!(s.welcomed(), "{out:?}");
    // Results need no tag of their own: the channel authenticated every byte.
    s.on_jobs(vec![job(0, 1, 1)], now);
    let out = s.on_message(answer(&s, &ResultKey::Channel, 0, 1, 1), now);
    assert!(matches!(out[..], [Action::Answered { .. }]), "{out:?}");

    // A wrong secret: refused at its first message, nothing else sent.
    let mut s = ProtocolState::new(1, config(Some(SECRET)), now);
    let (out, keys) = channel(&mut s, b"guess", now);
    assert_eq!(out, [Action::Reject(Rejection::WrongSecret)]);
    assert!(keys.is_none());
    // No secret (a plain Hello): refused, as is a wrong MAC inside the channel.
    let mut s = ProtocolState::new(1, config(Some(SECRET)), now);
    assert_eq!(s.on_message(hello(), now), [Action::Reject(Rejection::NoSecret)]);
    let mut s = ProtocolState::new(1, config(Some(SECRET)), now);
    channel(&mut s, SECRET, now);
    s.on_message(hello(), now);
    let out = s.on_message(WorkerMsg::Auth { mac: Some([0; 32]) }, now);
    assert_eq!(rejection(&out), Some(&Rejection::WrongSecret));
    // A second handshake on an encrypted connection is out of phase.
    let mut s = ProtocolState::new(1, config(Some(SECRET)), now);
    channel(&mut s, SECRET, now);
    let (out, _) = channel(&mut s, SECRET, now);
    assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Phase));
}

#[test]
fn without_a_secret_the_channel_is_refused_and_results_need_their_checksum() {
    let now = Instant::now();
    let mut s = ProtocolState::new(1, config(None), now);
    let (out, keys) = channel(&mut s, SECRET, now);
    assert_eq!(out, [Action::Reject(Rejection::NotEncrypting)]);
    assert!(keys.is_none());
    // A plain connection's result without its checksum is corrupt.
    let (mut s, _) = welcomed(now);
    s.on_jobs(vec![job(0, 1, 1)], now);
    let out = s.on_message(answer(&s, &ResultKey::Channel, 0, 1, 1), now);
    assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Corrupt));
}

#[test]
fn a_record_that_fails_authentication_is_rejected_as_decrypt() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    let out = s.on_bad_frame(&ProtocolError::Channel(ChannelError::Decrypt));
    assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Decrypt));
}

#[test]
fn messages_out_of_phase_are_rejected() {
    let now = Instant::now();
    let mut s = ProtocolState::new(1, config(None), now);
    let out = s.on_message(WorkerMsg::Ready { credits: 1 }, now);
    assert_eq!(rejection(&out), Some(&Rejection::Phase { message: "Ready", phase: "hello" }));
}

#[test]
fn credits_never_let_a_worker_hold_more_than_k() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    assert_eq!(s.on_message(WorkerMsg::Ready { credits: 5 }, now), [Action::RequestJobs(2)]);
    assert!(s.on_message(WorkerMsg::Ready { credits: 1 }, now).is_empty(), "k already asked for");
    s.on_jobs(vec![job(0, 0, 1)], now);
    assert!(s.on_message(WorkerMsg::Ready { credits: 1 }, now).is_empty(), "one held, one asked");
}

#[test]
fn a_state_version_is_sent_once_before_the_first_job_that_names_it() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    let out = s.on_jobs(vec![job(0, 0, 1), job(0, 1, 1), job(1, 0, 2)], now);
    let names: Vec<_> = out
        .iter()
        .map(|a| match a {
            Action::Send(MasterMsg::State(st)) => format!("state {}", st.version),
            Action::Send(MasterMsg::Job { frame, set, state_version, spp }) => {
                format!("job {frame}/{set}@{state_version}x{spp}")
            }
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(names, ["state 1", "job 0/0@1x3", "job 0/1@1x3", "state 2", "job 1/0@2x3"]);
}

#[test]
fn results_are_checked_once_answered_duplicate_or_unknown() {
    let now = Instant::now();
    let (mut s, key) = welcomed(now);
    s.on_jobs(vec![job(3, 1, 1)], now);
    let out = s.on_message(answer(&s, &key, 3, 1, 1), now);
    assert!(matches!(out[..], [Action::Answered { .. }]), "{out:?}");
    assert_eq!(s.held(), 0);
    let out = s.on_message(answer(&s, &key, 3, 1, 1), now);
    assert!(
        out[..] == [Action::Duplicate { frame: 3, set: 1 }],
        "a second answer is a duplicate: {out:?}"
    );
    let out = s.on_message(answer(&s, &key, 3, 2, 1), now);
    assert_eq!(out[0], Action::Unknown { frame: 3, set: 2 });
    assert_eq!(rejection(&out), Some(&Rejection::UnknownResult { frame: 3, set: 2 }));
}

#[test]
fn a_bad_result_is_rejected_with_its_kind() {
    let now = Instant::now();
    type Make = fn(&ProtocolState, &ResultKey) -> WorkerMsg;
    let cases: [(Make, RejectionKind); 4] = [
        (|s, k| answer(s, k, 0, 9, 1), RejectionKind::SetRange),
        (|s, k| answer(s, k, 0, 0, 2), RejectionKind::StateVersion),
        (
            |_, k| WorkerMsg::Result(k.seal(0, 0, 1, PackedRadiance::Rgb9e5(vec![0; 1]), 1)),
            RejectionKind::PixelCount,
        ),
        (
            |s, k| {
                let WorkerMsg::Result(mut r) = answer(s, k, 0, 0, 1) else { unreachable!() };
                r.frame = 1;
                WorkerMsg::Result(r)
            },
            RejectionKind::Corrupt,
        ),
    ];
    for (make, kind) in cases {
        let (mut s, key) = welcomed(now);
        s.on_jobs(vec![job(0, 0, 1)], now);
        let msg = make(&s, &key);
        let out = s.on_message(msg, now);
        assert_eq!(rejection(&out).map(Rejection::kind), Some(kind), "{out:?}");
    }
}

#[test]
fn a_paused_worker_loses_its_jobs_and_may_not_ask_for_more() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    s.on_message(WorkerMsg::Ready { credits: 2 }, now);
    s.on_jobs(vec![job(0, 0, 1)], now);
    let reason = PauseReason::OwnerInput { seconds_ago: 1.0 };
    let out = s.on_message(WorkerMsg::Paused { reason: reason.clone() }, now);
    assert_eq!(out, [Action::Paused { reason: reason.clone(), first: true, lost: vec![0] }]);
    assert_eq!(s.held(), 0, "the held job is lost");
    assert!(s.on_jobs(vec![job(0, 1, 1)], now).is_empty(), "no job reaches a paused worker");
    let again = s.on_message(WorkerMsg::Paused { reason: reason.clone() }, now);
    assert_eq!(again, [Action::Paused { reason, first: false, lost: vec![] }]);
    assert_eq!(s.on_message(WorkerMsg::Resumed, now), [Action::Resumed]);
    let out = s.on_message(WorkerMsg::Resumed, now);
    assert_eq!(rejection(&out), Some(&Rejection::NotPaused));
}

#[test]
fn a_quiet_link_gets_heartbeats_and_a_silent_peer_is_ended() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    assert!(s.tick(now + Duration::from_millis(500)).is_empty());
    assert_eq!(s.tick(now + Duration::from_secs(1)), [Action::Send(MasterMsg::Heartbeat)]);
    let out = s.tick(now + Duration::from_secs(11));
    assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Timeout));
}

#[test]
fn an_asset_not_in_the_manifest_is_refused() {
    let now = Instant::now();
    let (mut s, _) = welcomed(now);
    let out = s.on_message(WorkerMsg::AssetRequest { hash: [3; 32] }, now);
    assert_eq!(rejection(&out).map(Rejection::kind), Some(RejectionKind::Asset));
}

#[test]
fn the_one_record_of_held_jobs_follows_every_change_of_hands() {
    let now = Instant::now();
    let (mut s, key) = welcomed(now);
    let held = |s: &ProtocolState| -> Vec<(FrameNo, SetNo)> {
        s.config.held.lock().of(7).iter().map(|h| (h.frame, h.set)).collect()
    };
    s.on_jobs(vec![job(0, 0, 1), job(0, 1, 1), job(1, 0, 1)], now);
    assert_eq!(held(&s), [(0, 0), (0, 1), (1, 0)]);
    s.on_message(WorkerMsg::Superseded { frame: 0, set: 1 }, now);
    s.on_message(answer(&s, &key, 0, 0, 1), now);
    assert_eq!(held(&s), [(1, 0)], "answered and superseded jobs leave it");
    assert_eq!(s.release_held().len(), 1, "the rest is lost when the connection ends");
    assert!(held(&s).is_empty());
}
