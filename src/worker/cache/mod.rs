//! The worker's asset cache, keyed by content hash (docs/design.md, decision 4): on disk, or
//! in memory only (`--cache none`).
//!
//! Layout under the cache directory (owner-only: [`private`]):
//! - `blobs/<sha256 hex>`: one file per asset, named by the SHA-256 of its bytes. A blob
//!   is written to a unique temporary file, hashed while it is written, and renamed into
//!   place only when length and hash match the manifest; a blob under its final name is
//!   therefore always complete and correct, and several worker processes can fill the
//!   same cache at once.
//! - `views/<manifest digest>/<asset path>`: hard links (or copies) of the blobs under
//!   the paths the scene names them by. Loaders resolve relative references (an OBJ's
//!   MTL, an MTL's textures) next to the file they read, so they need the original
//!   directory structure; a view gives them that without trusting a name for content.
//!
//! In memory the same checks hold (length, order, hash before a blob is kept) and a view
//! is a map from asset path to bytes; nothing is written to disk, and the assets are gone
//! when the process ends. [`AssetCache::forget`] removes one manifest's entries (its view
//! and the blobs no other view links), for `--forget-on-exit`.
//!
//! Asset paths come from the master: absolute paths and `..` are refused so that a
//! hostile master cannot write outside the cache.

pub mod private;

use std::borrow::Cow;
use std::collections::HashMap;
use std::fs;
use std::io::{self, Write};
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex};

use gridlight_actors::protocol::{AssetEntry, AssetHash};
use sha2::{Digest, Sha256};

use crate::scene::{AssetBytes, AssetError, AssetResolver, ResolveError};

/// Subdirectory of the user's cache directory used when `--cache-dir` is not given.
pub const CACHE_SUBDIR: &str = "gridlight";

/// What can go wrong with the cache.
#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    #[error("asset cache {path}: {source}")]
    Io { path: PathBuf, source: io::Error },
    #[error("asset `{path}`: chunk at offset {offset}, expected offset {expected}")]
    OutOfOrder { path: String, offset: u64, expected: u64 },
    #[error("asset `{path}`: {got} bytes received, the manifest says {len}")]
    TooLong { path: String, got: u64, len: u64 },
    #[error("asset `{path}`: {got} bytes received, the manifest says {len}")]
    Incomplete { path: String, got: u64, len: u64 },
    #[error("asset `{path}`: SHA-256 {got} does not match the manifest's {expected}")]
    HashMismatch { path: String, got: String, expected: String },
    #[error("asset path `{0}` is not a plain relative path")]
    BadPath(String),
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> CacheError + '_ {
    move |source| CacheError::Io { path: path.to_path_buf(), source }
}

/// Verified blobs held in memory, by hash.
type Blobs = Arc<Mutex<HashMap<AssetHash, Arc<[u8]>>>>;

/// The hash-keyed asset store of one cache directory, or of this process's memory.
#[derive(Clone, Debug)]
pub enum AssetCache {
    Disk { root: PathBuf },
    Memory { blobs: Blobs },
}

impl AssetCache {
    /// Opens (creating if needed) the cache at `root`, owner-only.
    pub fn open(root: impl Into<PathBuf>) -> Result<Self, CacheError> {
        let root = root.into();
        private::private_dir(&root).map_err(io_err(&root))?;
        for sub in ["blobs", "views", "tmp"] {
            let dir = root.join(sub);
            private::private_dir(&dir).map_err(io_err(&dir))?;
        }
        Ok(Self::Disk { root })
    }

    /// A cache that keeps every asset in this process's memory (`--cache none`).
    pub fn in_memory() -> Self {
        Self::Memory { blobs: Blobs::default() }
    }

