//! The G-buffer as a wgpu raster pass (`raster.wgsl`): what the CPU path
//! (`render::primary_hit` per pixel centre) computes, by drawing the scene instead of
//! tracing it, so the master's G-buffer costs milliseconds rather than a BVH traversal
//! per pixel.
//!
//! The scene state goes through the tracer's own [`RenderScene`] — instances, transforms,
//! material bindings, quad lights and the camera are exactly what the workers render, and
//! nothing of `RenderScene::set_state` is repeated here (the price: the scene's BVHs are
//! built although only the CPU path traces them). Meshes are uploaded once (every
//! mesh of the [`Assets`] up front, built-in shapes on first use), de-indexed so that each
//! vertex can carry its triangle's geometric normal, with triangles grouped by material
//! slot: one draw per (instance, slot). Rays that hit nothing take their emission from the
//! tracer's environment lookup (`Lights::escaped`) on the CPU: it is a function of the
//! direction only, and calling the tracer's code keeps both paths identical for maps,
//! rotations and sun discs alike.

use std::collections::HashMap;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;

use glam::{Affine3A, Mat3A, Vec3};
use gridlight_actors::state::{Geometry, SceneState};
use rayon::prelude::*;

use super::raster::{
    draw_buffer, frame_group, frame_layout, pipelines, slot_vertices, texture_group,
    texture_layout, vertex_buffer, DrawUniform, Targets, Vertex, ViewUniform, DRAW_STRIDE,
};
use super::{GBuffer, GBufferError, SceneScale, NO_OBJECT};
use crate::assets::{Assets, Mesh, Texture};
use crate::gpu::{GpuContext, GpuError};
use crate::render::RenderScene;

/// Near plane in units of the scene scale: far closer than any camera sits to a surface,
/// and harmless to precision with reverse-Z floating-point depth.
const NEAR: f32 = 1e-4;

/// A mesh on the device: de-indexed vertices and each material slot's vertex range.
#[derive(Debug)]
struct GpuMesh {
    vertices: wgpu::Buffer,
    slots: Vec<Range<u32>>,
}

/// World-space triangles of the `Light::Quad`s, which are not objects (albedo 1, no id).
fn quad_vertices(scene: &RenderScene) -> Vec<Vertex> {
    let mut vertices = Vec::new();
    for q in scene.lights.quads() {
        let face = q.e1.cross(q.e2).to_array();
        let corners = [q.v0, q.v0 + q.e1, q.v0 + q.e1 + q.e2, q.v0 + q.e2];
        for i in [0, 1, 2, 0, 2, 3] {
            let position = corners[i].to_array();
            vertices.push(Vertex { position, normal: [0.0; 3], uv: [0.0; 2], face });
        }
    }
    vertices
}

/// One draw call: a vertex range with its uniforms (at `index * DRAW_STRIDE`) and texture.
struct Draw {
    vertices: wgpu::Buffer,
    range: Range<u32>,
    texture: wgpu::BindGroup,
}

/// The raster G-buffer of scene states over one set of assets.
pub struct GpuGBuffer {
    ctx: Arc<GpuContext>,
    assets: Arc<Assets>,
    scene: RenderScene,
    meshes: HashMap<Geometry, GpuMesh>,
    /// Albedo textures by asset path, as bind groups of the shader's group 1.
    textures: HashMap<String, wgpu::BindGroup>,
    /// Bound for untextured materials (the shader does not read it).
    placeholder: wgpu::BindGroup,
    texture_layout: wgpu::BindGroupLayout,
    frame_layout: wgpu::BindGroupLayout,
    geometry_pipeline: wgpu::RenderPipeline,
    material_pipeline: wgpu::RenderPipeline,
    view: wgpu::Buffer,
    draws: wgpu::Buffer,
    frame_group: wgpu::BindGroup,
    scale: SceneScale,
    targets: Option<Targets>,
    last_ms: Option<f64>,
}

