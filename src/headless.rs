//! The headless frame sink: what the master shows when there is no window.
//!
//! For each shown frame it takes the G-buffer of the frame's scene state (computed on the
//! CPU with `primary_hit`, once per state version), turns the frame's demodulated radiance
//! into final colour with a [`FrameComposer`] (`albedo · radiance + emission`), writes it
//! as `frame-NNNNNN.png` into the output directory, appends the frame's statistics as one
//! JSON line to the stats file, and at the end writes a summary.
//!
//! Composition is a trait so that reconstruction plugs in here: the default composer,
//! [`HolesVisible`], fills nothing, so pixels no result covered keep only their emission
//! and the holes stay visible.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::sink::{FrameSink, ShownFrame, SinkError};
use gridlight_actors::state::{SceneState, StateVersion};
use rayon::prelude::*;
use serde::Serialize;
use tracing::info;

use crate::assets::Assets;
use crate::reconstruct::gbuffer::{scene_scale, GBuffer};
use crate::render::{primary_hit, PixelSample, RenderError, RenderScene};

/// Exposure of written PNGs, in stops.
pub const PNG_EXPOSURE_STOPS: f32 = 0.0;

/// Computes G-buffers on the CPU, reusing the render structures and the last state's.
pub struct GBufferCache {
    assets: Arc<Assets>,
    scene: RenderScene,
    current: Option<(StateVersion, Arc<GBuffer>)>,
}

impl GBufferCache {
    /// Prepares G-buffers of scenes over `assets`, starting from `state`.
    pub fn new(assets: Arc<Assets>, state: &SceneState) -> Result<Self, RenderError> {
        Ok(Self { scene: RenderScene::new(Arc::clone(&assets), state)?, assets, current: None })
    }

    /// The G-buffer of `state`, computed (on all cores) only when its version is new.
    pub fn get(&mut self, state: &SceneState) -> Result<Arc<GBuffer>, RenderError> {
        if let Some((version, g)) = &self.current {
            if *version == state.version {
                return Ok(Arc::clone(g));
            }
        }
        if self.scene.state().version != state.version {
            self.scene.set_state(state)?;
        }
        let res = state.resolution;
        let scene = &self.scene;
        let hits: Vec<PixelSample> =
            (0..res.pixels() as u32).into_par_iter().map(|p| primary_hit(scene, p)).collect();
        let mut g = GBuffer::empty(res.width, res.height, scene_scale(state, &self.assets));
        for (i, h) in hits.iter().enumerate() {
            g.normal[i] = h.normal;
            g.position[i] = h.position;
            g.albedo[i] = h.albedo;
            g.emission[i] = h.emission;
            g.object[i] = h.object;
        }
        let g = Arc::new(g);
        self.current = Some((state.version, Arc::clone(&g)));
        Ok(g)
    }
}

/// Turns a shown frame and its G-buffer into final linear colour (row-major).
pub trait FrameComposer: Send {
    fn compose(&mut self, frame: &ShownFrame, gbuffer: &GBuffer) -> Vec<Vec3>;
}

/// No reconstruction: accumulated radiance while the state is unchanged, this frame's
/// results otherwise; pixels without any result get radiance 0 (holes stay visible).
#[derive(Debug, Default, Clone, Copy)]
pub struct HolesVisible;

impl FrameComposer for HolesVisible {
    fn compose(&mut self, frame: &ShownFrame, gbuffer: &GBuffer) -> Vec<Vec3> {
        (0..gbuffer.len())
            .map(|i| gbuffer.albedo[i] * demodulated(frame, i) + gbuffer.emission[i])
            .collect()
    }
}

/// The radiance a pixel shows without reconstruction: the mean of every result since
/// the last state change, else zero.
pub fn demodulated(frame: &ShownFrame, pixel: usize) -> Vec3 {
    match frame.accumulated_frames.get(pixel) {
        Some(&n) if n > 0 => frame.accumulated[pixel],
        _ => Vec3::ZERO,
    }
}

