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
