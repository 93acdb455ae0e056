//! The path tracer: the rendering kernel every worker runs.
//!
//! A [`RenderScene`] turns a [`SceneState`] plus loaded [`Assets`] into render
//! structures: one bottom-level BVH per mesh (built once, cached by geometry), a
//! top-level BVH over the object instances (rebuilt per state), the material and
//! light tables and the camera. [`render_pixels`] path-traces a list of pixels on
//! the calling thread, deterministically for (scene seed, frame, pixel, sample),
//! and returns what reconstruction needs per pixel (docs/design.md): demodulated
//! radiance, directly seen emission and the primary hit's G-buffer values.
//!
//! Modules: [`accel`] (BVHs), [`alpha`] (cut-out and blended surfaces), [`sampler`]
//! (scrambled Sobol), [`camera`], [`bsdf`], [`microfacet`] and [`pbr`] (materials),
//! [`lights`] and [`envmap`] (emitters), [`integrator`] (the path loop); [`gpu`] the same
//! kernel in WGSL for GPU workers.

pub mod accel;
pub mod alpha;
pub mod bsdf;
pub mod camera;
pub mod envmap;
mod glossy_lanes;
pub mod gpu;
pub mod integrator;
pub mod isa;
pub mod lanes;
pub mod layering;
pub mod lights;
pub mod microfacet;
pub mod normal_map;
pub mod pbr;
pub mod sampler;
mod stream;
pub mod testscenes;
pub mod trig;

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Affine3A, Vec2, Vec3};
use gridlight_actors::state::{AlphaMode, Geometry, MaterialKind, SceneState, TextureUse};

use crate::assets::{Assets, Lookup, Mesh, Texture};
use crate::shapes;
use accel::{Blas, Instance, MeshError, Tlas};
use camera::{CameraError, CameraRays};
use envmap::Environment;
use lights::{AreaLight, Lights};

pub use integrator::{
    area_emission, escaped_emission, pick, primary_block_in, primary_hit, render_pixels,
    render_pixels_counted, render_pixels_in, RenderStats, Strategy, PRIMARY_TILE,
};

/// Why a scene state cannot be rendered with the given assets.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("object `{object}` uses geometry {geometry:?}, which is not in the loaded assets")]
    MissingMesh { object: String, geometry: Geometry },
    #[error("object `{object}`: {source}")]
    BadMesh { object: String, source: MeshError },
    #[error("material `{material}` uses texture `{path}`, which is not in the loaded assets")]
    MissingTexture { material: String, path: String },
    #[error("environment map `{path}` is not in the loaded assets")]
    MissingEnvironment { path: String },
    #[error(
        "object `{object}` refers to material {material}, but the state has {count} materials"
    )]
    MaterialOutOfRange { object: String, material: u32, count: usize },
    #[error(
        "object `{object}` binds {bound} materials, but its geometry has {slots} material slots"
    )]
    SlotCount { object: String, bound: usize, slots: u32 },
    #[error("object `{object}` has a non-finite or singular transform")]
    BadTransform { object: String },
    #[error("material `{material}` has a non-finite or negative parameter")]
    BadMaterial { material: String },
    #[error("light {index} has a non-finite parameter")]
    BadLight { index: usize },
    #[error("texture `{path}` has {texels} texels for {width}x{height}")]
    BadTexture { path: String, texels: usize, width: u32, height: u32 },
    #[error("camera: {0}")]
    Camera(#[from] CameraError),
}

