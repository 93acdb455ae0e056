//! The Gaussian pass (while interacting): the edge-aware Gaussian, each tap weighted by
//! g(dx)·g(dy)·D.
//!
//! A tap's weight is the same seen from either end: g is even and D is symmetric, bit for
//! bit (the dot products multiply the same pairs, and z_i − z_j is −(z_j − z_i) exactly).
//! So each weight is computed once, for the half of the window that lies ahead (rows
//! below, or the same row to the right, and the pixel itself), and the taps behind a pixel
//! read the weight its neighbour computed. A thread walks down a band of rows and keeps
//! the weights of the last gauss_radius + 1 rows in a ring; where a band starts it computes
//! the rows above first. Every pixel still adds its taps in the shader's (dy, dx) order,
//! with the same weights, so the result is the shader's sum exactly.

use super::{PassConsts, GAUSS_TABLE};
use crate::gpu::compute::{Binding, ComputePass};
use crate::reconstruct::discontinuity::Thresholds;
use crate::reconstruct::planes::{normalise, view, write_rows, GuidePlanes, GuideView, Layout};
use crate::reconstruct::planes::{PlaneRow, Planes3, View3};
use crate::reconstruct::rows::{store, RowKernel};
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s, WIDTH};

/// WGSL: reads the blended radiance and the G-buffer, writes the filtered radiance.
pub const WGSL: &str = include_str!("../../../shaders/reconstruct/gaussian.wgsl");

/// The GPU binding: the compiled pass with its bindings in `gaussian.wgsl`'s order.
pub fn gpu_pass(device: &wgpu::Device) -> ComputePass {
    use Binding::{Storage, Texture as T, Uniform as U};
    let f32x4 = wgpu::TextureFormat::Rgba32Float;
    ComputePass::new(device, "gaussian", &super::with_common(WGSL), &[U, T, T, T, Storage(f32x4)])
}

/// The edge-aware Gaussian (width 2·gauss_radius + 1) of `src`, weighted by D.
pub fn gaussian(
    src: &Planes3,
    guide: &GuidePlanes,
    c: &PassConsts,
    layout: &Layout,
    out: &mut Planes3,
) {
    let r = c.gauss_radius;
    assert!(layout.pad >= r as usize, "the border is narrower than the Gaussian");
    for plane in src.iter().chain(&guide.normal).chain(&guide.position) {
        assert_eq!(plane.len(), layout.plane_len(), "a plane of another layout");
    }
    let g = |d: i32| c.gauss[d.unsigned_abs() as usize];
    // The half of the window whose weights a pixel computes.
    let ahead: Vec<(i32, i32)> = (0..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|&(dx, dy)| dy > 0 || dx >= 0)
        .collect();
    let ring_width = layout.width + 2 * r as usize + WIDTH;
    let position = |dx: i32, dy: i32| ahead.iter().position(|&a| a == (dx, dy));
    let taps = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .map(|(dx, dy)| {
            // A tap ahead reads this pixel's weight; one behind reads the weight that the
            // pixel it lands on computed for the opposite offset.
            let (weight, above, shift) = match position(dx, dy) {
                Some(f) => (f, 0, 0),
                None => (position(-dx, -dy).expect("the other half"), -dy, dx),
            };
            Tap {
                src: layout.offset(dx, dy),
                above: above as usize,
                column: weight * ring_width + (r + shift) as usize,
            }
        })
        .collect();
    let pass = GaussianPass {
        src: view(src),
        guide: guide.view(),
        d: c.d,
        layout: *layout,
        ahead: ahead.iter().map(|&(dx, dy)| (layout.offset(dx, dy), g(dy) * g(dx))).collect(),
        taps,
        radius: r as usize,
        ring_width,
    };
    write_rows(&pass, layout, out);
}

/// Where one tap of an output pixel finds its source value and its weight.
#[derive(Debug)]
struct Tap {
    /// Offset of the source pixel.
    src: isize,
    /// Rows above the output row where the weight was computed.
    above: usize,
    /// Index of the weight in that row's part of the ring, less the output x.
    column: usize,
}

struct GaussianPass<'a> {
    src: View3<'a>,
    guide: GuideView<'a>,
    d: Thresholds,
    layout: Layout,
    /// Guide offset and g(dy)·g(dx) of each weight a pixel computes.
    ahead: Vec<(isize, f32)>,
    /// Every tap, in the shader's (dy, dx) order.
    taps: Vec<Tap>,
    radius: usize,
    /// Entries per weight per row in the ring: the image width with a zero margin of
    /// `radius` on both sides (weights towards pixels outside the image are 0), and room
    /// for the last run of lanes.
    ring_width: usize,
}

