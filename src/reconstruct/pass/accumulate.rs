//! The accumulate pass (first of every frame): adds this frame's samples to the running
//! average, restarted when the scene state changes; on the GPU the sums ping-pong
//! between two textures.

use glam::{Vec3, Vec4};
use rayon::prelude::*;

use crate::gpu::compute::{Binding, ComputePass};

/// WGSL: reads the samples and the previous sums, writes the new sums.
pub const WGSL: &str = include_str!("../../../shaders/reconstruct/accumulate.wgsl");

/// The GPU binding: the compiled pass with its bindings in `accumulate.wgsl`'s order.
pub fn gpu_pass(device: &wgpu::Device) -> ComputePass {
    use Binding::{Storage, Texture as T, Uniform as U};
    ComputePass::new(device, "accumulate", &super::with_common(WGSL), &[U, T, T, Storage(F32X4)])
}

const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Accumulates this frame's results. `reset` starts a new average (the scene state
/// changed); rgb is the sum, w the number of samples.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn accumulate_averages_and_resets() {
        let mut acc = vec![Vec4::ZERO; 2];
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[true, false], &mut acc, 2);
        accumulate(false, &[Vec3::splat(3.0), Vec3::ONE], &[true, true], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::new(4.0, 4.0, 4.0, 2.0), Vec4::new(1.0, 1.0, 1.0, 1.0)]);
        accumulate(true, &[Vec3::ONE, Vec3::ONE], &[false, false], &mut acc, 2);
        assert_eq!(acc, vec![Vec4::ZERO; 2]);
    }
}