    /// The default cache directory: `$XDG_CACHE_HOME/gridlight`, else
    /// `$HOME/.cache/gridlight`, else `gridlight-cache` under the temporary directory.
    pub fn default_dir() -> PathBuf {
        let base = std::env::var_os("XDG_CACHE_HOME")
            .filter(|v| !v.is_empty())
            .map(PathBuf::from)
            .or_else(|| {
                std::env::var_os("HOME")
                    .filter(|v| !v.is_empty())
                    .map(|h| PathBuf::from(h).join(".cache"))
            });
        match base {
            Some(dir) => dir.join(CACHE_SUBDIR),
            None => std::env::temp_dir().join("gridlight-cache"),
        }
    }

    /// The cache directory; `None` in memory.
    pub fn root(&self) -> Option<&Path> {
        match self {
            Self::Disk { root } => Some(root),
            Self::Memory { .. } => None,
        }
    }

    /// True when the blob of `entry` is in the cache with the manifest's length.
    ///
    /// Blobs get their final name only after their hash was verified, so the length
    /// check guards against truncation by something outside gridlight only.
    pub fn contains(&self, entry: &AssetEntry) -> bool {
        match self {
            Self::Disk { root } => fs::metadata(blob_path(root, &entry.hash))
                .is_ok_and(|m| m.is_file() && m.len() == entry.len),
            Self::Memory { blobs } => {
                lock(blobs).get(&entry.hash).is_some_and(|b| b.len() as u64 == entry.len)
            }
        }
    }

    /// The entries of `manifest` not in the cache, without duplicate hashes.
    pub fn missing(&self, manifest: &[AssetEntry]) -> Vec<AssetEntry> {
        let mut seen = std::collections::HashSet::new();
        manifest.iter().filter(|e| !self.contains(e) && seen.insert(e.hash)).cloned().collect()
    }

    /// Starts receiving the blob of `entry`.
    pub fn begin(&self, entry: &AssetEntry) -> Result<BlobWriter, CacheError> {
        let sink = match self {
            Self::Disk { root } => {
                let tmp = unique(root, &hex::encode(entry.hash));
                let file = private::private_file(&tmp).map_err(io_err(&tmp))?;
                let dest = blob_path(root, &entry.hash);
                Sink::File { file: io::BufWriter::new(file), tmp, dest }
            }
            Self::Memory { blobs } => Sink::Memory { bytes: Vec::new(), blobs: Arc::clone(blobs) },
        };
        Ok(BlobWriter { entry: entry.clone(), sink, hasher: Sha256::new(), written: 0 })
    }

    /// Stores `bytes` as the blob of `entry`, verifying them first.
    pub fn insert(&self, entry: &AssetEntry, bytes: &[u8]) -> Result<(), CacheError> {
        let mut w = self.begin(entry)?;
        w.write_chunk(0, bytes)?;
        w.finish()
    }

    /// A view in which every asset of `manifest` appears under its path.
    /// Every blob must already be in the cache.
    pub fn view(&self, manifest: &[AssetEntry]) -> Result<CacheView, CacheError> {
        for e in manifest {
            check_relative(&e.path)?;
        }
        let digest = manifest_digest(manifest);
        let at = match self {
            Self::Disk { root } => At::Dir(disk_view(root, &digest, manifest)?),
            Self::Memory { blobs } => {
                let blobs = lock(blobs);
                let mut files = HashMap::with_capacity(manifest.len());
                for e in manifest {
                    let bytes = blobs.get(&e.hash).ok_or_else(|| CacheError::Incomplete {
                        path: e.path.clone(),
                        got: 0,
                        len: e.len,
                    })?;
                    files.insert(e.path.clone(), Arc::clone(bytes));
                }
                At::Memory(Arc::new(files))
            }
        };
        Ok(CacheView { digest, at })
    }

