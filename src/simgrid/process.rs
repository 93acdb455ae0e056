//! One process of a simulated grid: many simulated workers as tokio tasks, each its own
//! TCP connection and the real worker link (`worker::link`), so the master pays for
//! every one of them what it pays for a real worker.
//!
//! Worker `g` of the grid (numbered across all its processes) takes jobs while
//! `g < R_i`, `i` being the newest frame this process was given a job of (or, at a fixed
//! frame rate, the frame due at this time since the process started); otherwise it is
//! paused (`Paused { Withdrawn }` on the wire), as a desk whose owner came back: the jobs
//! it held are lost, never recomputed.

use std::sync::Arc;
use std::time::Duration;

use gridlight_actors::protocol::PauseReason;
use tokio::sync::watch;
use tokio_util::sync::CancellationToken;
use tracing::info;

use super::availability::Availability;
use super::renderer::SimGrid;
use crate::worker::idle::Activity;
use crate::worker::link::LinkConfig;
use crate::worker::shared::Shared;
use crate::worker::{cache::AssetCache, connection_loop, Priority, RendererKind, WorkerError};

/// How often the availability is brought up to date with the newest frame.
const FOLLOW_INTERVAL: Duration = Duration::from_millis(5);

/// What one process of the grid runs.
#[derive(Clone, Debug)]
pub struct ProcessOptions {
    /// The master's `HOST:PORT`.
    pub master: String,
    /// The whole grid's availability.
    pub availability: Availability,
    /// This process's workers: `first..first + count` of the grid's peak.
    pub first: u32,
    pub count: u32,
    /// Jobs each worker holds (k).
    pub pipeline: u32,
    /// With a fixed frame rate, frame `i` is the one due `i / fps` seconds after start;
    /// `None`: the newest frame a job named.
    pub frame_rate: Option<f32>,
}

/// Runs this process's workers until `cancel` fires or one fails fatally.
pub async fn run_until(
    opts: ProcessOptions,
    grid: Arc<SimGrid>,
    cancel: CancellationToken,
) -> Result<(), WorkerError> {
    let shared = Arc::new(Shared::new(AssetCache::in_memory()));
    info!(master = %opts.master, first = opts.first, count = opts.count, "simulated workers starting");
    let mut switches = Vec::new();
    let mut tasks = tokio::task::JoinSet::new();
    for g in opts.first..opts.first + opts.count {
        let (tx, rx) = watch::channel(wanted(g, opts.availability.at(0)));
        switches.push((g, tx));
        let link = LinkConfig {
            name: format!("sim#{g}"),
            secret: None,
            pipeline: opts.pipeline,
            renderer: RendererKind::Simulated(Arc::clone(&grid)),
            priority: Priority::Normal,
        };
        tasks.spawn(connection_loop(
            opts.master.clone(),
            link,
            Arc::clone(&shared),
            cancel.clone(),
            rx,
        ));
    }
    let follow = tokio::spawn(follow_availability(
        opts.availability,
        opts.frame_rate,
        grid,
        switches,
        cancel.clone(),
    ));
    let mut outcome = Ok(());
    while let Some(done) = tasks.join_next().await {
        let result = done.unwrap_or_else(|e| Err(WorkerError::Connection(format!("task: {e}"))));
        if let Err(err) = result {
            cancel.cancel();
            if outcome.is_ok() {
                outcome = Err(err);
            }
        }
    }
    follow.abort();
    outcome
}

/// Whether worker `g` works when `available` workers are.
fn wanted(g: u32, available: u32) -> Activity {
    if g < available {
        Activity::Working
    } else {
        Activity::Paused(PauseReason::Withdrawn)
    }
}

/// Pauses and resumes workers as the newest frame moves along the curve.
async fn follow_availability(
    availability: Availability,
    frame_rate: Option<f32>,
    grid: Arc<SimGrid>,
    switches: Vec<(u32, watch::Sender<Activity>)>,
    cancel: CancellationToken,
) {
    let started = tokio::time::Instant::now();
    let mut tick = tokio::time::interval(FOLLOW_INTERVAL);
    while !cancel.is_cancelled() {
        tick.tick().await;
        let frame = match frame_rate {
            Some(fps) => (started.elapsed().as_secs_f64() * f64::from(fps)) as u64,
            None => grid.newest_frame(),
        };
        let available = availability.at(frame);
        for (g, tx) in &switches {
            let want = wanted(*g, available);
            tx.send_if_modified(|now| {
                let change = *now != want;
                if change {
                    *now = want.clone();
                }
                change
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simgrid::availability::{Curve, PAPER_PERIOD};

    #[test]
    fn workers_above_the_curve_are_withdrawn() {
        let a = Availability { curve: Curve::Sine, n: 8, period: PAPER_PERIOD };
        let at_trough = a.at(25);
        assert_eq!(at_trough, 6);
        assert_eq!(wanted(5, at_trough), Activity::Working);
        assert_eq!(wanted(6, at_trough), Activity::Paused(PauseReason::Withdrawn));
    }
}
