//! The wgpu instance, adapter, device and queue, created once and shared by the passes.
//!
//! No window is needed: reconstruction runs headless too. On machines without a GPU,
//! Mesa's lavapipe (software Vulkan) is an adapter like any other.

use std::sync::Arc;

/// Why the GPU could not be used.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter found: {0}")]
    NoAdapter(String),
    #[error("requesting a device from adapter `{adapter}` failed: {cause}")]
    RequestDevice { adapter: String, cause: String },
    #[error("the GPU does not support {0}")]
    Unsupported(String),
    #[error("reading results back from the GPU failed: {0}")]
    Readback(String),
    #[error("the GPU reported a validation error: {0}")]
    Validation(String),
}

/// A device and queue with what the passes need to know about the adapter.
#[derive(Debug)]
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter_info: wgpu::AdapterInfo,
    /// Whether GPU timestamps can be written at pass boundaries.
    pub timestamps: bool,
}

impl GpuContext {
    /// Opens the default adapter for `Auto` choices: `Err` when it is a software rasteriser
    /// (Mesa's lavapipe/llvmpipe), which runs the passes slower in wall time, uploads and
    /// readbacks included, than the multithreaded CPU reference (`gridlight bench
    /// reconstruct`: 183 ms against 36 ms per 640×480 frame on 2 cores).
    pub fn new_hardware() -> Result<Self, GpuError> {
        let ctx = Self::new()?;
        if ctx.is_software() {
            return Err(ctx.software());
        }
        Ok(ctx)
    }

    /// Opens the default adapter (the `WGPU_BACKEND` etc. environment variables apply).
    pub fn new() -> Result<Self, GpuError> {
        pollster::block_on(Self::open())
    }

    async fn open() -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        Self::check_storage(&adapter)?;
        Self::on_adapter(&adapter, "gridlight").await
    }

    /// `Err` unless `adapter` can write the `rgba32float` storage textures the
    /// reconstruction passes write.
    pub fn check_storage(adapter: &wgpu::Adapter) -> Result<(), GpuError> {
        let formats = adapter.get_texture_format_features(wgpu::TextureFormat::Rgba32Float);
        if !formats.allowed_usages.contains(wgpu::TextureUsages::STORAGE_BINDING) {
            return Err(GpuError::Unsupported(format!(
                "rgba32float storage textures on `{}`",
                adapter.get_info().name
            )));
        }
        Ok(())
    }

    /// Opens a device on `adapter` with what the passes use where it is offered
    /// (timestamps, the adapter's largest storage buffers). The window opens its device
    /// here too, so that the reconstruction can run on it (`crate::gpu::offer`).
    pub async fn on_adapter(adapter: &wgpu::Adapter, label: &str) -> Result<Self, GpuError> {
        let adapter_info = adapter.get_info();
        let timestamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
        let required_features =
            if timestamps { wgpu::Features::TIMESTAMP_QUERY } else { wgpu::Features::empty() };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some(label),
                required_features,
                // Storage buffers as large as the adapter allows: the GPU path tracer's
                // scene is one buffer, larger than the default 128 MiB for big meshes.
                required_limits: wgpu::Limits {
                    max_storage_buffer_binding_size: adapter
                        .limits()
                        .max_storage_buffer_binding_size,
                    max_buffer_size: adapter.limits().max_buffer_size,
                    ..wgpu::Limits::default().using_resolution(adapter.limits())
                },
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::RequestDevice {
                adapter: adapter_info.name.clone(),
                cause: e.to_string(),
            })?;
        tracing::debug!(adapter = %adapter_info.name, backend = ?adapter_info.backend, timestamps, "GPU context");
        Ok(Self { device, queue, adapter_info, timestamps })
    }

    /// Why `Auto` choices pass over this (software) adapter.
    pub fn software(&self) -> GpuError {
        GpuError::NoAdapter(format!(
            "{} is a software adapter; the CPU path is faster",
            self.adapter_info.name
        ))
    }

    /// Whether the adapter is a software rasteriser (Mesa's lavapipe/llvmpipe), where the
    /// CPU reconstruction is faster ([`GpuContext::new_hardware`]).
    pub fn is_software(&self) -> bool {
        self.adapter_info.device_type == wgpu::DeviceType::Cpu
    }

    /// Shared handle for several passes.
    pub fn shared(self) -> Arc<Self> {
        Arc::new(self)
    }
}
