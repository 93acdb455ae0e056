//! One worker connection from connect to close: the worker side of the protocol's phases.
//!
//! Phases (see `gridlight_actors::protocol`): Hello → Challenge → Auth → Welcome (inside
//! the encrypted channel with a secret: `connect` ran its handshake), then the assets
//! missing from the cache are fetched by hash, and from then on the link keeps `k` jobs
//! in flight: it sends `Ready{credits}`, stores every `State` it is sent, hands each `Job`
//! with its state to the render thread (which tags each result with a checksum seeded by
//! the `Challenge` nonce on a plain connection, and leaves it to the channel on an
//! encrypted one) and sends each result back followed by a new credit. A writer task owns the socket's sending half and sends a heartbeat whenever
//! the link has been quiet for `HEARTBEAT_INTERVAL`, so long renders and downloads
//! never look like a dead worker; a master silent for `PEER_TIMEOUT` is gone.
//!
//! While the worker's owner monitor says *paused* (`--when-idle`), the link tells the
//! master `Paused` with the reason, forgets the jobs it holds (queued ones are never
//! rendered, a result still being rendered is dropped: the master counts them lost and
//! never recomputes them), ignores jobs still on their way and sends no credit; when it
//! says *working* again, `Resumed` and fresh credits (the protocol's *Pausing* section).
//!
//! The link is generic over its transport (a stream of decoded `MasterMsg`s and a sink
//! of `WorkerMsg`s) so that the framing stays the codec's business.

use std::collections::{BTreeMap, HashSet};
use std::sync::Arc;
use std::time::Duration;

use futures::{Sink, SinkExt, Stream, StreamExt};
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::protocol::{
    AssetEntry, FrameNo, MasterMsg, SetNo, WorkerMsg, HEARTBEAT_INTERVAL, PEER_TIMEOUT,
    PROTOCOL_VERSION,
};
use gridlight_actors::state::{SceneState, StateVersion};
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;
use tracing::{debug, info, warn};

use super::idle::Activity;
use super::priority::Priority;
use super::render::{Answer, RenderJob, RenderThread, RendererKind};
use super::shared::Shared;
use super::WorkerError;

/// Scene states kept per connection; jobs only ever name recent versions, and a job
/// naming one that was dropped is a protocol error the master would have to cause.
const KEPT_STATES: usize = 8;

/// What one link needs to know about its worker.
#[derive(Clone, Debug)]
pub struct LinkConfig {
    /// Name sent in `Hello` (unique per connection, for the master's logs).
    pub name: String,
    /// The shared secret, if any (`--secret-file`).
    pub secret: Option<Arc<Vec<u8>>>,
    /// Jobs held at once (docs/design.md, decision 7).
    pub pipeline: u32,
    /// Real path tracing or the null renderer.
    pub renderer: RendererKind,
    /// Priority of the render thread.
    pub priority: Priority,
}

/// How a link ended without an error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkEnd {
    /// Shutdown was requested (Ctrl-C).
    Shutdown,
    /// The master closed the connection.
    Closed,
}

/// Progress a link made, for the reconnect policy.
#[derive(Debug, Default, Clone, Copy)]
pub struct LinkProgress {
    /// The link got past the handshake and asset fetch.
    pub welcomed: bool,
    /// Jobs rendered and sent back.
    pub results_sent: u64,
}

/// Runs one link over `transport` until it ends, `cancel` fires or an error occurs.
pub async fn run<T, E>(
    transport: T,
    config: &LinkConfig,
    shared: &Arc<Shared>,
    cancel: &CancellationToken,
    activity: &mut watch::Receiver<Activity>,
    progress: &mut LinkProgress,
) -> Result<LinkEnd, WorkerError>
where
    T: Stream<Item = Result<MasterMsg, E>> + Sink<WorkerMsg, Error = E> + Send + 'static,
    E: std::fmt::Display + Send + 'static,
{
    let (sink, mut stream) = transport.split();
    let (out_tx, out_rx) = mpsc::channel::<WorkerMsg>(64);
    let writer = tokio::spawn(write_loop(sink, out_rx));
    let result = tokio::select! {
        r = drive(&mut stream, &out_tx, config, shared, activity, progress) => r,
        () = cancel.cancelled() => Ok(LinkEnd::Shutdown),
    };
    drop(out_tx);
    // Let the writer flush what is queued (a last result), but never hang on it.
    let _ = tokio::time::timeout(Duration::from_secs(1), writer).await;
    result
}

