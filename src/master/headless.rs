//! The headless frame sink: what the master shows when there is no window.
//!
//! Each shown frame is reconstructed by a [`Composer`] (G-buffer of the frame's scene
//! state, the paper's fill/temporal/Gaussian/accumulation passes, remodulation, tonemap)
//! and the chosen [`View`] is written as `frame-NNNNNN.png` into the output directory (the
//! final view also as linear `frame-NNNNNN.exr` with `--exr`); the frame's statistics are
//! appended as one JSON line to the stats file, and at the end a summary is written.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use gridlight_actors::sink::{FrameSink, Preparer, ShownFrame, SinkError};
use serde::Serialize;
use tracing::info;

use crate::master::compose::{ComposeTimings, Composer};
use crate::master::view::View;

/// What the sink writes, and where.
#[derive(Debug, Clone, Default)]
pub struct HeadlessOptions {
    /// Directory for `frame-NNNNNN.png` and `summary.json`; nothing is written when `None`.
    pub out_dir: Option<PathBuf>,
    /// JSON-lines statistics file, one line per shown frame.
    pub stats: Option<PathBuf>,
    /// Print a short progress line per shown frame (demo and master commands).
    pub verbose: bool,
    /// The view written as PNG.
    pub view: View,
    /// Also write the final view's linear colour as `frame-NNNNNN.exr`.
    pub exr: bool,
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
    /// Results used in shown frames ÷ results returned (accepted or late); `null` before any.
    pub useful_fraction: Option<f64>,
    pub max_workers: u64,
    /// Most workers paused at once (their desks' owners were active).
    pub max_paused_workers: u64,
    /// Shown frames × paused workers, by reason kind (`owner_cpu`, `owner_input`).
    pub paused_by_reason: std::collections::BTreeMap<String, u64>,
    pub bytes_in: u64,
    pub bytes_out: u64,
    /// Queued jobs of outdated scene states discarded (never handed out).
    pub jobs_discarded_stale: u64,
    /// Held jobs of outdated scene states that workers dropped unrendered.
    pub jobs_superseded: u64,
    pub seconds: f64,
}

/// One line of the stats file: the display's statistics of a frame and where its compose
/// time went.
#[derive(Serialize)]
struct StatsLine<'a> {
    #[serde(flatten)]
    frame: &'a gridlight_actors::stats::FrameStats,
    /// Each edit's latency up to the display's decision to show this frame (the rest of
    /// `edit_latency_ms` is the compose).
    edit_to_decision_ms: Vec<f64>,
    #[serde(flatten)]
    compose: ComposeTimings,
}

/// The headless [`FrameSink`].
pub struct HeadlessSink {
    composer: Composer,
    options: HeadlessOptions,
    stats: Option<BufWriter<File>>,
    summary: Summary,
    q_sum: f64,
    wait_sum: f64,
    started: std::time::Instant,
}

