//! `--forget-on-exit`: the scenes this worker process fetched, wiped from its asset cache
//! when it leaves the grid.
//!
//! A worker leaves the grid when it stops (Ctrl-C, SIGTERM, a fatal error) and when every
//! one of its connections to the master is gone (the master stopped or cannot be reached);
//! a worker that reconnects later fetches the scene again. Only the manifests this process
//! was welcomed with are wiped: another scene's entries stay, and so does a blob that
//! another scene's view links too (`AssetCache::forget`).

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use gridlight_actors::protocol::AssetEntry;
use tracing::{info, warn};

use super::cache::AssetCache;

/// What to wipe, and whether any connection still uses it.
#[derive(Debug, Default)]
pub struct Forget {
    /// `--forget-on-exit` was given.
    on: bool,
    /// Manifests this process was welcomed with since the last wipe.
    manifests: Mutex<Vec<Vec<AssetEntry>>>,
    /// Connections past their asset fetch and not yet ended.
    live: AtomicUsize,
}

impl Forget {
    /// Wipes only when `on`.
    pub fn new(on: bool) -> Self {
        Self { on, ..Self::default() }
    }

    /// Records the scene a connection was welcomed with, before any of it is fetched.
    pub fn note_scene(&self, manifest: &[AssetEntry]) {
        if !self.on {
            return;
        }
        let mut manifests = self.manifests.lock().unwrap_or_else(|e| e.into_inner());
        if !manifests.iter().any(|m| m.as_slice() == manifest) {
            manifests.push(manifest.to_vec());
        }
    }

    /// A connection fetched its assets and renders from them.
    pub fn connection_started(&self) {
        self.live.fetch_add(1, Ordering::SeqCst);
    }

    /// A connection that had started ended; true when no other one is left.
    pub fn connection_ended(&self) -> bool {
        self.live.fetch_sub(1, Ordering::SeqCst) == 1
    }

    /// True when no connection renders from the cache now.
    pub fn idle(&self) -> bool {
        self.live.load(Ordering::SeqCst) == 0
    }

    /// Wipes the recorded scenes from `cache` (when on); `why` goes into the log line.
    /// Answers the manifests wiped, for the loaded-asset table.
    pub fn wipe(&self, cache: &AssetCache, why: &str) -> Vec<Vec<AssetEntry>> {
        if !self.on {
            return Vec::new();
        }
        let manifests =
            std::mem::take(&mut *self.manifests.lock().unwrap_or_else(|e| e.into_inner()));
        let mut blobs = 0;
        for manifest in &manifests {
            match cache.forget(manifest) {
                Ok(n) => blobs += n,
                Err(e) => warn!(cause = %e, "--forget-on-exit: cannot remove a cache entry"),
            }
        }
        if !manifests.is_empty() {
            info!(
                scenes = manifests.len(),
                blobs, why, "--forget-on-exit: scene assets wiped from the cache"
            );
        }
        manifests
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_connection_to_end_is_told_so() {
        let f = Forget::new(true);
        f.connection_started();
        f.connection_started();
        assert!(!f.connection_ended());
        assert!(!f.idle());
        assert!(f.connection_ended());
        assert!(f.idle());
    }

    #[test]
    fn a_scene_is_recorded_once_and_only_when_asked_to_forget() {
        let entry = AssetEntry { path: "a.obj".into(), hash: [1; 32], len: 3 };
        let off = Forget::new(false);
        off.note_scene(std::slice::from_ref(&entry));
        assert!(off.wipe(&AssetCache::in_memory(), "test").is_empty());
        let on = Forget::new(true);
        on.note_scene(std::slice::from_ref(&entry));
        on.note_scene(std::slice::from_ref(&entry));
        assert_eq!(on.wipe(&AssetCache::in_memory(), "test").len(), 1);
        assert!(on.wipe(&AssetCache::in_memory(), "test").is_empty(), "wiped once");
    }
}
