//! The scene state: the absolute value a worker needs to render one view.
//!
//! A [`SceneState`] is camera, objects (geometry reference, transform, material
//! binding), materials, lights, environment and render settings. It never carries
//! asset data (meshes, textures, environment maps): those are named by their asset
//! path and fetched once per worker (docs/design.md, decision 4). It travels whole, never
//! as a diff (docs/design.md, decision 3), and every edit gives it a new
//! [`StateVersion`]; the master's scene-state holder is the only place that bumps it.
//!
//! The types are plain serde values with glam vectors so that the master, the
//! worker and the wire share one vocabulary; building render structures from them
//! (meshes, BVHs) happens in the `gridlight` crate.

use glam::{Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// Version of a scene state; strictly increasing within one master run.
pub type StateVersion = u64;

/// Index of a material in [`SceneState::materials`].
pub type MaterialId = u32;

/// Everything a worker needs to render one view, as an absolute value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneState {
    /// Changes on every edit; jobs name the version they must be rendered with.
    pub version: StateVersion,
    /// Scene-wide seed mixed into every sample's seed (STYLE.md item 9).
    pub seed: u64,
    pub resolution: Resolution,
    pub camera: Camera,
    pub objects: Vec<Object>,
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    /// Radiance arriving from infinity; `None` means black.
    pub environment: Option<Environment>,
    pub render: RenderSettings,
}

impl SceneState {
    /// An empty scene seen through `camera`: version 1, seed 0, no objects, materials,
    /// lights or environment, default render settings. Scene files build the full value
    /// (`gridlight::scene`); tests and benches start here and add what they need.
    pub fn empty(resolution: Resolution, camera: Camera) -> Self {
        Self {
            version: 1,
            seed: 0,
            resolution,
            camera,
            objects: Vec::new(),
            materials: Vec::new(),
            lights: Vec::new(),
            environment: None,
            render: RenderSettings::default(),
        }
    }

    /// Adds `object` with `material` as its only material.
    pub fn with_object(mut self, mut object: Object, material: Material) -> Self {
        object.materials = vec![self.materials.len() as MaterialId];
        self.objects.push(object);
        self.materials.push(material);
        self
    }
}

/// Image size in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Resolution {
    pub width: u32,
    pub height: u32,
}

impl Resolution {
    /// The largest side the scene file, the command line and a live resize accept: a
    /// 16384² frame's pixel sets and planes already take gigabytes on the master.
    pub const MAX_SIDE: u32 = 16384;

    /// Number of pixels in the image.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }
}

/// A pinhole camera (aperture 0) or a thin lens.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub vfov_deg: f32,
    /// Lens radius in scene units; 0 is a pinhole.
    pub aperture: f32,
    /// Distance to the plane in focus (used only when `aperture > 0`).
    pub focus_distance: f32,
}

impl Camera {
    /// A pinhole camera at `position` looking at `look_at`, +y up, in focus at `look_at`.
    pub fn pinhole(position: Vec3, look_at: Vec3, vfov_deg: f32) -> Self {
        let focus_distance = (look_at - position).length();
        Self { position, look_at, up: Vec3::Y, vfov_deg, aperture: 0.0, focus_distance }
    }
}

/// One placed instance of a piece of geometry.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// Unique within the scene; edits and picking refer to objects by name.
    pub name: String,
    pub geometry: Geometry,
    pub transform: Transform,
    /// Material of each material slot of the geometry. An OBJ mesh has one slot per
    /// material of its MTL, in the MTL's order, plus a last slot for faces that name
    /// no material; a glTF file likewise, one slot per material of the file plus a last
    /// one for primitives without; built-in shapes have one slot.
    pub materials: Vec<MaterialId>,
    pub visible: bool,
}

impl Object {
    /// A visible object at the origin (identity transform) using material 0.
    pub fn new(name: &str, geometry: Geometry) -> Self {
        Self {
            name: name.into(),
            geometry,
            transform: Transform::default(),
            materials: vec![0],
            visible: true,
        }
    }
}

/// What an object is made of. Files are asset paths relative to an asset root,
/// resolved by the loader (master: the asset search path; worker: its cache).
#[derive(Clone, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Geometry {
    /// A Wavefront OBJ file (triangulated on load); its MTL and textures are assets too.
    Obj { path: String },
    /// A glTF 2.0 file (`.gltf` or `.glb`): its default scene's meshes, with the node
    /// hierarchy's transforms applied, as one mesh; its buffers and images are assets too.
    Gltf { path: String },
    /// A unit square in the xz-plane centred at the origin, normal +y.
    Quad,
    /// An axis-aligned unit cube centred at the origin.
    Cube,
    /// A unit sphere tessellated with the given number of subdivisions.
    Sphere { subdivisions: u32 },
}

