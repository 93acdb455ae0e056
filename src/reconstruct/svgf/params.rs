//! Which reconstruction runs (`--reconstruction paper|svgf`) and the SVGF filter's numbers.

use serde::{Deserialize, Serialize};

use crate::reconstruct::ReconstructError;

/// The reconstruction method.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// The paper's filter (§4.3.1): fill, temporal blend of the last frames without motion
    /// compensation, edge-aware Gaussian; accumulation restarts at every scene change.
    #[default]
    Paper,
    /// Reprojected history with sample counts and moments, and variance-guided à-trous
    /// filtering (`reconstruct::svgf`).
    Svgf,
}

impl Method {
    /// Every method, in the order the panel lists them.
    pub const ALL: [Method; 2] = [Method::Paper, Method::Svgf];

    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::Svgf => "svgf",
        }
    }
}

/// Numbers of the SVGF-class reconstruction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SvgfParams {
    /// À-trous iterations (steps 1, 2, 4, …); 0 leaves the filled accumulation unfiltered.
    pub iterations: u32,
    /// Samples a pixel's reprojected history may count for after the camera or an object
    /// moved: view-dependent shading drifts, so old samples are worth less than new ones.
    pub motion_samples: f32,
    /// The same after a material, light or environment edit (the lighting changed).
    pub edit_samples: f32,
    /// Luminance edge-stopping: neighbours within this many standard deviations of the
    /// pixel's estimate blend.
    pub sigma_luminance: f32,
    /// Normal edge-stopping exponent (a power of two): weight (n_i·n_j)^k.
    pub normal_power: u32,
    /// Plane edge-stopping: the tangent of the largest angle between a neighbour's offset
    /// and the pixel's tangent plane that still blends.
    pub sigma_plane: f32,
}

impl Default for SvgfParams {
    fn default() -> Self {
        Self {
            iterations: 5,
            motion_samples: 32.0,
            edit_samples: 4.0,
            sigma_luminance: 4.0,
            normal_power: 64,
            sigma_plane: 0.1,
        }
    }
}

/// Most à-trous iterations: the last step is 2^(n−1) pixels, which the planes' border covers.
pub const MAX_ITERATIONS: u32 = 6;

impl SvgfParams {
    pub fn validate(&self) -> Result<(), ReconstructError> {
        let bad = |name: &'static str, why: String| Err(ReconstructError::BadParam { name, why });
        if self.iterations > MAX_ITERATIONS {
            return bad(
                "svgf.iterations",
                format!("{} is above {MAX_ITERATIONS}", self.iterations),
            );
        }
        for (name, v) in
            [("svgf.motion_samples", self.motion_samples), ("svgf.edit_samples", self.edit_samples)]
        {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, format!("{v} is not a number of samples >= 0"));
            }
        }
        for (name, v) in
            [("svgf.sigma_luminance", self.sigma_luminance), ("svgf.sigma_plane", self.sigma_plane)]
        {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, format!("{v} is not a positive number"));
            }
        }
        if !(self.normal_power.is_power_of_two() && self.normal_power <= 1024) {
            return bad(
                "svgf.normal_power",
                format!("{} is not a power of two up to 1024", self.normal_power),
            );
        }
        Ok(())
    }

    /// The widest tap offset of the filter, in pixels: the planes' border.
    pub fn reach(&self) -> usize {
        match self.iterations {
            0 => variance_reach(),
            n => (1usize << (n - 1)).max(variance_reach()),
        }
    }
}

/// Radius of the spatial variance estimate.
pub const fn variance_reach() -> usize {
    2
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