/// What the kernel returns for one pixel: the mean colour of its samples is
/// `reflected + emission` exactly.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSample {
    /// L - emission, averaged over the samples, not demodulated. What workers send: the
    /// master divides it by its G-buffer's albedo and multiplies the same albedo back in,
    /// so the two cancel exactly wherever a pixel's samples hit surfaces of different
    /// albedos (demodulating each sample by its own hit and remodulating by the pixel
    /// centre's made every edge between two albedos brighter: a/b + b/a > 2).
    pub reflected: Vec3,
    /// Directly seen emission (the environment for escaping camera rays).
    pub emission: Vec3,
    /// Primary hit albedo (textured, clamped away from 0), 1 for escaping rays.
    pub albedo: Vec3,
    /// Primary hit shading normal (world), 0 for escaping rays.
    pub normal: Vec3,
    /// Primary hit world position.
    pub position: Vec3,
    /// Index into `state.objects`, `u32::MAX` for escaping rays and `Light::Quad`s.
    pub object: u32,
}

/// Each map's lookup where it is not the default (repeat, untransformed).
#[derive(Clone, Copy, Debug, Default)]
pub struct Lookups {
    pub base_color: Option<Lookup>,
    pub metallic_roughness: Option<Lookup>,
    pub normal: Option<Lookup>,
    pub emissive: Option<Lookup>,
}

/// A material with its texture resolved.
#[derive(Clone, Debug)]
pub struct MaterialData {
    pub kind: MaterialKind,
    pub base_color: Vec3,
    pub texture: Option<Arc<Texture>>,
    pub roughness: f32,
    pub ior: f32,
    /// Emitted radiance, the state's `emission` times its `emission_strength`.
    pub emission: Vec3,
    /// `Pbr` only.
    pub metallic: f32,
    /// `Pbr` only.
    pub transmission: f32,
    /// `Pbr` only: B multiplies `metallic`, G `roughness` (linear).
    pub metallic_roughness: Option<Arc<Texture>>,
    /// `Pbr` only: a tangent-space normal map, its xy scaled by `normal_scale`.
    pub normal_map: Option<Arc<Texture>>,
    pub normal_scale: f32,
    /// `Pbr` only: an sRGB map multiplying `emission`. Such an emitter is not sampled by
    /// next-event estimation (see [`MaterialData::emission_at`]).
    pub emission_map: Option<Arc<Texture>>,
    /// Coverage factor (times the base colour map's alpha), its mode and mask cutoff.
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    pub alpha_cutoff: f32,
    /// How each map is looked up (wrap modes, texture transform).
    pub lookups: Lookups,
    /// Whether some hit on this material can let a ray through ([`alpha::can_let_through`]):
    /// checked before any texture lookup, so opaque materials cost nothing.
    pub cutout: bool,
}

impl MaterialData {
    #[inline]
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }

    /// Whether a hit needs its texture coordinates.
    #[inline(always)]
    pub fn textured(&self) -> bool {
        self.texture.is_some()
            || self.metallic_roughness.is_some()
            || self.normal_map.is_some()
            || self.emission_map.is_some()
    }

    /// Emitted radiance at texture coordinates `uv`: `emission` times the emission map.
    #[inline(always)]
    pub fn emission_at(&self, uv: Vec2) -> Vec3 {
        match &self.emission_map {
            Some(t) => self.emission * t.sample_with(uv, self.lookups.emissive.as_ref()),
            None => self.emission,
        }
    }

    /// Whether light sampling picks this material's triangles: emissive and uniform.
    /// A mapped emitter is found by BSDF sampling alone (its light-sampling pdf is 0, so
    /// MIS weighs what a path hits by 1): unbiased, noisier for small bright maps, where
    /// sampling it would need the map's texels per triangle in the light table.
    #[inline]
    pub fn is_sampled_light(&self) -> bool {
        self.is_emissive() && self.emission_map.is_none()
    }

    /// The scattering function at texture coordinates `uv`, of albedo `albedo`.
    #[inline(always)]
    pub fn bsdf(&self, albedo: Vec3, uv: Vec2) -> bsdf::Bsdf {
        match self.kind {
            MaterialKind::Pbr => {
                let (mut metallic, mut roughness) = (self.metallic, self.roughness);
                if let Some(t) = &self.metallic_roughness {
                    let texel = t.sample_with(uv, self.lookups.metallic_roughness.as_ref());
                    metallic *= texel.z;
                    roughness *= texel.y;
                }
                bsdf::Bsdf::pbr(albedo, metallic, roughness, self.transmission, self.ior)
            }
            kind => bsdf::Bsdf::new(kind, albedo, self.roughness, self.ior),
        }
    }
}

