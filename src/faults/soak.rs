//! The soak run behind `gridlight soak`: the harness under random faults of every kind
//! for a bounded number of steps, with the live workers following the paper's curve,
//! and resident-set samples at the start and end.

use std::time::{Duration, Instant};

use gridlight_actors::master::ActorKind;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::curve::live_workers;
use super::harness::{Harness, HarnessConfig, HarnessError, HarnessReport};
use super::invariants::lock;
use super::proxy::Mode;
use super::rss::rss_kb;

/// Time between two fault decisions.
pub const STEP: Duration = Duration::from_millis(500);
/// Frames the grid must show before the first fault (and before RSS is first read).
const WARM_UP_FRAMES: u64 = 20;
/// Steps a link fault or a freeze lasts.
const FAULT_STEPS: u64 = 3;

/// What the soak reports (one JSON object).
#[derive(Debug, serde::Serialize)]
pub struct SoakReport {
    pub seed: u64,
    pub minutes: f64,
    pub workers: usize,
    pub steps: u64,
    pub rss_start_kb: u64,
    pub rss_end_kb: u64,
    #[serde(flatten)]
    pub run: HarnessReport,
}

/// Runs the soak for `minutes` with `workers` workers at the curve's mean.
pub fn run(config: HarnessConfig, minutes: f64, seed: u64) -> Result<SoakReport, HarnessError> {
    let n = config.workers.max(1);
    let steps = ((minutes * 60.0) / STEP.as_secs_f64()).ceil().max(1.0) as u64;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut h = Harness::start(config)?;
    if !h.wait_frames(WARM_UP_FRAMES, Duration::from_secs(60)) {
        lock(h.checker()).violate("no frames during the warm-up".into());
    }
    let rss_start_kb = rss_kb(None).unwrap_or(0);
    let mut undo_at: Option<u64> = None;
    for i in 0..steps {
        let began = Instant::now();
        if undo_at == Some(i) {
            h.link_fault(Mode::Pass);
            h.thaw_all();
            undo_at = None;
        }
        if undo_at.is_none() {
            h.set_live(live_workers(n, i))?;
            if inject(&mut h, &mut rng, n)? {
                undo_at = Some(i + FAULT_STEPS);
            }
        }
        h.tick();
        std::thread::sleep(STEP.saturating_sub(began.elapsed()));
    }
    h.link_fault(Mode::Pass);
    h.thaw_all();
    let rss_end_kb = rss_kb(None).unwrap_or(0);
    // Memory must not grow: allow noise (allocator, a restarted master's buffers).
    let slack = (rss_start_kb / 2).max(32 * 1024);
    if rss_end_kb > rss_start_kb + slack {
        lock(h.checker()).violate(format!("RSS grew from {rss_start_kb} kB to {rss_end_kb} kB"));
    }
    let run = h.finish();
    Ok(SoakReport { seed, minutes, workers: n, steps, rss_start_kb, rss_end_kb, run })
}

/// Injects one random fault; true when it lasts and must be undone later.
fn inject(h: &mut Harness, rng: &mut StdRng, n: usize) -> Result<bool, HarnessError> {
    // Roughly one step in three is quiet, so the grid shows frames between faults.
    match rng.gen_range(0..24) {
        0 | 1 => {
            let i = rng.gen_range(0..n.max(1));
            h.kill_worker(i);
        }
        2 => return Ok(h.freeze_worker(rng.gen_range(0..n.max(1)))),
        3 => {
            h.spawn_worker()?;
        }
        4 => h.panic_actor(ActorKind::Scheduler),
        5 => h.panic_actor(ActorKind::Assembler),
        6 => h.panic_actor(ActorKind::Display),
        7 => h.panic_actor(ActorKind::SceneHolder),
        8 => {
            h.fault_connection(rng.gen_range(0..64), false);
        }
        9 => {
            h.fault_connection(rng.gen_range(0..64), true);
        }
        10 => {
            let ms = rng.gen_range(10..300);
            h.link_fault(Mode::Delay(Duration::from_millis(ms)));
            return Ok(true);
        }
        11..=15 => {
            let mode = [Mode::Drop, Mode::Truncate, Mode::Corrupt, Mode::Stall, Mode::Cut]
                [rng.gen_range(0..5)];
            h.link_fault(mode);
            return Ok(true);
        }
        16 => h.restart_master()?,
        _ => {}
    }
    Ok(false)
}
