//! The worker's on-disk asset cache, keyed by content hash (docs/design.md, decision 4).
//!
//! Layout under the cache directory:
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
//! Asset paths come from the master: absolute paths and `..` are refused so that a
//! hostile master cannot write outside the cache.

use std::fs;
use std::io::{self, Write};
use std::path::{Component, Path, PathBuf};

use gridlight_actors::protocol::{AssetEntry, AssetHash};
use sha2::{Digest, Sha256};

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

/// The hash-keyed asset store of one cache directory.
#[derive(Clone, Debug)]
pub struct AssetCache {
    root: PathBuf,
}

impl AssetCache {
    /// Opens (creating if needed) the cache at `root`.
    pub fn open(root: impl Into<PathBuf>) -> Result<Self, CacheError> {
        let root = root.into();
        for sub in ["blobs", "views", "tmp"] {
            let dir = root.join(sub);
            fs::create_dir_all(&dir).map_err(io_err(&dir))?;
        }
        Ok(Self { root })
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

    /// The cache directory.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Where the blob of `hash` lives (whether or not it is there).
    pub fn blob_path(&self, hash: &AssetHash) -> PathBuf {
        self.root.join("blobs").join(hex::encode(hash))
    }

    /// True when the blob of `entry` is in the cache with the manifest's length.
    ///
    /// Blobs get their final name only after their hash was verified, so the length
    /// check guards against truncation by something outside gridlight only.
    pub fn contains(&self, entry: &AssetEntry) -> bool {
        fs::metadata(self.blob_path(&entry.hash)).is_ok_and(|m| m.is_file() && m.len() == entry.len)
    }

    /// The entries of `manifest` not in the cache, without duplicate hashes.
    pub fn missing(&self, manifest: &[AssetEntry]) -> Vec<AssetEntry> {
        let mut seen = std::collections::HashSet::new();
        manifest.iter().filter(|e| !self.contains(e) && seen.insert(e.hash)).cloned().collect()
    }

    /// Starts receiving the blob of `entry`.
    pub fn begin(&self, entry: &AssetEntry) -> Result<BlobWriter, CacheError> {
        let tmp = self.root.join("tmp").join(format!(
            "{}.{}.{}",
            hex::encode(entry.hash),
            std::process::id(),
            rand::random::<u64>()
        ));
        let file = fs::File::create(&tmp).map_err(io_err(&tmp))?;
        Ok(BlobWriter {
            entry: entry.clone(),
            file: io::BufWriter::new(file),
            tmp,
            dest: self.blob_path(&entry.hash),
            hasher: Sha256::new(),
            written: 0,
        })
    }

    /// Stores `bytes` as the blob of `entry`, verifying them first.
    pub fn insert(&self, entry: &AssetEntry, bytes: &[u8]) -> Result<(), CacheError> {
        let mut w = self.begin(entry)?;
        w.write_chunk(0, bytes)?;
        w.finish()
    }

    /// A directory in which every asset of `manifest` appears under its path.
    /// Every blob must already be in the cache.
    pub fn view(&self, manifest: &[AssetEntry]) -> Result<CacheView, CacheError> {
        for e in manifest {
            check_relative(&e.path)?;
        }
        let dir = self.root.join("views").join(manifest_digest(manifest));
        if dir.is_dir() {
            return Ok(CacheView { dir });
        }
        // Build under a unique name and rename: concurrent workers never see half a view.
        let tmp = self.root.join("tmp").join(format!(
            "view.{}.{}",
            std::process::id(),
            rand::random::<u64>()
        ));
        for e in manifest {
            let dest = tmp.join(&e.path);
            if let Some(parent) = dest.parent() {
                fs::create_dir_all(parent).map_err(io_err(parent))?;
            }
            let blob = self.blob_path(&e.hash);
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
        Ok(CacheView { dir })
    }
}

/// Receives one blob chunk by chunk, hashing as it goes.
pub struct BlobWriter {
    entry: AssetEntry,
    file: io::BufWriter<fs::File>,
    tmp: PathBuf,
    dest: PathBuf,
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
        self.file.write_all(data).map_err(io_err(&self.tmp))?;
        self.hasher.update(data);
        self.written = got;
        Ok(())
    }

    /// Verifies length and hash and moves the blob to its final name.
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
        self.file.flush().map_err(io_err(&self.tmp))?;
        fs::rename(&self.tmp, &self.dest).map_err(io_err(&self.dest))?;
        Ok(())
    }
}

impl Drop for BlobWriter {
    fn drop(&mut self) {
        // After a successful finish the file is gone and this fails harmlessly.
        let _ = fs::remove_file(&self.tmp);
    }
}

/// A directory holding a manifest's assets under their scene paths.
#[derive(Clone, Debug)]
pub struct CacheView {
    dir: PathBuf,
}

impl CacheView {
    /// The view's directory: an asset root for the scene loader.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file of the asset the scene names `path`.
    pub fn resolve(&self, path: &str) -> Result<PathBuf, CacheError> {
        check_relative(path)?;
        Ok(self.dir.join(path))
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
        assert_eq!(fs::read(cache.blob_path(&e.hash)).unwrap(), b"v 0 0 0\n");
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
        let obj_file = view.resolve("bunny/bunny.obj").unwrap();
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
}