/// Everything the kernel needs to render one scene state. `Send + Sync`: one
/// scene is shared by all render threads.
pub struct RenderScene {
    assets: Arc<Assets>,
    state: SceneState,
    blas_cache: HashMap<Geometry, Arc<Blas>>,
    pub(crate) tlas: Tlas,
    pub(crate) materials: Vec<MaterialData>,
    /// Per instance (from `Instance::material_base`): material of each slot.
    pub(crate) slot_materials: Vec<u32>,
    /// Whether some material is [`MaterialData::cutout`]: without one, hits are taken as
    /// found and shadow rays stop at any hit.
    pub(crate) cutouts: bool,
    /// Whether some emissive material has an emission map.
    pub(crate) mapped_emission: bool,
    pub(crate) lights: Lights,
    pub(crate) camera: CameraRays,
    triangles: usize,
}

impl RenderScene {
    /// Builds one bottom-level BVH per mesh (cached by Geometry, built once) and the
    /// top-level BVH over the state's object instances.
    pub fn new(assets: Arc<Assets>, state: &SceneState) -> Result<Self, RenderError> {
        let camera = CameraRays::new(&state.camera, state.resolution)?;
        let mut scene = Self {
            assets,
            state: state.clone(),
            blas_cache: HashMap::new(),
            tlas: Tlas::build(Vec::new()),
            materials: Vec::new(),
            slot_materials: Vec::new(),
            cutouts: false,
            mapped_emission: false,
            lights: Lights::default(),
            camera,
            triangles: 0,
        };
        scene.set_state(state)?;
        Ok(scene)
    }

    /// Applies a new scene state: rebuilds only the top-level BVH (and material/light
    /// tables); bottom-level BVHs are reused. New geometry must be present in the
    /// Assets (built-in shapes are generated when absent). On error the previous
    /// state stays in force.
    pub fn set_state(&mut self, state: &SceneState) -> Result<(), RenderError> {
        let camera = CameraRays::new(&state.camera, state.resolution)?;
        let materials = self.resolve_materials(state)?;
        let mut instances = Vec::new();
        let mut slot_materials = Vec::new();
        let mut areas = Vec::new();
        let mut triangles = 0;
        for (index, object) in state.objects.iter().enumerate() {
            if !object.visible {
                continue;
            }
            let blas = self.blas_for(&object.name, &object.geometry)?;
            let slots = blas.mesh.slot_count.max(1);
            if object.materials.len() < slots as usize {
                return Err(RenderError::SlotCount {
                    object: object.name.clone(),
                    bound: object.materials.len(),
                    slots,
                });
            }
            if let Some(&material) =
                object.materials.iter().find(|&&m| m as usize >= materials.len())
            {
                return Err(RenderError::MaterialOutOfRange {
                    object: object.name.clone(),
                    material,
                    count: materials.len(),
                });
            }
            let matrix = Affine3A::from_mat4(object.transform.matrix());
            if !matrix.is_finite() || matrix.matrix3.determinant().abs() < 1e-20 {
                return Err(RenderError::BadTransform { object: object.name.clone() });
            }
            let base = slot_materials.len() as u32;
            slot_materials.extend_from_slice(&object.materials[..slots as usize]);
            let instance = Instance::new(blas.clone(), matrix, index as u32, base);
            collect_emitters(&instance, &object.materials, &materials, &mut areas);
            triangles += blas.triangle_count();
            instances.push(instance);
        }
        let environment = self.resolve_environment(state)?;
        for (index, light) in state.lights.iter().enumerate() {
            if !light_is_finite(light) {
                return Err(RenderError::BadLight { index });
            }
        }
        self.lights = Lights::new(areas, &state.lights, environment);
        self.tlas = Tlas::build(instances);
        self.cutouts = materials.iter().any(|m| m.cutout);
        self.mapped_emission = materials.iter().any(|m| m.is_emissive() && !m.is_sampled_light());
        self.materials = materials;
        self.slot_materials = slot_materials;
        self.camera = camera;
        self.triangles = triangles;
        self.state = state.clone();
        Ok(())
    }