/// Sends queued messages, and a heartbeat after `HEARTBEAT_INTERVAL` of silence.
///
/// Everything already queued goes out in one flush: a result and the credit that follows
/// it become one write (one system call, one segment) instead of two.
async fn write_loop<S, E>(mut sink: S, mut rx: mpsc::Receiver<WorkerMsg>) -> Result<(), String>
where
    S: Sink<WorkerMsg, Error = E> + Unpin,
    E: std::fmt::Display,
{
    loop {
        let msg = match tokio::time::timeout(HEARTBEAT_INTERVAL, rx.recv()).await {
            Ok(Some(msg)) => msg,
            Ok(None) => break,
            Err(_) => WorkerMsg::Heartbeat,
        };
        sink.feed(msg).await.map_err(|e| e.to_string())?;
        while let Ok(more) = rx.try_recv() {
            sink.feed(more).await.map_err(|e| e.to_string())?;
        }
        sink.flush().await.map_err(|e| e.to_string())?;
    }
    sink.close().await.map_err(|e| e.to_string())
}

/// The phases, in order.
async fn drive<S, E>(
    stream: &mut S,
    out: &mpsc::Sender<WorkerMsg>,
    config: &LinkConfig,
    shared: &Arc<Shared>,
    activity: &mut watch::Receiver<Activity>,
    progress: &mut LinkProgress,
) -> Result<LinkEnd, WorkerError>
where
    S: Stream<Item = Result<MasterMsg, E>> + Unpin,
    E: std::fmt::Display,
{
    let mut conn = Conn { stream, out };
    conn.send(WorkerMsg::Hello { protocol: PROTOCOL_VERSION, name: config.name.clone(), cores: 1 })
        .await?;

    // Challenge → Auth. A rejection before Welcome is about who we are (version, secret).
    let (nonce, auth_required) = match conn.recv_handshake().await? {
        MasterMsg::Challenge { nonce, auth_required } => (nonce, auth_required),
        other => return Err(unexpected("Challenge", &other)),
    };
    if auth_required && config.secret.is_none() {
        return Err(WorkerError::NeedSecret);
    }
    let mac = config.secret.as_ref().map(|s| gridlight_actors::auth::mac(s, &nonce));
    conn.send(WorkerMsg::Auth { mac }).await?;
    // With a secret the link is encrypted (`connect` made sure of it): the channel
    // authenticates results; without one they carry a checksum.
    let result_key = ResultKey::for_connection(config.secret.is_some(), &nonce);
    let (worker_id, sets, manifest) = match conn.recv_handshake().await? {
        MasterMsg::Welcome { worker_id, sets, assets } => (worker_id, sets, assets),
        other => return Err(unexpected("Welcome", &other)),
    };
    info!(worker = %config.name, worker_id, sets = sets.sets, assets = manifest.len(), "welcomed");
    shared.forget.note_scene(&manifest);

    let view = fetch_assets(&mut conn, shared, &manifest).await?;
    progress.welcomed = true;

    let (results_tx, mut results_rx) = mpsc::unbounded_channel();
    let mut render = RenderThread::spawn(
        &config.name,
        config.renderer.clone(),
        config.priority,
        Some(view),
        Arc::clone(shared),
        sets,
        result_key,
        results_tx,
    )?;
    let mut states: BTreeMap<StateVersion, Arc<SceneState>> = BTreeMap::new();
    // Jobs given to the render thread since the last pause; a result of any other is
    // one the master already counts as lost.
    let mut live: HashSet<(FrameNo, SetNo)> = HashSet::new();
    let mut paused = false;
    let mut follow = true;
    let now = activity.borrow_and_update().clone();
    match now {
        Activity::Working => {
            conn.send(WorkerMsg::Ready { credits: config.pipeline.max(1) }).await?
        }
        now => follow_activity(&mut conn, now, &mut paused, &mut live, &mut render, config).await?,
    }

    loop {
        tokio::select! {
            changed = activity.changed(), if follow => match changed {
                Ok(()) => {
                    let now = activity.borrow_and_update().clone();
                    follow_activity(&mut conn, now, &mut paused, &mut live, &mut render, config).await?;
                }
                // The monitor is gone: the last decision stands.
                Err(_) => follow = false,
            },
            msg = conn.recv() => match msg? {
                None => return Ok(LinkEnd::Closed),
                Some(MasterMsg::State(state)) => {
                    debug!(version = state.version, "state received");
                    states.insert(state.version, Arc::from(state));
                    while states.len() > KEPT_STATES {
                        states.pop_first();
                    }
                }
                Some(MasterMsg::Job { frame, set, state_version, spp }) => {
                    if spp == 0 {
                        return Err(WorkerError::Protocol(format!(
                            "job (frame {frame}, set {set}) asks for 0 samples per pixel"
                        )));
                    }
                    let Some(state) = states.get(&state_version) else {
                        return Err(WorkerError::Protocol(format!(
                            "job (frame {frame}, set {set}) names state version {state_version}, which was never sent"
                        )));
                    };
                    // Tests count these: a (frame, set) received twice was handed out twice.
                    debug!(frame, set, "job received");
                    if paused {
                        debug!(frame, set, "job dropped: paused");
                        continue;
                    }
                    live.insert((frame, set));
                    render.submit(RenderJob { frame, set, state: Arc::clone(state), spp })?;
                }
                Some(MasterMsg::Heartbeat) => {}
                Some(MasterMsg::Rejected { reason }) => {
                    return Err(WorkerError::Rejected { reason, fatal: false });
                }
                Some(other) => return Err(unexpected("State, Job or Heartbeat", &other)),
            },
            result = results_rx.recv() => match result {
                Some(Ok(Answer::Superseded { frame, set })) => {
                    // Lost like a paused worker's jobs when it is not live any more.
                    if live.remove(&(frame, set)) {
                        conn.send(WorkerMsg::Superseded { frame, set }).await?;
                        conn.send(WorkerMsg::Ready { credits: 1 }).await?;
                        debug!(frame, set, "held job superseded by a newer state's");
                    }
                }
                Some(Ok(Answer::Rendered(result))) => {
                    let (frame, set) = (result.frame, result.set);
                    if !live.remove(&(frame, set)) {
                        debug!(frame, set, "result dropped: its job was held when the worker paused");
                        continue;
                    }
                    conn.send(WorkerMsg::Result(result)).await?;
                    debug!(frame, set, "result sent");
                    conn.send(WorkerMsg::Ready { credits: 1 }).await?;
                    progress.results_sent += 1;
                }
                Some(Err(err)) => return Err(err),
                None => return Err(WorkerError::Protocol("render thread ended".into())),
            },
        }
    }
}