    /// Removes the entries of `manifest`: its view, and each of its blobs that no other
    /// view links (on disk, a blob another scene's view holds stays). Answers how many
    /// blobs were removed.
    pub fn forget(&self, manifest: &[AssetEntry]) -> Result<usize, CacheError> {
        let mut removed = 0;
        match self {
            Self::Disk { root } => {
                let view = root.join("views").join(manifest_digest(manifest));
                match fs::remove_dir_all(&view) {
                    Err(e) if e.kind() != io::ErrorKind::NotFound => {
                        return Err(CacheError::Io { path: view, source: e })
                    }
                    _ => {}
                }
                for e in manifest {
                    let blob = blob_path(root, &e.hash);
                    if fs::metadata(&blob).is_ok_and(|m| !linked_elsewhere(&m)) {
                        fs::remove_file(&blob).map_err(io_err(&blob))?;
                        removed += 1;
                    }
                }
            }
            Self::Memory { blobs } => {
                let mut blobs = lock(blobs);
                removed = manifest.iter().filter(|e| blobs.remove(&e.hash).is_some()).count();
            }
        }
        Ok(removed)
    }
}

/// Where the blob of `hash` lives under `root` (whether or not it is there).
fn blob_path(root: &Path, hash: &AssetHash) -> PathBuf {
    root.join("blobs").join(hex::encode(hash))
}

/// A fresh name under `root/tmp` that no other process or call picks.
fn unique(root: &Path, stem: &str) -> PathBuf {
    root.join("tmp").join(format!("{stem}.{}.{}", std::process::id(), rand::random::<u64>()))
}

/// True when a blob has a hard link besides its own name (another view holds it).
fn linked_elsewhere(meta: &fs::Metadata) -> bool {
    #[cfg(unix)]
    {
        std::os::unix::fs::MetadataExt::nlink(meta) > 1
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        false
    }
}

/// A poisoned lock only means another thread panicked between two complete inserts.
fn lock(blobs: &Blobs) -> std::sync::MutexGuard<'_, HashMap<AssetHash, Arc<[u8]>>> {
    blobs.lock().unwrap_or_else(|e| e.into_inner())
}

/// The view directory of `manifest` under `root`, built if needed.
fn disk_view(root: &Path, digest: &str, manifest: &[AssetEntry]) -> Result<PathBuf, CacheError> {
    let dir = root.join("views").join(digest);
    if dir.is_dir() {
        return Ok(dir);
    }
    // Build under a unique name and rename: concurrent workers never see half a view.
    let tmp = unique(root, "view");
    for e in manifest {
        let dest = tmp.join(&e.path);
        if let Some(parent) = dest.parent() {
            fs::create_dir_all(parent).map_err(io_err(parent))?;
        }
        let blob = blob_path(root, &e.hash);
        if fs::hard_link(&blob, &dest).is_err() {
            fs::copy(&blob, &dest).map_err(io_err(&blob))?;
        }
    }
    fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
    if let Err(err) = fs::rename(&tmp, &dir) {
        // Another worker won the race: use its view, drop ours.
        let _ = fs::remove_dir_all(&tmp);
        if !dir.is_dir() {
            return Err(CacheError::Io { path: dir, source: err });
        }
    }
    Ok(dir)
}

/// Where a blob being received goes.
enum Sink {
    /// A temporary file renamed to `dest` once verified.
    File { file: io::BufWriter<fs::File>, tmp: PathBuf, dest: PathBuf },
    /// Bytes added to the blobs once verified.
    Memory { bytes: Vec<u8>, blobs: Blobs },
}

/// Receives one blob chunk by chunk, hashing as it goes.
pub struct BlobWriter {
    entry: AssetEntry,
    sink: Sink,
    hasher: Sha256,
    written: u64,
}

impl BlobWriter {
    /// The manifest entry being received.
    pub fn entry(&self) -> &AssetEntry {
        &self.entry
    }

    /// True once every byte of the manifest's length arrived.
    pub fn is_complete(&self) -> bool {
        self.written == self.entry.len
    }

