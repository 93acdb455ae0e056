//! The temporal pass (while interacting): blends each pixel with its filled values in
//! the previous frames, weighted by the temporal D (same pixel, that frame's G-buffer)
//! times w = 1/(F_i − F_j); the current frame has w = 1.

use crate::gpu::compute::{Binding, ComputePass};
use crate::reconstruct::discontinuity::Thresholds;
use crate::reconstruct::params::MAX_HISTORY;
use crate::reconstruct::planes::{normalise, view, write_rows, GuidePlanes, GuideView, Layout};
use crate::reconstruct::planes::{PlaneRow, Planes3, View3};
use crate::reconstruct::rows::RowKernel;
use crate::render::isa::Isa;
use crate::render::lanes::{F32s, Vec3s, WIDTH};

use super::PassConsts;

/// WGSL: past frames are texture-array layers.
pub const WGSL: &str = include_str!("../../../shaders/reconstruct/temporal.wgsl");

/// The GPU binding: the compiled pass with its bindings in `temporal.wgsl`'s order.
pub fn gpu_pass(device: &wgpu::Device) -> ComputePass {
    use Binding::{Storage, Texture as T, TextureArray as A, Uniform as U};
    ComputePass::new(
        device,
        "temporal",
        &super::with_common(WGSL),
        &[U, T, T, T, A, A, A, Storage(F32X4)],
    )
}

const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// One previous frame as the temporal filter sees it.
#[derive(Clone, Copy)]
pub struct PastFrame<'a> {
    /// Weight w = 1/(F_i − F_j); 0 disables the slot.
    pub weight: f32,
    /// Its filled radiance.
    pub radiance: &'a Planes3,
    pub guide: &'a GuidePlanes,
}

/// Blends each pixel with its values in previous frames (see the module doc).
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

/// Chunks of [`WIDTH`] pixels that the temporal filter blends together, one past frame
/// after the other: a few long runs through each frame's planes, which the hardware
/// prefetchers follow, rather than a dozen planes at every pixel. 64 runs of 16 lanes:
/// 1024 pixels, whose sums (16 KiB) stay in the L1 cache.
const SEGMENT: usize = 64;

impl RowKernel<PlaneRow<'_>> for TemporalPass<'_> {
    type Scratch = ();

    fn scratch(&self) {}

    #[inline(always)]
    fn row<I: Isa>(&self, y: usize, mut out: PlaneRow<'_>, _: &mut ()) {
        let (w, base) = (self.layout.width, self.layout.index(0, y));
        let (normal, position) = (&self.guide.normal, &self.guide.position);
        for start in (0..w).step_by(WIDTH * SEGMENT) {
            let chunks = (start..w.min(start + WIDTH * SEGMENT)).step_by(WIDTH);
            // (Σ w·D·L, Σ w·D) of each chunk, the current frame first.
            let mut acc = [(Vec3s::<I>::default(), F32s::default()); SEGMENT];
            for ((sum, wsum), x0) in acc.iter_mut().zip(chunks.clone()) {
                let i = base + x0;
                let (n, z) =
                    (Vec3s::load(normal, i).to_array(), Vec3s::load(position, i).to_array());
                let d0 = self.d.d3(n, n, z, z);
                (*sum, *wsum) = (Vec3s::load(&self.current, i).scale(d0), d0);
            }
            for (weight, radiance, guide) in &self.past {
                for ((sum, wsum), x0) in acc.iter_mut().zip(chunks.clone()) {
                    let i = base + x0;
                    let (n, z) = (Vec3s::load(normal, i), Vec3s::load(position, i));
                    let (n_j, z_j) =
                        (Vec3s::load(&guide.normal, i), Vec3s::load(&guide.position, i));
                    let (n, z, n_j, z_j) =
                        (n.to_array(), z.to_array(), n_j.to_array(), z_j.to_array());
                    let dw = self.d.d3(n, n_j, z, z_j) * F32s::splat(*weight);
                    *sum += Vec3s::load(radiance, i).scale(dw);
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

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::reconstruct::pass::testing::{consts, flat, planes, setup};
    use crate::reconstruct::planes::at;

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
}