    /// The two-level BVH (for the stage benchmarks in `benches/stages.rs`).
    pub fn tlas(&self) -> &Tlas {
        &self.tlas
    }

    /// The lights as the kernel samples them (for the stage benchmarks).
    pub fn lights(&self) -> &Lights {
        &self.lights
    }

    pub fn state(&self) -> &SceneState {
        &self.state
    }

    /// Renders `spp` samples per pixel from now on (a job's own; the state's
    /// `render.spp` until then): nothing is rebuilt.
    pub fn set_spp(&mut self, spp: u32) {
        self.state.render.spp = spp.max(1);
    }

    /// Triangles of all visible instances (instanced meshes counted per instance).
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// The cached BLAS of a geometry, building it on first use.
    fn blas_for(&mut self, object: &str, geometry: &Geometry) -> Result<Arc<Blas>, RenderError> {
        if let Some(blas) = self.blas_cache.get(geometry) {
            return Ok(blas.clone());
        }
        let mesh: Arc<Mesh> = match self.assets.meshes.get(geometry) {
            Some(mesh) => mesh.clone(),
            None => shapes::mesh(geometry).map(Arc::new).ok_or_else(|| {
                RenderError::MissingMesh { object: object.to_string(), geometry: geometry.clone() }
            })?,
        };
        let blas = Arc::new(
            Blas::build(mesh)
                .map_err(|source| RenderError::BadMesh { object: object.to_string(), source })?,
        );
        self.blas_cache.insert(geometry.clone(), blas.clone());
        Ok(blas)
    }

    fn resolve_materials(&self, state: &SceneState) -> Result<Vec<MaterialData>, RenderError> {
        state
            .materials
            .iter()
            .map(|m| {
                let unit = |v: f32| (0.0..=1.0).contains(&v);
                let l = &m.lookups;
                let ok = m.base_color.is_finite()
                    && m.base_color.min_element() >= 0.0
                    && m.emission.is_finite()
                    && m.emission.min_element() >= 0.0
                    && m.emission_strength.is_finite()
                    && m.emission_strength >= 0.0
                    && m.roughness.is_finite()
                    && m.ior.is_finite()
                    && unit(m.metallic)
                    && unit(m.transmission)
                    && unit(m.alpha)
                    && unit(m.alpha_cutoff)
                    && m.normal_scale.is_finite()
                    && [l.base_color, l.metallic_roughness, l.normal, l.emissive]
                        .iter()
                        .all(|l| l.is_finite());
                if !ok {
                    return Err(RenderError::BadMaterial { material: m.name.clone() });
                }
                let (mut texture, mut metallic_roughness, mut normal_map) = (None, None, None);
                let mut emission_map = None;
                for (path, usage) in m.textures() {
                    let tex = self.assets.texture(path, usage).ok_or_else(|| {
                        RenderError::MissingTexture { material: m.name.clone(), path: path.into() }
                    })?;
                    check_texture(path, tex)?;
                    match usage {
                        TextureUse::Color => texture = Some(tex.clone()),
                        TextureUse::Data => metallic_roughness = Some(tex.clone()),
                        TextureUse::Normal => normal_map = Some(tex.clone()),
                        TextureUse::Emission => emission_map = Some(tex.clone()),
                    }
                }
                let mut data = MaterialData {
                    kind: m.kind,
                    base_color: m.base_color,
                    texture,
                    roughness: m.roughness,
                    ior: m.ior,
                    emission: m.emission * m.emission_strength,
                    metallic: m.metallic,
                    transmission: m.transmission,
                    metallic_roughness,
                    normal_map,
                    normal_scale: m.normal_scale,
                    emission_map,
                    lookups: Lookups {
                        base_color: Lookup::new(&l.base_color),
                        metallic_roughness: Lookup::new(&l.metallic_roughness),
                        normal: Lookup::new(&l.normal),
                        emissive: Lookup::new(&l.emissive),
                    },
                    alpha: m.alpha,
                    alpha_mode: m.alpha_mode,
                    alpha_cutoff: m.alpha_cutoff,
                    cutout: false,
                };
                data.cutout = alpha::can_let_through(&data);
                Ok(data)
            })
            .collect()
    }

