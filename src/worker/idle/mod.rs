//! `--when-idle`: the worker stops taking jobs while its desk's owner is active and
//! takes them again once the machine has been idle for a while (docs/design.md, decision 9).
//!
//! A monitor thread samples the machine every `sample_every` ([`cpu`]: CPU times from
//! `/proc`; [`input`]: keyboard/mouse idle time where the platform tells), feeds the
//! samples to the pure [`decide::Decider`] and publishes each change of [`Activity`] on
//! a watch channel; every connection of the worker follows it (`link`): it tells the
//! master `Paused` with the reason, drops the jobs it holds (the master never recomputes
//! them) and sends `Resumed` and fresh credits when the decision turns. The monitor runs
//! at normal priority (it wakes once per sample and reads two small files), so that a
//! pause is noticed at once even when the owner keeps every CPU busy and the render
//! threads, at `SCHED_IDLE`, get nothing.

pub mod cpu;
pub mod decide;
pub mod input;

use std::time::{Duration, Instant};

use tokio::sync::watch;
use tokio_util::sync::CancellationToken;
use tracing::{info, warn};

pub use decide::{Activity, Decider, IdlePolicy, Sample};
pub use input::{InputIdle, InputSource};

/// Why the machine could not be sampled.
#[derive(Debug, thiserror::Error)]
pub enum IdleError {
    #[error("reading {0}")]
    Read(String),
    #[error("parsing {0}")]
    Parse(String),
}

/// Starts the monitor thread; the receiver always holds the latest decision. The thread
/// ends when `cancel` fires or every receiver is gone.
pub fn spawn_monitor(
    policy: IdlePolicy,
    mut input: Box<dyn InputSource>,
    cancel: CancellationToken,
) -> std::io::Result<watch::Receiver<Activity>> {
    let (tx, rx) = watch::channel(Activity::Working);
    let first_input = input.idle();
    let cpu_ok =
        cpu::read().map_err(|e| warn!(cause = %e, "no CPU times: the CPU criterion is off"));
    info!(
        cpu_percent = policy.cpu_percent,
        cpu_window_s = policy.cpu_window.as_secs_f32(),
        input_idle_s = policy.input_idle.as_secs_f32(),
        resume_after_s = policy.resume_after.as_secs_f32(),
        input = if first_input == InputIdle::Unknown {
            "unknown here (the CPU decides alone)"
        } else {
            "known"
        },
        cpu = if cpu_ok.is_ok() { "known" } else { "unknown" },
        "when idle: pausing while the desk's owner is active"
    );
    std::thread::Builder::new().name("owner-monitor".into()).spawn(move || {
        let started = Instant::now();
        let mut decider = Decider::new(policy);
        while !cancel.is_cancelled() && !tx.is_closed() {
            let sample =
                Sample { at: started.elapsed(), cpu: cpu::read().ok(), input: input.idle() };
            let now = decider.observe(sample).clone();
            // Published when it pauses, resumes or pauses for another kind of reason; the
            // reason's figures change every sample and need not travel each time.
            let changed = match (&*tx.borrow(), &now) {
                (Activity::Working, Activity::Working) => false,
                (Activity::Paused(a), Activity::Paused(b)) => a.kind() != b.kind(),
                _ => true,
            };
            if changed {
                match &now {
                    Activity::Paused(reason) => info!(%reason, "owner active: pausing"),
                    Activity::Working => info!("owner idle: resuming"),
                }
                let _ = tx.send(now);
            }
            sleep_unless_cancelled(policy.sample_every, &cancel);
        }
    })?;
    Ok(rx)
}

fn sleep_unless_cancelled(d: Duration, cancel: &CancellationToken) {
    let step = Duration::from_millis(100);
    let end = Instant::now() + d;
    while !cancel.is_cancelled() {
        let left = end.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        std::thread::sleep(left.min(step));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Input whose idle time the test sets.
    struct Scripted(std::sync::Arc<std::sync::Mutex<InputIdle>>);

    impl InputSource for Scripted {
        fn name(&self) -> &'static str {
            "scripted"
        }
        fn idle(&mut self) -> InputIdle {
            *self.0.lock().unwrap()
        }
    }

    #[test]
    fn the_monitor_publishes_a_pause_and_the_resume() {
        let input = std::sync::Arc::new(std::sync::Mutex::new(InputIdle::Unknown));
        let policy = IdlePolicy {
            // Only input decides: no CPU share can exceed 100 %.
            cpu_percent: 100.0,
            cpu_window: Duration::from_millis(200),
            input_idle: Duration::from_secs(60),
            resume_after: Duration::from_millis(200),
            sample_every: Duration::from_millis(20),
        };
        let cancel = CancellationToken::new();
        let mut rx =
            spawn_monitor(policy, Box::new(Scripted(input.clone())), cancel.clone()).unwrap();
        let wait_for = |rx: &mut watch::Receiver<Activity>, paused: bool| {
            let deadline = Instant::now() + Duration::from_secs(20);
            while matches!(*rx.borrow_and_update(), Activity::Paused(_)) != paused {
                assert!(Instant::now() < deadline, "no change to paused = {paused}");
                std::thread::sleep(Duration::from_millis(10));
            }
        };
        *input.lock().unwrap() = InputIdle::Known(Duration::from_secs(2));
        wait_for(&mut rx, true);
        assert!(matches!(&*rx.borrow(), Activity::Paused(r) if r.kind() == "owner_input"));
        *input.lock().unwrap() = InputIdle::Known(Duration::from_secs(120));
        wait_for(&mut rx, false);
        cancel.cancel();
    }
}
