//! Figure 8's gold standard: the paper's "converged image after 200 frames", made of
//! frames rendered independently of the ones the simulated workers return (their own
//! sample seeds), accumulated by the display's reconstruction, and cached on disk.
//!
//! Rendering 200 complete frames costs minutes on two shared cores, so the composed image
//! is kept under the evaluation cache ([`cache_dir`]) by the content of the scene state,
//! the frame count and the size, and made again only when one of them changes (or the
//! file is deleted). The cost of making it is stored with it and reported.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::Context as _;
use glam::Vec3;
use gridlight_actors::master::ShownFrame;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::grid::Prepared;
use crate::gpu::Backend;
use crate::master::compose::Composer;
use crate::master::view::View;
use crate::reconstruct::ReconstructParams;
use crate::render::RenderScene;
use crate::simgrid::frames::{render_reflected, state_key};

/// The gold frames' numbers start here: the simulated workers' cached frames are numbered
/// from 0, so no gold frame shares their sample seeds.
const FIRST_FRAME: u64 = 1 << 32;
/// Bumped when what is cached changes meaning.
const FORMAT: u32 = 1;

/// The composed gold standard and what it cost.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Gold {
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    /// Seconds it took to render and compose, on the machine that made it.
    pub seconds: f64,
    /// Linear colour per pixel, as the display's reconstruction made it.
    pub pixels: Vec<[f32; 3]>,
    /// Loaded from the cache in this run (not rendered).
    #[serde(skip)]
    pub cached: bool,
    #[serde(skip)]
    pub file: PathBuf,
}

impl Gold {
    pub fn linear(&self) -> Vec<Vec3> {
        self.pixels.iter().map(|&p| Vec3::from(p)).collect()
    }
}

/// Where the evaluation keeps what outlives a run: `GRIDLIGHT_EVAL_CACHE`, else
/// `$XDG_CACHE_HOME/gridlight/eval`, else `~/.cache/gridlight/eval`, else the temp dir.
pub fn cache_dir() -> PathBuf {
    let env = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty()).map(PathBuf::from);
    env("GRIDLIGHT_EVAL_CACHE")
        .or_else(|| env("XDG_CACHE_HOME").map(|d| d.join("gridlight").join("eval")))
        .or_else(|| env("HOME").map(|d| d.join(".cache").join("gridlight").join("eval")))
        .unwrap_or_else(|| std::env::temp_dir().join("gridlight-eval-cache"))
}

/// `frames` independent frames of `prepared`'s view, converged; from `dir` when made before.
pub fn gold_standard(prepared: &Prepared, frames: u32, dir: &Path) -> anyhow::Result<Gold> {
    let res = prepared.state.resolution;
    let key = {
        let mut h = Sha256::new();
        h.update(state_key(&prepared.state));
        h.update(frames.to_le_bytes());
        h.update(FORMAT.to_le_bytes());
        h.update(format!("{:?}", ReconstructParams::default()));
        h.finalize()
    };
    let hex: String = key.iter().take(8).map(|b| format!("{b:02x}")).collect();
    let file = dir.join(format!("gold-{}x{}-{frames}-{hex}.msgpack", res.width, res.height));
    if let Ok(bytes) = std::fs::read(&file) {
        if let Ok(gold) = rmp_serde::from_slice::<Gold>(&bytes) {
            if gold.pixels.len() == res.pixels() && gold.frames == frames {
                return Ok(Gold { cached: true, file, ..gold });
            }
        }
    }
    let started = Instant::now();
    let pixels = render_and_compose(prepared, frames)?;
    let gold = Gold {
        width: res.width,
        height: res.height,
        frames,
        seconds: started.elapsed().as_secs_f64(),
        pixels: pixels.iter().map(|p| p.to_array()).collect(),
        cached: false,
        file: file.clone(),
    };
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let bytes = rmp_serde::to_vec(&gold).context("encoding the gold standard")?;
    std::fs::write(&file, bytes).with_context(|| format!("writing {}", file.display()))?;
    Ok(gold)
}

/// Renders each frame on every core and composes it (complete, every pixel covered) as
/// the display would show the static view accumulating.
fn render_and_compose(prepared: &Prepared, frames: u32) -> anyhow::Result<Vec<Vec3>> {
    let scene = RenderScene::new(Arc::clone(&prepared.assets), &prepared.state)
        .context("building the render scene")?;
    let mut composer = Composer::new(
        Arc::clone(&prepared.assets),
        &prepared.state,
        ReconstructParams::default(),
        Backend::Cpu,
    )?;
    let state = Arc::new(prepared.state.clone());
    let pixels = state.resolution.pixels() as u32;
    let mut last = Vec::new();
    for i in 0..u64::from(frames.max(1)) {
        let current = render_reflected(&scene, FIRST_FRAME + i, pixels);
        let frame = ShownFrame {
            frame: i + 1,
            state: Arc::clone(&state),
            current_mask: vec![true; current.len()],
            current,
            owners: Default::default(),
            // Every frame accumulates, as the frame assembler counts a static view's.
            stats: gridlight_actors::stats::FrameStats {
                accumulated_frames: i as u32 + 1,
                ..Default::default()
            },
        };
        last = composer.compose(&frame, View::Final)?.image.into_host()?.1.unwrap_or_default();
    }
    Ok(last)
}
