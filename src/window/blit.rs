//! The picture pass: draws the newest frame into a viewport of the window with
//! `blit.wgsl`. A picture on the CPU is uploaded into a texture at render resolution
//! (recreated only when the render resolution changes, not when the window is resized); a
//! frame left on the window's device by the reconstruction is sampled where it is, with
//! no copy. It counts both, so that a test can check that the one-device path uploads
//! nothing.
//!
//! A small GPU pass in the STYLE.md item 5 shape (`new`, `show`, `encode`).

use super::layout::Rect;
use super::picture::{FrameImage, Picture};
use crate::reconstruct::DeviceImage;

/// What the pass draws from.
enum Source {
    /// A texture of its own, filled by [`BlitPass::show`] uploads.
    Uploaded(wgpu::Texture),
    /// The reconstruction's texture, held so that no later frame writes it meanwhile.
    Device { _held: DeviceImage },
}

/// How the shown frames reached the pass.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BlitCounts {
    /// Pictures uploaded from the CPU (`write_texture`).
    pub uploads: u64,
    /// Frames sampled in place on the device.
    pub device_frames: u64,
}

/// The blit shader's source, checked by naga in the tests.
pub const SHADER: &str = include_str!("../../shaders/window/blit.wgsl");

/// Texture, bind group and pipeline that show one picture.
pub struct BlitPass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// Same encoding as the surface (sRGB or not), so the copy is exact.
    texture_format: wgpu::TextureFormat,
    /// What is drawn and its bind group, once a frame arrived.
    current: Option<(Source, wgpu::BindGroup)>,
    counts: BlitCounts,
}

impl BlitPass {
    /// Builds the pipeline for drawing into targets of `target_format`.
    pub fn new(device: &wgpu::Device, target_format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blit"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("blit"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("blit"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_main"),
                buffers: &[],
                compilation_options: Default::default(),
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_main"),
                targets: &[Some(wgpu::ColorTargetState {
                    format: target_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
                compilation_options: Default::default(),
            }),
            multiview_mask: None,
            cache: None,
        });
        // Linear filtering: the picture is scaled to the window's size.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("blit"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let texture_format = if target_format.is_srgb() {
            wgpu::TextureFormat::Rgba8UnormSrgb
        } else {
            wgpu::TextureFormat::Rgba8Unorm
        };
        Self {
            pipeline,
            layout,
            sampler,
            texture_format,
            current: None,
            counts: BlitCounts::default(),
        }
    }

    /// True once a frame arrived.
    pub fn has_picture(&self) -> bool {
        self.current.is_some()
    }

    /// How the frames shown so far arrived.
    pub fn counts(&self) -> BlitCounts {
        self.counts
    }

    /// Takes `image` as the frame to draw: uploads a picture, or samples a device image in
    /// place. The composer leaves a frame on the device only when it reconstructs on the
    /// window's own device, so a device image from elsewhere is a bug, not a case to copy.
    pub fn show(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, image: &FrameImage) {
        match image {
            FrameImage::Picture { picture, .. } => self.upload(device, queue, picture),
            FrameImage::Device(image) if image.is_on(device) => self.sample(device, image),
            FrameImage::Device(_) => {
                tracing::error!("a frame left on another device than the window's: not shown");
            }
        }
    }

    /// Binds the display texture of `image` (on this pass's device).
    fn sample(&mut self, device: &wgpu::Device, image: &DeviceImage) {
        let view = image.display().create_view(&wgpu::TextureViewDescriptor {
            format: Some(self.texture_format),
            ..Default::default()
        });
        let bind_group = self.bind(device, &view);
        self.current = Some((Source::Device { _held: image.clone() }, bind_group));
        self.counts.device_frames += 1;
    }

    fn bind(&self, device: &wgpu::Device, view: &wgpu::TextureView) -> wgpu::BindGroup {
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("picture"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        })
    }

    /// Uploads `picture`, reallocating the texture only when its size changed.
    fn upload(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, picture: &Picture) {
        let size = wgpu::Extent3d {
            width: picture.width,
            height: picture.height,
            depth_or_array_layers: 1,
        };
        let same_size = self
            .current
            .as_ref()
            .is_some_and(|(s, _)| matches!(s, Source::Uploaded(t) if t.size() == size));
        if !same_size {
            let texture = device.create_texture(&wgpu::TextureDescriptor {
                label: Some("picture"),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: self.texture_format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
            let bind_group = self.bind(device, &view);
            self.current = Some((Source::Uploaded(texture), bind_group));
        }
        if let Some((Source::Uploaded(texture), _)) = &self.current {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                &picture.rgba,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(4 * picture.width),
                    rows_per_image: Some(picture.height),
                },
                size,
            );
            self.counts.uploads += 1;
        }
    }

    /// Draws the current picture into `viewport` of the pass's target (nothing before the
    /// first upload).
    pub fn encode(&self, pass: &mut wgpu::RenderPass<'_>, viewport: Rect) {
        let Some((_, bind_group)) = &self.current else { return };
        pass.set_viewport(viewport.x, viewport.y, viewport.width, viewport.height, 0.0, 1.0);
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.draw(0..3, 0..1);
    }
}

#[cfg(test)]
mod tests {
    use super::SHADER;

    #[test]
    fn blit_shader_validates() {
        let module = naga::front::wgsl::parse_str(SHADER).expect("blit.wgsl parses");
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .expect("blit.wgsl validates");
        let entry_points: Vec<_> = module.entry_points.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(entry_points, ["vs_main", "fs_main"]);
    }
}