impl GpuGBuffer {
    /// Compiles the pass, uploads every mesh and texture of `assets` and prepares `initial`.
    pub fn new(
        ctx: Arc<GpuContext>,
        assets: Arc<Assets>,
        initial: &SceneState,
    ) -> Result<Self, GBufferError> {
        let scene = RenderScene::new(Arc::clone(&assets), initial)?;
        let device = &ctx.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let frame_layout = frame_layout(device);
        let texture_layout = texture_layout(device);
        let [geometry_pipeline, material_pipeline] =
            pipelines(device, &frame_layout, &texture_layout);
        let view = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("gbuffer view"),
            size: std::mem::size_of::<ViewUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let draws = draw_buffer(device, 64);
        let frame_group = frame_group(device, &frame_layout, &view, &draws);
        let placeholder =
            texture_group(&ctx, &texture_layout, &Texture::linear(1, 1, vec![Vec3::ONE]));
        let mut this = Self {
            meshes: HashMap::new(),
            textures: HashMap::new(),
            placeholder,
            texture_layout,
            frame_layout,
            geometry_pipeline,
            material_pipeline,
            view,
            draws,
            frame_group,
            scale: SceneScale::default(),
            targets: None,
            last_ms: None,
            scene,
            assets,
            ctx: Arc::clone(&ctx),
        };
        for (geometry, mesh) in &this.assets.meshes {
            upload_mesh(&this.ctx, &mut this.meshes, geometry, mesh);
        }
        for (path, texture) in &this.assets.textures {
            let group = texture_group(&this.ctx, &this.texture_layout, texture);
            this.textures.insert(path.clone(), group);
        }
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Validation(err.to_string()).into());
        }
        Ok(this)
    }

    /// The render scene of the last state drawn (the same one the tracer would build).
    pub fn scene(&self) -> &RenderScene {
        &self.scene
    }

    /// The adapter the pass runs on.
    pub fn adapter_name(&self) -> &str {
        &self.ctx.adapter_info.name
    }

    /// Wall-clock milliseconds of the last [`Self::compute`], readback included.
    pub fn last_ms(&self) -> Option<f64> {
        self.last_ms
    }

    /// Brings the render scene (picking's) to `state` without drawing.
    pub fn set_state(&mut self, state: &SceneState) -> Result<(), GBufferError> {
        if self.scene.state().version != state.version {
            self.scene.set_state(state)?;
        }
        Ok(())
    }

    /// The G-buffer of `state`: draws every visible instance and quad light, reads the
    /// targets back and fills in the environment seen by rays that hit nothing.
    pub fn compute(&mut self, state: &SceneState) -> Result<GBuffer, GBufferError> {
        let start = Instant::now();
        if self.scene.state().version != state.version {
            self.scene.set_state(state)?;
        }
        let res = state.resolution;
        if self.targets.as_ref().map(|t| (t.width, t.height)) != Some((res.width, res.height)) {
            self.targets = Some(Targets::new(&self.ctx.device, res.width, res.height));
        }
        let scale = self.scale.get(state, &self.assets);
        if self.scene.cutouts || self.scene.mapped_emission {
            // The raster pass draws every triangle whole with one emission per draw;
            // alpha-masked and blended surfaces (`render::alpha`) and emission maps are
            // the CPU probe's only, so it draws this state.
            let g = GBuffer::from_scene(&self.scene, scale);
            self.last_ms = Some(start.elapsed().as_secs_f64() * 1e3);
            return Ok(g);
        }
        let (eye, view_proj) = self.scene.camera.raster_view(NEAR * scale);
        let view = ViewUniform {
            view_proj: view_proj.to_cols_array_2d(),
            eye: eye.extend(1.0).to_array(),
        };
        self.ctx.queue.write_buffer(&self.view, 0, bytemuck::bytes_of(&view));
        let draws = self.prepare_draws(state);
        let scope = self.ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.encode(&draws);
        let mut g = self.read_back(scale)?;
        if let Some(err) = pollster::block_on(scope.pop()) {
            return Err(GpuError::Validation(err.to_string()).into());
        }
        self.fill_escaped(&mut g);
        self.last_ms = Some(start.elapsed().as_secs_f64() * 1e3);
        Ok(g)
    }

    /// Uniforms of every draw, written to the device; the draws in order.
    fn prepare_draws(&mut self, state: &SceneState) -> Vec<Draw> {
        let (ctx, scene) = (&self.ctx, &self.scene);
        let mut uniforms = Vec::new();
        let mut draws = Vec::new();
        for inst in &scene.tlas.instances {
            let geometry = &state.objects[inst.object as usize].geometry;
            if !self.meshes.contains_key(geometry) {
                upload_mesh(ctx, &mut self.meshes, geometry, &inst.blas.mesh);
            }
            let mesh = &self.meshes[geometry];
            for (slot, range) in mesh.slots.iter().enumerate() {
                if range.start == range.end {
                    continue;
                }
                let id = scene.slot_materials[inst.material_base as usize + slot] as usize;
                let material = &scene.materials[id];
                let mut u = DrawUniform::new(inst.object_to_world, inst.normal_to_world);
                u.base_color = material.base_color.extend(0.0).to_array();
                u.emission = material.emission.extend(0.0).to_array();
                u.info = [inst.object + 1, 0, 0, 0];
                let texture = match (&material.texture, &state.materials[id].base_color_texture) {
                    (Some(texture), Some(path)) => {
                        u.base_color[3] = 1.0;
                        let layout = &self.texture_layout;
                        self.textures
                            .entry(path.clone())
                            .or_insert_with(|| texture_group(ctx, layout, texture))
                            .clone()
                    }
                    _ => self.placeholder.clone(),
                };
                uniforms.push(u);
                draws.push(Draw { vertices: mesh.vertices.clone(), range: range.clone(), texture });
            }
        }
        let quads = quad_vertices(scene);
        if !quads.is_empty() {
            // Each quad's radiance differs, so each gets its own draw of six vertices.
            let vertices = vertex_buffer(&ctx.device, "gbuffer quad lights", &quads);
            for (k, q) in scene.lights.quads().enumerate() {
                let mut u = DrawUniform::new(Affine3A::IDENTITY, Mat3A::IDENTITY);
                u.emission = q.radiance.extend(0.0).to_array();
                u.info = [0, 1, 0, 0];
                uniforms.push(u);
                let (vertices, texture) = (vertices.clone(), self.placeholder.clone());
                draws.push(Draw { vertices, range: 6 * k as u32..6 * k as u32 + 6, texture });
            }
        }
        self.write_uniforms(&uniforms);
        draws
    }

    /// Writes the draw uniforms at `DRAW_STRIDE` intervals, growing the buffer if needed.
    fn write_uniforms(&mut self, uniforms: &[DrawUniform]) {
        if uniforms.len() as u64 * DRAW_STRIDE > self.draws.size() {
            let device = &self.ctx.device;
            self.draws = draw_buffer(device, uniforms.len().next_power_of_two() as u64);
            self.frame_group = frame_group(device, &self.frame_layout, &self.view, &self.draws);
        }
        let mut bytes = vec![0u8; uniforms.len() * DRAW_STRIDE as usize];
        for (chunk, u) in bytes.chunks_exact_mut(DRAW_STRIDE as usize).zip(uniforms) {
            chunk[..std::mem::size_of::<DrawUniform>()].copy_from_slice(bytemuck::bytes_of(u));
        }
        if !bytes.is_empty() {
            self.ctx.queue.write_buffer(&self.draws, 0, &bytes);
        }
    }

    /// Records and submits both passes and the copies into the staging buffers.
    fn encode(&self, draws: &[Draw]) {
        let Some(t) = &self.targets else { return };
        let views = t.colour.each_ref().map(|c| c.create_view(&Default::default()));
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("gbuffer") });
        let passes = [
            (&self.geometry_pipeline, [&views[0], &views[1]], wgpu::Color::TRANSPARENT, true),
            (&self.material_pipeline, [&views[2], &views[3]], wgpu::Color::WHITE, false),
        ];
        // Albedo clears to 1 and everything else to 0: what primary_hit gives a miss.
        let clear_colour =
            |c: wgpu::Color, k: usize| if k == 0 { c } else { wgpu::Color::TRANSPARENT };
        for (pipeline, targets, clear, first) in passes {
            let colour = |k: usize| {
                Some(wgpu::RenderPassColorAttachment {
                    view: targets[k],
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(clear_colour(clear, k)),
                        store: wgpu::StoreOp::Store,
                    },
                })
            };
            let depth_load = if first { wgpu::LoadOp::Clear(0.0) } else { wgpu::LoadOp::Load };
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some(if first { "gbuffer geometry" } else { "gbuffer material" }),
                color_attachments: &[colour(0), colour(1)],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &t.depth,
                    depth_ops: Some(wgpu::Operations {
                        load: depth_load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(pipeline);
            for (k, d) in draws.iter().enumerate() {
                pass.set_bind_group(0, &self.frame_group, &[(k as u64 * DRAW_STRIDE) as u32]);
                pass.set_bind_group(1, &d.texture, &[]);
                pass.set_vertex_buffer(0, d.vertices.slice(..));
                pass.draw(d.range.clone(), 0..1);
            }
        }
        for (staging, texture) in t.staging.iter().zip(&t.colour) {
            staging.copy_from(&mut encoder, texture);
        }
        self.ctx.queue.submit([encoder.finish()]);
    }

    /// The targets as G-buffer planes.
    fn read_back(&self, scene_scale: f32) -> Result<GBuffer, GBufferError> {
        let t = self.targets.as_ref().ok_or(GpuError::Readback("no render targets".into()))?;
        let mut g = GBuffer::empty(t.width, t.height, scene_scale);
        let mut planes: [Vec<[f32; 4]>; 4] = Default::default();
        for (plane, staging) in planes.iter_mut().zip(&t.staging) {
            plane.reserve(g.len());
            staging.read(&self.ctx.device, |_, row| {
                plane.extend(row.chunks_exact(16).map(bytemuck::pod_read_unaligned::<[f32; 4]>));
            })?;
        }
        let [position, normal, albedo, emission] = &planes;
        for i in 0..g.len() {
            if normal[i][3] == 0.0 {
                continue; // missed: `GBuffer::empty`'s values, emission filled in later
            }
            let v = |p: &[f32; 4]| Vec3::new(p[0], p[1], p[2]);
            g.position[i] = v(&position[i]);
            g.normal[i] = v(&normal[i]);
            g.albedo[i] = v(&albedo[i]);
            g.emission[i] = v(&emission[i]);
            // Object + 1 as a float: exact below 2^24 objects.
            g.object[i] = match position[i][3] as u32 {
                0 => NO_OBJECT,
                id => id - 1,
            };
        }
        Ok(g)
    }

    /// Emission of the environment (and sun disc) along the camera rays that hit nothing.
    fn fill_escaped(&self, g: &mut GBuffer) {
        let scene = &self.scene;
        let hit: Vec<bool> = g.normal.iter().map(|n| *n != Vec3::ZERO).collect();
        g.emission.par_iter_mut().enumerate().filter(|(i, _)| !hit[*i]).for_each(|(i, e)| {
            *e = crate::render::escaped_emission(scene, i as u32);
        });
    }
}

fn upload_mesh(
    ctx: &GpuContext,
    meshes: &mut HashMap<Geometry, GpuMesh>,
    geometry: &Geometry,
    mesh: &Mesh,
) {
    let (vertices, slots) = slot_vertices(mesh);
    let vertices = vertex_buffer(&ctx.device, "gbuffer mesh", &vertices);
    meshes.insert(geometry.clone(), GpuMesh { vertices, slots });
}
