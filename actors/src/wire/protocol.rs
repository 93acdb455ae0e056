//! The wire protocol between master and workers: every message, and its invariants.
//!
//! # Framing
//! TCP; each message is one frame: a 4-byte big-endian length `n`, then `n` bytes of
//! MessagePack (rmp-serde, structs as maps are *not* used: fields are positional).
//! `0 < n <= MAX_FRAME_LEN`, checked before anything is allocated. A frame that fails
//! to decode, or a message that is not allowed in the connection's current phase,
//! ends that connection (never the process) after a [`MasterMsg::Rejected`] naming
//! the problem where the peer can still read it.
//!
//! # The encrypted channel (a shared secret)
//! With a shared secret, the frames above travel inside an encrypted channel
//! (`wire::channel`, Noise `NNpsk0` under a key derived from the secret). Invariants:
//! - **Handshake first, in two plain frames.** The worker's first frame is
//!   [`WorkerMsg::Handshake`] (protocol version, Noise message 1); the master answers
//!   [`MasterMsg::Handshake`] (message 2) or a plain `Rejected`. Nothing else is ever
//!   plain on such a connection: from the next byte on, each direction is a sequence of
//!   *records* (2-byte big-endian length `16 < n <= 65535`, then `n` bytes of ciphertext
//!   and AEAD tag, the nonce the record's index in its direction, never sent).
//! - **Records carry the frame stream.** Their plaintexts, concatenated, are frames as
//!   above, decoded by the same decoder under the same limits; a frame larger than a
//!   record (assets, scene states, results) is cut into consecutive records of at most
//!   65519 plaintext bytes; no record holds bytes of two frames.
//! - **Authenticated before parsed.** A record is opened (tag checked) before any of its
//!   bytes is decoded; one that fails (altered, dropped, replayed, reordered, another
//!   key) ends the connection, so an altered result, job, state or asset never becomes a
//!   message. Results therefore carry no tag of their own (`JobResult::tag` is `None`).
//! - **No downgrade.** A master with a secret answers a plain `Hello` with `Rejected`
//!   ("requires a shared secret"); a master without one answers a `Handshake` with
//!   `Rejected` ("does not encrypt"); a worker with a secret sends nothing but its
//!   `Handshake` until the master's answer has authenticated. Both rejections are final
//!   for the worker.
//! - **Secret proven without sending it, keys fresh per connection.** Noise's PSK mixes
//!   the secret into the handshake; both sides' ephemeral keys make every connection's
//!   keys new (forward secrecy, replays fail). Inside the channel, the phases below run
//!   unchanged.
//!
//! # Phases (master's view of one connection)
//! 1. **Hello**: the worker's first frame (inside the channel, with a secret) is
//!    [`WorkerMsg::Hello`]. A wrong `protocol` gets `Rejected` and close. The master
//!    answers [`MasterMsg::Challenge`] with a fresh random nonce.
//! 2. **Auth**: the worker answers [`WorkerMsg::Auth`] with HMAC-SHA256(secret, nonce)
//!    (`None` when it has no secret). With a secret configured on the master, a
//!    missing or wrong MAC gets `Rejected` and close; the secret itself never travels.
//! 3. **Scene**: the master sends [`MasterMsg::Welcome`]: the worker id, the sets
//!    configuration and the manifest of assets (path, SHA-256, length). The worker
//!    requests every asset missing from its cache with [`WorkerMsg::AssetRequest`]
//!    (only hashes in the manifest are served) and receives [`MasterMsg::AssetChunk`]s
//!    in order; it verifies the hash of the whole file before using it.
//! 4. **Work**: the worker sends [`WorkerMsg::Ready`] with credits (how many more
//!    jobs it can hold; at most `k` in total: docs/design.md, decision 7). For each job the
//!    master sends, *before the first job that names a state version on this
//!    connection*, that [`MasterMsg::State`]; then [`MasterMsg::Job`]. A worker never
//!    renders with a state it was not sent. A job names its samples per pixel, which
//!    every job of one frame shares and which may change between frames (the scheduler
//!    sizes jobs to the grid: `scheduler::job_size`); a result's size never depends on
//!    it. Each job is answered by exactly one
//!    [`WorkerMsg::Result`], whose frame, set and state version must equal the job's,
//!    and whose radiance holds exactly one pixel per pixel of the set (pixel indices
//!    never travel: both sides derive them from `(resolution, sets, partition, set)`).
//!
//! # Worker identity
//! The `name` of a worker's `Hello` is who it is to the master: log lines, the status
//! panel and the listener's per-peer back-off (`supervision::peers`) key on it, never on
//! the address (every worker behind one NAT, and every test worker, shares one). A worker
//! keeps its name across reconnects: `--name` or the host name and process id, with one
//! `#n` suffix per connection slot (render thread). So a worker whose connections keep
//! failing is refused as itself, and another worker on the same host is not.
//!
//! # Result integrity
//! On an encrypted connection the channel authenticates every byte of every result
//! (above). On a plain one every [`JobResult`] carries a 128-bit `tag`, an XXH3-128
//! checksum over (frame, set, state version, radiance) seeded per connection from the
//! `Challenge` nonce (see [`crate::wire::integrity`]): against accidental corruption
//! only, since without a secret anyone can compute it. The master verifies the tag (or
//! its absence) before any other check of a result; a mismatch is rejected like any bad
//! input (kind `corrupt`), so a corrupted payload never reaches an image. `render_us`
//! is advisory and not covered.
//!
//! # Pausing (a guest on someone's desk)
//! In the work phase a worker may send [`WorkerMsg::Paused`] with a [`PauseReason`]
//! (its desk's owner is active) and later [`WorkerMsg::Resumed`]. Invariants:
//! - **A paused worker holds no job.** Every job the connection held when `Paused`
//!   arrived, and every job already on its way, is lost: the worker renders none of them
//!   and sends no result for them, and the master never hands them out again.
//! - **A paused worker gets no job.** Its unserved credits are void; the master sends no
//!   `Job` until `Resumed`, after which the worker grants fresh credits with `Ready`.
//!   `Ready`, `Result` or a second `Resumed` while paused, or `Resumed` while not paused,
//!   ends the connection like any out-of-phase message; `Paused` while paused only
//!   updates the reason.
//! - **A paused worker is not a live worker**: statistics count it apart, with its reason.
//!
//! # Superseded jobs
//! A worker that receives a job of a newer state version drops the jobs of older
//! versions it holds and has not started, and says so with [`WorkerMsg::Superseded`]
//! (then `Ready`): after an edit it renders the new view next instead of finishing the
//! old one's queue. The master forgets the job (lost, never redone).
//!
//! Either side sends [`WorkerMsg::Heartbeat`]/[`MasterMsg::Heartbeat`] when it has
//! been quiet for [`HEARTBEAT_INTERVAL`]; a peer silent for [`PEER_TIMEOUT`] is gone.
//!
//! # What the master never does
//! Re-send a job whose result was lost: a late or missing result leaves a hole that
//! reconstruction fills (docs/design.md, "Nothing lost is redone").

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::scene::state::{SceneState, StateVersion};

