//! What the experiments share: options (quick or full), the output directory, scenes
//! with their frame caches, the modelled cores, and the progress bar.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use gridlight_actors::edit::Edit;
use gridlight_actors::state::Resolution;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::grid::{Prepared, Timing};
use crate::assets::Assets;
use crate::scene::SceneSource;
use crate::simgrid::Curve;

/// The paper's image size.
pub const PAPER_WIDTH: u32 = 640;
pub const PAPER_HEIGHT: u32 = 480;

/// Samples per second of one of the paper's cores on its Cornell box, from its own
/// numbers: 96 cores showed 640×480 frames at 4 samples per pixel at the fixed rate of
/// 6.66 frames per second (Table 1), taken as complete frames:
/// 640·480·4·6.66 / 96 ≈ 85 000. A lower bound (frames were not all complete).
pub const PAPER_CORE_SAMPLES_PER_SECOND: f64 = 640.0 * 480.0 * 4.0 * 6.66 / 96.0;

/// Sets per frame on the simulated grids: four times the master's default, so that jobs
/// per frame exceed the workers of most grids here (the paper's rule) while the master's
/// per-job cost stays within two shared cores (a 640×480 job is 1200 pixels, about 56 ms
/// on the paper's cores; 1024 sets made the master and the simulated grid's processes the
/// bottleneck at a few thousand jobs per second).
pub const GRID_SETS: u32 = 256;

/// Figure 3's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Fig3 {
    pub losses: Vec<f64>,
}

/// Figure 9's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Fig9 {
    pub frames: usize,
    pub loss: f64,
}

/// Figure 5's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Fig5 {
    pub workers: u32,
    pub fps: f32,
    pub curve: Curve,
    /// Period of the curve in frames.
    pub period: u32,
    /// The recorded camera path (an interaction script).
    pub path: PathBuf,
}

/// Table 1 / Figure 7's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Table1 {
    pub scenes: Vec<String>,
    pub workers: Vec<u32>,
    /// The variable-resources row's N (the paper's 96).
    pub variable: u32,
    pub seconds: f64,
}

/// Figure 8's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Fig8 {
    pub workers: Vec<u32>,
    pub variable: u32,
    pub seconds: f64,
    /// Mean FLIP below which two images are taken to look the same.
    pub threshold: f64,
    /// Frames of the gold standard.
    pub gold_frames: u32,
}

/// Figure 10's parameters.
#[derive(Clone, Debug, Serialize)]
pub struct Fig10 {
    pub workers: Vec<u32>,
    pub seconds: f64,
}

/// Beyond the paper's parameters: the runs across rate-limited links.
#[derive(Clone, Debug, Serialize)]
pub struct Lan {
    pub workers: Vec<u32>,
    pub links_mbit: Vec<u32>,
    pub seconds: f64,
}

/// Everything the experiments are run with.
#[derive(Clone, Debug, Serialize)]
pub struct Options {
    pub quick: bool,
    /// Size of the cached (and reconstructed) frames; jobs are timed as 640×480 ones.
    pub width: u32,
    pub height: u32,
    /// Sets per frame of the offline figures (3 and 9): the master's default.
    pub sets: u32,
    /// Sets per frame of the runs on simulated grids: the paper's rule is that jobs
    /// per frame must be much greater than the number of workers (up to 256 here).
    pub grid_sets: u32,
    /// Frames cached per static view (sample seeds differ per frame).
    pub cached_frames: u32,
    pub fig3: Fig3,
    pub fig5: Fig5,
    pub table1: Table1,
    pub fig8: Fig8,
    pub fig9: Fig9,
    pub fig10: Fig10,
    pub lan: Lan,
}

