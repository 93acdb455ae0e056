//! The fill pass: fills pixels without samples from the calculated neighbours in a disc
//! around them, weighted by D (k = 1).
//!
//! Each tap computes the shader's f32 expressions, but the disc is covered by runs of
//! [`WIDTH`] consecutive taps of one row (lanes outside the disc are masked to exactly 0),
//! so that a run is a handful of vector instructions; a pixel's sum therefore adds its
//! taps run by run and then across lanes, an order that differs from the shader's by
//! rounding only.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use super::PassConsts;
use crate::gpu::compute::{Binding, ComputePass};
use crate::reconstruct::discontinuity::{is_surface, Thresholds};
use crate::reconstruct::planes::{at, image_rows, view, write_rows, GuidePlanes, GuideView};
use crate::reconstruct::planes::{Layout, Plane, PlaneRow, Planes3, View3};
use crate::reconstruct::rows::RowKernel;
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Mask, Vec3s, WIDTH};

/// WGSL: reads the running sums and the G-buffer, writes the filled radiance.
pub const WGSL: &str = include_str!("../../../shaders/reconstruct/fill.wgsl");

/// The GPU binding: the compiled pass with its bindings in `fill.wgsl`'s order.
pub fn gpu_pass(device: &wgpu::Device) -> ComputePass {
    use Binding::{Storage, Texture as T, Uniform as U};
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    ComputePass::new(device, "fill", &super::with_common(WGSL), &[U, T, T, T, Storage(f32x4)])
}

/// The accumulated samples as the fill reads them: each pixel's mean (the division the
/// GPU does per tap; 0 where nothing was calculated), whether it was calculated (1 or 0)
/// and whether it is a calculated surface pixel. An uncalculated pixel, or the zero
/// border, then adds exactly 0 to every sum without a branch.
#[derive(Debug)]
pub struct FillInputs {
    mean: Planes3,
    calc: Plane,
    surf_calc: Plane,
}

impl FillInputs {
    pub fn new(layout: &Layout) -> Self {
        let [m0, m1, m2, calc, surf_calc] = [(); 5].map(|_| Plane::zeroed(layout.plane_len()));
        Self { mean: [m0, m1, m2], calc, surf_calc }
    }

    fn prepare(&mut self, accum: &[Vec4], guide: &GuidePlanes, layout: &Layout) {
        let Self { mean: [m0, m1, m2], calc, surf_calc } = self;
        let planes = [m0, m1, m2, calc, surf_calc].map(|p| p.as_mut_slice());
        let (w, normal) = (layout.width, view(&guide.normal));
        image_rows(planes, layout).into_par_iter().for_each(|(y, [m0, m1, m2, calc, surf])| {
            let base = layout.index(0, y);
            for (x, a) in accum[y * w..(y + 1) * w].iter().enumerate() {
                let (m, has, surface) = if a.w > 0.0 {
                    (a.truncate() / a.w, 1.0, is_surface(at(&normal, base + x)))
                } else {
                    (Vec3::ZERO, 0.0, false)
                };
                (m0[x], m1[x], m2[x], calc[x]) = (m.x, m.y, m.z, has);
                surf[x] = if surface { 1.0 } else { 0.0 };
            }
        });
    }
}

/// Fills pixels without samples from calculated neighbours within the radius, weighted by
/// D (k = 1). Where every neighbour has D = 0 the plain mean of the calculated surface
/// neighbours is used; where there are none the value is 0 (a hole stays black). Pixels
/// that hit no surface have radiance 0 by convention. `inputs` is scratch space.
pub fn fill(
    accum: &[Vec4],
    guide: &GuidePlanes,
    c: &PassConsts,
    layout: &Layout,
    inputs: &mut FillInputs,
    out: &mut Planes3,
) {
    assert!(layout.pad >= c.radius as usize, "the border is narrower than the fill radius");
    let planes = inputs.mean.iter().chain([&inputs.calc, &inputs.surf_calc]);
    for plane in planes.chain(&guide.normal).chain(&guide.position) {
        assert_eq!(plane.len(), layout.plane_len(), "a plane of another layout");
    }
    inputs.prepare(accum, guide, layout);
    let pass = FillPass {
        mean: view(&inputs.mean),
        calc: &inputs.calc,
        surf_calc: &inputs.surf_calc,
        guide: guide.view(),
        d: c.d,
        layout: *layout,
        runs: disc(c.radius, layout),
    };
    write_rows(&pass, layout, out);
}

