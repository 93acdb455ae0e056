//! The variance of each pixel's estimate, which guides the à-trous filter's luminance
//! edge-stopping.
//!
//! From the pixel's own temporal moments (Σl, Σl² of its n samples, history included)
//! where n ≥ [`TEMPORAL_MIN`]; where the history is shorter, from the moments of the
//! pixel's surface in a 5×5 neighbourhood pooled (weighted by the geometric
//! edge-stopping). Either estimates one sample's variance; the estimate of the pixel is the
//! mean of its n samples, so the result is that divided by n (filled pixels, n = 0, count
//! as one sample). Where even the neighbourhood has fewer than two samples the variance
//! is the squared luminance of the filled value: a relative deviation of 1.

use rayon::prelude::*;

use super::edges::{luminance, Edges};
use super::params::variance_reach;
use super::reproject::Moments;
use crate::reconstruct::planes::{image_rows, view, GuidePlanes, GuideView, Layout, Plane};
use crate::reconstruct::planes::{Planes3, View3};
use crate::reconstruct::rows::{run_rows, store, RowKernel};
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s, WIDTH};

/// Samples from which a pixel's own moments are trusted.
pub const TEMPORAL_MIN: f32 = 4.0;

/// Each pixel's sample count and luminance moments as planes (border 0).
#[derive(Debug)]
pub struct MomentPlanes {
    count: Plane,
    lum: Plane,
    lum2: Plane,
}

impl MomentPlanes {
    pub fn new(layout: &Layout) -> Self {
        let [count, lum, lum2] = [(); 3].map(|_| Plane::zeroed(layout.plane_len()));
        Self { count, lum, lum2 }
    }

    /// Splits the history's moments into the planes.
    pub fn split(&mut self, history: &[Moments], layout: &Layout) {
        let w = layout.width;
        let planes = [&mut self.count, &mut self.lum, &mut self.lum2].map(|p| p.as_mut_slice());
        image_rows(planes, layout).into_par_iter().for_each(|(y, [n, l, l2])| {
            for (x, m) in history[y * w..(y + 1) * w].iter().enumerate() {
                (n[x], l[x], l2[x]) = (m.sum.w, m.lum.x, m.lum.y);
            }
        });
    }
}

/// Writes the variance of each pixel's estimate of `filled` (the filled mean) to `out`.
pub fn variance(
    moments: &MomentPlanes,
    filled: &Planes3,
    guide: &GuidePlanes,
    edges: Edges,
    layout: &Layout,
    out: &mut Plane,
) {
    assert!(layout.pad >= variance_reach(), "the border is narrower than the variance window");
    let r = variance_reach() as i32;
    let taps = (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| layout.offset(dx, dy)))
        .filter(|&o| o != 0)
        .collect();
    let kernel = Variance {
        count: &moments.count,
        lum: &moments.lum,
        lum2: &moments.lum2,
        filled: view(filled),
        guide: guide.view(),
        edges,
        layout: *layout,
        taps,
    };
    run_rows(&kernel, image_rows([out.as_mut_slice()], layout));
}

struct Variance<'a> {
    count: &'a [f32],
    lum: &'a [f32],
    lum2: &'a [f32],
    filled: View3<'a>,
    guide: GuideView<'a>,
    edges: Edges,
    layout: Layout,
    /// Offsets of the neighbourhood, the pixel itself excluded.
    taps: Vec<isize>,
}

/// One sample's variance from n samples' Σl and Σl² (unbiased; valid for n ≥ 2).
#[inline(always)]
fn sample_variance<I: Isa>(n: F32s<I>, s1: F32s<I>, s2: F32s<I>) -> F32s<I> {
    let one = F32s::splat(1.0);
    let n = n.max(F32s::splat(2.0));
    let mean = s1 / n;
    ((s2 / n - mean * mean) * n / (n - one)).positive_part()
}

impl RowKernel<[&mut [f32]; 1]> for Variance<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, [out]: [&mut [f32]; 1], _: &mut ()) {
        assert!(y < self.layout.height, "row {y} is outside the image");
        let (w, base) = (self.layout.width, self.layout.index(0, y));
        let (normal, position) = (&self.guide.normal, &self.guide.position);
        let min = F32s::<I>::splat(TEMPORAL_MIN);
        for x0 in (0..w).step_by(WIDTH) {
            let i = base + x0;
            let n = F32s::<I>::load(self.count, i);
            let (s1, s2) = (F32s::load(self.lum, i), F32s::load(self.lum2, i));
            let mut var = sample_variance(n, s1, s2);
            let short = n.lt(min);
            if short.0.iter().any(|&m| m != 0) {
                let (n_i, p_i) = (Vec3s::load(normal, i), Vec3s::load(position, i));
                let (mut wn, mut w1, mut w2) = (n, s1, s2);
                for &o in &self.taps {
                    let j = i.wrapping_add_signed(o);
                    // SAFETY: `j` is at most the variance reach from a pixel of the image,
                    // which the border covers (checked in `variance`).
                    let (n_j, p_j, c, l, l2) = unsafe {
                        (
                            Vec3s::load_unchecked(normal, j),
                            Vec3s::load_unchecked(position, j),
                            F32s::load_unchecked(self.count, j),
                            F32s::load_unchecked(self.lum, j),
                            F32s::load_unchecked(self.lum2, j),
                        )
                    };
                    let g = self.edges.geometry(n_i, p_i, n_j, p_j);
                    wn += g * c;
                    w1 += g * l;
                    w2 += g * l2;
                }
                let pooled = sample_variance(wn, w1, w2);
                let l = luminance(Vec3s::load(&self.filled, i));
                let enough = wn.ge(F32s::splat(2.0));
                let spatial = F32s::select(enough, pooled, l * l);
                var = F32s::select(short, spatial, var);
            }
            let v = var / n.max(F32s::splat(1.0));
            store(&mut out[x0..w.min(x0 + WIDTH)], &v.0);
        }
    }
}