/// Translation, rotation and uniform scale, applied as `T * R * S`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE }
    }
}

impl Transform {
    /// The object-to-world matrix.
    pub fn matrix(&self) -> glam::Mat4 {
        glam::Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }
}

/// How a surface scatters light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum MaterialKind {
    /// Lambertian.
    Diffuse,
    /// GGX microfacet conductor; `base_color` is the reflectance at normal incidence.
    Conductor,
    /// Diffuse base under a GGX dielectric coat (plastic-like gloss).
    Glossy,
    /// Smooth (roughness 0) or rough GGX glass.
    Dielectric,
    /// glTF 2.0 metallic-roughness (the specification's BRDF appendix): a Lambertian base
    /// under an F0 = ((ior − 1)/(ior + 1))² GGX layer, mixed with a GGX metal of
    /// reflectance `base_color` by `metallic`; `transmission` replaces the non-metal's
    /// diffuse base by rough glass (`KHR_materials_transmission`).
    Pbr,
}

/// How a material's `alpha` (times its base colour texture's alpha) covers the surface
/// (glTF's `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AlphaMode {
    /// Alpha is ignored.
    #[default]
    Opaque,
    /// Covered where alpha ≥ `alpha_cutoff`, absent elsewhere.
    Mask,
    /// Covered with probability alpha.
    Blend,
}

/// How a texture coordinate outside [0, 1] is brought back (glTF's sampler `wrapS`,
/// `wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Wrap {
    #[default]
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// How a material looks one of its maps up: the wrap along u and v, and glTF's
/// `KHR_texture_transform` in glTF's texture space (v down): uv' = offset + R (scale × uv),
/// R turning the coordinates by `rotation` radians counter-clockwise.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MapLookup {
    pub wrap: [Wrap; 2],
    pub offset: Vec2,
    pub rotation: f32,
    pub scale: Vec2,
}

impl Default for MapLookup {
    /// Repeat, untransformed.
    fn default() -> Self {
        Self { wrap: [Wrap::Repeat; 2], offset: Vec2::ZERO, rotation: 0.0, scale: Vec2::ONE }
    }
}

impl MapLookup {
    /// Whether the lookup is the default one (repeat, untransformed).
    pub fn is_plain(&self) -> bool {
        *self == Self::default()
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.offset.is_finite() && self.rotation.is_finite() && self.scale.is_finite()
    }
}

/// The [`MapLookup`] of each map a material may have.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MapLookups {
    pub base_color: MapLookup,
    pub metallic_roughness: MapLookup,
    pub normal: MapLookup,
    pub emissive: MapLookup,
}

impl MapLookups {
    /// The lookup of the map read as `usage`.
    pub fn of(&self, usage: TextureUse) -> &MapLookup {
        match usage {
            TextureUse::Color => &self.base_color,
            TextureUse::Data => &self.metallic_roughness,
            TextureUse::Normal => &self.normal,
            TextureUse::Emission => &self.emissive,
        }
    }
}

/// Material parameters; everything here can be edited live.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Material {
    pub name: String,
    pub kind: MaterialKind,
    /// Linear RGB albedo / reflectance.
    pub base_color: Vec3,
    /// Asset path of an sRGB albedo texture that replaces `base_color`.
    pub base_color_texture: Option<String>,
    /// GGX roughness (perceptual, squared to alpha).
    pub roughness: f32,
    /// Index of refraction (dielectric, and the coat of `Glossy`).
    pub ior: f32,
    /// Emitted radiance (linear RGB), times `emission_strength`; non-zero makes the
    /// surface a light.
    pub emission: Vec3,
    /// Multiplies `emission` (glTF's `KHR_materials_emissive_strength`); 1 by default.
    pub emission_strength: f32,
    /// `Pbr`: 0 a non-metal, 1 a metal of reflectance `base_color`; linear in between.
    pub metallic: f32,
    /// `Pbr`: the share of the non-metal's diffuse base replaced by rough glass.
    pub transmission: f32,
    /// Coverage in [0, 1], used as `alpha_mode` says (1 by default).
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    /// `AlphaMode::Mask`: covered where alpha ≥ this (glTF's default 0.5).
    pub alpha_cutoff: f32,
    /// glTF's `doubleSided`; kept for the file's sake: gridlight shades both sides.
    pub double_sided: bool,
    /// `Pbr`: asset path of a linear texture whose blue channel multiplies `metallic` and
    /// green channel `roughness` (glTF's `metallicRoughnessTexture`).
    pub metallic_roughness_texture: Option<String>,
    /// `Pbr`: asset path of a tangent-space normal map, and its xy scale.
    pub normal_texture: Option<String>,
    pub normal_scale: f32,
    /// `Pbr`: asset path of an sRGB texture multiplying `emission`.
    pub emissive_texture: Option<String>,
    /// How each map is looked up (wrap modes, texture transform).
    pub lookups: MapLookups,
}

