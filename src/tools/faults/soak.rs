//! The soak run behind `gridlight soak`: the harness under random faults of every kind
//! for a bounded time, with the live workers following the paper's curve, and the
//! resident set compared between the end of a warm-up and the end of the run.
//!
//! # Phases
//! 1. **Warm-up**: the grid shows its first frames, then every fault kind is injected
//!    once ([`Fault::every_kind`]) and the grid shows frames again. This is not about
//!    finding faults (the invariants are checked throughout); it makes every lazy
//!    one-off allocation happen before memory is measured: the panic machinery
//!    (symbolising a backtrace maps debug info, hundreds of MB, once), a restarted
//!    master's threads and buffers, the proxy's tasks, the allocator's per-thread arenas.
//! 2. **Steady part**: `minutes` of random faults, one decision per [`STEP`].
//!
//! `rss_boot_kb` is read once the harness is up (master, proxy, first workers started),
//! `rss_start_kb` at the end of the warm-up, `rss_end_kb` at the end of the steady part
//! with every lasting fault undone. Only the steady part's growth is bounded: a leak per
//! fault or per frame shows there, one-off costs do not.

use std::time::{Duration, Instant};

use gridlight_actors::master::ActorKind;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::curve::live_workers;
use super::harness::{Fault, Harness, HarnessConfig, HarnessError, HarnessReport};
use super::invariants::lock;
use super::proxy::LinkMode;
use super::rss::rss_kb;

/// Time between two fault decisions.
pub const STEP: Duration = Duration::from_millis(500);
/// Frames the grid must show before the warm-up faults, and again after them.
const WARM_UP_FRAMES: u64 = 20;
/// Longest wait for those frames (a loaded machine, workers reconnecting).
const WARM_UP_TIMEOUT: Duration = Duration::from_secs(60);
/// Steps a link fault or a freeze lasts.
const FAULT_STEPS: u64 = 3;
/// Growth of the resident set over the steady part that counts as a leak: allocator
/// noise and a restarted master's buffers stay well below it.
const RSS_SLACK_KB: u64 = 32 * 1024;

/// What the soak reports (one JSON object).
#[derive(Debug, serde::Serialize)]
pub struct SoakReport {
    pub seed: u64,
    /// Length of the steady part; the warm-up comes on top.
    pub minutes: f64,
    pub workers: usize,
    pub steps: u64,
    /// Resident set once the harness is up, before the warm-up.
    pub rss_boot_kb: u64,
    /// Resident set after the warm-up (first frames and one fault of every kind).
    pub rss_start_kb: u64,
    /// Resident set at the end of the steady part.
    pub rss_end_kb: u64,
    #[serde(flatten)]
    pub run: HarnessReport,
}

/// Runs the warm-up, then `minutes` of random faults with `workers` workers at the
/// curve's mean.
pub fn run(config: HarnessConfig, minutes: f64, seed: u64) -> Result<SoakReport, HarnessError> {
    let n = config.workers.max(1);
    let steps = ((minutes * 60.0) / STEP.as_secs_f64()).ceil().max(1.0) as u64;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut h = Harness::start(config)?;
    let rss_boot_kb = rss_kb(None).unwrap_or(0);
    warm_up(&mut h)?;
    let rss_start_kb = rss_kb(None).unwrap_or(0);
    let mut undo_at: Option<u64> = None;
    for i in 0..steps {
        let began = Instant::now();
        if undo_at == Some(i) {
            h.undo();
            undo_at = None;
        }
        if undo_at.is_none() {
            h.set_live(live_workers(n, i))?;
            if let Some(fault) = random_fault(&mut rng, n) {
                if h.inject(fault)? {
                    undo_at = Some(i + FAULT_STEPS);
                }
            }
        }
        h.tick();
        std::thread::sleep(STEP.saturating_sub(began.elapsed()));
    }
    h.undo();
    let rss_end_kb = rss_kb(None).unwrap_or(0);
    if rss_end_kb > rss_start_kb + RSS_SLACK_KB {
        lock(h.checker()).violate(format!(
            "RSS grew from {rss_start_kb} kB after the warm-up to {rss_end_kb} kB (allowed {RSS_SLACK_KB} kB)"
        ));
    }
    let run = h.finish();
    Ok(SoakReport { seed, minutes, workers: n, steps, rss_boot_kb, rss_start_kb, rss_end_kb, run })
}

/// First frames, one fault of every kind (each undone after [`FAULT_STEPS`]), frames again.
pub fn warm_up(h: &mut Harness) -> Result<(), HarnessError> {
    if !h.wait_frames(WARM_UP_FRAMES, WARM_UP_TIMEOUT) {
        lock(h.checker()).violate("no frames during the warm-up".into());
    }
    for fault in Fault::every_kind() {
        let lasts = h.inject(fault)?;
        let until = Instant::now() + STEP * FAULT_STEPS as u32;
        while Instant::now() < until {
            h.tick();
            std::thread::sleep(STEP / 10);
        }
        if lasts {
            h.undo();
        }
    }
    if !h.wait_frames(WARM_UP_FRAMES, WARM_UP_TIMEOUT) {
        lock(h.checker()).violate(format!(
            "fewer than {WARM_UP_FRAMES} frames within {} s after the warm-up faults",
            WARM_UP_TIMEOUT.as_secs()
        ));
    }
    Ok(())
}

/// A random fault, or `None` for a quiet step (about one in three, so the grid shows
/// frames between faults).
fn random_fault(rng: &mut StdRng, n: usize) -> Option<Fault> {
    let worker = rng.gen_range(0..n.max(1));
    Some(match rng.gen_range(0..24) {
        0 | 1 => Fault::KillWorker(worker),
        2 => Fault::FreezeWorker(worker),
        3 => Fault::SpawnWorker,
        4 => Fault::PanicActor(ActorKind::Scheduler),
        5 => Fault::PanicActor(ActorKind::Assembler),
        6 => Fault::PanicActor(ActorKind::Presenter),
        7 => Fault::PanicActor(ActorKind::SceneHolder),
        8 => Fault::KillConnection(rng.gen_range(0..64)),
        9 => Fault::PanicConnection(rng.gen_range(0..64)),
        10 => Fault::Link(LinkMode::Delay(Duration::from_millis(rng.gen_range(10..300)))),
        11..=15 => Fault::Link(
            [LinkMode::Drop, LinkMode::Truncate, LinkMode::Corrupt, LinkMode::Stall, LinkMode::Cut]
                [rng.gen_range(0..5)],
        ),
        16 => Fault::RestartMaster,
        _ => return None,
    })
}
