//! Where the GPU reconstruction's last pass writes: the linear colour and the display
//! image of one frame, in textures of their own, so that a frame handed to the window
//! ([`super::DeviceImage`]) stays intact while later frames are reconstructed.
//!
//! The pool hands out a target nobody else holds; one still held (the window shows it,
//! or it waits in the window's slot) is never written. A target comes back to the pool
//! when its last holder drops it: the window does so only after it submitted the draw
//! that sampled it, so on the one shared queue the next frame's writes come after that
//! draw (ARCHITECTURE.md, "One device on the master").

use std::sync::Arc;

use super::pass::remodulate::DISPLAY;

/// The display image read as sRGB: for a window whose surface is sRGB-encoded.
pub const DISPLAY_SRGB: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

/// One frame's outputs of the remodulate pass, with the bind groups that write them.
#[derive(Debug)]
pub struct DisplayTarget {
    /// Final linear colour (albedo · radiance + emission), `rgba32float`.
    pub colour: wgpu::Texture,
    /// Tonemapped sRGB bytes, [`DISPLAY`] (viewable as [`DISPLAY_SRGB`]).
    pub display: wgpu::Texture,
    /// Remodulate's bind groups into this target: `[0]` from the filtered radiance,
    /// `[1]` from the filled one.
    pub remodulate: [wgpu::BindGroup; 2],
}

impl DisplayTarget {
    /// Textures for `width`×`height` frames; `bind` makes remodulate's two bind groups
    /// given the colour and display views.
    fn new(
        device: &wgpu::Device,
        (width, height): (u32, u32),
        bind: &dyn Fn(&wgpu::TextureView, &wgpu::TextureView) -> [wgpu::BindGroup; 2],
    ) -> Self {
        use wgpu::TextureUsages as U;
        let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
        let make = |label, format, view_formats: &[wgpu::TextureFormat], usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats,
            })
        };
        let colour =
            make("colour", wgpu::TextureFormat::Rgba32Float, &[], U::STORAGE_BINDING | U::COPY_SRC);
        let display = make(
            "display",
            DISPLAY,
            &[DISPLAY_SRGB],
            U::STORAGE_BINDING | U::COPY_SRC | U::TEXTURE_BINDING,
        );
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let remodulate = bind(&view(&colour), &view(&display));
        Self { colour, display, remodulate }
    }
}

/// The targets of one frame size.
#[derive(Debug, Default)]
pub struct TargetPool {
    targets: Vec<Arc<DisplayTarget>>,
}

/// More targets than a window can hold at once (shown, waiting, being written): a
/// holder that never lets go, worth a log line.
const EXPECTED_AT_MOST: usize = 4;

impl TargetPool {
    /// A target that nobody outside the pool holds, made when every one is held.
    pub fn free(
        &mut self,
        device: &wgpu::Device,
        size: (u32, u32),
        bind: &dyn Fn(&wgpu::TextureView, &wgpu::TextureView) -> [wgpu::BindGroup; 2],
    ) -> Arc<DisplayTarget> {
        if let Some(t) = self.targets.iter().find(|t| Arc::strong_count(t) == 1) {
            return Arc::clone(t);
        }
        let target = Arc::new(DisplayTarget::new(device, size, bind));
        self.targets.push(Arc::clone(&target));
        if self.targets.len() > EXPECTED_AT_MOST {
            tracing::warn!(
                targets = self.targets.len(),
                "display targets held longer than expected"
            );
        }
        target
    }

    /// Forgets every target (the frame size changed); holders keep theirs alive.
    pub fn clear(&mut self) {
        self.targets.clear();
    }
}