/// What the sink writes, and where.
#[derive(Debug, Clone, Default)]
pub struct HeadlessOptions {
    /// Directory for `frame-NNNNNN.png` and `summary.json`; nothing is written when `None`.
    pub out_dir: Option<PathBuf>,
    /// JSON-lines statistics file, one line per shown frame.
    pub stats: Option<PathBuf>,
    /// Print a short progress line per shown frame (demo and master commands).
    pub verbose: bool,
    /// Also write each frame's own results, unfiltered and linear, as
    /// `frame-NNNNNN.current.exr` (zero where no result of the frame arrived): lets the
    /// process tests check where every shown pixel came from.
    pub dump_current: bool,
}

/// Totals over a run, written as `summary.json` and printed at the end.
#[derive(Debug, Default, Clone, Serialize)]
pub struct Summary {
    pub frames_shown: u64,
    pub frames_skipped: u64,
    pub mean_q: f64,
    pub mean_wait_ms: f64,
    pub frames_per_second: f64,
    pub dropped_late: u64,
    pub dropped_duplicate: u64,
    pub dropped_unknown: u64,
    pub max_workers: u64,
    pub bytes_in: u64,
    pub bytes_out: u64,
    pub seconds: f64,
}

/// The headless [`FrameSink`].
pub struct HeadlessSink {
    gbuffers: GBufferCache,
    composer: Box<dyn FrameComposer>,
    options: HeadlessOptions,
    stats: Option<BufWriter<File>>,
    summary: Summary,
    q_sum: f64,
    wait_sum: f64,
    started: std::time::Instant,
}

impl HeadlessSink {
    /// A sink writing as `options` say, composing with `composer`.
    pub fn new(
        gbuffers: GBufferCache,
        composer: Box<dyn FrameComposer>,
        options: HeadlessOptions,
    ) -> std::io::Result<Self> {
        if let Some(dir) = &options.out_dir {
            std::fs::create_dir_all(dir)?;
        }
        let stats = match &options.stats {
            Some(path) => Some(BufWriter::new(File::create(path)?)),
            None => None,
        };
        Ok(Self {
            gbuffers,
            composer,
            options,
            stats,
            summary: Summary::default(),
            q_sum: 0.0,
            wait_sum: 0.0,
            started: std::time::Instant::now(),
        })
    }

    /// The summary so far.
    pub fn summary(&self) -> &Summary {
        &self.summary
    }

    fn write_frame(&mut self, frame: &ShownFrame) -> Result<(), String> {
        let gbuffer = self.gbuffers.get(&frame.state).map_err(|e| format!("G-buffer: {e}"))?;
        let colour = self.composer.compose(frame, &gbuffer);
        if let Some(dir) = &self.options.out_dir {
            let path = frame_path(dir, frame.frame);
            crate::image_io::write_png(
                &path,
                gbuffer.width,
                gbuffer.height,
                &colour,
                PNG_EXPOSURE_STOPS,
            )
            .map_err(|e| e.to_string())?;
            if self.options.dump_current {
                let path = dir.join(format!("frame-{:06}.current.exr", frame.frame));
                crate::image_io::write_exr(&path, gbuffer.width, gbuffer.height, &frame.current)
                    .map_err(|e| e.to_string())?;
            }
        }
        if let Some(stats) = &mut self.stats {
            let line = serde_json::to_string(&frame.stats).map_err(|e| e.to_string())?;
            writeln!(stats, "{line}")
                .and_then(|()| stats.flush())
                .map_err(|e| format!("stats file: {e}"))?;
        }
        Ok(())
    }

    fn count(&mut self, frame: &ShownFrame) {
        let s = &frame.stats;
        let sum = &mut self.summary;
        sum.frames_shown += 1;
        sum.frames_skipped += s.skipped;
        sum.dropped_late = s.dropped_late;
        sum.dropped_duplicate = s.dropped_duplicate;
        sum.dropped_unknown = s.dropped_unknown;
        sum.max_workers = sum.max_workers.max(s.workers);
        sum.bytes_in = s.bytes_in;
        sum.bytes_out = s.bytes_out;
        self.q_sum += s.q;
        self.wait_sum += s.wait_ms;
        sum.mean_q = self.q_sum / sum.frames_shown as f64;
        sum.mean_wait_ms = self.wait_sum / sum.frames_shown as f64;
        sum.seconds = self.started.elapsed().as_secs_f64();
        sum.frames_per_second = sum.frames_shown as f64 / sum.seconds.max(1e-9);
    }
}