    /// Appends the chunk at `offset`; chunks must arrive in order.
    pub fn write_chunk(&mut self, offset: u64, data: &[u8]) -> Result<(), CacheError> {
        if offset != self.written {
            return Err(CacheError::OutOfOrder {
                path: self.entry.path.clone(),
                offset,
                expected: self.written,
            });
        }
        let got = self.written + data.len() as u64;
        if got > self.entry.len {
            return Err(CacheError::TooLong {
                path: self.entry.path.clone(),
                got,
                len: self.entry.len,
            });
        }
        match &mut self.sink {
            Sink::File { file, tmp, .. } => file.write_all(data).map_err(io_err(tmp))?,
            Sink::Memory { bytes, .. } => bytes.extend_from_slice(data),
        }
        self.hasher.update(data);
        self.written = got;
        Ok(())
    }

    /// Verifies length and hash and keeps the blob under its hash.
    pub fn finish(mut self) -> Result<(), CacheError> {
        let entry = self.entry.clone();
        if self.written != entry.len {
            return Err(CacheError::Incomplete {
                path: entry.path,
                got: self.written,
                len: entry.len,
            });
        }
        let got: [u8; 32] = std::mem::take(&mut self.hasher).finalize().into();
        if got != entry.hash {
            return Err(CacheError::HashMismatch {
                path: entry.path,
                got: hex::encode(got),
                expected: hex::encode(entry.hash),
            });
        }
        match &mut self.sink {
            Sink::File { file, tmp, dest } => {
                file.flush().map_err(io_err(tmp))?;
                fs::rename(&*tmp, &*dest).map_err(io_err(dest))?;
            }
            Sink::Memory { bytes, blobs } => {
                lock(blobs).insert(entry.hash, Arc::from(std::mem::take(bytes)));
            }
        }
        Ok(())
    }
}

impl Drop for BlobWriter {
    fn drop(&mut self) {
        // After a successful finish the file is gone and this fails harmlessly.
        if let Sink::File { tmp, .. } = &self.sink {
            let _ = fs::remove_file(tmp);
        }
    }
}

/// A manifest's assets under their scene paths: a directory, or a map in memory.
#[derive(Clone, Debug)]
pub struct CacheView {
    digest: String,
    at: At,
}

#[derive(Clone, Debug)]
enum At {
    Dir(PathBuf),
    Memory(Arc<HashMap<String, Arc<[u8]>>>),
}

impl CacheView {
    /// A name of the manifest, the same for every view of it.
    pub fn digest(&self) -> &str {
        &self.digest
    }

    /// The view's directory (an asset root for the scene loader); `None` in memory.
    pub fn dir(&self) -> Option<&Path> {
        match &self.at {
            At::Dir(dir) => Some(dir),
            At::Memory(_) => None,
        }
    }
}

impl AssetResolver for CacheView {
    fn resolve(&self, asset: &str) -> Result<PathBuf, ResolveError> {
        crate::scene::search::check_asset_path(asset)?;
        match &self.at {
            At::Dir(dir) if dir.join(asset).is_file() => Ok(dir.join(asset)),
            At::Memory(files) if files.contains_key(asset) => Err(ResolveError::Unavailable {
                asset: asset.to_owned(),
                reason: "held in memory (--cache none), not in a file".to_owned(),
            }),
            _ => Err(not_in_manifest(asset)),
        }
    }

    fn read(&self, asset: &str) -> Result<AssetBytes<'_>, AssetError> {
        match &self.at {
            At::Dir(_) => crate::scene::search::read_file(self.resolve(asset)?),
            At::Memory(files) => {
                crate::scene::search::check_asset_path(asset)?;
                let bytes = files.get(asset).ok_or_else(|| not_in_manifest(asset))?;
                Ok(AssetBytes { file: PathBuf::from(asset), bytes: Cow::Borrowed(bytes) })
            }
        }
    }
}

fn not_in_manifest(asset: &str) -> ResolveError {
    ResolveError::Unavailable {
        asset: asset.to_owned(),
        reason: "not in the master's manifest, so not in the worker's cache".to_owned(),
    }
}

