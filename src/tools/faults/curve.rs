//! The paper's resource curve R_i = N − (N/4)·sin(2πi/100): how many workers are live
//! at step `i` when a run varies the grid's resources (section 5), scaled to this
//! machine by the choice of N.

/// Steps of one full period of the curve.
pub const PERIOD: u64 = 100;

/// R_i rounded to a whole number of workers, at least 1 (a grid is never empty here:
/// the invariants are about a master with at least one live worker).
pub fn live_workers(n: usize, i: u64) -> usize {
    let phase = 2.0 * std::f64::consts::PI * (i % PERIOD) as f64 / PERIOD as f64;
    let r = n as f64 - (n as f64 / 4.0) * phase.sin();
    (r.round() as usize).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn follows_the_papers_curve() {
        assert_eq!(live_workers(8, 0), 8);
        assert_eq!(live_workers(8, 25), 6); // N − N/4 at the trough
        assert_eq!(live_workers(8, 75), 10); // N + N/4 at the crest
        assert_eq!(live_workers(8, 100), 8);
        assert_eq!(live_workers(1, 25), 1);
        let all: Vec<usize> = (0..PERIOD).map(|i| live_workers(4, i)).collect();
        assert_eq!(all.iter().min(), Some(&3));
        assert_eq!(all.iter().max(), Some(&5));
    }
}