impl FrameSink for HeadlessSink {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        self.count(&frame);
        if self.options.verbose {
            let s = &frame.stats;
            info!(
                frame = s.frame,
                q = format!("{:.2}", s.q),
                workers = s.workers,
                wait_ms = format!("{:.1}", s.wait_ms),
                "frame shown"
            );
        }
        self.write_frame(&frame).map_err(SinkError::Other)
    }

    fn finish(&mut self) {
        let Ok(json) = serde_json::to_string(&self.summary) else { return };
        if let Some(dir) = &self.options.out_dir {
            if let Err(err) = std::fs::write(dir.join("summary.json"), format!("{json}\n")) {
                tracing::warn!(cause = %err, "cannot write summary.json");
            }
        }
        info!(summary = %json, "run finished");
    }
}

/// `DIR/frame-NNNNNN.png`.
pub fn frame_path(dir: &Path, frame: u64) -> PathBuf {
    dir.join(format!("frame-{frame:06}.png"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::master::FrameStats;

    fn frame(accumulated: Vec<Vec3>, counts: Vec<u32>) -> ShownFrame {
        let n = counts.len();
        ShownFrame {
            frame: 7,
            state: Arc::new(crate::bench::master::bench_state()),
            current: accumulated.clone(),
            current_mask: counts.iter().map(|c| *c > 0).collect(),
            accumulated,
            accumulated_frames: counts,
            stats: FrameStats {
                frame: 7,
                q: 0.5,
                jobs_back: n as u32 / 2,
                ..FrameStats::default()
            },
        }
    }

    #[test]
    fn covered_pixels_are_remodulated_and_holes_keep_only_their_emission() {
        let mut g = GBuffer::empty(2, 1, 1.0);
        g.albedo = vec![Vec3::new(0.5, 0.25, 1.0), Vec3::splat(0.5)];
        g.emission = vec![Vec3::splat(0.1), Vec3::splat(2.0)];
        let f = frame(vec![Vec3::splat(2.0), Vec3::splat(9.0)], vec![1, 0]);
        let colour = HolesVisible.compose(&f, &g);
        assert_eq!(colour[0], Vec3::new(1.1, 0.6, 2.1));
        assert_eq!(colour[1], Vec3::splat(2.0), "a hole shows its emission only");
    }

    #[test]
    fn stats_lines_and_the_summary_follow_the_shown_frames() {
        let dir = tempfile::tempdir().unwrap();
        let state = crate::bench::master::bench_state();
        let mut small = state.clone();
        small.resolution = gridlight_actors::state::Resolution { width: 2, height: 1 };
        let gbuffers = GBufferCache::new(Arc::new(Assets::default()), &small).unwrap();
        let options = HeadlessOptions {
            out_dir: Some(dir.path().join("frames")),
            stats: Some(dir.path().join("stats.jsonl")),
            verbose: false,
            dump_current: false,
        };
        let mut sink = HeadlessSink::new(gbuffers, Box::new(HolesVisible), options).unwrap();
        for _ in 0..2 {
            let mut f = frame(vec![Vec3::ONE; 2], vec![1, 1]);
            f.state = Arc::new(small.clone());
            sink.show(f).unwrap();
        }
        sink.finish();
        let stats = std::fs::read_to_string(dir.path().join("stats.jsonl")).unwrap();
        assert_eq!(stats.lines().count(), 2);
        let line: serde_json::Value = serde_json::from_str(stats.lines().next().unwrap()).unwrap();
        assert_eq!(line["frame"], 7);
        assert!(frame_path(&dir.path().join("frames"), 7).is_file());
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("frames/summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(summary["frames_shown"], 2);
        assert_eq!(summary["mean_q"], 0.5);
    }
}
