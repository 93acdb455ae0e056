//! Device objects of the G-buffer raster pass (`super::gpu`): the `#[repr(C)]` mirrors
//! of the shader's uniforms and vertices, meshes turned into per-slot vertex ranges, the
//! bind group layouts, the two pipelines and the render targets with their readback.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use glam::{Affine3A, Mat3A, Mat4, Vec2, Vec3};

use crate::assets::{Mesh, Texture};
use crate::gpu::readback::Staging;
use crate::gpu::GpuContext;

/// The raster pass's WGSL: standalone, it declares its own bindings.
pub const WGSL: &str = include_str!("../../shaders/gbuffer/raster.wgsl");

pub(super) const TARGET: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
pub(super) const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Draw uniforms sit at multiples of wgpu's default `min_uniform_buffer_offset_alignment`.
pub(super) const DRAW_STRIDE: u64 = 256;
/// Mirror of `View` in `raster.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct ViewUniform {
    pub(super) view_proj: [[f32; 4]; 4],
    pub(super) eye: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<ViewUniform>() == 80);

/// Mirror of `Draw` in `raster.wgsl` (a `mat3x3` is three 16-byte columns).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct DrawUniform {
    pub(super) object_to_world: [[f32; 4]; 4],
    pub(super) normal_to_world: [[f32; 4]; 3],
    pub(super) base_color: [f32; 4],
    pub(super) emission: [f32; 4],
    pub(super) info: [u32; 4],
}
const _: () = assert!(std::mem::size_of::<DrawUniform>() == 160);
const _: () = assert!(std::mem::size_of::<DrawUniform>() as u64 <= DRAW_STRIDE);

impl DrawUniform {
    pub(super) fn new(object_to_world: Affine3A, normal_to_world: Mat3A) -> Self {
        let n = normal_to_world.to_cols_array_2d();
        Self {
            object_to_world: Mat4::from(object_to_world).to_cols_array_2d(),
            normal_to_world: n.map(|c| [c[0], c[1], c[2], 0.0]),
            base_color: [1.0, 1.0, 1.0, 0.0],
            emission: [0.0; 4],
            info: [0; 4],
        }
    }
}

/// One vertex of a de-indexed triangle (`VertexIn` in the shader).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct Vertex {
    pub(super) position: [f32; 3],
    pub(super) normal: [f32; 3],
    pub(super) uv: [f32; 2],
    /// Object-space e1 × e2 of the triangle, as the tracer's `TriEdges` give it.
    pub(super) face: [f32; 3],
}
const _: () = assert!(std::mem::size_of::<Vertex>() == 44);

pub(super) const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 4] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 2 => Float32x2, 3 => Float32x3];

/// The vertices of `mesh`'s triangles grouped by material slot, and each slot's range.
pub(super) fn slot_vertices(mesh: &Mesh) -> (Vec<Vertex>, Vec<Range<u32>>) {
    let slots = mesh.slot_count.max(1) as usize;
    let slot_of = |t: usize| (mesh.slot(t) as usize).min(slots - 1);
    let mut order: Vec<usize> = (0..mesh.indices.len()).collect();
    order.sort_by_key(|&t| slot_of(t));
    let mut vertices = Vec::with_capacity(order.len() * 3);
    let mut ranges = vec![0..0; slots];
    for t in order {
        let idx = mesh.indices[t];
        let [a, b, c] = idx.map(|i| mesh.positions[i as usize]);
        let face = (b - a).cross(c - a).to_array();
        for i in idx.map(|i| i as usize) {
            vertices.push(Vertex {
                position: mesh.positions[i].to_array(),
                normal: mesh.normals.get(i).copied().unwrap_or(Vec3::ZERO).to_array(),
                uv: mesh.uvs.get(i).copied().unwrap_or(Vec2::ZERO).to_array(),
                face,
            });
        }
        let end = vertices.len() as u32;
        let range = &mut ranges[slot_of(t)];
        if range.end == 0 {
            *range = end - 3..end;
        } else {
            range.end = end;
        }
    }
    (vertices, ranges)
}

/// Render targets and their readback buffers for one resolution.
#[derive(Debug)]
pub(super) struct Targets {
    pub(super) width: u32,
    pub(super) height: u32,
    /// position + object, normal + hit, albedo, emission.
    pub(super) colour: [wgpu::Texture; 4],
    pub(super) depth: wgpu::TextureView,
    pub(super) staging: [Staging; 4],
}

impl Targets {
    pub(super) fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        let make = |label: &str, format, usage| {
            crate::gpu::texture_2d(device, label, (width, height, 1), format, usage)
        };
        let usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC;
        let names = ["gbuffer position", "gbuffer normal", "gbuffer albedo", "gbuffer emission"];
        let depth = make("gbuffer depth", DEPTH, wgpu::TextureUsages::RENDER_ATTACHMENT);
        Self {
            width,
            height,
            colour: names.map(|n| make(n, TARGET, usage)),
            depth: depth.create_view(&Default::default()),
            staging: names.map(|n| Staging::new(device, n, width, height, 16)),
        }
    }
}

