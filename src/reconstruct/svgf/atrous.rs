//! The variance-guided à-trous wavelet filter (Dammertz et al. 2010, as SVGF uses it).
//!
//! Iteration k blends each pixel with its eight neighbours 2^k pixels away (a 3×3 B-spline
//! kernel with holes, so five iterations reach 31 pixels for the price of 45 taps), each
//! weighted by the kernel, the geometric edge-stopping and the luminance edge-stopping
//! scaled by the standard deviation of the pixel's estimate (`variance`). The variance is
//! filtered alongside with the squared weights, so that each iteration stops at edges the
//! noise cannot explain any more. A pixel without a surface keeps its value.

use super::edges::{luminance, Edges};
use crate::reconstruct::planes::{image_rows, view, GuidePlanes, GuideView, Layout, Plane};
use crate::reconstruct::planes::{Planes3, View3};
use crate::reconstruct::rows::{run_rows, store, RowKernel};
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s, WIDTH};

/// The 1-D kernel: h(0), h(±1).
const KERNEL: [f32; 2] = [0.5, 0.25];

/// One iteration with step `step`: `colour`/`variance` in, `out_colour`/`out_variance`.
#[allow(clippy::too_many_arguments)] // two planes in, two out, the guide and its constants
pub fn iteration(
    colour: &Planes3,
    variance: &Plane,
    guide: &GuidePlanes,
    edges: Edges,
    sigma_luminance: f32,
    step: usize,
    layout: &Layout,
    (out_colour, out_variance): (&mut Planes3, &mut Plane),
) {
    assert!(layout.pad >= step, "the border is narrower than the step");
    let s = step as i32;
    let taps = (-1..=1)
        .flat_map(|dy: i32| (-1..=1).map(move |dx: i32| (dx, dy)))
        .filter(|&t| t != (0, 0))
        .map(|(dx, dy)| {
            let h = KERNEL[dx.unsigned_abs() as usize] * KERNEL[dy.unsigned_abs() as usize];
            (layout.offset(dx * s, dy * s), h)
        })
        .collect();
    let kernel = Atrous {
        colour: view(colour),
        variance,
        guide: guide.view(),
        edges,
        sigma_luminance,
        layout: *layout,
        taps,
    };
    let [c0, c1, c2] = out_colour.each_mut().map(Plane::as_mut_slice);
    run_rows(&kernel, image_rows([c0, c1, c2, out_variance.as_mut_slice()], layout));
}

struct Atrous<'a> {
    colour: View3<'a>,
    variance: &'a [f32],
    guide: GuideView<'a>,
    edges: Edges,
    sigma_luminance: f32,
    layout: Layout,
    /// Offset and kernel weight of each neighbour.
    taps: Vec<(isize, f32)>,
}

/// Keeps 1/(σ_l·σ_i) finite where the variance is 0.
const MIN_DEVIATION: f32 = 1e-6;

impl RowKernel<[&mut [f32]; 4]> for Atrous<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, [r, g, b, v]: [&mut [f32]; 4], _: &mut ()) {
        assert!(y < self.layout.height, "row {y} is outside the image");
        let (w, base) = (self.layout.width, self.layout.index(0, y));
        let (normal, position) = (&self.guide.normal, &self.guide.position);
        let centre = F32s::<I>::splat(KERNEL[0] * KERNEL[0]);
        for x0 in (0..w).step_by(WIDTH) {
            let i = base + x0;
            let (n_i, p_i) = (Vec3s::<I>::load(normal, i), Vec3s::load(position, i));
            let (c_i, var_i) = (Vec3s::load(&self.colour, i), F32s::load(self.variance, i));
            let l_i = luminance(c_i);
            let deviation = F32s::splat(self.sigma_luminance) * var_i.sqrt();
            let inv = F32s::splat(1.0) / deviation.max(F32s::splat(MIN_DEVIATION));
            let (mut sum, mut wsum, mut vsum) =
                (c_i.scale(centre), centre, centre * centre * var_i);
            for &(o, h) in &self.taps {
                let j = i.wrapping_add_signed(o);
                // SAFETY: `j` is at most the step away from a pixel of the image in each
                // direction, which the border covers (checked in `iteration`).
                let (n_j, p_j, c_j, var_j) = unsafe {
                    (
                        Vec3s::load_unchecked(normal, j),
                        Vec3s::load_unchecked(position, j),
                        Vec3s::load_unchecked(&self.colour, j),
                        F32s::load_unchecked(self.variance, j),
                    )
                };
                let geometry = self.edges.geometry(n_i, p_i, n_j, p_j);
                let wl = Edges::luminance(l_i - luminance(c_j), inv);
                let wgt = F32s::splat(h) * geometry * wl;
                sum += c_j.scale(wgt);
                wsum += wgt;
                vsum += wgt * wgt * var_j;
            }
            // The centre's weight is positive: wsum > 0 everywhere. Pixels without a
            // surface (normal 0) keep their value.
            let surface = n_i.dot(n_i).gt(F32s::splat(0.25));
            let out = Vec3s::select(surface, sum.div_by(wsum), c_i);
            let var = F32s::select(surface, vsum / (wsum * wsum), var_i);
            let n = WIDTH.min(w - x0);
            for (o, lanes) in [&mut *r, &mut *g, &mut *b].into_iter().zip(out.to_array()) {
                store(&mut o[x0..x0 + n], &lanes.0);
            }
            store(&mut v[x0..x0 + n], &var.0);
        }
    }
}
