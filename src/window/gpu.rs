//! The window's wgpu context: instance, surface, adapter, device and the surface
//! configuration, with resizing and frame acquisition.
//!
//! Created on the event-loop thread once the window exists. The device is opened the way
//! the reconstruction opens its own ([`GpuContext::on_adapter`]), so that the compose
//! thread can reconstruct on it and the window draw its textures directly
//! (`crate::gpu::offer`). On machines without a GPU,
//! Mesa's lavapipe (software Vulkan) is picked by default; `WGPU_BACKEND=vulkan|gl` overrides
//! the backend (the GL backend, llvmpipe, lacks float32 filtering, so prefer Vulkan).

use std::sync::Arc;

use thiserror::Error;
use winit::window::Window;

use crate::gpu::{GpuContext, GpuError};

/// Why the window could not get a GPU surface.
#[derive(Debug, Error)]
pub enum SurfaceError {
    #[error("cannot create a wgpu surface for the window: {0}")]
    Surface(#[from] wgpu::CreateSurfaceError),
    #[error("no graphics adapter can present to this window: {0}")]
    Adapter(#[from] wgpu::RequestAdapterError),
    #[error("cannot open the graphics device: {0}")]
    Device(#[from] GpuError),
    #[error("the adapter offers no surface format for this window")]
    NoFormat,
}

/// GPU state tied to one window.
pub struct Gpu {
    pub surface: wgpu::Surface<'static>,
    /// Device, queue and adapter (name and backend for the status panel and the log).
    pub ctx: Arc<GpuContext>,
    pub config: wgpu::SurfaceConfiguration,
    /// Whether the reconstruction can run on this device (`GpuContext::check_storage`).
    pub reconstructs: bool,
    /// A suboptimal texture was handed out: reconfigure before the next acquisition
    /// (wgpu refuses to configure while a surface texture is alive).
    stale: bool,
}

/// What acquiring the next surface texture gave.
pub enum Acquired {
    Frame(wgpu::SurfaceTexture),
    /// Nothing to draw into this time (occluded, timed out, reconfigured): try again later.
    Skip,
}

impl Gpu {
    /// Creates a surface for `window` and a device that can present to it.
    pub fn new(window: Arc<Window>) -> Result<Self, SurfaceError> {
        let size = window.inner_size();
        let display: Box<dyn wgpu::wgt::WgpuHasDisplayHandle> = Box::new(Arc::clone(&window));
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle_from_env(display),
        );
        let surface = instance.create_surface(Arc::clone(&window))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            ..Default::default()
        }))?;
        let ctx =
            pollster::block_on(GpuContext::on_adapter(&adapter, "gridlight window"))?.shared();
        let reconstructs = GpuContext::check_storage(&adapter).is_ok();
        let caps = surface.get_capabilities(&adapter);
        // egui draws best into a non-sRGB target; the picture's texture follows suit.
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .ok_or(SurfaceError::NoFormat)?;
        let alpha_mode =
            caps.alpha_modes.first().copied().unwrap_or(wgpu::CompositeAlphaMode::Auto);
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            format,
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: wgpu::PresentMode::AutoVsync,
            desired_maximum_frame_latency: 2,
            alpha_mode,
            view_formats: vec![],
            color_space: wgpu::SurfaceColorSpace::Auto,
        };
        surface.configure(&ctx.device, &config);
        tracing::info!(
            adapter = %ctx.adapter_info.name,
            backend = ?ctx.adapter_info.backend,
            format = ?format,
            "window surface ready"
        );
        Ok(Self { surface, ctx, config, reconstructs, stale: false })
    }

    /// Follows a window resize; a zero-sized window (minimised) keeps the old size.
    pub fn resize(&mut self, width: u32, height: u32) {
        if width == 0 || height == 0 {
            return;
        }
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.ctx.device, &self.config);
    }

    /// The next texture to draw into, reconfiguring the surface when it went stale.
    pub fn acquire(&mut self) -> Acquired {
        if std::mem::take(&mut self.stale) {
            self.surface.configure(&self.ctx.device, &self.config);
        }
        match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame) => Acquired::Frame(frame),
            wgpu::CurrentSurfaceTexture::Suboptimal(frame) => {
                // Draw this one; the next acquisition gets a matching configuration (not
                // now: configuring while `frame` lives is a validation error, which
                // panicked the window during a resize).
                self.stale = true;
                Acquired::Frame(frame)
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.ctx.device, &self.config);
                Acquired::Skip
            }
            wgpu::CurrentSurfaceTexture::Timeout
            | wgpu::CurrentSurfaceTexture::Occluded
            | wgpu::CurrentSurfaceTexture::Validation => Acquired::Skip,
        }
    }
}
