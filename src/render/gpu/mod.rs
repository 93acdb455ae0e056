//! The GPU path tracer: the CPU kernel (`render::integrator`) ported to one WGSL compute
//! pass (`shaders/trace/`), which renders lists of pixels of a [`RenderScene`] and returns
//! the same [`PixelSample`]s' radiance as [`render_pixels`](crate::render::render_pixels):
//! demodulation-ready reflected radiance and directly seen emission, averaged over the
//! state's samples per pixel.
//!
//! Geometry is the CPU tracer's own acceleration structure (`accel::export`); lights and
//! the environment's CDFs are the CPU's tables; every random number is the CPU sampler's
//! (the 64-bit pixel seed is computed here, the rest in WGSL), so the two tracers draw the
//! same samples and differ only by floating-point rounding. One invocation renders one
//! pixel; a dispatch may hold the pixels of many jobs (each with its own frame's seeds),
//! which is how a GPU worker keeps the device full.
//!
//! Not filled in: the G-buffer fields of [`PixelSample`] (albedo, normal, position,
//! object): workers send reflected radiance only, and the master has its own G-buffer.
//!
//! Modules: [`pack`] (the scene as buffers).

pub mod pack;

use std::sync::Arc;

use glam::Vec3;
use wgpu::util::DeviceExt;

use super::{sampler, PixelSample, RenderScene, RenderStats, Strategy};
use crate::gpu::compute::{Binding, ComputePass};
use crate::gpu::readback::map_read_blocking;
use crate::gpu::{GpuContext, GpuError};
use pack::Params;

/// The trace pass's WGSL, assembled from its files in dependency order.
pub const WGSL: &str = concat!(
    include_str!("../../../shaders/trace/scene.wgsl"),
    include_str!("../../../shaders/trace/bvh.wgsl"),
    include_str!("../../../shaders/trace/material.wgsl"),
    include_str!("../../../shaders/trace/lights.wgsl"),
    include_str!("../../../shaders/trace/path.wgsl"),
);

/// The files of [`WGSL`], in order, relative to `shaders/trace/`.
pub const WGSL_FILES: [&str; 5] =
    ["scene.wgsl", "bvh.wgsl", "material.wgsl", "lights.wgsl", "path.wgsl"];

/// Invocations per workgroup (`GROUP` in `path.wgsl`).
const GROUP: u32 = 64;

/// The compiled trace pass on one device.
#[derive(Debug)]
pub struct GpuTracer {
    ctx: Arc<GpuContext>,
    pass: ComputePass,
}

/// A scene state uploaded for the trace pass.
#[derive(Debug)]
pub struct GpuScene {
    params: Params,
    words: wgpu::Buffer,
    texels: wgpu::Buffer,
    seed: u64,
    version: u64,
}

impl GpuScene {
    /// The scene-state version it was uploaded from.
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Dispatches from now on take `spp` samples per pixel (a job's own; the state's
    /// `render.spp` until then): nothing is uploaded again.
    pub fn set_spp(&mut self, spp: u32) {
        self.params.image[2] = spp.max(1);
    }
}

/// One job's pixels: its frame (which seeds its samples) and pixel indices.
#[derive(Clone, Copy, Debug)]
pub struct PixelBatch<'a> {
    pub frame: u64,
    pub pixels: &'a [u32],
}

impl GpuTracer {
    /// Compiles the trace pass.
    pub fn new(ctx: Arc<GpuContext>) -> Self {
        use Binding::{ReadBuffer as R, ReadWriteBuffer as RW, Uniform as U};
        let pass = ComputePass::new(&ctx.device, "path trace", WGSL, &[U, R, R, R, RW]);
        Self { ctx, pass }
    }

    /// The adapter's name, for reports.
    pub fn adapter(&self) -> &str {
        &self.ctx.adapter_info.name
    }

    /// Whether the adapter is a software rasteriser (Mesa's lavapipe).
    pub fn is_software(&self) -> bool {
        self.ctx.adapter_info.device_type == wgpu::DeviceType::Cpu
    }

    /// Uploads `scene` (its BVHs, materials, lights, environment, textures); refuses a
    /// scene with a material the WGSL tracer does not render (`pack::PackError`).
    pub fn upload(&self, scene: &RenderScene) -> Result<GpuScene, pack::PackError> {
        let packed = pack::pack(scene)?;
        let device = &self.ctx.device;
        let storage = |label: &str, contents: &[u8]| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        Ok(GpuScene {
            params: packed.params,
            words: storage("trace scene", bytemuck::cast_slice(&packed.words)),
            texels: storage("trace texels", bytemuck::cast_slice(&packed.texels)),
            seed: scene.state().seed,
            version: scene.state().version,
        })
    }

    /// Renders every batch's pixels (`out` is cleared and filled in batch, then pixel
    /// order) and returns the work done. Blocks until the device has finished.
    pub fn render(
        &self,
        scene: &GpuScene,
        batches: &[PixelBatch],
        strategy: Strategy,
        out: &mut Vec<PixelSample>,
    ) -> Result<RenderStats, GpuError> {
        out.clear();
        let mut inputs: Vec<[u32; 2]> = Vec::new();
        for b in batches {
            inputs
                .extend(b.pixels.iter().map(|&p| [p, sampler::pixel_seed(scene.seed, b.frame, p)]));
        }
        let count = inputs.len() as u32;
        if count == 0 {
            return Ok(RenderStats::default());
        }
        let device = &self.ctx.device;
        let mut params = scene.params;
        params.job = [count, u32::from(strategy == Strategy::NeeMis), 0, 0];
        let uniform = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("trace params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let pixels = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("trace pixels"),
            contents: bytemuck::cast_slice(&inputs),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let bytes = count as u64 * 2 * 16;
        let results = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace results"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("trace staging"),
            size: bytes,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let bind = self.pass.bind(
            device,
            &[
                uniform.as_entire_binding(),
                scene.words.as_entire_binding(),
                scene.texels.as_entire_binding(),
                pixels.as_entire_binding(),
                results.as_entire_binding(),
            ],
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        self.pass.encode_linear(&mut encoder, &bind, count.div_ceil(GROUP));
        encoder.copy_buffer_to_buffer(&results, 0, &staging, 0, bytes);
        self.ctx.queue.submit([encoder.finish()]);
        let slice = staging.slice(..);
        map_read_blocking(device, &slice)?;
        let mut stats = RenderStats::default();
        {
            let view = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let values: &[[f32; 4]] = bytemuck::cast_slice(&view);
            out.reserve(count as usize);
            for pair in values.chunks_exact(2) {
                let (r, e) = (pair[0], pair[1]);
                stats.rays += u64::from(r[3].to_bits());
                out.push(PixelSample {
                    reflected: Vec3::new(r[0], r[1], r[2]),
                    emission: Vec3::new(e[0], e[1], e[2]),
                    albedo: Vec3::ONE,
                    object: u32::MAX,
                    ..Default::default()
                });
            }
        }
        staging.unmap();
        stats.samples = u64::from(count) * u64::from(scene.params.image[2].max(1));
        Ok(stats)
    }
}