impl Options {
    /// The full run (about 20 minutes on 2 cores) or `--quick` (under 3).
    pub fn new(quick: bool) -> Self {
        let path = scenes_dir().join("scripts").join("orbit.toml");
        if quick {
            Self {
                quick,
                width: 160,
                height: 120,
                sets: 64,
                grid_sets: GRID_SETS,
                cached_frames: 16,
                fig3: Fig3 { losses: vec![0.25, 0.5, 0.75] },
                fig5: Fig5 { workers: 32, fps: 4.0, curve: Curve::Sine, period: 20, path },
                table1: Table1 {
                    scenes: vec!["cornell-box".into()],
                    workers: vec![32, 96],
                    variable: 96,
                    seconds: 2.0,
                },
                fig8: Fig8 {
                    workers: vec![8, 32, 96],
                    variable: 96,
                    seconds: 3.0,
                    threshold: 0.05,
                    gold_frames: 32,
                },
                fig9: Fig9 { frames: 8, loss: 0.5 },
                fig10: Fig10 { workers: vec![8, 32, 128, 256], seconds: 3.0 },
                lan: Lan { workers: vec![32], links_mbit: vec![100, 1000], seconds: 2.0 },
            }
        } else {
            Self {
                quick,
                width: 320,
                height: 240,
                sets: 64,
                grid_sets: GRID_SETS,
                cached_frames: 64,
                fig3: Fig3 { losses: vec![0.25, 0.5, 0.75] },
                fig5: Fig5 { workers: 96, fps: 6.66, curve: Curve::Sine, period: 100, path },
                table1: Table1 {
                    scenes: vec![
                        "cornell-box".into(),
                        "glossy-glass".into(),
                        "bunny".into(),
                        "sponza".into(),
                    ],
                    workers: vec![32, 64, 96],
                    variable: 96,
                    seconds: 10.0,
                },
                fig8: Fig8 {
                    workers: vec![8, 32, 96],
                    variable: 96,
                    seconds: 20.0,
                    threshold: 0.05,
                    gold_frames: 200,
                },
                fig9: Fig9 { frames: 24, loss: 0.5 },
                fig10: Fig10 { workers: vec![1, 2, 4, 8, 16, 32, 64, 128, 256], seconds: 10.0 },
                lan: Lan { workers: vec![32, 96], links_mbit: vec![100, 1000], seconds: 8.0 },
            }
        }
    }
}

/// The experiments' shared state.
pub struct Context {
    pub opts: Options,
    pub out: PathBuf,
    /// The `gridlight` binary (simulated-grid processes are started from it).
    pub exe: PathBuf,
    pub asset_dirs: Vec<PathBuf>,
    pub progress: ProgressBar,
    /// Frame caches live here while the run lasts.
    pub work: WorkDir,
    pub timing: Option<Timing>,
    pub prepared: HashMap<String, Arc<Prepared>>,
    /// Each scene's cost on this machine, measured once per run.
    costs: HashMap<String, crate::simgrid::CostModel>,
    pub fig3: Fig3,
    pub fig5: Fig5,
    pub table1: Table1,
    pub fig8: Fig8,
    pub fig9: Fig9,
    pub fig10: Fig10,
    pub lan: Lan,
}

