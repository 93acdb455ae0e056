//! Path-traced frames rendered once and cached, so that simulated workers return real
//! pixels without spending the render time again.
//!
//! For every scene state an evaluation run will show (the start state and each edit of its camera
//! path, applied as the master applies them), a few complete frames are path-traced with
//! the real renderer, each with its own frame number and so its own sample seeds. A
//! simulated worker answers job (frame f, set s) of a state with set s's pixels of cached
//! frame `f mod frames`. States are found by content, not by version: the key is a hash of
//! the state with its version cleared, so the master's versions need not be known ahead.
//! Radiance is stored packed (RGB9E5), exactly as workers send it.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::packing::encode_rgb9e5;
use gridlight_actors::state::SceneState;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::cost::CostModel;
use crate::assets::Assets;
use crate::render::{render_pixels, RenderScene};

/// Errors of building, saving or loading a cache.
#[derive(Debug, thiserror::Error)]
pub enum FrameCacheError {
    #[error("rendering the cached frames: {0}")]
    Render(String),
    #[error("frame cache {path}: {cause}")]
    File { path: String, cause: String },
}

/// Identifies a state's content, whatever its version.
pub type StateKey = [u8; 32];

/// The content key of `state`.
pub fn state_key(state: &SceneState) -> StateKey {
    let mut plain = state.clone();
    plain.version = 0;
    let bytes = rmp_serde::to_vec(&plain).unwrap_or_default();
    Sha256::digest(&bytes).into()
}

/// Frames of one state.
#[derive(Clone, Debug, Serialize, Deserialize)]
struct CachedState {
    key: StateKey,
    /// RGB9E5 reflected radiance per pixel, one vector per cached frame.
    frames: Vec<Vec<u32>>,
}

/// Everything a simulated worker needs: the cost model and the cached frames.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct FrameCache {
    pub width: u32,
    pub height: u32,
    pub cost: CostModel,
    states: Vec<CachedState>,
}

impl FrameCache {
    /// An empty cache for images of `width`×`height` with `cost`.
    pub fn new(width: u32, height: u32, cost: CostModel) -> Self {
        Self { width, height, cost, states: Vec::new() }
    }

    /// Renders `frames` complete frames of `state` (frame numbers `0..frames`) on every
    /// core and adds them.
    pub fn add_state(
        &mut self,
        assets: &Arc<Assets>,
        state: &SceneState,
        frames: u32,
    ) -> Result<(), FrameCacheError> {
        let key = state_key(state);
        if self.states.iter().any(|s| s.key == key) {
            return Ok(());
        }
        let scene = RenderScene::new(Arc::clone(assets), state)
            .map_err(|e| FrameCacheError::Render(e.to_string()))?;
        let pixels = state.resolution.pixels() as u32;
        let rendered =
            (0..frames.max(1)).map(|f| render_frame(&scene, u64::from(f), pixels)).collect();
        self.states.push(CachedState { key, frames: rendered });
        Ok(())
    }

    /// The size of the cached frames.
    pub fn resolution(&self) -> gridlight_actors::state::Resolution {
        gridlight_actors::state::Resolution { width: self.width, height: self.height }
    }

    /// Pixels of cached frame `frame mod frames` of the state with `key`.
    pub fn frame(&self, key: &StateKey, frame: u64) -> Option<&[u32]> {
        let s = self.states.iter().find(|s| s.key == *key)?;
        s.frames.get((frame % s.frames.len() as u64) as usize).map(Vec::as_slice)
    }

    /// Every cached frame of the state with `key`.
    pub fn frames(&self, key: &StateKey) -> Option<&[Vec<u32>]> {
        self.states.iter().find(|s| s.key == *key).map(|s| s.frames.as_slice())
    }

    /// States cached.
    pub fn len(&self) -> usize {
        self.states.len()
    }

    pub fn is_empty(&self) -> bool {
        self.states.is_empty()
    }