/// The weights of the last radius + 1 rows a thread computed.
struct Ring {
    weights: Vec<f32>,
    /// The last row computed; rows up to radius above it are in the ring too.
    last: Option<usize>,
}

impl GaussianPass<'_> {
    /// Start of row `y`'s part of the ring (y may be above the image).
    fn slot(&self, y: isize) -> usize {
        let rows = self.radius as isize + 1;
        y.rem_euclid(rows) as usize * self.ahead.len() * self.ring_width
    }

    /// Fills row `y`'s part of the ring: the weights of every pixel for each offset ahead.
    #[inline(always)]
    fn weigh<I: Isa>(&self, y: isize, ring: &mut [f32]) {
        let slot = self.slot(y);
        let ring = &mut ring[slot..slot + self.ahead.len() * self.ring_width];
        if y < 0 {
            // A row above the image: no weights.
            ring.fill(0.0);
            return;
        }
        let (normal, position) = (&self.guide.normal, &self.guide.position);
        let (w, base) = (self.layout.width, self.layout.index(0, y as usize));
        for x0 in (0..w).step_by(WIDTH) {
            let i = base + x0;
            let (n, z) = (Vec3s::<I>::load(normal, i), Vec3s::<I>::load(position, i));
            let (n, z) = (n.to_array(), z.to_array());
            for (row, &(offset, g)) in ring.chunks_exact_mut(self.ring_width).zip(&self.ahead) {
                let j = i.wrapping_add_signed(offset);
                // SAFETY: `j` is a pixel of the image moved by at most the radius, which the
                // border covers (checked in `gaussian`).
                let (n_j, z_j) = unsafe {
                    (Vec3s::load_unchecked(normal, j), Vec3s::load_unchecked(position, j))
                };
                let wgt = F32s::splat(g) * self.d.d3(n, n_j.to_array(), z, z_j.to_array());
                let row = &mut row[self.radius + x0..][..WIDTH.min(w - x0)];
                match <&mut [f32; WIDTH]>::try_from(&mut *row) {
                    Ok(whole) => wgt.store(whole),
                    Err(_) => store(row, &wgt.0),
                }
            }
        }
    }
}

impl RowKernel<PlaneRow<'_>> for GaussianPass<'_> {
    type Scratch = Ring;

    fn scratch(&self) -> Ring {
        let len = (self.radius + 1) * self.ahead.len() * self.ring_width;
        Ring { weights: vec![0.0; len], last: None }
    }

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, mut out: PlaneRow<'_>, ring: &mut Ring) {
        // The unchecked loads below and in `weigh` rely on it.
        assert!(y < self.layout.height, "row {y} is outside the image");
        // This row's weights, and those of the rows above unless this thread has just
        // computed them.
        let continuing = y > 0 && ring.last == Some(y - 1);
        let (y_i, r) = (y as isize, self.radius as isize);
        for yy in if continuing { y_i } else { y_i - r }..=y_i {
            self.weigh::<I>(yy, &mut ring.weights);
        }
        ring.last = Some(y);
        let mut slots = [0; GAUSS_TABLE];
        for (above, slot) in slots.iter_mut().enumerate().take(self.radius + 1) {
            *slot = self.slot(y_i - above as isize);
        }
        let base = self.layout.index(0, y);
        for x0 in (0..self.layout.width).step_by(WIDTH) {
            let i = base + x0;
            let (mut sum, mut wsum) = (Vec3s::<I>::default(), F32s::splat(0.0));
            for tap in &self.taps {
                // SAFETY: a weight's column is within its row of the ring, margins included,
                // and `tap.src` moves a pixel by at most the radius, which the border covers
                // (both checked in `gaussian`).
                let (wgt, src) = unsafe {
                    let wgt =
                        F32s::load_unchecked(&ring.weights, slots[tap.above] + tap.column + x0);
                    (wgt, Vec3s::load_unchecked(&self.src, i.wrapping_add_signed(tap.src)))
                };
                sum += src.scale(wgt);
                wsum += wgt;
            }
            normalise(sum, wsum, Vec3s::load(&self.src, i), x0, &mut out);
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::reconstruct::params::ReconstructParams;
    use crate::reconstruct::pass::testing::{consts, image, planes, setup};

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

    /// `gaussian.wgsl`, line by line.
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
        // distant positions keep it out. Widths that are not a multiple of WIDTH.
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
}
