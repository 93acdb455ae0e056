//! The remodulate pass (last of every frame): multiplies the albedo back in, adds the
//! directly seen emission (linear colour, kept for EXR) and tonemaps for display (8-bit
//! sRGB RGBA, the curve of `image_io::display_pixel`).

use glam::Vec3;

use crate::gpu::compute::{Binding, ComputePass};
use crate::reconstruct::planes::{view, Layout, Planes3, View3};
use crate::reconstruct::rows::{load, run_rows, store, RowKernel};
use crate::reconstruct::tonemap::{exposure_scale, to_rgba8_lanes};
use crate::render::isa::Isa;
use crate::render::lanes::{Vec3s, WIDTH};

use super::PassConsts;

/// WGSL: writes the linear colour and the display image.
pub const WGSL: &str = include_str!("../../../shaders/reconstruct/remodulate.wgsl");

/// The GPU binding: the compiled pass with its bindings in `remodulate.wgsl`'s order.
pub fn gpu_pass(device: &wgpu::Device) -> ComputePass {
    use Binding::{Storage, Texture as T, Uniform as U};
    ComputePass::new(
        device,
        "remodulate",
        &super::with_common(WGSL),
        &[U, T, T, T, Storage(F32X4), Storage(DISPLAY)],
    )
}

const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Format of the display image.
pub const DISPLAY: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// Where [`remodulate`] writes, one entry per pixel (row-major).
pub struct Outputs<'a> {
    pub radiance: &'a mut [Vec3],
    pub colour: &'a mut [Vec3],
    pub display: &'a mut [[u8; 4]],
}

/// Remodulates the albedo, adds the directly seen emission (linear colour) and
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
        for x0 in (0..w).step_by(WIDTH) {
            // WIDTH pixels at a time (the row's last chunk padded), so that the filmic
            // curve vectorises.
            let x1 = w.min(x0 + WIDTH);
            let l = Vec3s::<I>::load(&self.radiance, base + x0).to_vec3s();
            let albedo = load(&self.albedo[y * w + x0..y * w + x1], Vec3::ZERO);
            let emission = load(&self.emission[y * w + x0..y * w + x1], Vec3::ZERO);
            let c: [Vec3; WIDTH] = std::array::from_fn(|k| albedo[k] * l[k] + emission[k]);
            store(&mut radiance[x0..x1], &l);
            store(&mut colour[x0..x1], &c);
            store(&mut display[x0..x1], &to_rgba8_lanes(&c, self.scale));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reconstruct::pass::testing::{consts, planes};
    use crate::reconstruct::tonemap::to_rgba8;

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
