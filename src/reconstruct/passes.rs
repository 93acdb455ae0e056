//! The CPU reference of each reconstruction step, one function per GPU pass.
//!
//! Every function computes what its WGSL twin in `shaders/` computes, each tap with the
//! same f32 expressions in the same order (D, the weights, the products and the final
//! division), so that the parity test can hold the two to a tight tolerance. The temporal
//! filter and the Gaussian also add their terms in the shader's order; the fill
//! (`super::fill`) adds its taps [`LANES`] at a time, which changes its sums by rounding
//! only.
//!
//! The filters work on planes with a border (`super::planes`): taps need no bounds checks
//! and one vector load fetches [`LANES`] neighbours. Rows are processed in parallel with
//! rayon.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use super::discontinuity::Real;
use super::discontinuity::Thresholds;
pub use super::fill::{fill, FillInputs};
pub use super::gaussian::gaussian;
use super::params::{ReconstructParams, MAX_GAUSS_WIDTH, MAX_HISTORY};
use super::planes::{normalise, view, write_rows, GuidePlanes, GuideView, Layout, PlaneRow};
use super::planes::{Planes3, View3};
use super::simd::{load, run_rows, store, F32s, Isa, RowKernel, Vec3s, LANES};
#[cfg(test)]
use super::tonemap::to_rgba8;
use super::tonemap::{exposure_scale, to_rgba8_lanes};

/// Entries of the 1-D Gaussian table (radius 0..=MAX_GAUSS_WIDTH/2).
pub const GAUSS_TABLE: usize = (MAX_GAUSS_WIDTH as usize / 2) + 1;

/// The numbers every pass needs, derived once per frame from the parameters and the scene
/// scale (the GPU uniform is built from this very value).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassConsts {
    pub width: u32,
    pub height: u32,
    /// α and β (β in scene units) of the discontinuity function.
    pub d: Thresholds,
    pub radius: i32,
    pub gauss_radius: i32,
    /// Exposure in stops.
    pub exposure: f32,
    /// exp(−d²/2σ²) for d = 0, 1, …; the 2-D weight is the product of two entries.
    pub gauss: [f32; GAUSS_TABLE],
}

impl PassConsts {
    pub fn new(width: u32, height: u32, params: &ReconstructParams, scene_scale: f32) -> Self {
        let mut gauss = [0.0; GAUSS_TABLE];
        for (d, g) in gauss.iter_mut().enumerate() {
            let d = d as f32;
            *g = (-(d * d) / (2.0 * params.sigma * params.sigma)).exp();
        }
        Self {
            width,
            height,
            d: Thresholds::new(params.alpha, params.beta * scene_scale),
            radius: params.radius as i32,
            gauss_radius: params.gauss_radius(),
            exposure: params.exposure,
            gauss,
        }
    }
}

/// One previous frame as the temporal filter sees it.
#[derive(Clone, Copy)]
pub struct PastFrame<'a> {
    /// Weight w = 1/(F_i − F_j); 0 disables the slot.
    pub weight: f32,
    /// Its filled radiance.
    pub radiance: &'a Planes3,
    pub guide: &'a GuidePlanes,
}

/// Step 4 (and the start of every frame): accumulates this frame's results. `reset` starts
/// a new average (the scene state changed); rgb is the sum, w the number of samples.
pub fn accumulate(reset: bool, radiance: &[Vec3], mask: &[bool], accum: &mut [Vec4], width: u32) {
    accum.par_chunks_mut(width as usize).enumerate().for_each(|(y, row)| {
        let base = y * width as usize;
        for (x, a) in row.iter_mut().enumerate() {
            let i = base + x;
            let prev = if reset { Vec4::ZERO } else { *a };
            *a = if mask[i] { prev + radiance[i].extend(1.0) } else { prev };
        }
    });
}

/// Step 2: blends each pixel with its values in previous frames, weighted by the temporal
/// D (same pixel, that frame's G-buffer) times w = 1/(F_i − F_j); the current frame has
/// w = 1.
pub fn temporal(
    current: &Planes3,
    guide: &GuidePlanes,
    past: &[PastFrame],
    c: &PassConsts,
    layout: &Layout,
    out: &mut Planes3,
) {
    assert!(past.len() <= MAX_HISTORY as usize);
    let past = past
        .iter()
        .filter(|p| p.weight > 0.0)
        .map(|p| (p.weight, view(p.radiance), p.guide.view()))
        .collect();
    let pass =
        TemporalPass { current: view(current), guide: guide.view(), past, d: c.d, layout: *layout };
    write_rows(&pass, layout, out);
}

