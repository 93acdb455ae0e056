//! The views of a frame: the final (reconstructed) image and the diagnostic ones (partial
//! frame, missing-pixel mask, normals, albedo), shared by the window and headless output.
//!
//! The final view is the reconstructor's tonemapped output; the others are made here from
//! plain per-pixel slices, so they are unit-tested without a GPU or a master.

use glam::Vec3;

/// Which image of a frame is shown (window) or written (headless `--view`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum View {
    /// The reconstructed frame (the normal view).
    #[default]
    Final,
    /// This frame's results only, remodulated, with holes (missing pixels) left black.
    Partial,
    /// White where this frame has a result, black where reconstruction must fill.
    Mask,
    /// Primary-hit normals mapped from [-1, 1] to colours.
    Normals,
    /// Primary-hit albedo.
    Albedo,
}

impl View {
    /// Every view, in the order the panel lists them.
    pub const ALL: [View; 5] =
        [View::Final, View::Partial, View::Mask, View::Normals, View::Albedo];

    /// The panel's label.
    pub fn label(self) -> &'static str {
        match self {
            View::Final => "final",
            View::Partial => "partial",
            View::Mask => "mask",
            View::Normals => "normals",
            View::Albedo => "albedo",
        }
    }
}

/// Per-pixel planes the diagnostic views read; every slice has one entry per pixel.
#[derive(Clone, Copy, Debug)]
pub struct ViewInputs<'a> {
    pub width: u32,
    pub height: u32,
    /// This frame's demodulated radiance (meaningful where `mask` is set).
    pub radiance: &'a [Vec3],
    pub mask: &'a [bool],
    pub albedo: &'a [Vec3],
    pub emission: &'a [Vec3],
    pub normal: &'a [Vec3],
}

/// Builds the pixels of a diagnostic view; `tonemap` turns linear colour into display
/// RGBA (the reconstructor's, so partial and final match). `View::Final` is not made here
/// (it is the reconstructor's output) and gives `None`, as do inconsistent slice lengths.
pub fn diagnostic(
    view: View,
    inputs: &ViewInputs,
    tonemap: impl Fn(Vec3) -> [u8; 4],
) -> Option<Vec<[u8; 4]>> {
    let n = inputs.width as usize * inputs.height as usize;
    let planes =
        [inputs.radiance.len(), inputs.albedo.len(), inputs.emission.len(), inputs.normal.len()];
    if inputs.mask.len() != n || planes.iter().any(|&len| len != n) {
        return None;
    }
    let pixel = |i: usize| -> [u8; 4] {
        match view {
            View::Final => [0, 0, 0, 255],
            View::Partial if inputs.mask[i] => {
                tonemap(inputs.albedo[i] * inputs.radiance[i] + inputs.emission[i])
            }
            View::Partial => [0, 0, 0, 255],
            View::Mask => {
                let v = if inputs.mask[i] { 255 } else { 0 };
                [v, v, v, 255]
            }
            View::Normals => {
                // Escaping rays have a zero normal and show as mid grey.
                let c = (inputs.normal[i] * 0.5 + Vec3::splat(0.5)).clamp(Vec3::ZERO, Vec3::ONE);
                [unorm(c.x), unorm(c.y), unorm(c.z), 255]
            }
            View::Albedo => {
                let c = inputs.albedo[i].clamp(Vec3::ZERO, Vec3::ONE);
                [unorm(srgb(c.x)), unorm(srgb(c.y)), unorm(srgb(c.z)), 255]
            }
        }
    };
    if view == View::Final {
        return None;
    }
    Some((0..n).map(pixel).collect())
}

/// [0, 1] to 0..=255, rounded.
fn unorm(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Linear to sRGB transfer function.
fn srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Planes {
        radiance: Vec<Vec3>,
        mask: Vec<bool>,
        albedo: Vec<Vec3>,
        emission: Vec<Vec3>,
        normal: Vec<Vec3>,
    }

    /// Two pixels: the first has a result, the second is a hole.
    fn planes() -> Planes {
        Planes {
            radiance: vec![Vec3::new(0.5, 0.5, 0.5), Vec3::splat(9.0)],
            mask: vec![true, false],
            albedo: vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)],
            emission: vec![Vec3::new(0.0, 0.0, 0.25), Vec3::ZERO],
            normal: vec![Vec3::Z, Vec3::ZERO],
        }
    }

    fn inputs(p: &Planes) -> ViewInputs<'_> {
        ViewInputs {
            width: 2,
            height: 1,
            radiance: &p.radiance,
            mask: &p.mask,
            albedo: &p.albedo,
            emission: &p.emission,
            normal: &p.normal,
        }
    }

    /// A tonemap that shows its linear input directly, to check what reaches it.
    fn linear(c: Vec3) -> [u8; 4] {
        [unorm(c.x), unorm(c.y), unorm(c.z), 255]
    }

    #[test]
    fn partial_remodulates_results_and_leaves_holes_black() {
        let p = planes();
        let pic = diagnostic(View::Partial, &inputs(&p), linear).expect("consistent");
        assert_eq!(pic[0], [128, 0, 64, 255], "albedo·radiance + emission");
        assert_eq!(pic[1], [0, 0, 0, 255], "hole");
    }

    #[test]
    fn mask_is_white_where_results_are() {
        let p = planes();
        let pic = diagnostic(View::Mask, &inputs(&p), linear).expect("consistent");
        assert_eq!(pic, vec![[255, 255, 255, 255], [0, 0, 0, 255]]);
    }

    #[test]
    fn normals_and_albedo_map_to_colours() {
        let p = planes();
        let normals = diagnostic(View::Normals, &inputs(&p), linear).expect("consistent");
        assert_eq!(normals[0], [128, 128, 255, 255]);
        assert_eq!(normals[1], [128, 128, 128, 255], "escaped ray is grey");
        let albedo = diagnostic(View::Albedo, &inputs(&p), linear).expect("consistent");
        assert_eq!(albedo[0], [255, 0, 0, 255]);
        assert_eq!(albedo[1], [0, 255, 0, 255]);
    }

    #[test]
    fn final_and_bad_lengths_give_none() {
        let p = planes();
        assert!(diagnostic(View::Final, &inputs(&p), linear).is_none());
        let mut short = planes();
        short.mask.pop();
        assert!(diagnostic(View::Mask, &inputs(&short), linear).is_none());
    }
}
