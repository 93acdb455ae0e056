//! A reconstructed frame left on the device: what the window draws without a read-back
//! when the reconstruction runs on its device (ARCHITECTURE.md, "One device on the
//! master"). Its textures are not written again while the value lives
//! ([`super::display_target`]); reading it back is for the rare consumer that needs
//! pixels on the CPU (a screenshot, a headless sink given one).

use std::sync::Arc;

use glam::Vec3;
use gridlight_actors::protocol::FrameNo;

use super::display_target::DisplayTarget;
use super::Mode;
use crate::gpu::readback::Staging;
use crate::gpu::{GpuContext, GpuError};

/// One reconstructed frame in textures of the reconstruction's device.
#[derive(Clone, Debug)]
pub struct DeviceImage {
    target: Arc<DisplayTarget>,
    ctx: Arc<GpuContext>,
    pub frame: FrameNo,
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
}

impl DeviceImage {
    pub(super) fn new(
        target: Arc<DisplayTarget>,
        ctx: Arc<GpuContext>,
        frame: FrameNo,
        mode: Mode,
    ) -> Self {
        let size = target.display.size();
        Self { target, ctx, frame, mode, width: size.width, height: size.height }
    }

    /// The display image: tonemapped sRGB bytes in an `rgba8unorm` texture (viewable as
    /// `rgba8unorm-srgb`, [`super::display_target::DISPLAY_SRGB`]).
    pub fn display(&self) -> &wgpu::Texture {
        &self.target.display
    }

    /// Whether this image lives on `device` (the window only draws it there).
    pub fn is_on(&self, device: &wgpu::Device) -> bool {
        &self.ctx.device == device
    }

    /// Copies the display image and the linear colour back to the CPU.
    pub fn read_back(&self) -> Result<(Vec<[u8; 4]>, Vec<Vec3>), GpuError> {
        let (device, (w, h)) = (&self.ctx.device, (self.width, self.height));
        let display = Staging::new(device, "display readback", w, h, 4);
        let colour = Staging::new(device, "colour readback", w, h, 16);
        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("read back") });
        display.copy_from(&mut encoder, &self.target.display);
        colour.copy_from(&mut encoder, &self.target.colour);
        self.ctx.queue.submit([encoder.finish()]);
        Ok((display.read_rgba8(device)?, colour.read_vec3(device)?))
    }
}
