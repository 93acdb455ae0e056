//! The reconstruction pipeline on the GPU: the passes of `super::pass` (each with its
//! WGSL and binding) over textures kept on the device; the same steps and maths as the CPU
//! reference (`super::cpu`).
//!
//! Per frame: upload this frame's samples (and the G-buffer when the scene state changed),
//! then accumulate → fill → [temporal → Gaussian while interacting] → remodulate, copy the
//! filled radiance and G-buffer into the history layers, and read the results back
//! ([`GpuReconstructor::reconstruct`]) or leave them on the device for a window that
//! shares it ([`GpuReconstructor::reconstruct_on_device`]). Running sums ping-pong
//! between two textures; history lives in texture arrays; each frame's colour and
//! display image go to a target of their own (`display_target`).
//!
//! With `--reconstruction svgf` the SVGF passes (`svgf::gpu`) take the place of
//! accumulate, temporal and Gaussian; uploads, fill, remodulate, targets and read-back
//! stay the same.

use std::sync::Arc;

use super::device_image::DeviceImage;
use super::display_target::{DisplayTarget, TargetPool};
use super::history::HistoryRing;
use super::params::MAX_HISTORY;
use super::pass::{self, PassConsts, Uniforms};
use super::svgf::gpu::{Shared, SvgfGpu};
use super::svgf::Method;
use super::{FrameInputs, Mode, ReconstructError, ReconstructParams, Reconstructed};
use crate::gbuffer::NO_OBJECT;
use crate::gpu::compute::ComputePass;
use crate::gpu::readback::{map_read_blocking, Staging};
use crate::gpu::{GpuContext, GpuError};

const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// Every texture of the pipeline, sized for one resolution.
#[derive(Debug)]
struct Textures {
    samples: wgpu::Texture,
    normal: wgpu::Texture,
    position: wgpu::Texture,
    albedo: wgpu::Texture,
    emission: wgpu::Texture,
    sums: [wgpu::Texture; 2],
    filled: wgpu::Texture,
    blended: wgpu::Texture,
    filtered: wgpu::Texture,
    past_radiance: wgpu::Texture,
    past_normal: wgpu::Texture,
    past_position: wgpu::Texture,
}

impl Textures {
    fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        use wgpu::TextureUsages as U;
        let make = |label: &str, format, layers: u32, usage| {
            crate::gpu::texture_2d(device, label, (width, height, layers), format, usage)
        };
        let input = U::TEXTURE_BINDING | U::COPY_DST | U::COPY_SRC;
        let work = U::TEXTURE_BINDING | U::STORAGE_BINDING | U::COPY_SRC;
        let past = U::TEXTURE_BINDING | U::COPY_DST;
        Self {
            samples: make("samples", F32X4, 1, input),
            normal: make("normal", F32X4, 1, input),
            position: make("position", F32X4, 1, input),
            albedo: make("albedo", F32X4, 1, input),
            emission: make("emission", F32X4, 1, input),
            sums: [make("sums 0", F32X4, 1, work), make("sums 1", F32X4, 1, work)],
            filled: make("filled", F32X4, 1, work),
            blended: make("blended", F32X4, 1, work),
            filtered: make("filtered", F32X4, 1, work),
            past_radiance: make("past radiance", F32X4, MAX_HISTORY, past),
            past_normal: make("past normal", F32X4, MAX_HISTORY, past),
            past_position: make("past position", F32X4, MAX_HISTORY, past),
        }
    }

    /// Remodulate's bind groups into a target's `colour` and `display` views: `[0]` from
    /// the filtered radiance, `[1]` from the filled one.
    /// What the SVGF passes share with the paper's.
    fn shared(&self) -> Shared<'_> {
        Shared {
            normal: &self.normal,
            position: &self.position,
            samples: &self.samples,
            filled: &self.filled,
            images: [&self.blended, &self.filtered],
        }
    }

    fn remodulate(
        &self,
        device: &wgpu::Device,
        pass: &ComputePass,
        uniforms: &wgpu::Buffer,
        colour: &wgpu::TextureView,
        display: &wgpu::TextureView,
    ) -> [wgpu::BindGroup; 2] {
        use wgpu::BindingResource::TextureView as V;
        let (albedo, emission) = (view(&self.albedo), view(&self.emission));
        let bind = |src: &wgpu::TextureView| {
            pass.bind(
                device,
                &[
                    uniforms.as_entire_binding(),
                    V(src),
                    V(&albedo),
                    V(&emission),
                    V(colour),
                    V(display),
                ],
            )
        };
        [bind(&view(&self.filtered)), bind(&view(&self.filled))]
    }
}

