//! What the connections of one worker process share: the asset cache, the pixel-set
//! tables and the loaded assets.
//!
//! Every render thread is an independent worker with its own connection, but they run
//! in one process: downloading an asset once, computing a resolution's pixel sets once
//! and loading a mesh once is what keeps N threads from costing N times the memory and
//! start-up time.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sets::{SetTable, SetsError};
use gridlight_actors::state::{Resolution, SceneState};

use super::cache::{AssetCache, CacheView};
use super::forget::Forget;
use super::WorkerError;
use crate::assets::Assets;

/// Key of a set table: width, height, sets, partition.
type SetKey = (u32, u32, u32, u8);

/// State shared by the connections of one worker process.
pub struct Shared {
    pub cache: AssetCache,
    /// Held while one connection fetches assets, so the others wait and find them cached.
    pub fetch_lock: tokio::sync::Mutex<()>,
    /// The scenes to wipe when the worker leaves the grid (`--forget-on-exit`).
    pub forget: Forget,
    set_tables: Mutex<HashMap<SetKey, Arc<SetTable>>>,
    /// Loaded assets by manifest digest ([`CacheView::digest`]).
    assets: Mutex<HashMap<String, Arc<Assets>>>,
}

impl Shared {
    /// Shares `cache` between the connections of this process.
    pub fn new(cache: AssetCache) -> Self {
        Self::forgetting(cache, false)
    }

    /// [`Shared::new`], wiping the scenes it fetched when the worker leaves the grid when
    /// `forget_on_exit`.
    pub fn forgetting(cache: AssetCache, forget_on_exit: bool) -> Self {
        Self {
            cache,
            fetch_lock: tokio::sync::Mutex::new(()),
            forget: Forget::new(forget_on_exit),
            set_tables: Mutex::new(HashMap::new()),
            assets: Mutex::new(HashMap::new()),
        }
    }

    /// The pixel sets of a `width × height` frame split by `sets`, computed once.
    pub fn set_table(&self, res: Resolution, sets: SetsConfig) -> Result<Arc<SetTable>, SetsError> {
        let partition = match sets.partition {
            Partition::QuasiRandom => 0,
            Partition::Tiles => 1,
        };
        let key = (res.width, res.height, sets.sets, partition);
        // A poisoned lock only means another thread panicked mid-insert of a complete value.
        let mut tables = self.set_tables.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(table) = tables.get(&key) {
            return Ok(Arc::clone(table));
        }
        let table = Arc::new(SetTable::new(res, sets)?);
        tables.insert(key, Arc::clone(&table));
        Ok(table)
    }

    /// Assets with everything `state` needs, loaded from `view` (once per view, and again
    /// only when a state names something not loaded yet).
    pub fn assets_for(
        &self,
        view: &CacheView,
        state: &SceneState,
    ) -> Result<Arc<Assets>, WorkerError> {
        let mut loaded = self.assets.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(assets) = loaded.get(view.digest()) {
            if super::resolver::assets_cover(assets, state) {
                return Ok(Arc::clone(assets));
            }
        }
        let assets = Arc::new(super::resolver::load_assets(view, state)?);
        loaded.insert(view.digest().to_owned(), Arc::clone(&assets));
        Ok(assets)
    }

    /// Wipes the fetched scenes from the cache and memory under `--forget-on-exit`, once
    /// no connection renders from them (checked under the fetch lock, so that none is
    /// fetching meanwhile either).
    pub async fn forget_if_idle(&self, why: &str) {
        let _guard = self.fetch_lock.lock().await;
        if !self.forget.idle() {
            return;
        }
        let wiped = self.forget.wipe(&self.cache, why);
        if !wiped.is_empty() {
            // Loaded meshes and textures too: this process may go on and join again.
            self.assets.lock().unwrap_or_else(|e| e.into_inner()).clear();
        }
    }
}