struct TemporalPass<'a> {
    current: View3<'a>,
    guide: GuideView<'a>,
    /// Weight, filled radiance and G-buffer of each past frame with a weight.
    past: Vec<(f32, View3<'a>, GuideView<'a>)>,
    d: Thresholds,
    layout: Layout,
}

/// Chunks of [`LANES`] pixels that the temporal filter blends together, one past frame
/// after the other: a few long runs through each frame's planes, which the hardware
/// prefetchers follow, rather than a dozen planes at every pixel.
const SEGMENT: usize = 128;

impl RowKernel<PlaneRow<'_>> for TemporalPass<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, mut out: PlaneRow<'_>, _: &mut ()) {
        let (w, base) = (self.layout.width, self.layout.index(0, y));
        let (normal, position) = (&self.guide.normal, &self.guide.position);
        for start in (0..w).step_by(LANES * SEGMENT) {
            let chunks = (start..w.min(start + LANES * SEGMENT)).step_by(LANES);
            // (Σ w·D·L, Σ w·D) of each chunk, the current frame first.
            let mut acc = [(Vec3s::<I>::zero(), F32s::zero()); SEGMENT];
            for ((sum, wsum), x0) in acc.iter_mut().zip(chunks.clone()) {
                let (n, z) = (Vec3s::load(normal, base + x0).0, Vec3s::load(position, base + x0).0);
                let d0 = self.d.d3(n, n, z, z);
                (*sum, *wsum) = (Vec3s::load(&self.current, base + x0) * d0, d0);
            }
            for (weight, radiance, guide) in &self.past {
                for ((sum, wsum), x0) in acc.iter_mut().zip(chunks.clone()) {
                    let i = base + x0;
                    let (n, z) = (Vec3s::load(normal, i).0, Vec3s::load(position, i).0);
                    let (n_j, z_j) =
                        (Vec3s::load(&guide.normal, i).0, Vec3s::load(&guide.position, i).0);
                    let dw = self.d.d3(n, n_j, z, z_j) * F32s::splat(*weight);
                    *sum += Vec3s::load(radiance, i) * dw;
                    *wsum += dw;
                }
            }
            for (&(sum, wsum), x0) in acc.iter().zip(chunks) {
                let current = Vec3s::load(&self.current, base + x0);
                normalise(sum, wsum, current, x0, &mut out);
            }
        }
    }
}

/// Where [`remodulate`] writes, one entry per pixel (row-major).
pub struct Outputs<'a> {
    pub radiance: &'a mut [Vec3],
    pub colour: &'a mut [Vec3],
    pub display: &'a mut [[u8; 4]],
}

/// Step 5: remodulates the albedo, adds the directly seen emission (linear colour) and
/// tonemaps it for display (8-bit sRGB RGBA); the radiance is copied out of its planes on
/// the way.
pub fn remodulate(
    radiance: &Planes3,
    layout: &Layout,
    albedo: &[Vec3],
    emission: &[Vec3],
    c: &PassConsts,
    out: Outputs,
) {
    let w = layout.width;
    let rows = out
        .radiance
        .chunks_mut(w)
        .zip(out.colour.chunks_mut(w))
        .zip(out.display.chunks_mut(w))
        .map(|((l, c), d)| (l, c, d))
        .enumerate()
        .collect();
    let scale = exposure_scale(c.exposure);
    let pass =
        RemodulatePass { radiance: view(radiance), albedo, emission, layout: *layout, scale };
    run_rows(&pass, rows);
}

/// One row of [`Outputs`].
type OutputRow<'a> = (&'a mut [Vec3], &'a mut [Vec3], &'a mut [[u8; 4]]);

struct RemodulatePass<'a> {
    radiance: View3<'a>,
    albedo: &'a [Vec3],
    emission: &'a [Vec3],
    layout: Layout,
    /// Exposure multiplier.
    scale: f32,
}

