//! The SVGF reconstruction on the GPU: the passes of `shaders/reconstruct/svgf/` (reproject,
//! the temporal gradient's tiles and factor, accumulate, variance, à-trous), run by the
//! GPU pipeline (`reconstruct::gpu`) in place of the paper's accumulate, temporal and
//! Gaussian; its fill and remodulate are the paper's. The same steps and maths as the CPU
//! [`SvgfReconstructor`](super::SvgfReconstructor), with the same decision of what a new
//! scene state does to the history ([`Follower`]).
//!
//! Textures: the history (sums with their count, luminance moments) ping-pongs between
//! two pairs; the previous state's normals and positions (whose w holds the object index)
//! are copies kept for the next reprojection; the variance rides in the alpha of the
//! à-trous images, which are the paper's `blended` and `filtered`, arranged so that the last
//! iteration writes `filtered`, where the pipeline reads its result.

use bytemuck::{Pod, Zeroable};

use super::gradient::TILE;
use super::reproject::STILL_PLANE;
use super::{Carry, Follower, SvgfParams};
use crate::gpu::compute::{Binding, ComputePass};
use crate::reconstruct::FrameInputs;

const F32X4: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;

/// The SVGF passes' shared WGSL (uniform block, edge-stopping weights), prefixed after the
/// reconstruction's common block.
pub const COMMON_WGSL: &str = include_str!("../../../shaders/reconstruct/svgf/common.wgsl");

/// Every SVGF pass's WGSL by file name, in pipeline order (for the naga validation test).
pub const WGSL: [(&str, &str); 6] = [
    ("reproject.wgsl", include_str!("../../../shaders/reconstruct/svgf/reproject.wgsl")),
    ("tiles.wgsl", include_str!("../../../shaders/reconstruct/svgf/tiles.wgsl")),
    ("factor.wgsl", include_str!("../../../shaders/reconstruct/svgf/factor.wgsl")),
    ("accumulate.wgsl", include_str!("../../../shaders/reconstruct/svgf/accumulate.wgsl")),
    ("variance.wgsl", include_str!("../../../shaders/reconstruct/svgf/variance.wgsl")),
    ("atrous.wgsl", include_str!("../../../shaders/reconstruct/svgf/atrous.wgsl")),
];

/// A pass's complete module source: the reconstruction's common block, SVGF's, the pass.
pub fn with_common(pass: &str) -> String {
    crate::reconstruct::pass::with_common(&format!("{COMMON_WGSL}\n{pass}"))
}

/// Mirror of `Svgf` in `svgf/common.wgsl` (112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SvgfUniforms {
    pub step: i32,
    pub normal_squarings: u32,
    pub plane2: f32,
    pub eps2: f32,
    pub sigma_luminance: f32,
    pub cap: f32,
    pub has_camera: u32,
    pub keep: u32,
    pub camera: [[f32; 4]; 4],
    pub still_plane: f32,
    pub gradient: u32,
    pub tiles_x: u32,
    pub tiles_y: u32,
}
const _: () = assert!(std::mem::size_of::<SvgfUniforms>() == 112);

/// Mirror of `ObjectMotion` in `reproject.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ObjectMotion {
    to_prev: [[f32; 4]; 4],
    prev: [i32; 4],
}

/// The tiles of the temporal gradient for a frame size.
fn tiles(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(TILE as u32), height.div_ceil(TILE as u32))
}

/// The textures of the paper's pipeline that SVGF reads or writes.
pub struct Shared<'a> {
    pub normal: &'a wgpu::Texture,
    pub position: &'a wgpu::Texture,
    pub samples: &'a wgpu::Texture,
    pub filled: &'a wgpu::Texture,
    /// The à-trous ping-pong pair; the last iteration writes `[1]`.
    pub images: [&'a wgpu::Texture; 2],
}

#[derive(Debug)]
struct Passes {
    reproject: ComputePass,
    tiles: ComputePass,
    factor: ComputePass,
    accumulate: ComputePass,
    variance: ComputePass,
    atrous: ComputePass,
}

impl Passes {
    fn new(device: &wgpu::Device) -> Self {
        use Binding::{ReadBuffer as B, Storage as S, Texture as T, Uniform as U};
        let pass = |name, k: usize, bindings: &[Binding]| {
            let mut all = vec![U, U];
            all.extend_from_slice(bindings);
            ComputePass::new(device, name, &with_common(WGSL[k].1), &all)
        };
        Self {
            reproject: pass("svgf reproject", 0, &[T, T, T, T, T, T, B, S(F32X4), S(F32X4)]),
            tiles: pass("svgf tiles", 1, &[T, T, T, S(F32X4)]),
            factor: pass("svgf factor", 2, &[T, S(F32X4)]),
            accumulate: pass("svgf accumulate", 3, &[T, T, T, T, S(F32X4), S(F32X4)]),
            variance: pass("svgf variance", 4, &[T, T, T, T, T, S(F32X4)]),
            atrous: pass("svgf atrous", 5, &[T, T, T, S(F32X4)]),
        }
    }
}