/// Refuses absolute paths, `..` and anything else that could leave the view.
fn check_relative(path: &str) -> Result<(), CacheError> {
    let p = Path::new(path);
    let plain = !path.is_empty()
        && p.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir));
    if plain {
        Ok(())
    } else {
        Err(CacheError::BadPath(path.to_string()))
    }
}

/// A name for a manifest: SHA-256 over its (path, hash) pairs in order.
fn manifest_digest(manifest: &[AssetEntry]) -> String {
    let mut h = Sha256::new();
    for e in manifest {
        h.update((e.path.len() as u64).to_le_bytes());
        h.update(e.path.as_bytes());
        h.update(e.hash);
    }
    hex::encode(&h.finalize()[..16])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(path: &str, bytes: &[u8]) -> AssetEntry {
        AssetEntry {
            path: path.into(),
            hash: Sha256::digest(bytes).into(),
            len: bytes.len() as u64,
        }
    }

    #[test]
    fn a_verified_blob_is_found_by_hash() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let e = entry("meshes/a.obj", b"v 0 0 0\n");
        assert_eq!(cache.missing(std::slice::from_ref(&e)), vec![e.clone()]);
        cache.insert(&e, b"v 0 0 0\n").unwrap();
        assert!(cache.contains(&e));
        assert!(cache.missing(std::slice::from_ref(&e)).is_empty());
        assert_eq!(fs::read(blob_path(dir.path(), &e.hash)).unwrap(), b"v 0 0 0\n");
    }

    #[test]
    fn wrong_bytes_are_refused_and_leave_nothing_behind() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let e = entry("a.obj", b"good");
        let err = cache.insert(&e, b"evil").unwrap_err();
        assert!(matches!(err, CacheError::HashMismatch { .. }), "{err}");
        assert!(!cache.contains(&e));
        assert_eq!(fs::read_dir(dir.path().join("tmp")).unwrap().count(), 0);
    }

    #[test]
    fn chunks_must_come_in_order_and_fit_the_length() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let e = entry("a.bin", b"abcdef");
        let mut w = cache.begin(&e).unwrap();
        w.write_chunk(0, b"abc").unwrap();
        assert!(matches!(w.write_chunk(4, b"ef"), Err(CacheError::OutOfOrder { expected: 3, .. })));
        assert!(matches!(w.write_chunk(3, b"defg"), Err(CacheError::TooLong { .. })));
        assert!(!w.is_complete());
        w.write_chunk(3, b"def").unwrap();
        assert!(w.is_complete());
        w.finish().unwrap();
        assert!(cache.contains(&e));
    }

    #[test]
    fn an_incomplete_blob_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let e = entry("a.bin", b"abcdef");
        let mut w = cache.begin(&e).unwrap();
        w.write_chunk(0, b"abc").unwrap();
        assert!(matches!(w.finish(), Err(CacheError::Incomplete { got: 3, len: 6, .. })));
    }

    #[test]
    fn a_view_puts_assets_under_their_scene_paths() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let obj = entry("bunny/bunny.obj", b"mtllib bunny.mtl\n");
        let mtl = entry("bunny/bunny.mtl", b"newmtl m\n");
        cache.insert(&obj, b"mtllib bunny.mtl\n").unwrap();
        cache.insert(&mtl, b"newmtl m\n").unwrap();
        let view = cache.view(&[obj.clone(), mtl.clone()]).unwrap();
        let obj_file = AssetResolver::resolve(&view, "bunny/bunny.obj").unwrap();
        assert_eq!(fs::read(&obj_file).unwrap(), b"mtllib bunny.mtl\n");
        // The MTL sits next to the OBJ, as the loader expects.
        assert_eq!(fs::read(obj_file.with_file_name("bunny.mtl")).unwrap(), b"newmtl m\n");
        // The same manifest gives the same view.
        assert_eq!(cache.view(&[obj, mtl]).unwrap().dir(), view.dir());
    }

    #[test]
    fn paths_that_leave_the_view_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        for bad in ["../x", "/etc/passwd", "a/../../b", ""] {
            let e = entry(bad, b"x");
            assert!(matches!(cache.view(&[e]), Err(CacheError::BadPath(_))), "{bad} accepted");
        }
    }

    #[cfg(unix)]
    #[test]
    fn the_cache_is_owner_only_and_a_wider_one_is_tightened() {
        use std::os::unix::fs::PermissionsExt;
        let mode = |p: &Path| fs::metadata(p).unwrap().permissions().mode() & 0o777;
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("cache");
        fs::create_dir_all(root.join("blobs")).unwrap();
        fs::set_permissions(&root, fs::Permissions::from_mode(0o755)).unwrap();
        fs::set_permissions(root.join("blobs"), fs::Permissions::from_mode(0o777)).unwrap();
        let cache = AssetCache::open(&root).unwrap();
        for sub in ["", "blobs", "views", "tmp"] {
            assert_eq!(mode(&root.join(sub)), 0o700, "{sub:?}");
        }
        let e = entry("m/a.obj", b"secret mesh");
        cache.insert(&e, b"secret mesh").unwrap();
        assert_eq!(mode(&blob_path(&root, &e.hash)), 0o600);
        let view = cache.view(std::slice::from_ref(&e)).unwrap();
        assert_eq!(mode(&view.dir().unwrap().join("m/a.obj")), 0o600);
    }

    #[test]
    fn in_memory_the_same_checks_hold_and_views_read_bytes() {
        let cache = AssetCache::in_memory();
        let e = entry("m/a.obj", b"v 0 0 0\n");
        assert!(matches!(cache.insert(&e, b"v 1 1 1\n"), Err(CacheError::HashMismatch { .. })));
        assert!(!cache.contains(&e));
        cache.insert(&e, b"v 0 0 0\n").unwrap();
        assert!(cache.missing(std::slice::from_ref(&e)).is_empty());
        let view = cache.view(std::slice::from_ref(&e)).unwrap();
        assert!(view.dir().is_none());
        assert_eq!(&*view.read("m/a.obj").unwrap().bytes, b"v 0 0 0\n");
        let err = view.read("m/b.obj").unwrap_err().to_string();
        assert!(err.contains("not in the master's manifest"), "{err}");
        assert!(view.read("../m/a.obj").is_err());
        assert_eq!(cache.forget(std::slice::from_ref(&e)).unwrap(), 1);
        assert!(!cache.contains(&e));
    }

    #[cfg(unix)] // views are hard links there
    #[test]
    fn forgetting_a_scene_keeps_other_scenes_and_the_blobs_they_share() {
        let dir = tempfile::tempdir().unwrap();
        let cache = AssetCache::open(dir.path()).unwrap();
        let (only_a, shared, only_b) =
            (entry("a.obj", b"a"), entry("t.png", b"t"), entry("b.obj", b"b"));
        for (e, bytes) in [(&only_a, b"a"), (&shared, b"t"), (&only_b, b"b")] {
            cache.insert(e, bytes).unwrap();
        }
        let scene_a = [only_a.clone(), shared.clone()];
        let scene_b = [only_b.clone(), shared.clone()];
        let (view_a, view_b) = (cache.view(&scene_a).unwrap(), cache.view(&scene_b).unwrap());
        assert_eq!(cache.forget(&scene_a).unwrap(), 1, "the blob scene b links stays");
        assert!(!view_a.dir().unwrap().exists() && !cache.contains(&only_a));
        assert!(view_b.dir().unwrap().join("t.png").is_file());
        assert!(cache.contains(&only_b) && cache.contains(&shared));
        assert_eq!(cache.forget(&scene_b).unwrap(), 2);
        assert!(!cache.contains(&shared) && !view_b.dir().unwrap().exists());
    }
}
