//! How many of a simulated grid's `N` workers are available at frame `i` (paper, §6.1).
//!
//! The paper varies its resources per frame as `R_i = N − (N/4)·sin(2πi/100)`; the other
//! curves are for trying the method against sharper changes. A grid of `N` workers opens
//! [`Availability::peak`] connections and withdraws those above `R_i`.

use std::f64::consts::PI;

/// The shape of the availability over frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Curve {
    /// Always `N`.
    Constant,
    /// The paper's `N − (N/4)·sin(2πi/period)`.
    Sine,
    /// `N` for half a period, `N/2` for the other half (a sharp loss and return).
    Square,
}

/// A curve over a grid of `n` workers with a period in frames.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Availability {
    pub curve: Curve,
    pub n: u32,
    pub period: u32,
}

/// The paper's period, in frames.
pub const PAPER_PERIOD: u32 = 100;

impl Availability {
    /// Workers available at frame `i`.
    pub fn at(&self, i: u64) -> u32 {
        let n = f64::from(self.n);
        let phase = (i % u64::from(self.period.max(1))) as f64 / f64::from(self.period.max(1));
        let r = match self.curve {
            Curve::Constant => n,
            Curve::Sine => n - n / 4.0 * (2.0 * PI * phase).sin(),
            Curve::Square if phase < 0.5 => n,
            Curve::Square => (n / 2.0).ceil(),
        };
        r.round() as u32
    }

    /// The most workers ever available: the connections a simulated grid opens.
    pub fn peak(&self) -> u32 {
        match self.curve {
            Curve::Sine => (f64::from(self.n) * 1.25).ceil() as u32,
            Curve::Constant | Curve::Square => self.n,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sine(n: u32) -> Availability {
        Availability { curve: Curve::Sine, n, period: PAPER_PERIOD }
    }

    #[test]
    fn the_papers_curve_for_96_workers_swings_between_72_and_120() {
        let a = sine(96);
        assert_eq!(a.at(0), 96);
        assert_eq!(a.at(25), 72, "a quarter period in, sin = 1");
        assert_eq!(a.at(50), 96);
        assert_eq!(a.at(75), 120, "three quarters in, sin = -1");
        assert_eq!(a.at(125), 72, "periodic");
        assert_eq!(a.peak(), 120);
        assert!((0..200).all(|i| a.at(i) <= a.peak()));
    }

    #[test]
    fn square_halves_the_grid_for_half_a_period() {
        let a = Availability { curve: Curve::Square, n: 32, period: 10 };
        assert_eq!(
            (0..10).map(|i| a.at(i)).collect::<Vec<_>>(),
            [32, 32, 32, 32, 32, 16, 16, 16, 16, 16]
        );
        assert_eq!(a.peak(), 32);
    }

    #[test]
    fn constant_is_constant() {
        let a = Availability { curve: Curve::Constant, n: 8, period: 100 };
        assert!((0..300).all(|i| a.at(i) == 8));
    }
}
