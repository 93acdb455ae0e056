//! The modelled render time of a job: the path tracer's per-core throughput on this
//! machine for this scene, with its measured spread.
//!
//! [`CostModel::measure`] renders real jobs (pixel sets of the scene's view) one at a time
//! on one thread and records samples per second per job; a simulated worker then takes
//! `pixels · spp / throughput` per job (`spp` the job's own, which the master's scheduler
//! sizes to the grid), scaled by a normal factor of the measured relative
//! spread (clamped so that no job is free). The measurement runs on whatever else this
//! machine is doing: jobs are timed in the thread's CPU time, in several rounds, and the
//! median and the median absolute deviation keep a few jobs that another process slowed
//! (through shared caches) from making every modelled core slow and erratic.

use std::time::{Duration, Instant};

use gridlight_actors::sets::SetTable;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::render::{render_pixels, RenderScene};

/// Per-core render cost of one scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CostModel {
    /// Mean path-traced samples per second of one core.
    pub samples_per_second: f64,
    /// Standard deviation of a job's time ÷ its mean.
    pub spread: f64,
    /// Samples per pixel of a job (the scene's `spp`).
    pub spp: u32,
    /// Jobs timed to make this model.
    pub jobs_measured: u32,
    /// Every modelled time is multiplied by this: 1 for this machine's cores rendering the
    /// cached frames' pixels; more for slower cores, or for jobs timed as if the frame
    /// had more pixels than the cached one (see `eval paper`).
    pub time_scale: f64,
}

/// The shortest job, as a share of the mean: a spread wider than 1 must not make a job free.
const MIN_FACTOR: f64 = 0.2;
/// Rounds of a measurement ([`CostModel::measure`]).
pub const ROUNDS: u32 = 5;

impl CostModel {
    /// Times `jobs` sets of `table` rendered one after another on this thread, in
    /// [`ROUNDS`] rounds over different sets: the rate is the median of the rounds'
    /// medians. Each job is timed in this thread's CPU time, not wall time, so that other
    /// processes taking the cores (a build, the rest of the evaluation) do not make the
    /// scene look slower: a wall-time measurement once per run had Sponza come out as
    /// cheap as the Cornell box under load.
    pub fn measure(scene: &RenderScene, table: &SetTable, jobs: u32) -> Self {
        let spp = scene.state().render.spp.max(1);
        let sets = table.sets().max(1);
        let per_round = (jobs / ROUNDS).max(2);
        let mut out = Vec::new();
        let mut times = Vec::new();
        let mut round_medians = Vec::new();
        for round in 0..ROUNDS {
            let mut round_times = Vec::new();
            for j in 0..per_round {
                let n = round * per_round + j;
                let set = (n * 7919) % sets;
                let pixels = table.pixels(set).unwrap_or(&[]);
                let started = (Instant::now(), thread_cpu_seconds());
                render_pixels(scene, u64::from(n), pixels, &mut out);
                let cpu = thread_cpu_seconds() - started.1;
                // Without a thread clock (NaN), wall time.
                let secs = if cpu.is_finite() { cpu } else { started.0.elapsed().as_secs_f64() };
                let samples = (pixels.len() as u64 * u64::from(spp)).max(1) as f64;
                // Time per sample.
                round_times.push(secs.max(1e-9) / samples);
            }
            round_medians.push(median(&round_times));
            times.extend(round_times);
        }
        // Robust centre and spread (MAD × 1.4826 estimates a normal σ).
        let centre = median(&round_medians);
        let deviations: Vec<f64> = times.iter().map(|t| (t - centre).abs()).collect();
        Self {
            samples_per_second: 1.0 / centre,
            spread: 1.4826 * median(&deviations) / centre,
            spp,
            jobs_measured: times.len() as u32,
            time_scale: 1.0,
        }
    }

    /// Mean time of a job of `pixels` pixels at the scene's samples per pixel.
    pub fn mean_job_time(&self, pixels: usize) -> Duration {
        self.mean_time(pixels, self.spp)
    }

    /// Mean time of `pixels` pixels at `spp` samples each.
    pub fn mean_time(&self, pixels: usize, spp: u32) -> Duration {
        Duration::from_secs_f64(
            pixels as f64 * f64::from(spp) / self.samples_per_second * self.time_scale,
        )
    }

    /// One job's time, `pixels` pixels at `spp` samples each: the mean scaled by
    /// `1 + spread·z`, z standard normal.
    pub fn job_time(&self, pixels: usize, spp: u32, rng: &mut impl Rng) -> Duration {
        let factor = (1.0 + self.spread * standard_normal(rng)).max(MIN_FACTOR);
        self.mean_time(pixels, spp).mul_f64(factor)
    }
}

pub use gridlight_actors::cpu_clock::thread_cpu_seconds;

/// Median of a non-empty slice (0 when empty).
fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

/// Box–Muller: one standard normal deviate.
fn standard_normal(rng: &mut impl Rng) -> f64 {
    let u1: f64 = rng.gen_range(f64::EPSILON..1.0);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn model(spread: f64) -> CostModel {
        CostModel { samples_per_second: 1e6, spread, spp: 4, jobs_measured: 10, time_scale: 1.0 }
    }

    #[test]
    fn the_mean_job_takes_its_samples_at_the_measured_rate() {
        assert_eq!(model(0.0).mean_job_time(4800), Duration::from_secs_f64(4800.0 * 4.0 / 1e6));
        let mut rng = rand::rngs::StdRng::seed_from_u64(1);
        assert_eq!(model(0.0).job_time(4800, 4, &mut rng), model(0.0).mean_job_time(4800));
        let eight = model(0.0).job_time(4800, 8, &mut rng);
        assert_eq!(eight, model(0.0).mean_job_time(4800) * 2, "a job's own samples per pixel");
    }

    #[test]
    fn the_time_scale_multiplies_every_time() {
        let slow = CostModel { time_scale: 20.0, ..model(0.0) };
        assert_eq!(slow.mean_job_time(100), model(0.0).mean_job_time(100).mul_f64(20.0));
    }

    #[test]
    fn sampled_times_have_the_measured_mean_and_spread() {
        let m = model(0.1);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let t: Vec<f64> =
            (0..20_000).map(|_| m.job_time(1000, 4, &mut rng).as_secs_f64()).collect();
        let mean = t.iter().sum::<f64>() / t.len() as f64;
        let sd = (t.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / t.len() as f64).sqrt();
        let expected = m.mean_job_time(1000).as_secs_f64();
        assert!((mean / expected - 1.0).abs() < 0.01, "mean {mean} vs {expected}");
        assert!((sd / mean - 0.1).abs() < 0.01, "relative spread {}", sd / mean);
    }

    #[test]
    fn a_wide_spread_never_makes_a_job_free() {
        let m = model(3.0);
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let floor = m.mean_job_time(100).mul_f64(MIN_FACTOR);
        assert!((0..1000).all(|_| m.job_time(100, 4, &mut rng) >= floor));
    }
}
