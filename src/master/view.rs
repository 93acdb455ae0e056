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
    /// This frame's results tinted by the worker that rendered each pixel (holes black);
    /// the panel's worker list is the legend ([`worker_colour`]).
    Workers,
}

impl View {
    /// Every view, in the order the panel lists them.
    pub const ALL: [View; 6] =
        [View::Final, View::Partial, View::Mask, View::Normals, View::Albedo, View::Workers];

    /// The panel's label.
    pub fn label(self) -> &'static str {
        match self {
            View::Final => "final",
            View::Partial => "partial",
            View::Mask => "mask",
            View::Normals => "normals",
            View::Albedo => "albedo",
            View::Workers => "workers",
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
    /// The worker (connection) whose result covers each pixel; only the workers view
    /// reads it, the others accept an empty slice.
    pub owner: &'a [Option<u64>],
}

/// The colour that stands for worker (connection) `id` in the workers view and its
/// legend: hues spread by the golden ratio, so neighbouring ids differ clearly.
pub fn worker_colour(id: u64) -> [u8; 3] {
    let hue = (id as f64 * 0.618_033_988_749_895).fract() as f32;
    let c = hsv(hue, 0.75, 1.0);
    [unorm(c.x), unorm(c.y), unorm(c.z)]
}

/// HSV (all in [0, 1]) to linear-looking RGB; enough for a palette.
fn hsv(h: f32, s: f32, v: f32) -> Vec3 {
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    Vec3::new(k(5.0), k(3.0), k(1.0))
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
    if view == View::Workers && inputs.owner.len() != n {
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
            View::Workers => match inputs.owner[i] {
                Some(id) if inputs.mask[i] => {
                    // The worker's colour, shaded by the pixel's brightness so the scene
                    // stays recognisable under the tint.
                    let shown = tonemap(inputs.albedo[i] * inputs.radiance[i] + inputs.emission[i]);
                    let luma = (0.2126 * f32::from(shown[0])
                        + 0.7152 * f32::from(shown[1])
                        + 0.0722 * f32::from(shown[2]))
                        / 255.0;
                    let shade = 0.35 + 0.65 * luma;
                    let c = worker_colour(id);
                    let tint = |v: u8| (f32::from(v) * shade + 0.5) as u8;
                    [tint(c[0]), tint(c[1]), tint(c[2]), 255]
                }
                _ => [0, 0, 0, 255],
            },
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
        owner: Vec<Option<u64>>,
    }

    /// Two pixels: the first has a result, the second is a hole.
    fn planes() -> Planes {
        Planes {
            radiance: vec![Vec3::new(0.5, 0.5, 0.5), Vec3::splat(9.0)],
            mask: vec![true, false],
            albedo: vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)],
            emission: vec![Vec3::new(0.0, 0.0, 0.25), Vec3::ZERO],
            normal: vec![Vec3::Z, Vec3::ZERO],
            owner: vec![Some(3), None],
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
            owner: &p.owner,
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
    fn workers_view_tints_each_result_by_its_worker_and_leaves_holes_black() {
        let mut p = planes();
        // White light so that the shade is full: the pixel is the worker's colour.
        p.albedo[0] = Vec3::ONE;
        p.radiance[0] = Vec3::splat(100.0);
        let white = |_: Vec3| [255, 255, 255, 255];
        let pic = diagnostic(View::Workers, &inputs(&p), white).expect("consistent");
        let c = worker_colour(3);
        assert_eq!(pic[0], [c[0], c[1], c[2], 255]);
        assert_eq!(pic[1], [0, 0, 0, 255], "hole");
        // A dark pixel keeps a dimmed tint of the same hue.
        let black = |_: Vec3| [0, 0, 0, 255];
        let dim = diagnostic(View::Workers, &inputs(&p), black).expect("consistent")[0];
        assert!(dim[..3].iter().zip(c).all(|(d, c)| *d < c || c == 0), "{dim:?} vs {c:?}");
        // Without owners the view cannot be made.
        p.owner.clear();
        assert!(diagnostic(View::Workers, &inputs(&p), white).is_none());
    }

    #[test]
    fn worker_colours_differ_between_neighbouring_ids() {
        for id in 0..16u64 {
            let (a, b) = (worker_colour(id), worker_colour(id + 1));
            let d: i32 = a.iter().zip(b).map(|(x, y)| (i32::from(*x) - i32::from(y)).abs()).sum();
            assert!(d > 60, "ids {id} and {}: {a:?} vs {b:?}", id + 1);
        }
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
