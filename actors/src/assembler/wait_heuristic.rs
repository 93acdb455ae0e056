//! When to show a frame (paper §4.3): pure logic behind the frame assembler actor ([`pacer`](super::pacer) keeps its clock).
//!
//! Q_t = jobs back / jobs of the frame; I_t = time on this frame / time of the last
//! shown frame. The display waits while `(Q < Q_max ∧ I < I_min) ∨ (Q < Q_min ∧ I < I_max)`;
//! when `I_max` passes with `Q < Q_min` the frame is skipped. A fixed-frame-rate mode
//! replaces the heuristic with a fixed wait. Every frame is shown at once when all its
//! jobs are back under the heuristic (nothing more can come).

use std::time::Duration;

use crate::shared::pacing::Pacing;

/// What the frame assembler does with the oldest frame now.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Decision {
    /// Keep waiting; decide again when a result arrives or, at the latest, when the
    /// frame has been waited on for `recheck_at` in total.
    Wait {
        recheck_at: Duration,
    },
    Show,
    Skip,
}

/// Decides for a frame with `back` of `total` jobs in, `elapsed` after it started,
/// when the last shown frame took `last_frame`.
pub fn decide(
    pacing: &Pacing,
    back: u32,
    total: u32,
    elapsed: Duration,
    last_frame: Duration,
) -> Decision {
    match *pacing {
        Pacing::FixedFps(fps) => {
            let period = Duration::from_secs_f64(1.0 / f64::from(fps));
            if elapsed >= period {
                Decision::Show
            } else {
                Decision::Wait { recheck_at: period }
            }
        }
        Pacing::Heuristic(h) => {
            if total > 0 && back >= total {
                return Decision::Show;
            }
            let q = quality(back, total);
            let i = interaction(elapsed, last_frame);
            let wait_min = q < h.q_max && i < h.i_min;
            let wait_max = q < h.q_min && i < h.i_max;
            if wait_min || wait_max {
                let until = if i < h.i_min && q < h.q_max { h.i_min } else { h.i_max };
                Decision::Wait { recheck_at: last_frame.mul_f64(until) }
            } else if q < h.q_min {
                Decision::Skip
            } else {
                Decision::Show
            }
        }
    }
}

/// Q_t.
pub fn quality(back: u32, total: u32) -> f64 {
    if total == 0 {
        0.0
    } else {
        f64::from(back) / f64::from(total)
    }
}

/// I_t; the last frame's time is floored at a millisecond so I stays finite.
pub fn interaction(elapsed: Duration, last_frame: Duration) -> f64 {
    elapsed.as_secs_f64() / last_frame.max(Duration::from_millis(1)).as_secs_f64()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shared::pacing::Heuristic;

    const H: Pacing =
        Pacing::Heuristic(Heuristic { q_min: 0.2, q_max: 0.5, i_min: 2.0, i_max: 4.0 });
    const LAST: Duration = Duration::from_millis(100);

    fn at(back: u32, ms: u64) -> Decision {
        decide(&H, back, 10, Duration::from_millis(ms), LAST)
    }

    #[test]
    fn waits_below_q_max_until_i_min() {
        assert_eq!(at(3, 50), Decision::Wait { recheck_at: Duration::from_millis(200) });
        assert_eq!(at(3, 200), Decision::Show, "Q_min <= Q < Q_max shows once I_min passes");
    }

    #[test]
    fn shows_early_at_q_max() {
        assert_eq!(at(5, 1), Decision::Show);
        assert_eq!(at(10, 0), Decision::Show);
    }

    #[test]
    fn waits_below_q_min_until_i_max_then_skips() {
        assert_eq!(at(1, 250), Decision::Wait { recheck_at: Duration::from_millis(400) });
        assert_eq!(at(1, 399), Decision::Wait { recheck_at: Duration::from_millis(400) });
        assert_eq!(at(1, 400), Decision::Skip);
        assert_eq!(at(0, 1000), Decision::Skip);
        assert_eq!(at(2, 400), Decision::Show, "Q = Q_min is enough");
    }

    #[test]
    fn fixed_rate_waits_its_period_whatever_came_back() {
        let p = Pacing::FixedFps(20.0);
        assert_eq!(
            decide(&p, 10, 10, Duration::from_millis(10), LAST),
            Decision::Wait { recheck_at: Duration::from_millis(50) }
        );
        assert_eq!(decide(&p, 0, 10, Duration::from_millis(50), LAST), Decision::Show);
    }
}