pub use crate::scene::asset_store::{AssetEntry, AssetHash};

/// Bumped on every incompatible change of any message below.
/// 2: RGB9E5 radiance travels as one MessagePack `bin` of little-endian `u32`s.
/// 3: every result carries an integrity tag (`JobResult::tag`).
/// 4: the tag is keyed BLAKE3 instead of HMAC-SHA256 (the key derivation is unchanged).
/// 5: the tag is 128 bits, and XXH3-128 when no secret is configured.
/// 6: `WorkerMsg::Paused` / `WorkerMsg::Resumed` (workers that give way to their desk's owner).
/// 7: results carry reflected radiance, no longer divided by the albedo (the master
///    demodulates by its G-buffer's); an older worker's pixels would be wrong.
/// 8: `WorkerMsg::Superseded` (a held job dropped unrendered for a newer state's job).
/// 9: with a secret, the encrypted channel (`Handshake` messages, records); results carry
///    a tag only on plain connections (`JobResult::tag` is optional), keyed BLAKE3 is gone.
/// 10: every `Job` names its samples per pixel (`MasterMsg::Job::spp`): the scheduler sizes
///    jobs to the grid, the master's cost per result and its link (`scheduler::job_size`).
/// 11: `Geometry::Gltf` (glTF 2.0 meshes); an older worker cannot decode such a state.
/// 12: `MaterialKind::Pbr` (glTF metallic-roughness) and the material fields it needs
///    (metallic, transmission, emission strength, alpha and its mode, maps): every
///    material has more positional fields, so no older worker decodes a newer state.
/// 13: `Material::lookups` (each map's wrap modes and glTF texture transform).
pub const PROTOCOL_VERSION: u32 = 13;

/// Largest frame either side accepts, in bytes (length prefix excluded).
pub const MAX_FRAME_LEN: usize = 4 * 1024 * 1024;