fn view(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&wgpu::TextureViewDescriptor::default())
}

fn array_view(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    })
}

/// The five passes.
#[derive(Debug)]
struct Passes {
    accumulate: ComputePass,
    fill: ComputePass,
    temporal: ComputePass,
    gaussian: ComputePass,
    remodulate: ComputePass,
}

impl Passes {
    fn new(device: &wgpu::Device) -> Self {
        Self {
            accumulate: pass::accumulate::gpu_pass(device),
            fill: pass::fill::gpu_pass(device),
            temporal: pass::temporal::gpu_pass(device),
            gaussian: pass::gaussian::gpu_pass(device),
            remodulate: pass::remodulate::gpu_pass(device),
        }
    }
}

/// Bind groups for one set of textures; index `[p]` is the ping-pong parity. Remodulate's
/// are per display target ([`Textures::remodulate`]).
#[derive(Debug)]
struct BindGroups {
    accumulate: [wgpu::BindGroup; 2],
    fill: [wgpu::BindGroup; 2],
    temporal: wgpu::BindGroup,
    gaussian: wgpu::BindGroup,
}

impl BindGroups {
    fn new(device: &wgpu::Device, p: &Passes, t: &Textures, uniforms: &wgpu::Buffer) -> Self {
        use wgpu::BindingResource::TextureView as V;
        let u = || uniforms.as_entire_binding();
        let (normal, position) = (view(&t.normal), view(&t.position));
        let sums = [view(&t.sums[0]), view(&t.sums[1])];
        let (samples, filled, blended, filtered) =
            (view(&t.samples), view(&t.filled), view(&t.blended), view(&t.filtered));
        let accumulate =
            |k: usize| p.accumulate.bind(device, &[u(), V(&samples), V(&sums[k]), V(&sums[1 - k])]);
        let fill = |k: usize| {
            p.fill.bind(device, &[u(), V(&sums[1 - k]), V(&normal), V(&position), V(&filled)])
        };
        let (past_radiance, past_normal, past_position) = (
            array_view(&t.past_radiance),
            array_view(&t.past_normal),
            array_view(&t.past_position),
        );
        Self {
            accumulate: [accumulate(0), accumulate(1)],
            fill: [fill(0), fill(1)],
            temporal: p.temporal.bind(
                device,
                &[
                    u(),
                    V(&filled),
                    V(&normal),
                    V(&position),
                    V(&past_radiance),
                    V(&past_normal),
                    V(&past_position),
                    V(&blended),
                ],
            ),
            gaussian: p
                .gaussian
                .bind(device, &[u(), V(&blended), V(&normal), V(&position), V(&filtered)]),
        }
    }
}

/// GPU timestamps around the whole pipeline, where the adapter supports them.
#[derive(Debug)]
struct Timer {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    staging: wgpu::Buffer,
    period_ns: f32,
}

impl Timer {
    fn new(ctx: &GpuContext) -> Option<Self> {
        if !ctx.timestamps {
            return None;
        }
        let d = &ctx.device;
        Some(Self {
            queries: d.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("reconstruct timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            }),
            resolve: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp resolve"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            staging: d.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamp staging"),
                size: 16,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            period_ns: ctx.queue.get_timestamp_period(),
        })
    }