impl Context {
    /// A context writing into `out` (created), with a progress bar of `steps` steps.
    pub fn new(
        opts: Options,
        out: &Path,
        asset_dirs: Vec<PathBuf>,
        steps: u64,
    ) -> anyhow::Result<Self> {
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        let progress = ProgressBar::new(steps);
        progress.set_style(
            ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        progress.enable_steady_tick(Duration::from_millis(500));
        Ok(Self {
            fig3: opts.fig3.clone(),
            fig5: opts.fig5.clone(),
            table1: opts.table1.clone(),
            fig8: opts.fig8.clone(),
            fig9: opts.fig9.clone(),
            fig10: opts.fig10.clone(),
            lan: opts.lan.clone(),
            opts,
            out: out.to_path_buf(),
            exe: std::env::current_exe().context("finding the gridlight executable")?,
            asset_dirs,
            progress,
            work: WorkDir::create()?,
            timing: None,
            prepared: HashMap::new(),
            costs: HashMap::new(),
        })
    }

    /// Says what runs now, beside the progress bar.
    pub fn step(&self, what: impl Into<String>) {
        self.progress.set_message(what.into());
    }

    /// The scene called `name` (built-in, `scenes/NAME.toml`, or a file) at the
    /// experiments' size; `Ok(None)` when its assets are not on this machine.
    pub fn scene(
        &self,
        name: &str,
    ) -> anyhow::Result<Option<(Arc<Assets>, gridlight_actors::state::SceneState)>> {
        let source = SceneSource::find(Path::new(name), &[scenes_dir()])
            .with_context(|| format!("finding scene `{name}`"))?;
        let search = source.search_path(&self.asset_dirs);
        match crate::scene::load_source(&source, &search) {
            Ok(loaded) => {
                let mut state = loaded.state;
                state.resolution = Resolution { width: self.opts.width, height: self.opts.height };
                Ok(Some((Arc::new(loaded.assets), state)))
            }
            Err(err) if err.to_string().contains("not found") => Ok(None),
            Err(err) => Err(err).with_context(|| format!("loading scene `{name}`")),
        }
    }

    /// The modelled cores: the paper's speed, relative to this machine's on the Cornell box.
    pub fn timing(&mut self) -> anyhow::Result<Timing> {
        if let Some(t) = self.timing {
            return Ok(t);
        }
        let cornell = self
            .prepared("cornell-box", false, Cores::Paper)?
            .ok_or_else(|| anyhow::anyhow!("the built-in Cornell box did not load"))?;
        let t = Timing {
            reference_samples_per_second: Some(cornell.cost.samples_per_second),
            ..paper_timing()
        };
        self.timing = Some(t);
        Ok(t)
    }

    /// `name` measured and cached (with the camera path's states when `with_path`),
    /// once per run; `Ok(None)` when the scene's assets are missing.
    pub fn prepared(
        &mut self,
        name: &str,
        with_path: bool,
        cores: Cores,
    ) -> anyhow::Result<Option<Arc<Prepared>>> {
        let key = format!(
            "{name}{}{}",
            if with_path { "-path" } else { "" },
            match cores {
                Cores::Paper => "",
                Cores::Machine => "-machine",
            }
        );
        if let Some(p) = self.prepared.get(&key) {
            return Ok(Some(Arc::clone(p)));
        }
        let Some((assets, state)) = self.scene(name)? else { return Ok(None) };
        // The Cornell box is the reference every scene's cost is relative to: the first
        // one prepared measures it (its own measurement is then the reference).
        let reference = name == "cornell-box" && !with_path && cores == Cores::Paper;
        let timing = match (cores, self.timing) {
            (Cores::Machine, _) => Timing { core_samples_per_second: None, ..paper_timing() },
            (Cores::Paper, Some(t)) => t,
            (Cores::Paper, None) if reference => paper_timing(),
            (Cores::Paper, None) => self.timing()?,
        };
        self.step(format!("measuring {name} and rendering its frame cache"));
        let cost = match self.costs.get(name) {
            Some(c) => *c,
            None => {
                *self.costs.entry(name.to_string()).or_insert(Prepared::measure(&assets, &state)?)
            }
        };
        let path = if with_path { self.path()? } else { Vec::new() };
        let frames = if with_path { 1 } else { self.opts.cached_frames };
        let prepared = Arc::new(Prepared::new(
            &key,
            assets,
            state,
            self.opts.grid_sets,
            frames,
            &path,
            1,
            self.work.path(),
            timing,
            cost,
        )?);
        if reference && self.timing.is_none() {
            self.timing = Some(Timing {
                reference_samples_per_second: Some(prepared.cost.samples_per_second),
                ..paper_timing()
            });
        }
        self.prepared.insert(key, Arc::clone(&prepared));
        Ok(Some(prepared))
    }

    /// The recorded camera path of Figure 5, at most one edit per frame of its fixed
    /// rate ([`thin`]).
    pub fn path(&self) -> anyhow::Result<Vec<(Duration, Edit)>> {
        let path = gridlight_actors::script::load(&self.fig5.path)
            .with_context(|| format!("loading the camera path {}", self.fig5.path.display()))?;
        Ok(thin(path, Duration::from_secs_f64(1.0 / f64::from(self.fig5.fps.max(0.01)))))
    }
}

/// Keeps the last edit of each `period` of `path` (a window applies input once per shown
/// frame). Edits that set the camera absolutely lose nothing but intermediate poses.
pub fn thin(path: Vec<(Duration, Edit)>, period: Duration) -> Vec<(Duration, Edit)> {
    let slot = |at: &Duration| (at.as_secs_f64() / period.as_secs_f64().max(1e-9)) as u64;
    let mut out: Vec<(Duration, Edit)> = Vec::new();
    for (at, edit) in path {
        match out.last_mut() {
            Some(last) if slot(&last.0) == slot(&at) => *last = (at, edit),
            _ => out.push((at, edit)),
        }
    }
    out
}

/// A directory for frame caches, removed with everything in it when dropped.
pub struct WorkDir(PathBuf);

impl WorkDir {
    fn create() -> anyhow::Result<Self> {
        let dir = std::env::temp_dir().join(format!("gridlight-eval-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(Self(dir))
    }

    pub fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for WorkDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Which cores the simulated workers model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Cores {
    /// The paper's ([`PAPER_CORE_SAMPLES_PER_SECOND`] on the Cornell box).
    Paper,
    /// This machine's, as measured.
    Machine,
}

/// Jobs timed as 640×480 ones on the paper's cores, the reference not yet known.
fn paper_timing() -> Timing {
    Timing {
        paper_pixels: (PAPER_WIDTH * PAPER_HEIGHT) as usize,
        core_samples_per_second: Some(PAPER_CORE_SAMPLES_PER_SECOND),
        reference_samples_per_second: None,
    }
}

/// `scenes/` in the current directory, else the one of the source tree.
pub fn scenes_dir() -> PathBuf {
    let local = PathBuf::from("scenes");
    if local.is_dir() {
        local
    } else {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::edit::CameraEdit;

    fn at(ms: u64) -> (Duration, Edit) {
        (Duration::from_millis(ms), Edit::Camera(CameraEdit::default()))
    }

    #[test]
    fn thinning_keeps_the_last_edit_of_each_frame() {
        let path = vec![at(0), at(100), at(200), at(300), at(400), at(500), at(1300)];
        let times: Vec<u64> = thin(path, Duration::from_millis(400))
            .iter()
            .map(|(t, _)| t.as_millis() as u64)
            .collect();
        assert_eq!(times, [300, 500, 1300]);
    }
}