pub(super) fn vertex_buffer(
    device: &wgpu::Device,
    label: &str,
    vertices: &[Vertex],
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    // A zero-sized buffer cannot be bound; an empty mesh gets one unused vertex.
    let placeholder = [Vertex::zeroed()];
    let vertices = if vertices.is_empty() { &placeholder[..] } else { vertices };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(vertices),
        usage: wgpu::BufferUsages::VERTEX,
    })
}

pub(super) fn draw_buffer(device: &wgpu::Device, draws: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("gbuffer draws"),
        size: draws.max(1) * DRAW_STRIDE,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Group 0: the view, and the draw uniforms at a dynamic offset.
pub(super) fn frame_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    let uniform = |binding, dynamic: bool, size: usize| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: dynamic,
            min_binding_size: wgpu::BufferSize::new(size as u64),
        },
        count: None,
    };
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("gbuffer frame"),
        entries: &[
            uniform(0, false, std::mem::size_of::<ViewUniform>()),
            uniform(1, true, std::mem::size_of::<DrawUniform>()),
        ],
    })
}

pub(super) fn frame_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    view: &wgpu::Buffer,
    draws: &wgpu::Buffer,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("gbuffer frame"),
        layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: view.as_entire_binding() },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: draws,
                    offset: 0,
                    size: wgpu::BufferSize::new(std::mem::size_of::<DrawUniform>() as u64),
                }),
            },
        ],
    })
}

/// Group 1: one albedo texture, read with `textureLoad`.
pub(super) fn texture_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("gbuffer albedo"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        }],
    })
}

/// Uploads a linear RGB texture as rgba32float (the CPU lookup's precision).
pub(super) fn texture_group(
    ctx: &GpuContext,
    layout: &wgpu::BindGroupLayout,
    texture: &Texture,
) -> wgpu::BindGroup {
    let size = wgpu::Extent3d {
        width: texture.width.max(1),
        height: texture.height.max(1),
        depth_or_array_layers: 1,
    };
    let gpu = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("gbuffer albedo texture"),
        size,
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: TARGET,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    let texels: Vec<[f32; 4]> = texture.texels.iter().map(|t| t.extend(1.0).to_array()).collect();
    if texels.len() == size.width as usize * size.height as usize {
        ctx.queue.write_texture(
            gpu.as_image_copy(),
            bytemuck::cast_slice(&texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(size.width * 16),
                rows_per_image: Some(size.height),
            },
            size,
        );
    }
    ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("gbuffer albedo"),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: wgpu::BindingResource::TextureView(&gpu.create_view(&Default::default())),
        }],
    })
}

/// The geometry pass (writes depth) and the material pass (depth test `equal`).
pub(super) fn pipelines(
    device: &wgpu::Device,
    frame: &wgpu::BindGroupLayout,
    texture: &wgpu::BindGroupLayout,
) -> [wgpu::RenderPipeline; 2] {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("gbuffer.wgsl"),
        source: wgpu::ShaderSource::Wgsl(WGSL.into()),
    });
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("gbuffer"),
        bind_group_layouts: &[Some(frame), Some(texture)],
        immediate_size: 0,
    });
    let target = Some(wgpu::ColorTargetState {
        format: TARGET,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    });
    let buffers = [Some(wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<Vertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &VERTEX_ATTRIBUTES,
    })];
    // Reverse-Z: nearer is larger. `GreaterEqual` lets the last of equally deep fragments
    // win, and `Equal` in the second pass then shades that same one.
    let make = |entry: &str, write: bool, compare| {
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(entry),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &buffers,
            },
            // Both sides: the tracer's rays hit back faces too.
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH,
                depth_write_enabled: Some(write),
                depth_compare: Some(compare),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets: &[target.clone(), target.clone()],
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    [
        make("fs_geometry", true, wgpu::CompareFunction::GreaterEqual),
        make("fs_material", false, wgpu::CompareFunction::Equal),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_are_grouped_by_slot_with_their_face_normal() {
        let mut mesh = crate::shapes::cube();
        mesh.slot_count = 2;
        mesh.slots = (0..mesh.indices.len() as u32).map(|t| t % 2).collect();
        let (vertices, slots) = slot_vertices(&mesh);
        assert_eq!(vertices.len(), mesh.indices.len() * 3);
        assert_eq!(slots, vec![0..18, 18..36]);
        for (k, tri) in vertices.chunks_exact(3).enumerate() {
            let p: Vec<Vec3> = tri.iter().map(|v| Vec3::from(v.position)).collect();
            let face = Vec3::from(tri[0].face);
            assert!((p[1] - p[0]).cross(p[2] - p[0]).abs_diff_eq(face, 1e-6), "triangle {k}");
            // A cube face's shading normals agree with its winding.
            assert!(Vec3::from(tri[0].normal).dot(face) > 0.0);
        }
    }
}