    fn read_ms(&self, device: &wgpu::Device) -> Result<f64, GpuError> {
        let slice = self.staging.slice(..);
        map_read_blocking(device, &slice)?;
        let ticks = {
            let v = slice.get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let t: &[u64] = bytemuck::cast_slice(&v[..16]);
            t[1].saturating_sub(t[0])
        };
        self.staging.unmap();
        Ok(ticks as f64 * self.period_ns as f64 * 1e-6)
    }
}

/// Reconstructs frames of one size on the GPU, keeping sums and history on the device.
#[derive(Debug)]
pub struct GpuReconstructor {
    ctx: Arc<GpuContext>,
    width: u32,
    height: u32,
    params: ReconstructParams,
    ring: HistoryRing,
    /// Ping-pong parity of the running sums.
    parity: usize,
    /// State version whose G-buffer is on the device (the G-buffer is a function of it).
    gbuffer_version: Option<u64>,
    uniforms: wgpu::Buffer,
    passes: Passes,
    textures: Textures,
    groups: BindGroups,
    /// The SVGF passes, with `--reconstruction svgf`.
    svgf: Option<Box<SvgfGpu>>,
    /// Colour and display images of frames, one per frame still held by someone.
    targets: TargetPool,
    staging: [Staging; 3],
    timer: Option<Timer>,
    last_gpu_ms: Option<f64>,
    /// Frames whose results were copied back to the CPU ([`GpuReconstructor::read_backs`]).
    read_backs: u64,
}