    /// Writes the cache as MessagePack.
    pub fn save(&self, path: &Path) -> Result<(), FrameCacheError> {
        let err = |cause: String| FrameCacheError::File { path: path.display().to_string(), cause };
        let bytes = rmp_serde::to_vec(self).map_err(|e| err(e.to_string()))?;
        std::fs::write(path, bytes).map_err(|e| err(e.to_string()))
    }

    /// Reads a cache written by [`FrameCache::save`].
    pub fn load(path: &Path) -> Result<Self, FrameCacheError> {
        let err = |cause: String| FrameCacheError::File { path: path.display().to_string(), cause };
        let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
        let cache: Self = rmp_serde::from_slice(&bytes).map_err(|e| err(e.to_string()))?;
        let pixels = cache.width as usize * cache.height as usize;
        if cache.states.iter().flat_map(|s| &s.frames).any(|f| f.len() != pixels) {
            return Err(err(format!("a frame is not {}×{}", cache.width, cache.height)));
        }
        Ok(cache)
    }
}

/// Rows rendered per parallel task.
const CHUNK: u32 = 2048;

/// One complete frame, packed, rendered on every core.
fn render_frame(scene: &RenderScene, frame: u64, pixels: u32) -> Vec<u32> {
    render_reflected(scene, frame, pixels).into_iter().map(encode_rgb9e5).collect()
}

/// One complete frame's reflected radiance (what workers send, unpacked), rendered on
/// every core with frame number `frame`'s sample seeds.
pub fn render_reflected(scene: &RenderScene, frame: u64, pixels: u32) -> Vec<Vec3> {
    let chunks: Vec<u32> = (0..pixels).step_by(CHUNK as usize).collect();
    chunks
        .par_iter()
        .flat_map_iter(|&start| {
            let ids: Vec<u32> = (start..(start + CHUNK).min(pixels)).collect();
            let mut out = Vec::new();
            render_pixels(scene, frame, &ids, &mut out);
            out.into_iter().map(|s| s.reflected).collect::<Vec<_>>()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes;

    fn model() -> CostModel {
        CostModel {
            samples_per_second: 1e6,
            spread: 0.0,
            spp: 1,
            jobs_measured: 2,
            time_scale: 1.0,
        }
    }

    #[test]
    fn frames_are_found_by_content_and_differ_per_frame() {
        let (assets, mut state) = testscenes::cornell_box(16, 12);
        state.render.spp = 1;
        let mut cache = FrameCache::new(16, 12, model());
        cache.add_state(&assets, &state, 2).expect("rendered");
        let mut later = state.clone();
        later.version += 5;
        let key = state_key(&later);
        assert_eq!(cache.frame(&key, 0).map(<[u32]>::len), Some(16 * 12));
        assert_ne!(cache.frame(&key, 0), cache.frame(&key, 1), "each frame has its own seeds");
        assert_eq!(cache.frame(&key, 2), cache.frame(&key, 0), "frames repeat modulo the count");
        let mut moved = state.clone();
        moved.camera.position.x += 0.1;
        assert!(cache.frame(&state_key(&moved), 0).is_none(), "another view is not cached");
    }

    #[test]
    fn a_saved_cache_loads_back_and_a_bad_file_is_an_error() {
        let (assets, mut state) = testscenes::cornell_box(8, 8);
        state.render.spp = 1;
        let mut cache = FrameCache::new(8, 8, model());
        cache.add_state(&assets, &state, 1).expect("rendered");
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("c.msgpack");
        cache.save(&path).expect("saved");
        let back = FrameCache::load(&path).expect("loaded");
        assert_eq!(back.frame(&state_key(&state), 0), cache.frame(&state_key(&state), 0));
        std::fs::write(&path, b"not a cache").expect("written");
        let err = FrameCache::load(&path).expect_err("garbage");
        assert!(err.to_string().contains("c.msgpack"), "{err}");
    }
}