impl Material {
    /// A Lambertian, untextured, non-emissive material of this albedo.
    pub fn diffuse(name: &str, base_color: Vec3) -> Self {
        Self {
            name: name.into(),
            kind: MaterialKind::Diffuse,
            base_color,
            base_color_texture: None,
            roughness: 1.0,
            ior: 1.5,
            emission: Vec3::ZERO,
            emission_strength: 1.0,
            metallic: 0.0,
            transmission: 0.0,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            alpha_cutoff: 0.5,
            double_sided: true,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive_texture: None,
            lookups: MapLookups::default(),
        }
    }

    /// A glTF metallic-roughness material with these factors and no maps.
    pub fn pbr(name: &str, base_color: Vec3, metallic: f32, roughness: f32) -> Self {
        Self { kind: MaterialKind::Pbr, metallic, roughness, ..Self::diffuse(name, base_color) }
    }

    /// Every texture the material is rendered with: its asset path and how its texels
    /// are read.
    pub fn textures(&self) -> impl Iterator<Item = (&str, TextureUse)> + '_ {
        let pbr = self.kind == MaterialKind::Pbr;
        [
            (self.base_color_texture.as_deref(), TextureUse::Color),
            (self.metallic_roughness_texture.as_deref().filter(|_| pbr), TextureUse::Data),
            (self.normal_texture.as_deref().filter(|_| pbr), TextureUse::Normal),
            (self.emissive_texture.as_deref().filter(|_| pbr), TextureUse::Emission),
        ]
        .into_iter()
        .filter_map(|(path, usage)| Some((path?, usage)))
    }
}

/// How a texture's 8-bit codes are read.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TextureUse {
    /// sRGB-encoded colour (base colour).
    Color,
    /// Linear data, code / 255 (glTF's metallic-roughness texture).
    Data,
    /// A tangent-space normal map: linear data as `Data`, kept apart only for the
    /// material that reads it.
    Normal,
    /// sRGB-encoded emission (glTF's `emissiveTexture`): read as `Color`, kept apart only
    /// for the material that reads it.
    Emission,
}

/// A light that is not emissive geometry.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Light {
    /// Isotropic point light; `intensity` in W/sr per channel.
    Point { position: Vec3, intensity: Vec3 },
    /// Spot light with a smooth falloff between `inner_deg` and `outer_deg` half-angles.
    Spot { position: Vec3, direction: Vec3, intensity: Vec3, inner_deg: f32, outer_deg: f32 },
    /// Distant "sun" disc: `direction` points from the scene towards the sun;
    /// `radiance` is per steradian of the disc, `angular_radius_deg` its size.
    Sun { direction: Vec3, radiance: Vec3, angular_radius_deg: f32 },
    /// One-sided emissive parallelogram `corner + u*edge_u + v*edge_v`, emitting
    /// towards `edge_u × edge_v`.
    Quad { corner: Vec3, edge_u: Vec3, edge_v: Vec3, radiance: Vec3 },
}

/// Light from infinity: an equirectangular HDR map or a constant colour.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Environment {
    /// Asset path of an equirectangular HDR/EXR map; `None` means `color` everywhere.
    pub map: Option<String>,
    /// Constant radiance, or a tint multiplied into the map.
    pub color: Vec3,
    pub intensity: f32,
    /// Rotation about the up (+y) axis in degrees.
    pub rotation_deg: f32,
}

/// Path tracing settings that travel with the state.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Maximum path length in segments (5 = camera ray plus four bounces).
    pub max_depth: u32,
    /// Samples per pixel per update (per job).
    pub spp: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self { max_depth: 5, spp: 4 }
    }
}