/// Up to [`WIDTH`] consecutive taps of one row of the disc: the offset of the first from
/// the centre pixel, and each lane's mask (all ones inside the disc, 0 outside).
#[derive(Debug)]
struct Run {
    offset: isize,
    keep: [u32; WIDTH],
}

/// The runs covering the disc of radius `r`, row by row.
fn disc(r: i32, layout: &Layout) -> Vec<Run> {
    let mut runs = Vec::new();
    for dy in -r..=r {
        // Half-width of the disc on this row.
        let half = (0..=r).take_while(|dx| dx * dx + dy * dy <= r * r).count() as i32 - 1;
        for start in (-half..=half).step_by(WIDTH) {
            let inside = |k: usize| start + k as i32 <= half;
            let keep = std::array::from_fn(|k| if inside(k) { u32::MAX } else { 0 });
            runs.push(Run { offset: layout.offset(start, dy), keep });
        }
    }
    runs
}

/// The fill with its inputs borrowed (see [`FillInputs`]).
struct FillPass<'a> {
    mean: View3<'a>,
    calc: &'a [f32],
    surf_calc: &'a [f32],
    guide: GuideView<'a>,
    d: Thresholds,
    layout: Layout,
    runs: Vec<Run>,
}

impl RowKernel<PlaneRow<'_>> for FillPass<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, [r, g, b]: PlaneRow<'_>, _: &mut ()) {
        // The unchecked loads in `weighted_sum` rely on it.
        assert!(y < self.layout.height, "row {y} is outside the image");
        let (base, w) = (self.layout.index(0, y), self.layout.width);
        // The mean plane already holds every pixel's value but the holes' on a surface (a
        // calculated pixel's mean, 0 where nothing was calculated): the row is copied at
        // once, and only those holes are computed.
        for (out, mean) in [&mut *r, &mut *g, &mut *b].into_iter().zip(self.mean) {
            out.copy_from_slice(&mean[base..base + w]);
        }
        for (x, &calc) in self.calc[base..base + w].iter().enumerate() {
            let i = base + x;
            if calc <= 0.0 && is_surface(at(&self.guide.normal, i)) {
                let v = self.missing::<I>(i);
                (r[x], g[x], b[x]) = (v.x, v.y, v.z);
            }
        }
    }
}

