//! Parameters of the reconstruction, with the paper's values (section 5) as defaults.
//!
//! One plain value shared by the CPU reference and the GPU passes, so both run the same
//! maths with the same numbers; scene render settings and the command line override it.

use serde::{Deserialize, Serialize};

use super::svgf::{Method, SvgfParams};
use super::ReconstructError;

/// Largest fill radius accepted: the window is (2r+1)² pixels per missing pixel.
pub const MAX_RADIUS: u32 = 16;
/// Largest Gaussian kernel width accepted.
pub const MAX_GAUSS_WIDTH: u32 = 15;
/// Largest number of previous frames kept for the temporal filter (GPU texture layers).
pub const MAX_HISTORY: u32 = 4;

/// Everything that tunes reconstruction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ReconstructParams {
    /// Orientation threshold α of the discontinuity function (cosine of normals).
    pub alpha: f32,
    /// Position threshold β, in units of the scene's half-extent (see `GBuffer::scene_scale`),
    /// so that it does not depend on the model's scale. The classic Cornell box is 2 units
    /// wide, so there β = 1 is the paper's value in scene units.
    pub beta: f32,
    /// Fill radius in pixels: missing pixels take calculated neighbours within it.
    pub radius: u32,
    /// Width of the edge-aware Gaussian (odd), applied while interacting.
    pub gauss_width: u32,
    /// Standard deviation of the Gaussian in pixels.
    pub sigma: f32,
    /// Number of previous frames blended by the temporal filter; 0 is spatial-only.
    pub history: u32,
    /// Exposure in stops applied before the filmic tonemap (as `image_io`).
    pub exposure: f32,
    /// Which reconstruction runs: the paper's filter or SVGF (`reconstruct::svgf`).
    pub method: Method,
    /// The SVGF reconstruction's numbers (used when `method` is `svgf`).
    pub svgf: SvgfParams,
}

impl Default for ReconstructParams {
    fn default() -> Self {
        Self {
            alpha: 0.75,
            beta: 1.0,
            radius: 5,
            gauss_width: 7,
            sigma: 1.0,
            history: 4,
            exposure: 0.0,
            method: Method::Paper,
            svgf: SvgfParams::default(),
        }
    }
}

impl ReconstructParams {
    /// Checks every value is in range; bad values are a clear error, never clamped silently.
    pub fn validate(&self) -> Result<(), ReconstructError> {
        let bad = |name: &'static str, why: String| Err(ReconstructError::BadParam { name, why });
        if !(self.alpha.is_finite() && (-1.0..1.0).contains(&self.alpha)) {
            return bad("alpha", format!("{} is not in [-1, 1)", self.alpha));
        }
        if !(self.beta.is_finite() && self.beta > 0.0) {
            return bad("beta", format!("{} is not a positive number", self.beta));
        }
        if self.radius > MAX_RADIUS {
            return bad("radius", format!("{} is above {MAX_RADIUS}", self.radius));
        }
        if self.gauss_width.is_multiple_of(2) || self.gauss_width > MAX_GAUSS_WIDTH {
            return bad(
                "gauss_width",
                format!("{} is not odd and at most {MAX_GAUSS_WIDTH}", self.gauss_width),
            );
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return bad("sigma", format!("{} is not a positive number", self.sigma));
        }
        if self.history > MAX_HISTORY {
            return bad("history", format!("{} is above {MAX_HISTORY}", self.history));
        }
        if !(self.exposure.is_finite() && self.exposure.abs() <= 32.0) {
            return bad("exposure", format!("{} stops is not in [-32, 32]", self.exposure));
        }
        self.svgf.validate()
    }

    /// Half-width of the Gaussian window.
    pub fn gauss_radius(&self) -> i32 {
        (self.gauss_width / 2) as i32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let p = ReconstructParams::default();
        assert_eq!(
            (p.alpha, p.beta, p.radius, p.gauss_width, p.sigma, p.history),
            (0.75, 1.0, 5, 7, 1.0, 4)
        );
        p.validate().expect("defaults are valid");
    }

    #[test]
    fn bad_values_are_rejected_with_their_name() {
        let cases = [
            ReconstructParams { alpha: 1.0, ..Default::default() },
            ReconstructParams { beta: 0.0, ..Default::default() },
            ReconstructParams { radius: 40, ..Default::default() },
            ReconstructParams { gauss_width: 6, ..Default::default() },
            ReconstructParams { sigma: f32::NAN, ..Default::default() },
            ReconstructParams { history: 9, ..Default::default() },
            ReconstructParams { exposure: f32::INFINITY, ..Default::default() },
        ];
        let names = ["alpha", "beta", "radius", "gauss_width", "sigma", "history", "exposure"];
        for (params, name) in cases.iter().zip(names) {
            let err = params.validate().expect_err(name).to_string();
            assert!(err.contains(name), "{err}");
        }
    }
}