impl GpuReconstructor {
    pub fn new(
        ctx: Arc<GpuContext>,
        width: u32,
        height: u32,
        params: ReconstructParams,
    ) -> Result<Self, ReconstructError> {
        params.validate()?;
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("reconstruct params"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let passes = Passes::new(device);
        let textures = Textures::new(device, width, height);
        let groups = BindGroups::new(device, &passes, &textures, &uniforms);
        let svgf = Self::svgf(device, &params, (width, height), &passes, &uniforms, &textures);
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Validation(err.to_string()).into());
        }
        let staging = Self::stagings(device, width, height);
        let timer = Timer::new(&ctx);
        Ok(Self {
            width,
            height,
            params,
            ring: HistoryRing::new(params.history),
            parity: 0,
            gbuffer_version: None,
            uniforms,
            passes,
            textures,
            groups,
            svgf,
            targets: TargetPool::default(),
            staging,
            timer,
            last_gpu_ms: None,
            read_backs: 0,
            ctx,
        })
    }

    /// The SVGF passes when `params` ask for them.
    fn svgf(
        device: &wgpu::Device,
        params: &ReconstructParams,
        size: (u32, u32),
        passes: &Passes,
        uniforms: &wgpu::Buffer,
        textures: &Textures,
    ) -> Option<Box<SvgfGpu>> {
        (params.method == Method::Svgf).then(|| {
            let shared = textures.shared();
            Box::new(SvgfGpu::new(device, params.svgf, size, &passes.fill, uniforms, &shared))
        })
    }

    fn stagings(device: &wgpu::Device, width: u32, height: u32) -> [Staging; 3] {
        [
            Staging::new(device, "radiance readback", width, height, 16),
            Staging::new(device, "colour readback", width, height, 16),
            Staging::new(device, "display readback", width, height, 4),
        ]
    }

    /// Changes the frame size: new textures, and accumulation and history start over.
    pub fn resize(&mut self, width: u32, height: u32) {
        let device = &self.ctx.device;
        self.textures = Textures::new(device, width, height);
        self.groups = BindGroups::new(device, &self.passes, &self.textures, &self.uniforms);
        let (p, u, t) = (&self.passes, &self.uniforms, &self.textures);
        self.svgf = Self::svgf(device, &self.params, (width, height), p, u, t);
        self.staging = Self::stagings(device, width, height);
        self.targets.clear();
        (self.width, self.height) = (width, height);
        self.ring = HistoryRing::new(self.params.history);
        self.gbuffer_version = None;
    }

    pub fn adapter_name(&self) -> &str {
        &self.ctx.adapter_info.name
    }

    /// Frames whose results were read back to the CPU so far: one per
    /// [`GpuReconstructor::reconstruct`], none for [`GpuReconstructor::reconstruct_on_device`].
    pub fn read_backs(&self) -> u64 {
        self.read_backs
    }

    /// The device the pipeline runs on.
    pub fn context(&self) -> &Arc<GpuContext> {
        &self.ctx
    }

    /// GPU time of the last frame's passes in milliseconds (timestamps), if supported;
    /// only read-back frames measure it (reading the timestamps is a read-back too).
    pub fn last_gpu_ms(&self) -> Option<f64> {
        self.last_gpu_ms
    }

    /// Runs the pipeline on one frame and reads its results back.
    pub fn reconstruct(&mut self, inputs: &FrameInputs) -> Result<Reconstructed, ReconstructError> {
        let (target, mode, mut encoder) = self.encode(inputs)?;
        let result = match mode {
            _ if self.svgf.is_some() => &self.textures.filtered,
            Mode::Interacting => &self.textures.filtered,
            Mode::Accumulating { .. } => &self.textures.filled,
        };
        self.staging[0].copy_from(&mut encoder, result);
        self.staging[1].copy_from(&mut encoder, &target.colour);
        self.staging[2].copy_from(&mut encoder, &target.display);
        if let Some(t) = &self.timer {
            encoder.resolve_query_set(&t.queries, 0..2, &t.resolve, 0);
            encoder.copy_buffer_to_buffer(&t.resolve, 0, &t.staging, 0, 16);
        }
        self.ctx.queue.submit([encoder.finish()]);
        self.read_back(inputs.frame, mode)
    }

    /// Runs the pipeline on one frame and leaves its colour and display image on the
    /// device: nothing is copied back.
    pub fn reconstruct_on_device(
        &mut self,
        inputs: &FrameInputs,
    ) -> Result<DeviceImage, ReconstructError> {
        let (target, mode, encoder) = self.encode(inputs)?;
        self.ctx.queue.submit([encoder.finish()]);
        self.last_gpu_ms = None;
        Ok(DeviceImage::new(target, Arc::clone(&self.ctx), inputs.frame, mode))
    }

    /// Uploads one frame's inputs and records its passes and history copies into a new
    /// encoder, not yet submitted; returns the target written and the frame's mode (the
    /// reconstructed radiance is `filtered` while interacting or with SVGF, else `filled`).
    fn encode(
        &mut self,
        inputs: &FrameInputs,
    ) -> Result<(Arc<DisplayTarget>, Mode, wgpu::CommandEncoder), ReconstructError> {
        inputs.validate(self.width, self.height)?;
        let g = inputs.gbuffer;
        let c = PassConsts::new(self.width, self.height, &self.params, g.scene_scale);
        let mode = Mode::of(inputs.accumulated_frames);
        let reset = mode == Mode::Interacting;
        let weights = self.ring.weights(inputs.frame);
        let uniforms = Uniforms::new(&c, reset, weights);
        self.ctx.queue.write_buffer(&self.uniforms, 0, bytemuck::bytes_of(&uniforms));
        self.upload_inputs(inputs);
        let device = &self.ctx.device;
        let (t, p, u) = (&self.textures, &self.passes, &self.uniforms);
        let target = self.targets.free(device, (self.width, self.height), &|colour, display| {
            t.remodulate(device, &p.remodulate, u, colour, display)
        });

        let mut encoder = device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("reconstruct") });
        let stamp = |begin: bool| {
            self.timer.as_ref().map(|t| wgpu::ComputePassTimestampWrites {
                query_set: &t.queries,
                beginning_of_pass_write_index: begin.then_some(0),
                end_of_pass_write_index: (!begin).then_some(1),
            })
        };
        let (w, h, k) = (self.width, self.height, self.parity);
        let b = &self.groups;
        let remodulate = if let Some(svgf) = &mut self.svgf {
            let queue = &self.ctx.queue;
            let shared = t.shared();
            svgf.encode(device, queue, &mut encoder, inputs, &p.fill, u, &shared, stamp(true));
            &target.remodulate[0]
        } else {
            p.accumulate.encode(&mut encoder, &b.accumulate[k], w, h, stamp(true));
            p.fill.encode(&mut encoder, &b.fill[k], w, h, None);
            if mode == Mode::Interacting {
                p.temporal.encode(&mut encoder, &b.temporal, w, h, None);
                p.gaussian.encode(&mut encoder, &b.gaussian, w, h, None);
                &target.remodulate[0]
            } else {
                &target.remodulate[1]
            }
        };
        p.remodulate.encode(&mut encoder, remodulate, w, h, stamp(false));
        self.parity = 1 - k;

        // SVGF keeps its own history: the paper's past frames are not needed.
        let slot = if self.svgf.is_none() { self.ring.push(inputs.frame) } else { None };
        if let Some(slot) = slot {
            for (src, dst) in [
                (&t.filled, &t.past_radiance),
                (&t.normal, &t.past_normal),
                (&t.position, &t.past_position),
            ] {
                encoder.copy_texture_to_texture(
                    src.as_image_copy(),
                    wgpu::TexelCopyTextureInfo {
                        texture: dst,
                        mip_level: 0,
                        origin: wgpu::Origin3d { x: 0, y: 0, z: slot as u32 },
                        aspect: wgpu::TextureAspect::All,
                    },
                    wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                );
            }
        }
        Ok((target, mode, encoder))
    }

    /// Uploads this frame's samples, and the G-buffer when its state version is new.
    fn upload_inputs(&mut self, inputs: &FrameInputs) {
        let samples: Vec<[f32; 4]> = inputs
            .radiance
            .iter()
            .zip(inputs.mask)
            .map(|(v, &m)| if m { [v.x, v.y, v.z, 1.0] } else { [0.0; 4] })
            .collect();
        self.upload(&self.textures.samples, &samples);
        if self.gbuffer_version != Some(inputs.state_version) {
            let g = inputs.gbuffer;
            let t = &self.textures;
            for (texture, plane) in
                [(&t.normal, &g.normal), (&t.albedo, &g.albedo), (&t.emission, &g.emission)]
            {
                let texels: Vec<[f32; 4]> = plane.iter().map(|v| [v.x, v.y, v.z, 0.0]).collect();
                self.upload(texture, &texels);
            }
            // w: the object's index (−1 for none), which SVGF's reprojection compares.
            let texels: Vec<[f32; 4]> = (g.position.iter().zip(&g.object))
                .map(|(v, &o)| [v.x, v.y, v.z, if o == NO_OBJECT { -1.0 } else { o as f32 }])
                .collect();
            self.upload(&t.position, &texels);
            self.gbuffer_version = Some(inputs.state_version);
        }
    }

    fn upload(&self, texture: &wgpu::Texture, texels: &[[f32; 4]]) {
        self.ctx.queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(self.width * 16),
                rows_per_image: Some(self.height),
            },
            wgpu::Extent3d { width: self.width, height: self.height, depth_or_array_layers: 1 },
        );
    }

    fn read_back(&mut self, frame: u64, mode: Mode) -> Result<Reconstructed, ReconstructError> {
        let device = &self.ctx.device;
        let out = Reconstructed {
            frame,
            mode,
            radiance: self.staging[0].read_vec3(device)?,
            colour: self.staging[1].read_vec3(device)?,
            display: self.staging[2].read_rgba8(device)?,
        };
        self.read_backs += 1;
        self.last_gpu_ms = match &self.timer {
            Some(t) => Some(t.read_ms(device)?),
            None => None,
        };
        Ok(out)
    }
}
