//! Device plumbing of the master's GPU work: the wgpu context, the [`Backend`] choice,
//! compute passes as small structs, readback and textures, and the device the window
//! offers the reconstruction (`offer`). It knows no pass: the passes and their WGSL live
//! with their owners (`crate::reconstruct::pass`, `crate::gbuffer`).

mod backend;
pub mod compute;
pub mod context;
pub mod offer;
pub mod readback;

pub use backend::Backend;
pub use context::{GpuContext, GpuError};
pub use offer::DeviceOffer;

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