impl HeadlessSink {
    /// A sink writing as `options` say, composing with `composer`.
    pub fn new(composer: Composer, options: HeadlessOptions) -> std::io::Result<Self> {
        if let Some(dir) = &options.out_dir {
            std::fs::create_dir_all(dir)?;
        }
        let stats = match &options.stats {
            Some(path) => Some(BufWriter::new(File::create(path)?)),
            None => None,
        };
        Ok(Self {
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

    fn write_frame(&mut self, frame: &mut ShownFrame) -> Result<(), String> {
        // The display stamped the latencies when it decided to show the frame.
        let edit_to_decision_ms = frame.stats.edit_latency_ms.clone();
        let composed =
            self.composer.compose(frame, self.options.view).map_err(|e| e.to_string())?;
        // Composed is what the headless master shows (its picture exists; writing it to a
        // file is not showing it): the edit latency ends here, as the window's ends when
        // the picture is presented.
        frame.stats.stamp_edit_latency(std::time::Instant::now());
        let timings = composed.timings;
        if let Some(dir) = &self.options.out_dir {
            let (w, h) = (composed.width, composed.height);
            let (rgba, linear) = composed.image.into_host().map_err(|e| e.to_string())?;
            let path = frame_path(dir, frame.frame);
            crate::image_io::write_png_rgba8(&path, w, h, &rgba).map_err(|e| e.to_string())?;
            if let (true, Some(linear)) = (self.options.exr, &linear) {
                let path = path.with_extension("exr");
                crate::image_io::write_exr(&path, w, h, linear).map_err(|e| e.to_string())?;
            }
            if self.options.dump_current {
                let path = dir.join(format!("frame-{:06}.current.exr", frame.frame));
                crate::image_io::write_exr(&path, w, h, &frame.current)
                    .map_err(|e| e.to_string())?;
            }
        }
        if let Some(stats) = &mut self.stats {
            let line = StatsLine { frame: &frame.stats, edit_to_decision_ms, compose: timings };
            let line = serde_json::to_string(&line).map_err(|e| e.to_string())?;
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
        sum.useful_fraction = s.useful_fraction;
        sum.max_workers = sum.max_workers.max(s.workers);
        sum.max_paused_workers = sum.max_paused_workers.max(s.paused_workers);
        for p in &s.paused {
            *sum.paused_by_reason.entry(p.kind.to_owned()).or_default() += 1;
        }
        sum.bytes_in = s.bytes_in;
        sum.bytes_out = s.bytes_out;
        sum.jobs_discarded_stale = s.jobs_discarded_stale;
        sum.jobs_superseded = s.jobs_superseded;
        self.q_sum += s.q;
        self.wait_sum += s.wait_ms;
        sum.mean_q = self.q_sum / sum.frames_shown as f64;
        sum.mean_wait_ms = self.wait_sum / sum.frames_shown as f64;
        sum.seconds = self.started.elapsed().as_secs_f64();
        sum.frames_per_second = sum.frames_shown as f64 / sum.seconds.max(1e-9);
    }
}

impl FrameSink for HeadlessSink {
    fn show(&mut self, mut frame: ShownFrame) -> Result<(), SinkError> {
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
        self.write_frame(&mut frame).map_err(|e| SinkError::Other(e.into()))
    }

    fn preparer(&mut self) -> Option<Preparer> {
        self.composer.sink_preparer()
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
    use crate::assets::Assets;
    use crate::gpu::Backend;
    use crate::reconstruct::ReconstructParams;
    use glam::Vec3;
    use gridlight_actors::master::FrameStats;
    use std::sync::Arc;

    #[test]
    fn frames_stats_lines_and_the_summary_follow_the_shown_frames() {
        let dir = tempfile::tempdir().unwrap();
        let mut small = crate::tools::bench::master::bench_state();
        small.resolution = gridlight_actors::state::Resolution { width: 4, height: 2 };
        let composer = Composer::new(
            Arc::new(Assets::default()),
            &small,
            ReconstructParams::default(),
            Backend::Cpu,
        )
        .unwrap();
        let options = HeadlessOptions {
            out_dir: Some(dir.path().join("frames")),
            stats: Some(dir.path().join("stats.jsonl")),
            view: View::Final,
            exr: true,
            ..HeadlessOptions::default()
        };
        let mut sink = HeadlessSink::new(composer, options).unwrap();
        for _ in 0..2 {
            sink.show(ShownFrame {
                frame: 7,
                state: Arc::new(small.clone()),
                current: vec![Vec3::ONE; 8],
                current_mask: vec![true; 8],
                owners: Default::default(),
                stats: FrameStats { frame: 7, q: 0.5, jobs_back: 4, ..FrameStats::default() },
            })
            .unwrap();
        }
        sink.finish();
        let stats = std::fs::read_to_string(dir.path().join("stats.jsonl")).unwrap();
        assert_eq!(stats.lines().count(), 2);
        let line: serde_json::Value = serde_json::from_str(stats.lines().next().unwrap()).unwrap();
        assert_eq!(line["frame"], 7);
        let png = frame_path(&dir.path().join("frames"), 7);
        let img = image::open(&png).unwrap();
        assert_eq!((img.width(), img.height()), (4, 2));
        assert!(png.with_extension("exr").is_file(), "--exr writes the linear final view");
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join("frames/summary.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(summary["frames_shown"], 2);
        assert_eq!(summary["mean_q"], 0.5);
    }
}