/// Asset bytes per [`MasterMsg::AssetChunk`]; well below [`MAX_FRAME_LEN`].
pub const ASSET_CHUNK_LEN: usize = 1024 * 1024;

/// Send a heartbeat after this long without sending anything.
pub const HEARTBEAT_INTERVAL: Duration = Duration::from_secs(2);

/// A peer that sent nothing for this long is considered gone.
pub const PEER_TIMEOUT: Duration = Duration::from_secs(10);

/// Number of a scheduled frame; strictly increasing within one master run.
pub type FrameNo = u64;

/// Identifies one connection on the master (the `worker_id` of its `Welcome`).
pub type ConnId = u64;

/// Number of a pixel set within a frame, `0..sets`.
pub type SetNo = u32;

/// How pixels are assigned to sets (docs/design.md, decision 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Partition {
    /// Scrambled low-discrepancy assignment: every set covers the whole image.
    QuasiRandom,
    /// Square-ish tiles, as in the paper's Figure 3 comparison.
    Tiles,
}

/// How a frame is split into jobs; fixed for a master run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SetsConfig {
    /// Number of sets S per frame.
    pub sets: u32,
    pub partition: Partition,
}

/// Radiance of a set's pixels, in set order, packed (docs/design.md, decision 2): the mean over
/// each pixel's samples of the radiance minus what the primary hit emits, *not* divided by
/// the albedo. The master divides it by its G-buffer's albedo and multiplies that same
/// albedo back in after reconstruction, so the two cancel exactly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PackedRadiance {
    /// Shared-exponent RGB9E5, one `u32` per pixel (non-negative, finite by construction).
    /// On the wire: a single `bin` of 4 bytes per pixel, little-endian (4 bytes/pixel
    /// instead of MessagePack's 5 per large integer, and decoded by copying).
    Rgb9e5(#[serde(with = "le_u32_bytes")] Vec<u32>),
}

/// `Vec<u32>` as one byte string of little-endian words.
mod le_u32_bytes {
    use serde::de::{Error, Visitor};
    use serde::{Deserializer, Serializer};

    // On little-endian machines the words' memory already is the wire form, so both
    // directions are one copy (they were a loop per word, measurable on the master's
    // thread at thousands of results per second).
    pub fn serialize<S: Serializer>(v: &[u32], s: S) -> Result<S::Ok, S::Error> {
        if cfg!(target_endian = "little") {
            return s.serialize_bytes(bytemuck::cast_slice(v));
        }
        let bytes: Vec<u8> = v.iter().flat_map(|w| w.to_le_bytes()).collect();
        s.serialize_bytes(&bytes)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<u32>, D::Error> {
        d.deserialize_bytes(WordsVisitor)
    }

    struct WordsVisitor;

    impl<'de> Visitor<'de> for WordsVisitor {
        type Value = Vec<u32>;

        fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
            f.write_str("a byte string of little-endian u32 words")
        }

        fn visit_bytes<E: Error>(self, b: &[u8]) -> Result<Vec<u32>, E> {
            if !b.len().is_multiple_of(4) {
                return Err(E::custom(format!(
                    "packed radiance of {} bytes is not whole u32 words",
                    b.len()
                )));
            }
            // Copied into fresh capacity rather than zero-filled and overwritten: the
            // fill was a memset of every result on the master's actor thread.
            let n = b.len() / 4;
            let mut words = Vec::<u32>::with_capacity(n);
            // SAFETY: the capacity holds `n` words, `b.len()` bytes, all written before
            // `set_len`; any four bytes are a valid `u32`.
            unsafe {
                std::ptr::copy_nonoverlapping(b.as_ptr(), words.as_mut_ptr().cast::<u8>(), b.len());
                words.set_len(n);
            }
            words.iter_mut().for_each(|w| *w = u32::from_le(*w)); // no-op on little-endian
            Ok(words)
        }

        fn visit_borrowed_bytes<E: Error>(self, b: &'de [u8]) -> Result<Vec<u32>, E> {
            self.visit_bytes(b)
        }

        fn visit_byte_buf<E: Error>(self, b: Vec<u8>) -> Result<Vec<u32>, E> {
            self.visit_bytes(&b)
        }
    }
}

impl PackedRadiance {
    /// Number of pixels carried.
    pub fn len(&self) -> usize {
        match self {
            PackedRadiance::Rgb9e5(v) => v.len(),
        }
    }

