//! The master's asset files: the manifest workers receive (path, SHA-256, length) and
//! chunked reads by hash. Only files in the manifest can ever be served, so a worker
//! cannot ask the master for anything else on its disk. The manifest's entries travel in
//! `Welcome` (`wire::protocol` re-exports them).

use std::collections::HashMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use thiserror::Error;

/// SHA-256 of an asset file's bytes.
pub type AssetHash = [u8; 32];

/// One asset file the scene needs.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct AssetEntry {
    /// Path relative to an asset root, as scene states name it.
    pub path: String,
    pub hash: AssetHash,
    pub len: u64,
}

/// Errors reading asset files.
#[derive(Debug, Error)]
pub enum AssetStoreError {
    #[error("asset file {path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error(
        "asset {path} changed on disk since it was hashed (was {expected} bytes, now {actual})"
    )]
    Changed { path: PathBuf, expected: u64, actual: u64 },
}

/// Manifest entries and where each file lives.
#[derive(Clone, Debug, Default)]
pub struct AssetStore {
    entries: Vec<AssetEntry>,
    files: HashMap<AssetHash, PathBuf>,
}

impl AssetStore {
    /// An empty store (scenes made only of built-in shapes need no assets).
    pub fn new() -> Self {
        Self::default()
    }

    /// Hashes `file` and lists it under `asset_path` (the path scene states use).
    pub fn add_file(
        &mut self,
        asset_path: &str,
        file: &Path,
    ) -> Result<&AssetEntry, AssetStoreError> {
        let io = |source| AssetStoreError::Io { path: file.to_owned(), source };
        let mut f = File::open(file).map_err(io)?;
        let mut hasher = Sha256::new();
        let mut buf = vec![0u8; 1 << 16];
        let mut len = 0u64;
        loop {
            let n = f.read(&mut buf).map_err(io)?;
            if n == 0 {
                break;
            }
            hasher.update(&buf[..n]);
            len += n as u64;
        }
        let hash: AssetHash = hasher.finalize().into();
        self.entries.retain(|e| e.path != asset_path);
        self.entries.push(AssetEntry { path: asset_path.to_owned(), hash, len });
        self.files.insert(hash, file.to_owned());
        Ok(self.entries.last().expect("just pushed"))
    }

    /// What workers receive in `Welcome`.
    pub fn manifest(&self) -> &[AssetEntry] {
        &self.entries
    }

    /// The manifest entry with this hash, if any.
    pub fn entry(&self, hash: &AssetHash) -> Option<&AssetEntry> {
        self.entries.iter().find(|e| &e.hash == hash)
    }

    /// Reads up to `max` bytes at `offset` of the file with this hash; `None` when the
    /// hash is not in the manifest.
    pub fn read_chunk(
        &self,
        hash: &AssetHash,
        offset: u64,
        max: usize,
    ) -> Option<Result<Vec<u8>, AssetStoreError>> {
        let path = self.files.get(hash)?;
        let entry = self.entry(hash)?;
        Some(read_at(path, entry.len, offset, max))
    }
}

fn read_at(
    path: &Path,
    expected: u64,
    offset: u64,
    max: usize,
) -> Result<Vec<u8>, AssetStoreError> {
    let io = |source| AssetStoreError::Io { path: path.to_owned(), source };
    let mut f = File::open(path).map_err(io)?;
    let actual = f.metadata().map_err(io)?.len();
    if actual != expected {
        return Err(AssetStoreError::Changed { path: path.to_owned(), expected, actual });
    }
    let n = (expected.saturating_sub(offset)).min(max as u64) as usize;
    let mut buf = vec![0u8; n];
    f.seek(SeekFrom::Start(offset)).map_err(io)?;
    f.read_exact(&mut buf).map_err(io)?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serves_manifest_files_by_hash_in_chunks() {
        let dir = std::env::temp_dir().join(format!("gl-assets-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("dir");
        let p = dir.join("a.obj");
        std::fs::write(&p, b"hello world").expect("write");
        let mut store = AssetStore::new();
        let hash = store.add_file("meshes/a.obj", &p).expect("add").hash;
        assert_eq!(hash, <[u8; 32]>::from(Sha256::digest(b"hello world")));
        assert_eq!(store.manifest()[0].len, 11);
        assert_eq!(store.read_chunk(&hash, 6, 100).expect("in manifest").expect("read"), b"world");
        assert_eq!(store.read_chunk(&hash, 0, 5).expect("in manifest").expect("read"), b"hello");
        assert!(store.read_chunk(&[0; 32], 0, 5).is_none(), "served a hash not in the manifest");
        std::fs::write(&p, b"changed!").expect("write");
        assert!(matches!(
            store.read_chunk(&hash, 0, 5),
            Some(Err(AssetStoreError::Changed { .. }))
        ));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