/// Tells the master about a change of the owner monitor's decision.
async fn follow_activity<S, E>(
    conn: &mut Conn<'_, S>,
    now: Activity,
    paused: &mut bool,
    live: &mut HashSet<(FrameNo, SetNo)>,
    render: &mut RenderThread,
    config: &LinkConfig,
) -> Result<(), WorkerError>
where
    S: Stream<Item = Result<MasterMsg, E>> + Unpin,
    E: std::fmt::Display,
{
    match now {
        Activity::Paused(reason) => {
            if !*paused {
                info!(worker = %config.name, jobs_lost = live.len(), %reason, "paused");
            }
            *paused = true;
            live.clear();
            render.discard_queued();
            conn.send(WorkerMsg::Paused { reason }).await
        }
        Activity::Working if *paused => {
            info!(worker = %config.name, "resumed");
            *paused = false;
            conn.send(WorkerMsg::Resumed).await?;
            conn.send(WorkerMsg::Ready { credits: config.pipeline.max(1) }).await
        }
        Activity::Working => Ok(()),
    }
}

/// Fetches every asset of `manifest` missing from the cache and returns a view of them.
async fn fetch_assets<S, E>(
    conn: &mut Conn<'_, S>,
    shared: &Shared,
    manifest: &[AssetEntry],
) -> Result<super::cache::CacheView, WorkerError>
where
    S: Stream<Item = Result<MasterMsg, E>> + Unpin,
    E: std::fmt::Display,
{
    // One connection of this process downloads; the others find the blobs afterwards.
    let _guard = shared.fetch_lock.lock().await;
    let missing = shared.cache.missing(manifest);
    for entry in &missing {
        info!(path = %entry.path, bytes = entry.len, "fetching asset");
        let mut blob = shared.cache.begin(entry)?;
        if entry.len > 0 {
            conn.send(WorkerMsg::AssetRequest { hash: entry.hash }).await?;
        }
        while !blob.is_complete() {
            match conn.recv().await? {
                None => {
                    return Err(WorkerError::Protocol(
                        "connection closed during an asset download".into(),
                    ))
                }
                Some(MasterMsg::AssetChunk { hash, offset, len, data })
                    if hash == entry.hash && len == entry.len =>
                {
                    blob.write_chunk(offset, &data)?;
                }
                Some(MasterMsg::Heartbeat) => {}
                Some(MasterMsg::Rejected { reason }) => {
                    return Err(WorkerError::Rejected { reason, fatal: false })
                }
                Some(other) => {
                    return Err(unexpected(&format!("AssetChunk of `{}`", entry.path), &other))
                }
            }
        }
        blob.finish()?;
    }
    let view = shared.cache.view(manifest)?;
    // Under the fetch lock: a wipe (`--forget-on-exit`) sees this connection from now on.
    shared.forget.connection_started();
    Ok(view)
}