fn view(t: &wgpu::Texture) -> wgpu::TextureView {
    t.create_view(&wgpu::TextureViewDescriptor::default())
}

/// The SVGF part of the GPU pipeline for one frame size.
#[derive(Debug)]
pub struct SvgfGpu {
    params: SvgfParams,
    width: u32,
    height: u32,
    follower: Follower,
    passes: Passes,
    /// One per à-trous iteration (its step); `[0]` serves every other pass.
    uniforms: Vec<wgpu::Buffer>,
    sums: [wgpu::Texture; 2],
    lum: [wgpu::Texture; 2],
    prev_normal: wgpu::Texture,
    prev_position: wgpu::Texture,
    /// Which of the pairs holds the history.
    current: usize,
    /// Bind groups by the history's pair `[k]`: tiles, accumulate (k → 1 − k), fill,
    /// variance; à-trous per iteration.
    tiles_group: [wgpu::BindGroup; 2],
    factor_group: wgpu::BindGroup,
    accumulate: [wgpu::BindGroup; 2],
    fill: [wgpu::BindGroup; 2],
    variance: [wgpu::BindGroup; 2],
    atrous: Vec<wgpu::BindGroup>,
}

impl SvgfGpu {
    pub fn new(
        device: &wgpu::Device,
        params: SvgfParams,
        (width, height): (u32, u32),
        fill_pass: &ComputePass,
        paper_uniforms: &wgpu::Buffer,
        shared: &Shared,
    ) -> Self {
        use wgpu::BindingResource::TextureView as V;
        use wgpu::TextureUsages as Use;
        let passes = Passes::new(device);
        let make = |label, (w, h): (u32, u32), usage| {
            crate::gpu::texture_2d(device, label, (w, h, 1), F32X4, usage)
        };
        let work = Use::TEXTURE_BINDING | Use::STORAGE_BINDING | Use::COPY_SRC;
        let size = (width, height);
        let sums = [make("svgf sums 0", size, work), make("svgf sums 1", size, work)];
        let lum = [make("svgf moments 0", size, work), make("svgf moments 1", size, work)];
        let past = Use::TEXTURE_BINDING | Use::COPY_DST;
        let prev_normal = make("svgf previous normal", size, past);
        let prev_position = make("svgf previous position", size, past);
        let tile_size = tiles(width, height);
        let tiles_tex = make("svgf gradient tiles", tile_size, work);
        let factor = make("svgf gradient factor", tile_size, work);
        let uniforms: Vec<wgpu::Buffer> = (0..params.iterations.max(1))
            .map(|_| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("svgf params"),
                    size: std::mem::size_of::<SvgfUniforms>() as u64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let (p, s) = (paper_uniforms.as_entire_binding(), uniforms[0].as_entire_binding());
        let (sv, lv) = (sums.each_ref().map(view), lum.each_ref().map(view));
        let (normal, position, samples, filled) =
            (view(shared.normal), view(shared.position), view(shared.samples), view(shared.filled));
        let (tiles_v, factor_v) = (view(&tiles_tex), view(&factor));
        let images = shared.images.map(view);
        // The variance writes the image that leaves the last iteration in `images[1]`.
        let first = (params.iterations as usize + 1) % 2;
        let bind = |pass: &ComputePass, rest: &[wgpu::BindingResource]| {
            let mut all = vec![p.clone(), s.clone()];
            all.extend_from_slice(rest);
            pass.bind(device, &all)
        };
        let per_pair = |f: &dyn Fn(usize) -> wgpu::BindGroup| [f(0), f(1)];
        let tiles_group =
            per_pair(&|k| bind(&passes.tiles, &[V(&sv[k]), V(&lv[k]), V(&samples), V(&tiles_v)]));
        let factor_group = bind(&passes.factor, &[V(&tiles_v), V(&factor_v)]);
        let accumulate = per_pair(&|k| {
            let (a, b) = (V(&sv[1 - k]), V(&lv[1 - k]));
            bind(&passes.accumulate, &[V(&sv[k]), V(&lv[k]), V(&samples), V(&factor_v), a, b])
        });
        let fill = per_pair(&|k| {
            let guide = [V(&normal), V(&position)];
            let [n, z] = guide;
            fill_pass.bind(device, &[p.clone(), V(&sv[k]), n, z, V(&filled)])
        });
        let variance = per_pair(&|k| {
            let (guide, out) = ([V(&normal), V(&position)], V(&images[first]));
            let [n, z] = guide;
            bind(&passes.variance, &[V(&sv[k]), V(&lv[k]), V(&filled), n, z, out])
        });
        let atrous = (0..params.iterations as usize)
            .map(|i| {
                let (src, dst) = (&images[(first + i) % 2], &images[(first + i + 1) % 2]);
                passes.atrous.bind(
                    device,
                    &[
                        p.clone(),
                        uniforms[i].as_entire_binding(),
                        V(src),
                        V(&normal),
                        V(&position),
                        V(dst),
                    ],
                )
            })
            .collect();
        Self {
            params,
            width,
            height,
            follower: Follower::default(),
            passes,
            uniforms,
            sums,
            lum,
            prev_normal,
            prev_position,
            current: 0,
            tiles_group,
            factor_group,
            accumulate,
            fill,
            variance,
            atrous,
        }
    }

    /// Records one frame's SVGF passes up to the filtered radiance (in `shared.images[1]`),
    /// the fill included; `begin` stamps the first pass. The paper's uniforms must be
    /// written already; this writes its own.
    #[allow(clippy::too_many_arguments)] // the frame, the device's three handles, two passes' extras
    pub fn encode(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &FrameInputs,
        fill: &ComputePass,
        paper_uniforms: &wgpu::Buffer,
        shared: &Shared,
        begin: Option<wgpu::ComputePassTimestampWrites>,
    ) {
        let sp = self.params;
        let edges =
            super::edges::Edges::new(sp.normal_power, sp.sigma_plane, inputs.gbuffer.scene_scale);
        let (tiles_x, tiles_y) = tiles(self.width, self.height);
        let mut u = SvgfUniforms {
            step: 1,
            normal_squarings: edges.normal_squarings,
            plane2: edges.plane2,
            eps2: edges.eps2,
            sigma_luminance: sp.sigma_luminance,
            cap: 0.0,
            has_camera: 0,
            keep: 0,
            camera: [[0.0; 4]; 4],
            still_plane: STILL_PLANE * inputs.gbuffer.scene_scale,
            gradient: 0,
            tiles_x,
            tiles_y,
        };
        let carry = self.follower.follow(inputs, &sp);
        let mut objects = Vec::new();
        if let Some(Carry::Reproject { motion, cap, gradient }) = &carry {
            (u.keep, u.cap, u.gradient) = (1, *cap, *gradient as u32);
            if let Some(c) = motion.camera_vectors() {
                (u.has_camera, u.camera) = (1, c.map(|v| v.to_array()));
            }
            objects = motion
                .objects()
                .iter()
                .map(|o| match o {
                    Some((m, prev)) => ObjectMotion {
                        to_prev: m.to_cols_array_2d(),
                        prev: [*prev as i32, 0, 0, 0],
                    },
                    None => ObjectMotion { to_prev: [[0.0; 4]; 4], prev: [-1, 0, 0, 0] },
                })
                .collect();
        }
        for (k, buffer) in self.uniforms.iter().enumerate() {
            let step = SvgfUniforms { step: 1 << k, ..u };
            queue.write_buffer(buffer, 0, bytemuck::bytes_of(&step));
        }
        let (w, h) = (self.width, self.height);
        let mut begin = begin;
        if carry.is_some() {
            self.encode_reproject(device, encoder, &objects, paper_uniforms, shared, begin.take());
        }
        if u.gradient == 1 {
            let k = self.current;
            self.passes.tiles.encode(encoder, &self.tiles_group[k], tiles_x, tiles_y, None);
            self.passes.factor.encode(encoder, &self.factor_group, tiles_x, tiles_y, None);
        }
        let k = self.current;
        self.passes.accumulate.encode(encoder, &self.accumulate[k], w, h, begin.take());
        self.current = 1 - k;
        fill.encode(encoder, &self.fill[self.current], w, h, None);
        self.passes.variance.encode(encoder, &self.variance[self.current], w, h, None);
        for group in &self.atrous {
            self.passes.atrous.encode(encoder, group, w, h, None);
        }
        if carry.is_some() {
            for (src, dst) in
                [(shared.normal, &self.prev_normal), (shared.position, &self.prev_position)]
            {
                encoder.copy_texture_to_texture(
                    src.as_image_copy(),
                    dst.as_image_copy(),
                    wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                );
            }
        }
    }

    /// Reprojects the history from pair `current` into the other, which becomes current.
    fn encode_reproject(
        &mut self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        objects: &[ObjectMotion],
        paper_uniforms: &wgpu::Buffer,
        shared: &Shared,
        begin: Option<wgpu::ComputePassTimestampWrites>,
    ) {
        use wgpu::util::DeviceExt;
        use wgpu::BindingResource::TextureView as V;
        // WGSL wants a non-empty array: one entry that maps to nothing.
        let none = [ObjectMotion { to_prev: [[0.0; 4]; 4], prev: [-1, 0, 0, 0] }];
        let contents = if objects.is_empty() { &none[..] } else { objects };
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("svgf object motion"),
            contents: bytemuck::cast_slice(contents),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let k = self.current;
        let group = self.passes.reproject.bind(
            device,
            &[
                paper_uniforms.as_entire_binding(),
                self.uniforms[0].as_entire_binding(),
                V(&view(shared.normal)),
                V(&view(shared.position)),
                V(&view(&self.prev_normal)),
                V(&view(&self.prev_position)),
                V(&view(&self.sums[k])),
                V(&view(&self.lum[k])),
                buffer.as_entire_binding(),
                V(&view(&self.sums[1 - k])),
                V(&view(&self.lum[1 - k])),
            ],
        );
        self.passes.reproject.encode(encoder, &group, self.width, self.height, begin);
        self.current = 1 - k;
    }
}