    fn resolve_environment(&self, state: &SceneState) -> Result<Option<Environment>, RenderError> {
        let Some(env) = &state.environment else { return Ok(None) };
        let scale = env.color * env.intensity;
        if !scale.is_finite() || !env.rotation_deg.is_finite() {
            return Err(RenderError::BadLight { index: state.lights.len() });
        }
        match &env.map {
            None => Ok((scale.max_element() > 0.0).then(|| Environment::constant(scale))),
            Some(path) => {
                let tex = self
                    .assets
                    .environments
                    .get(path)
                    .ok_or_else(|| RenderError::MissingEnvironment { path: path.clone() })?;
                check_texture(path, tex)?;
                Ok(Some(Environment::map(tex.clone(), scale, env.rotation_deg)))
            }
        }
    }
}

fn check_texture(path: &str, tex: &Texture) -> Result<(), RenderError> {
    if tex.width == 0
        || tex.height == 0
        || tex.texels.len() != tex.width as usize * tex.height as usize
    {
        return Err(RenderError::BadTexture {
            path: path.to_string(),
            texels: tex.texels.len(),
            width: tex.width,
            height: tex.height,
        });
    }
    Ok(())
}

fn light_is_finite(light: &gridlight_actors::state::Light) -> bool {
    use gridlight_actors::state::Light;
    match *light {
        Light::Point { position, intensity } => position.is_finite() && intensity.is_finite(),
        Light::Spot { position, direction, intensity, inner_deg, outer_deg } => {
            position.is_finite()
                && direction.is_finite()
                && intensity.is_finite()
                && inner_deg.is_finite()
                && outer_deg.is_finite()
        }
        Light::Sun { direction, radiance, angular_radius_deg } => {
            direction.is_finite() && radiance.is_finite() && angular_radius_deg.is_finite()
        }
        Light::Quad { corner, edge_u, edge_v, radiance } => {
            corner.is_finite() && edge_u.is_finite() && edge_v.is_finite() && radiance.is_finite()
        }
    }
}

/// Appends the world-space emissive triangles of an instance.
fn collect_emitters(
    instance: &Instance,
    bindings: &[u32],
    materials: &[MaterialData],
    out: &mut Vec<AreaLight>,
) {
    let mesh = &instance.blas.mesh;
    if !bindings.iter().any(|&m| materials[m as usize].is_sampled_light()) {
        return;
    }
    let m = &instance.object_to_world;
    for (i, tri) in mesh.indices.iter().enumerate() {
        let slot = mesh.slot(i) as usize;
        let material = &materials[bindings[slot] as usize];
        if !material.is_sampled_light() {
            continue;
        }
        let [a, b, c] = tri.map(|v| m.transform_point3(mesh.positions[v as usize]));
        let (e1, e2) = (b - a, c - a);
        let object_normal = {
            let [oa, ob, oc] = tri.map(|v| mesh.positions[v as usize]);
            (ob - oa).cross(oc - oa)
        };
        let normal = instance.normal_to_world.mul_vec3(object_normal).normalize_or_zero();
        if normal == Vec3::ZERO {
            continue;
        }
        out.push(AreaLight {
            v0: a,
            e1,
            e2,
            normal,
            radiance: material.emission,
            parallelogram: false,
        });
    }
}
