//! A compute pass as a small struct: one WGSL entry point `main` with an 8×8 workgroup
//! over the image, a bind-group layout built from a list of binding kinds, and `encode`.
//! Device plumbing only: which passes exist and what they bind is the business of their
//! owners (`crate::reconstruct::pass`).

/// Workgroup edge of every image pass (`@workgroup_size(8, 8)` in the WGSL).
pub const WORKGROUP: u32 = 8;

/// What sits at each binding of a pass (binding index = position in the list).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Binding {
    /// The `Params` uniform buffer.
    Uniform,
    /// A non-filterable float texture read with `textureLoad`.
    Texture,
    /// A 2-D array of such textures (history layers).
    TextureArray,
    /// A write-only storage texture of the given format.
    Storage(wgpu::TextureFormat),
    /// A read-only storage buffer.
    ReadBuffer,
    /// A read-write storage buffer.
    ReadWriteBuffer,
}

/// One compiled compute pipeline and its layout.
#[derive(Debug)]
pub struct ComputePass {
    name: &'static str,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl ComputePass {
    /// Compiles `source` (a complete WGSL module) against the given bindings.
    pub fn new(
        device: &wgpu::Device,
        name: &'static str,
        source: &str,
        bindings: &[Binding],
    ) -> Self {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
            .iter()
            .enumerate()
            .map(|(i, binding)| wgpu::BindGroupLayoutEntry {
                binding: i as u32,
                visibility: wgpu::ShaderStages::COMPUTE,
                ty: binding_type(*binding),
                count: None,
            })
            .collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(name),
            entries: &entries,
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(name),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(name),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(name),
            layout: Some(&pipeline_layout),
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        Self { name, pipeline, layout }
    }

    /// A bind group with one resource per binding, in binding order.
    pub fn bind(
        &self,
        device: &wgpu::Device,
        resources: &[wgpu::BindingResource],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry { binding: i as u32, resource: r.clone() })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(self.name),
            layout: &self.layout,
            entries: &entries,
        })
    }

    /// Records one dispatch covering a `width`×`height` image in its own compute pass.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
        width: u32,
        height: u32,
        timestamps: Option<wgpu::ComputePassTimestampWrites>,
    ) {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(self.name),
            timestamp_writes: timestamps,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(width.div_ceil(WORKGROUP), height.div_ceil(WORKGROUP), 1);
    }

    /// Records one dispatch of `groups` workgroups of a one-dimensional pass, laid out in
    /// rows of at most 65535 (the shader flattens `(x, y)` with `num_workgroups`).
    pub fn encode_linear(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        bind_group: &wgpu::BindGroup,
        groups: u32,
    ) {
        if groups == 0 {
            return;
        }
        let x = groups.min(65_535);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(self.name),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(x, groups.div_ceil(x), 1);
    }
}

fn binding_type(slot: Binding) -> wgpu::BindingType {
    match slot {
        Binding::ReadBuffer | Binding::ReadWriteBuffer => wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: slot == Binding::ReadBuffer },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        Binding::Uniform => wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        Binding::Texture | Binding::TextureArray => wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: if slot == Binding::Texture {
                wgpu::TextureViewDimension::D2
            } else {
                wgpu::TextureViewDimension::D2Array
            },
            multisampled: false,
        },
        Binding::Storage(format) => wgpu::BindingType::StorageTexture {
            access: wgpu::StorageTextureAccess::WriteOnly,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
    }
}