impl RowKernel<OutputRow<'_>> for RemodulatePass<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, (radiance, colour, display): OutputRow<'_>, _: &mut ()) {
        let (w, base) = (self.layout.width, self.layout.index(0, y));
        for x0 in (0..w).step_by(LANES) {
            // LANES pixels at a time (the row's last chunk padded), so that the filmic
            // curve vectorises.
            let x1 = w.min(x0 + LANES);
            let l = Vec3s::<I>::load(&self.radiance, base + x0).to_vec3s();
            let albedo = load(&self.albedo[y * w + x0..y * w + x1], Vec3::ZERO);
            let emission = load(&self.emission[y * w + x0..y * w + x1], Vec3::ZERO);
            let c: [Vec3; LANES] = std::array::from_fn(|k| albedo[k] * l[k] + emission[k]);
            store(&mut radiance[x0..x1], &l);
            store(&mut colour[x0..x1], &c);
            store(&mut display[x0..x1], &to_rgba8_lanes(&c, self.scale));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::planes::{at, split};

    fn consts(w: u32, h: u32) -> PassConsts {
        PassConsts::new(w, h, &ReconstructParams::default(), 1.0)
    }

    /// A layout for `c` and the guide in it.
    fn setup(normal: &[Vec3], position: &[Vec3], c: &PassConsts) -> (Layout, GuidePlanes) {
        let layout = Layout::new(c.width, c.height, c.radius.max(c.gauss_radius) as usize);
        let mut guide = GuidePlanes::new(&layout);
        guide.split(normal, position, &layout);
        (layout, guide)
    }

    fn planes(v: &[Vec3], layout: &Layout) -> Planes3 {
        let mut p = layout.zeroed3();
        split(v, layout, 0.0, &mut p);
        p
    }

    fn image(p: &Planes3, layout: &Layout) -> Vec<Vec3> {
        let w = layout.width;
        (0..w * layout.height).map(|i| at(p, layout.index(i % w, i / w))).collect()
    }

    fn flat(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        (vec![Vec3::Z; n], (0..n).map(|i| Vec3::new(i as f32 * 1e-3, 0.0, 0.0)).collect())
    }

    #[test]
    fn accumulate_averages_and_resets() {
        let mut acc = vec![Vec4::ZERO; 2];
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[true, false], &mut acc, 2);
        accumulate(false, &[Vec3::splat(3.0), Vec3::ONE], &[true, true], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::new(4.0, 4.0, 4.0, 2.0), Vec4::new(1.0, 1.0, 1.0, 1.0)]);
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[false, false], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::ZERO; 2]);
    }

    #[test]
    fn temporal_weights_follow_frame_distance() {
        let c = consts(1, 1);
        let (normal, position) = flat(1);
        let (layout, guide) = setup(&normal, &position, &c);
        let (current, old) = (planes(&[Vec3::ZERO], &layout), planes(&[Vec3::splat(4.0)], &layout));
        let mut out = layout.zeroed3();
        let past = [PastFrame { weight: 1.0 / 3.0, radiance: &old, guide: &guide }];
        temporal(&current, &guide, &past, &c, &layout, &mut out);
        // (0·1 + 4·1/3) / (1 + 1/3) = 1
        let v = at(&out, layout.index(0, 0));
        assert!((v - Vec3::ONE).abs().max_element() < 1e-5, "{v}");
        let (_, moved) = setup(&normal, &[Vec3::new(0.0, 0.0, 9.0)], &c);
        let past = [PastFrame { weight: 1.0, radiance: &old, guide: &moved }];
        temporal(&current, &guide, &past, &c, &layout, &mut out);
        let v = at(&out, layout.index(0, 0));
        assert_eq!(v, Vec3::ZERO, "a different surface in the past frame is ignored");
    }

    #[test]
    fn gaussian_smooths_noise_but_keeps_edges() {
        let (w, h) = (16, 16);
        let n = (w * h) as usize;
        let normal: Vec<Vec3> =
            (0..n).map(|i| if i % 16 < 8 { Vec3::Z } else { Vec3::X }).collect();
        let position = vec![Vec3::ZERO; n];
        let src: Vec<Vec3> = (0..n)
            .map(|i| {
                if i % 16 < 8 {
                    Vec3::splat(if i % 2 == 0 { 0.0 } else { 2.0 })
                } else {
                    Vec3::splat(10.0)
                }
            })
            .collect();
        let c = consts(w, h);
        let (layout, guide) = setup(&normal, &position, &c);
        let mut out = layout.zeroed3();
        gaussian(&planes(&src, &layout), &guide, &c, &layout, &mut out);
        let out = image(&out, &layout);
        let left = 8 * 16 + 4;
        assert!((out[left].x - 1.0).abs() < 0.3, "{}", out[left]);
        assert_eq!(out[8 * 16 + 8], Vec3::splat(10.0), "nothing leaks across the normal edge");
    }

    /// `shaders/gaussian.wgsl`, line by line.
    fn wgsl_gaussian(
        src: &[Vec3],
        normal: &[Vec3],
        position: &[Vec3],
        c: &PassConsts,
    ) -> Vec<Vec3> {
        let (w, h, r) = (c.width as i32, c.height as i32, c.gauss_radius);
        let g = |d: i32| c.gauss[d.unsigned_abs() as usize];
        let pixel = |x: i32, y: i32| {
            let p = (y * w + x) as usize;
            let (mut acc, mut wsum) = (Vec3::ZERO, 0.0);
            for dy in (-r..=r).filter(|dy| (0..h).contains(&(y + dy))) {
                for dx in (-r..=r).filter(|dx| (0..w).contains(&(x + dx))) {
                    let q = ((y + dy) * w + x + dx) as usize;
                    let wgt = g(dy) * g(dx) * c.d.d(normal[p], normal[q], position[p], position[q]);
                    acc += src[q] * wgt;
                    wsum += wgt;
                }
            }
            if wsum > 0.0 {
                acc / wsum
            } else {
                src[p]
            }
        };
        (0..w * h).map(|p| pixel(p % w, p / w)).collect()
    }

    #[test]
    fn gaussian_adds_its_taps_as_the_shader() {
        // Negative α gives the border a positive orientation factor: only its infinitely
        // distant positions keep it out. Widths that are not a multiple of LANES.
        let (w, h) = (21, 13);
        let n = (w * h) as usize;
        let normal: Vec<Vec3> = (0..n)
            .map(|i| [Vec3::Z, Vec3::X, Vec3::ZERO, Vec3::new(0.6, 0.0, 0.8)][i * 7 % 11 % 4])
            .collect();
        let position: Vec<Vec3> =
            (0..n).map(|i| Vec3::new((i % 5) as f32 * 0.1, 0.0, 0.0)).collect();
        let src: Vec<Vec3> = (0..n).map(|i| Vec3::new(i as f32, 1.0, (i % 3) as f32)).collect();
        for (gauss_width, alpha) in [(7, 0.75), (15, -0.5), (1, 0.0)] {
            let params = ReconstructParams { gauss_width, alpha, sigma: 2.0, ..Default::default() };
            let c = PassConsts::new(w, h, &params, 1.0);
            let (layout, guide) = setup(&normal, &position, &c);
            let mut out = layout.zeroed3();
            gaussian(&planes(&src, &layout), &guide, &c, &layout, &mut out);
            assert_eq!(image(&out, &layout), wgsl_gaussian(&src, &normal, &position, &c));
        }
    }

    #[test]
    fn remodulate_multiplies_albedo_and_adds_emission() {
        let c = consts(1, 1);
        let layout = Layout::new(1, 1, 0);
        let (mut radiance, mut colour, mut display) = ([Vec3::ZERO], [Vec3::ZERO], [[0u8; 4]]);
        remodulate(
            &planes(&[Vec3::splat(2.0)], &layout),
            &layout,
            &[Vec3::new(0.5, 0.25, 0.0)],
            &[Vec3::Z],
            &c,
            Outputs { radiance: &mut radiance, colour: &mut colour, display: &mut display },
        );
        assert_eq!(radiance[0], Vec3::splat(2.0));
        assert_eq!(colour[0], Vec3::new(1.0, 0.5, 1.0));
        assert_eq!(display[0], to_rgba8(colour[0], 0.0));
    }
}