/// The receiving half and the writer queue of one connection.
struct Conn<'a, S> {
    stream: &'a mut S,
    out: &'a mpsc::Sender<WorkerMsg>,
}

impl<S, E> Conn<'_, S>
where
    S: Stream<Item = Result<MasterMsg, E>> + Unpin,
    E: std::fmt::Display,
{
    async fn send(&self, msg: WorkerMsg) -> Result<(), WorkerError> {
        self.out
            .send(msg)
            .await
            .map_err(|_| WorkerError::Connection("the connection's writer stopped".into()))
    }

    /// The next message; `None` when the master closed the connection.
    async fn recv(&mut self) -> Result<Option<MasterMsg>, WorkerError> {
        match tokio::time::timeout(PEER_TIMEOUT, self.stream.next()).await {
            Err(_) => Err(WorkerError::Connection(format!("master silent for {PEER_TIMEOUT:?}"))),
            Ok(None) => Ok(None),
            Ok(Some(Err(e))) => Err(WorkerError::Connection(e.to_string())),
            Ok(Some(Ok(msg))) => Ok(Some(msg)),
        }
    }

    /// A handshake answer: a rejection for a wrong version or secret is fatal; any other
    /// (a full master, a frame garbled on the way, a timeout on a stalled link) is
    /// retried, and so is the master closing without a word.
    async fn recv_handshake(&mut self) -> Result<MasterMsg, WorkerError> {
        loop {
            match self.recv().await? {
                Some(MasterMsg::Heartbeat) => continue,
                Some(MasterMsg::Rejected { reason }) => {
                    let fatal = is_fatal_rejection(&reason);
                    return Err(WorkerError::Rejected { reason, fatal });
                }
                Some(msg) => return Ok(msg),
                None => {
                    return Err(WorkerError::Connection(
                        "master closed the connection during the handshake".into(),
                    ))
                }
            }
        }
    }
}

/// Rejections that say "never", not "later": who we are (protocol version, secret) is
/// wrong, and reconnecting cannot change it; a link fault during the handshake (a
/// garbled frame, a stall) is not mistaken for one and does not end the worker.
fn is_fatal_rejection(reason: &str) -> bool {
    gridlight_actors::rejection::is_final(reason)
}

fn unexpected(wanted: &str, got: &MasterMsg) -> WorkerError {
    let name = match got {
        MasterMsg::Challenge { .. } => "Challenge",
        MasterMsg::Rejected { .. } => "Rejected",
        MasterMsg::Welcome { .. } => "Welcome",
        MasterMsg::AssetChunk { .. } => "AssetChunk",
        MasterMsg::State(_) => "State",
        MasterMsg::Job { .. } => "Job",
        MasterMsg::Heartbeat => "Heartbeat",
        MasterMsg::Handshake { .. } => "Handshake",
    };
    warn!(wanted, got = name, "unexpected message from the master");
    WorkerError::Protocol(format!("expected {wanted}, got {name}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_wrong_version_or_secret_is_fatal_during_the_handshake() {
        assert!(!is_fatal_rejection("too many connections (cap 256)"));
        assert!(!is_fatal_rejection("bad frame: undecodable message: x"));
        assert!(!is_fatal_rejection("no message from the worker for 2.0 s"));
        assert!(is_fatal_rejection("protocol version mismatch: worker speaks 2, master speaks 3"));
        assert!(is_fatal_rejection("authentication failed: wrong shared secret"));
    }
}