    /// True when no pixel is carried.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Messages from a worker to the master.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum WorkerMsg {
    /// First frame on a connection.
    Hello { protocol: u32, name: String, cores: u32 },
    /// Answer to [`MasterMsg::Challenge`]: HMAC-SHA256(secret, nonce), if it has a secret.
    Auth { mac: Option<[u8; 32]> },
    /// Ask for an asset of the manifest by hash.
    AssetRequest { hash: AssetHash },
    /// The worker can take `credits` more jobs.
    Ready { credits: u32 },
    /// The answer to one job.
    Result(JobResult),
    /// Nothing else to say; keeps the connection alive.
    Heartbeat,
    /// The worker stopped taking jobs (its desk's owner is active); the jobs it held are
    /// lost. See the module's *Pausing* section.
    Paused { reason: PauseReason },
    /// The worker takes jobs again; `Ready` follows.
    Resumed,
    /// A held job the worker dropped without rendering it: a job of a newer scene state
    /// came before it started, so its pixels would only show an outdated view (the paper
    /// discards stale jobs). It is lost like any other, never handed out again; a `Ready`
    /// returns its credit.
    Superseded { frame: FrameNo, set: SetNo },
    /// First frame on a connection with a shared secret, sent plain: the worker's
    /// protocol version and the Noise handshake's first message.
    Handshake {
        protocol: u32,
        #[serde(with = "serde_bytes")]
        noise: Vec<u8>,
    },
}

/// Why a worker paused: its desk's owner is using the machine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PauseReason {
    /// Other processes used `percent` % of all CPUs over the last `window_s` seconds.
    OwnerCpu { percent: f32, window_s: f32 },
    /// Keyboard or mouse input `seconds_ago` seconds ago.
    OwnerInput { seconds_ago: f32 },
    /// A simulated grid's availability curve took the worker away (`gridlight simgrid`).
    Withdrawn,
}

impl PauseReason {
    /// A fixed short name, for counting by kind.
    pub fn kind(&self) -> &'static str {
        match self {
            PauseReason::OwnerCpu { .. } => "owner_cpu",
            PauseReason::OwnerInput { .. } => "owner_input",
            PauseReason::Withdrawn => "withdrawn",
        }
    }
}

impl std::fmt::Display for PauseReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PauseReason::OwnerCpu { percent, window_s } => {
                write!(f, "owner's processes used {percent:.0} % of the CPUs over {window_s:.0} s")
            }
            PauseReason::OwnerInput { seconds_ago } => {
                write!(f, "keyboard or mouse used {seconds_ago:.0} s ago")
            }
            PauseReason::Withdrawn => write!(f, "withdrawn by the simulated grid's availability"),
        }
    }
}

/// The rendered pixels of one job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobResult {
    pub frame: FrameNo,
    pub set: SetNo,
    pub state_version: StateVersion,
    /// Demodulated radiance (divided by the primary hit's albedo) of the set's pixels.
    pub radiance: PackedRadiance,
    /// Time spent rendering, in microseconds.
    pub render_us: u64,
    /// [`crate::wire::integrity::ResultKey::tag`] over the fields above (`render_us`
    /// excepted) on a plain connection; `None` on an encrypted one.
    pub tag: Option<[u8; crate::wire::integrity::TAG_LEN]>,
}

/// Messages from the master to a worker.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum MasterMsg {
    /// Answer to `Hello`: prove the secret by MAC over `nonce`.
    Challenge { nonce: [u8; 32], auth_required: bool },
    /// The connection is refused or ended; `reason` says why, for a human.
    Rejected { reason: String },
    /// Authentication passed: who you are, how frames are split, what to fetch.
    Welcome { worker_id: u64, sets: SetsConfig, assets: Vec<AssetEntry> },
    /// Part of an asset, in order; `offset + data.len() == len` on the last one.
    AssetChunk {
        hash: AssetHash,
        offset: u64,
        len: u64,
        #[serde(with = "serde_bytes")]
        data: Vec<u8>,
    },
    /// A scene state, sent before the first job on this connection that names it.
    State(Box<SceneState>),
    /// Render set `set` of frame `frame` with state `state_version`, taking `spp` samples
    /// per pixel (at least 1; the state's own `render.spp` is only the default the
    /// scheduler starts from). A job with `spp` 0 ends the link as a protocol error.
    Job { frame: FrameNo, set: SetNo, state_version: StateVersion, spp: u32 },
    /// Nothing else to say; keeps the connection alive.
    Heartbeat,
    /// The answer to [`WorkerMsg::Handshake`], sent plain: the Noise handshake's second
    /// message. Every byte after it is a record of the encrypted channel.
    Handshake {
        #[serde(with = "serde_bytes")]
        noise: Vec<u8>,
    },
}
