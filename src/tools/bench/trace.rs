//! `gridlight bench trace`: single-thread throughput of the path-tracing kernel.
//!
//! Renders every pixel of a scene at the benchmark settings (640×480, max depth
//! 5, 4 spp unless overridden) with one thread, several times, and reports the
//! median run as camera paths ("samples") and rays (closest-hit plus shadow
//! rays) per second per core. Scene BVH construction is not timed. The render
//! thread's CPU time is reported too: on a shared, loaded machine wall-clock time
//! includes waiting for a core, CPU time does not.

use std::sync::Arc;
use std::time::Instant;

use gridlight_actors::state::SceneState;
use serde::Serialize;

use crate::assets::Assets;
use crate::render::isa::IsaLevel;
use crate::render::{render_pixels_in, RenderError, RenderScene, Strategy};
use crate::simgrid::cost::thread_cpu_seconds;

/// The settings of one benchmark run.
#[derive(Clone, Copy, Debug)]
pub struct TraceSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Timed repetitions; the median is reported.
    pub runs: u32,
    /// The instruction-set level whose kernel build renders (one this CPU runs).
    pub isa: IsaLevel,
}

impl Default for TraceSettings {
    fn default() -> Self {
        Self { width: 640, height: 480, spp: 4, max_depth: 5, runs: 3, isa: IsaLevel::best() }
    }
}

impl TraceSettings {
    /// `state` at these settings' resolution, samples and depth (the camera keeps its
    /// framing at the new resolution).
    pub fn applied_to(&self, state: &SceneState) -> SceneState {
        let mut state = state.clone();
        state.resolution.width = self.width;
        state.resolution.height = self.height;
        state.render.spp = self.spp;
        state.render.max_depth = self.max_depth;
        state
    }
}

/// The run with the median time of `runs` (time, what the run counted); `runs` is
/// reordered. Panics when `runs` is empty.
pub fn median_run<T: Copy>(runs: &mut [(f64, T)]) -> (f64, T) {
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    runs[runs.len() / 2]
}

/// One line of `bench trace --json`.
#[derive(Clone, Debug, Serialize)]
pub struct TraceReport {
    pub scene: String,
    pub samples_per_second_per_core: f64,
    pub rays_per_second_per_core: f64,
    pub triangles: usize,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub max_depth: u32,
    /// Median wall-clock seconds of one full-frame render.
    pub seconds: f64,
    /// CPU seconds of the render thread in the run with the median CPU time.
    pub cpu_seconds: f64,
    /// Samples per CPU second of that run.
    pub samples_per_cpu_second: f64,
    /// Rays per CPU second of that run: the per-core ray rate on a loaded machine.
    pub rays_per_cpu_second: f64,
    pub samples: u64,
    pub rays: u64,
    pub runs: u32,
    /// Share of the eight lanes of a BVH node test that hold a child box, over the
    /// scene's trees (the CPU tracer's SIMD runs across a node's children).
    pub node_lane_occupancy: f64,
    /// Share of the four lanes of a leaf's triangle test that hold a triangle.
    pub leaf_lane_occupancy: f64,
    /// The kernel build that rendered: `x86-64-v4` (paths in AVX-512 lanes), `x86-64-v3`
    /// (AVX2 lanes) or `baseline` (SSE2 lanes, every x86-64 CPU).
    pub build: &'static str,
    /// Share of the sixteen lanes that held a vertex each time the stream kernel's vector
    /// shading stage ran (null where the stage never ran).
    pub vector_lane_occupancy: Option<f64>,
    /// Share of path vertices shaded by the vector stage rather than the
    /// one-path step in their lane (glass and conductor vertices, and every vertex of
    /// the BSDF-only strategy).
    pub vector_vertex_share: Option<f64>,
}

