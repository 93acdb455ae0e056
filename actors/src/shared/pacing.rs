//! How frames are paced: the wait heuristic's parameters (paper §4.3) or a fixed rate. The
//! assembler decides by it; the scheduler's hand-out plan forecasts deadlines from it.

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Parameters of the wait heuristic.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Heuristic {
    pub q_min: f64,
    pub q_max: f64,
    pub i_min: f64,
    pub i_max: f64,
}

impl Default for Heuristic {
    /// The paper's values (§5): Q_min 20 %, Q_max 50 %, I_min 2, I_max 4.
    fn default() -> Self {
        Self { q_min: 0.2, q_max: 0.5, i_min: 2.0, i_max: 4.0 }
    }
}

/// How the frame assembler paces frames.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Pacing {
    Heuristic(Heuristic),
    /// Show a frame every `1/fps` seconds, whatever came back.
    FixedFps(f32),
}

impl Default for Pacing {
    fn default() -> Self {
        Pacing::Heuristic(Heuristic::default())
    }
}

impl Pacing {
    /// Checks the parameters; the error says what is wrong.
    pub fn validate(&self) -> Result<(), PacingError> {
        match *self {
            Pacing::Heuristic(h) => {
                let ok = (0.0..=1.0).contains(&h.q_min)
                    && (0.0..=1.0).contains(&h.q_max)
                    && h.q_min <= h.q_max
                    && h.i_min > 0.0
                    && h.i_min <= h.i_max
                    && h.i_max.is_finite();
                if ok {
                    Ok(())
                } else {
                    Err(PacingError::Heuristic(h))
                }
            }
            Pacing::FixedFps(fps) if fps.is_finite() && fps > 0.0 => Ok(()),
            Pacing::FixedFps(fps) => Err(PacingError::FrameRate(fps)),
        }
    }
}

/// A pacing whose parameters make no sense.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
pub enum PacingError {
    #[error(
        "wait heuristic needs 0 <= q_min <= q_max <= 1 and 0 < i_min <= i_max < inf, got {0:?}"
    )]
    Heuristic(Heuristic),
    #[error("frame rate must be positive and finite, got {0}")]
    FrameRate(f32),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation_names_bad_parameters() {
        assert!(Pacing::default().validate().is_ok());
        let h = Heuristic { q_min: 0.6, ..Heuristic::default() };
        let err = Pacing::Heuristic(h).validate().unwrap_err();
        assert_eq!(err, PacingError::Heuristic(h));
        assert!(err.to_string().contains("q_min"));
        assert_eq!(Pacing::FixedFps(0.0).validate(), Err(PacingError::FrameRate(0.0)));
        assert!(Pacing::FixedFps(f32::NAN).validate().is_err());
    }
}