impl FillPass<'_> {
    /// The value of surface pixel `i`, which has no samples.
    #[inline(always)]
    fn missing<I: Isa>(&self, i: usize) -> Vec3 {
        let (sum, wsum) = self.weighted_sum::<I>(i);
        if wsum > 0.0 {
            return sum / wsum;
        }
        let (sum, count) = self.plain_sum::<I>(i);
        if count > 0.0 {
            sum / count
        } else {
            Vec3::ZERO
        }
    }

    /// Σ D·L and Σ D over the calculated pixels of the disc around `i`.
    #[inline(always)]
    fn weighted_sum<I: Isa>(&self, i: usize) -> (Vec3, f32) {
        let g = &self.guide;
        let n_i = Vec3s::<I>::splat(at(&g.normal, i)).to_array();
        let z_i = Vec3s::<I>::splat(at(&g.position, i)).to_array();
        let (mut sum, mut wsum) = (Vec3s::splat(Vec3::ZERO), F32s::splat(0.0));
        for run in &self.runs {
            let j = i.wrapping_add_signed(run.offset);
            // SAFETY: a run starts at most the radius away from a pixel of the image, which
            // the border covers, and its lanes end within the plane's tail (checked in
            // `fill`).
            let (n_j, z_j, calc, mean) = unsafe {
                let (n_j, z_j) =
                    (Vec3s::load_unchecked(&g.normal, j), Vec3s::load_unchecked(&g.position, j));
                (
                    n_j.to_array(),
                    z_j.to_array(),
                    F32s::load_unchecked(self.calc, j),
                    Vec3s::load_unchecked(&self.mean, j),
                )
            };
            let keep = Mask::<I>::new(run.keep);
            let d = self.d.d3(n_i, n_j, z_i, z_j) * calc.masked(keep);
            sum += mean.masked(keep).scale(d);
            wsum += d;
        }
        (sum.sum(), wsum.sum())
    }

    /// Σ L and their number over the calculated surface pixels of the disc around `i`:
    /// needed only where every D is 0, so summed apart.
    #[inline(always)]
    fn plain_sum<I: Isa>(&self, i: usize) -> (Vec3, f32) {
        let (mut sum, mut count) = (Vec3s::<I>::splat(Vec3::ZERO), F32s::splat(0.0));
        for run in &self.runs {
            let j = i.wrapping_add_signed(run.offset);
            let keep = Mask::<I>::new(run.keep);
            let s = F32s::load(self.surf_calc, j).masked(keep);
            sum += Vec3s::load(&self.mean, j).masked(keep).scale(s);
            count += s;
        }
        (sum.sum(), count.sum())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::params::ReconstructParams;

    fn consts(w: u32, h: u32, params: ReconstructParams) -> PassConsts {
        PassConsts::new(w, h, &params, 1.0)
    }

    /// Fills `accum` on a guide of one vector per pixel; returns one value per pixel.
    fn run(accum: &[Vec4], normal: &[Vec3], position: &[Vec3], c: &PassConsts) -> Vec<Vec3> {
        let layout = Layout::new(c.width, c.height, c.radius as usize);
        let mut guide = GuidePlanes::new(&layout);
        guide.split(normal, position, &layout);
        let mut out = layout.zeroed3();
        fill(accum, &guide, c, &layout, &mut FillInputs::new(&layout), &mut out);
        let (w, h) = (layout.width, layout.height);
        (0..w * h).map(|i| at(&out, layout.index(i % w, i / w))).collect()
    }

    /// `fill.wgsl`, line by line.
    fn wgsl(accum: &[Vec4], normal: &[Vec3], position: &[Vec3], c: &PassConsts) -> Vec<Vec3> {
        let (w, h, r) = (c.width as i32, c.height as i32, c.radius);
        let pixel = |x: i32, y: i32| -> Vec3 {
            let p = (y * w + x) as usize;
            let a = accum[p];
            if a.w > 0.0 {
                return a.truncate() / a.w;
            }
            let (ni, zi) = (normal[p], position[p]);
            if !is_surface(ni) {
                return Vec3::ZERO;
            }
            let (mut acc, mut wsum, mut plain, mut plain_n) = (Vec3::ZERO, 0.0, Vec3::ZERO, 0.0);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (xx, yy) = (x + dx, y + dy);
                    if xx < 0 || xx >= w || yy < 0 || yy >= h || dx * dx + dy * dy > r * r {
                        continue;
                    }
                    let q = (yy * w + xx) as usize;
                    let b = accum[q];
                    if b.w <= 0.0 {
                        continue;
                    }
                    let lj = b.truncate() / b.w;
                    let d = c.d.d(ni, normal[q], zi, position[q]);
                    acc += lj * d;
                    wsum += d;
                    if is_surface(normal[q]) {
                        plain += lj;
                        plain_n += 1.0;
                    }
                }
            }
            if wsum > 0.0 {
                acc / wsum
            } else if plain_n > 0.0 {
                plain / plain_n
            } else {
                Vec3::ZERO
            }
        };
        (0..w * h).map(|p| pixel(p % w, p / w)).collect()
    }

    fn flat(n: usize) -> (Vec<Vec3>, Vec<Vec3>) {
        (vec![Vec3::Z; n], (0..n).map(|i| Vec3::new(i as f32 * 1e-3, 0.0, 0.0)).collect())
    }

    #[test]
    fn fill_reproduces_a_constant_and_keeps_calculated_pixels() {
        let (w, h) = (16, 12);
        let n = (w * h) as usize;
        let (normal, position) = flat(n);
        let accum: Vec<Vec4> = (0..n)
            .map(|i| if i % 3 == 0 { Vec4::ZERO } else { Vec4::new(0.5, 0.25, 1.0, 1.0) })
            .collect();
        let out = run(&accum, &normal, &position, &consts(w, h, ReconstructParams::default()));
        for v in out {
            assert!((v - Vec3::new(0.5, 0.25, 1.0)).abs().max_element() < 1e-6, "{v}");
        }
    }

    #[test]
    fn fill_does_not_cross_a_depth_edge() {
        // Left half at z = 0 with radiance 1, right half at z = 5 with radiance 0; the
        // missing pixel on the left must take only left values.
        let (w, h) = (12, 4);
        let n = (w * h) as usize;
        let normal = vec![Vec3::Z; n];
        let position: Vec<Vec3> =
            (0..n).map(|i| Vec3::new(0.0, 0.0, if i % 12 < 6 { 0.0 } else { 5.0 })).collect();
        let mut accum: Vec<Vec4> = (0..n)
            .map(|i| if i % 12 < 6 { Vec4::ONE } else { Vec4::new(0.0, 0.0, 0.0, 1.0) })
            .collect();
        accum[12 + 5] = Vec4::ZERO;
        let out = run(&accum, &normal, &position, &consts(w, h, ReconstructParams::default()));
        assert_eq!(out[12 + 5], Vec3::ONE);
    }

    #[test]
    fn fill_matches_the_shader_loop_up_to_summation_order() {
        // Random guide and samples (some sky, some pixels whose neighbours all have D = 0)
        // with radii whose disc rows take one, two and five runs.
        let (w, h) = (41, 29);
        let n = (w * h) as usize;
        let hash = |i: usize, k: u64| {
            let x = (i as u64 ^ k.wrapping_mul(0x9e37_79b9_7f4a_7c15))
                .wrapping_mul(0xff51_afd7_ed55_8ccd);
            (x >> 40) as f32 / (1u64 << 24) as f32
        };
        let normal: Vec<Vec3> = (0..n)
            .map(|i| match (hash(i, 1) * 4.0) as u32 {
                0 => Vec3::ZERO,
                1 => Vec3::X,
                _ => Vec3::new(hash(i, 2) - 0.5, 1.0, hash(i, 3) - 0.5).normalize(),
            })
            .collect();
        let position: Vec<Vec3> = (0..n).map(|i| Vec3::new(hash(i, 4), hash(i, 5), 0.0)).collect();
        let accum: Vec<Vec4> = (0..n)
            .map(|i| {
                let v = Vec4::new(hash(i, 6), hash(i, 7), hash(i, 8), 1.0) * 3.0;
                if hash(i, 9) < 0.4 {
                    Vec4::ZERO
                } else {
                    v
                }
            })
            .collect();
        for (radius, alpha) in [(0, 0.75), (1, 0.75), (5, 0.75), (9, -0.5), (16, 0.2)] {
            let params = ReconstructParams { radius, alpha, beta: 0.4, ..Default::default() };
            let c = consts(w, h, params);
            let (got, want) =
                (run(&accum, &normal, &position, &c), wgsl(&accum, &normal, &position, &c));
            for (i, (a, b)) in got.iter().zip(&want).enumerate() {
                let err = (*a - *b).abs().max_element() / b.max_element().max(1.0);
                assert!(err < 1e-5, "radius {radius} pixel {i}: {a} against {b}");
            }
        }
    }
}