/// Benchmarks one scene: the state's resolution and render settings are
/// replaced by `settings`.
pub fn bench_scene(
    name: &str,
    assets: Arc<Assets>,
    state: &SceneState,
    settings: TraceSettings,
) -> Result<TraceReport, RenderError> {
    let state = settings.applied_to(state);
    let scene = RenderScene::new(assets, &state)?;
    let pixels: Vec<u32> = (0..state.resolution.pixels() as u32).collect();
    let mut out = Vec::with_capacity(pixels.len());
    let mut runs = Vec::new();
    let mut cpu = Vec::new();
    for run in 0..settings.runs.max(1) {
        let (start, start_cpu) = (Instant::now(), thread_cpu_seconds());
        let frame = run as u64;
        let stats =
            render_pixels_in(settings.isa, &scene, frame, &pixels, &mut out, Strategy::NeeMis);
        runs.push((start.elapsed().as_secs_f64(), stats));
        cpu.push((thread_cpu_seconds() - start_cpu, stats));
    }
    let (seconds, stats) = median_run(&mut runs);
    // Rays of the run with the median CPU time (each run traces another frame).
    let (cpu_seconds, cpu_stats) = median_run(&mut cpu);
    let lanes = scene.tlas().lane_fill();
    Ok(TraceReport {
        scene: name.to_string(),
        samples_per_second_per_core: stats.samples as f64 / seconds,
        rays_per_second_per_core: stats.rays as f64 / seconds,
        triangles: scene.triangle_count(),
        width: settings.width,
        height: settings.height,
        spp: settings.spp,
        max_depth: settings.max_depth,
        seconds,
        cpu_seconds,
        samples_per_cpu_second: cpu_stats.samples as f64 / cpu_seconds,
        rays_per_cpu_second: cpu_stats.rays as f64 / cpu_seconds,
        samples: stats.samples,
        rays: stats.rays,
        runs: settings.runs.max(1),
        node_lane_occupancy: lanes.node_occupancy(),
        leaf_lane_occupancy: lanes.leaf_occupancy(),
        build: settings.isa.name(),
        vector_lane_occupancy: stats.vector_lane_occupancy(),
        vector_vertex_share: stats.vector_vertex_share(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes::cornell_box;

    #[test]
    fn the_median_run_is_the_middle_time_with_its_own_counts() {
        let mut runs = [(3.0, 'a'), (1.0, 'b'), (2.0, 'c'), (5.0, 'd'), (4.0, 'e')];
        assert_eq!(median_run(&mut runs), (3.0, 'a'));
        assert_eq!(median_run(&mut [(7.0, 1)]), (7.0, 1));
    }

    #[test]
    fn settings_replace_resolution_samples_and_depth_only() {
        let (_, state) = cornell_box(640, 480);
        let s = TraceSettings {
            width: 8,
            height: 6,
            spp: 2,
            max_depth: 3,
            runs: 1,
            ..Default::default()
        };
        let applied = s.applied_to(&state);
        assert_eq!((applied.resolution.width, applied.resolution.height), (8, 6));
        assert_eq!((applied.render.spp, applied.render.max_depth), (2, 3));
        assert_eq!(applied.camera, state.camera);
    }

    #[test]
    fn report_counts_every_sample_and_at_least_one_ray_each() {
        let (assets, state) = cornell_box(640, 480);
        for isa in IsaLevel::ALL.into_iter().filter(|b| b.available()) {
            let settings =
                TraceSettings { width: 8, height: 6, spp: 2, max_depth: 3, runs: 1, isa };
            let r = bench_scene("cornell-box", assets.clone(), &state, settings).unwrap();
            assert_eq!(r.samples, 8 * 6 * 2);
            assert!(r.rays >= r.samples && r.rays <= r.samples * 2 * 3);
            assert_eq!(r.triangles, 36);
            assert!(r.samples_per_second_per_core > 0.0);
            assert!(r.cpu_seconds > 0.0 && r.samples_per_cpu_second > 0.0);
            assert!(r.rays_per_cpu_second >= r.samples_per_cpu_second);
            // 36 triangles: leaves hold one to three of them, nodes at least two children.
            assert!(r.leaf_lane_occupancy > 0.25 && r.leaf_lane_occupancy <= 0.75);
            assert!(r.node_lane_occupancy >= 0.25 && r.node_lane_occupancy <= 1.0);
            // Every vertex of the Cornell box is diffuse and area-lit: all take the vector
            // stage, whose lanes drain only at the end of the 96 paths.
            assert_eq!((r.build, r.vector_vertex_share), (isa.name(), Some(1.0)));
            let occupancy = r.vector_lane_occupancy.unwrap();
            assert!(occupancy > 0.5 && occupancy <= 1.0, "{occupancy}");
            let json = serde_json::to_value(&r).unwrap();
            for key in [
                "scene",
                "samples_per_second_per_core",
                "rays_per_second_per_core",
                "rays_per_cpu_second",
                "triangles",
                "node_lane_occupancy",
                "leaf_lane_occupancy",
                "build",
                "vector_lane_occupancy",
                "vector_vertex_share",
            ] {
                assert!(json.get(key).is_some(), "missing {key}");
            }
        }
    }
}
