//! GPU side of the master: the wgpu context, the reconstruction compute passes and the
//! G-buffer raster pass. WGSL sources live in `shaders/` and are compiled in.

pub mod compute;
pub mod context;
pub mod gbuffer;
mod raster;
pub mod readback;
pub mod reconstruct;
pub mod shaders;

pub use context::{GpuContext, GpuError};
pub use gbuffer::GpuGBuffer;
pub use reconstruct::GpuReconstructor;

/// A 2-D texture (array of `layers`) without mipmaps or multisampling: every texture the
/// passes make.
pub(crate) fn texture_2d(
    device: &wgpu::Device,
    label: &str,
    (width, height, layers): (u32, u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    })
}
