//! Copying textures back to the CPU: rows padded to wgpu's 256-byte alignment in a
//! staging buffer, mapped after the queue has finished.

use std::sync::mpsc;

use super::GpuError;

/// Bytes per row of a texel copy, rounded up to `COPY_BYTES_PER_ROW_ALIGNMENT`.
pub fn padded_row(width: u32, texel_bytes: u32) -> u32 {
    (width * texel_bytes).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
        * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

/// Maps `slice` for reading and waits until the device has finished with it.
pub fn map_read_blocking(device: &wgpu::Device, slice: &wgpu::BufferSlice) -> Result<(), GpuError> {
    let (tx, rx) = mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        // The receiver outlives the poll below; a failed send only means it gave up.
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|e| GpuError::Readback(e.to_string()))?
        .map_err(|e| GpuError::Readback(e.to_string()))
}

/// A staging buffer sized for one texture of the given texel size.
#[derive(Debug)]
pub struct Staging {
    pub buffer: wgpu::Buffer,
    width: u32,
    height: u32,
    texel_bytes: u32,
}

impl Staging {
    pub fn new(
        device: &wgpu::Device,
        label: &str,
        width: u32,
        height: u32,
        texel_bytes: u32,
    ) -> Self {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: padded_row(width, texel_bytes) as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self { buffer, width, height, texel_bytes }
    }

    /// Records the copy of `texture` (mip 0, layer 0) into this buffer.
    pub fn copy_from(&self, encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture) {
        encoder.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(padded_row(self.width, self.texel_bytes)),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
    }

    /// Maps the buffer (the copy must have been submitted), hands the unpadded rows to
    /// `f` one by one and unmaps.
    pub fn read(
        &self,
        device: &wgpu::Device,
        mut f: impl FnMut(usize, &[u8]),
    ) -> Result<(), GpuError> {
        let slice = self.buffer.slice(..);
        map_read_blocking(device, &slice)?;
        {
            let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let stride = padded_row(self.width, self.texel_bytes) as usize;
            let row_bytes = (self.width * self.texel_bytes) as usize;
            for y in 0..self.height as usize {
                f(y, &view[y * stride..y * stride + row_bytes]);
            }
        }
        self.buffer.unmap();
        Ok(())
    }

    /// [`Staging::read`] of an `rgba32float` copy: each texel's RGB.
    pub fn read_vec3(&self, device: &wgpu::Device) -> Result<Vec<glam::Vec3>, GpuError> {
        let w = self.width as usize;
        let mut out = vec![glam::Vec3::ZERO; w * self.height as usize];
        self.read(device, |y, row| {
            let texels: &[[f32; 4]] = bytemuck::cast_slice(row);
            for (o, t) in out[y * w..(y + 1) * w].iter_mut().zip(texels) {
                *o = glam::Vec3::new(t[0], t[1], t[2]);
            }
        })?;
        Ok(out)
    }

    /// [`Staging::read`] of an `rgba8` copy: each texel's four bytes.
    pub fn read_rgba8(&self, device: &wgpu::Device) -> Result<Vec<[u8; 4]>, GpuError> {
        let w = self.width as usize;
        let mut out = vec![[0; 4]; w * self.height as usize];
        self.read(device, |y, row| {
            for (o, t) in out[y * w..(y + 1) * w].iter_mut().zip(row.chunks_exact(4)) {
                *o = [t[0], t[1], t[2], t[3]];
            }
        })?;
        Ok(out)
    }
}
