//! The scene file format: serde types mirroring the TOML, with defaults and nothing else.
//!
//! Every table denies unknown keys, so a typo is an error rather than a silently ignored
//! setting. Checking values (finite, in range, names that exist) is [`super::build`]'s job,
//! where the key of each value is known. Example:
//!
//! ```toml
//! [camera]
//! position = [0, 0, 3.9]
//! look_at = [0, 0, 0]
//! vfov = 39.3077
//!
//! [[materials]]
//! name = "white"
//! base_color = [0.8, 0.8, 0.8]
//!
//! [[objects]]
//! shape = "cube"            # or: mesh = "bunny/stanford-bunny.obj" (or a .gltf/.glb)
//! material = "white"
//! transform = { translation = [0, -0.7, 0], rotation = [0, -17, 0], scale = 0.6 }
//! ```

use std::collections::BTreeMap;
use std::fmt;

use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;

/// A whole scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub camera: CameraDesc,
    #[serde(default)]
    pub resolution: ResolutionDesc,
    /// Mixed into every sample's seed.
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub render: RenderDesc,
    #[serde(default)]
    pub materials: Vec<MaterialDesc>,
    #[serde(default)]
    pub objects: Vec<ObjectDesc>,
    #[serde(default)]
    pub lights: Vec<LightDesc>,
    pub environment: Option<EnvironmentDesc>,
}

/// `[camera]`: a pinhole (aperture 0) or thin-lens camera.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub position: [f32; 3],
    pub look_at: [f32; 3],
    #[serde(default = "default_up")]
    pub up: [f32; 3],
    /// Vertical field of view in degrees, in (0, 180).
    pub vfov: f32,
    /// Lens radius; 0 is a pinhole.
    #[serde(default)]
    pub aperture: f32,
    /// Distance to the plane in focus; defaults to the distance to `look_at`.
    pub focus_distance: Option<f32>,
}

fn default_up() -> [f32; 3] {
    [0.0, 1.0, 0.0]
}

/// `[resolution]`: image size in pixels.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ResolutionDesc {
    #[serde(default = "default_width")]
    pub width: u32,
    #[serde(default = "default_height")]
    pub height: u32,
}

/// Default image width.
pub const DEFAULT_WIDTH: u32 = 640;
/// Default image height.
pub const DEFAULT_HEIGHT: u32 = 480;

fn default_width() -> u32 {
    DEFAULT_WIDTH
}
fn default_height() -> u32 {
    DEFAULT_HEIGHT
}

impl Default for ResolutionDesc {
    fn default() -> Self {
        Self { width: DEFAULT_WIDTH, height: DEFAULT_HEIGHT }
    }
}

/// `[render]`: path tracing settings.
#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    /// Maximum path length in segments (5 = camera ray plus four bounces).
    #[serde(default = "default_max_depth")]
    pub max_depth: u32,
    /// Samples per pixel per update.
    #[serde(default = "default_spp")]
    pub spp: u32,
    /// `[render.reconstruction]`: the master's reconstruction (paper defaults).
    #[serde(default)]
    pub reconstruction: crate::reconstruct::ReconstructParams,
    /// `[render.display]`: when the master shows a frame.
    #[serde(default)]
    pub display: DisplayDesc,
}

/// `[render.display]`: the paper's wait heuristic (any of `q_min`, `q_max`, `i_min`,
/// `i_max`; the rest keep the paper's values) or a fixed frame rate (`fps`), not both.
/// Command-line flags override each.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DisplayDesc {
    pub fps: Option<f32>,
    pub q_min: Option<f64>,
    pub q_max: Option<f64>,
    pub i_min: Option<f64>,
    pub i_max: Option<f64>,
}

fn default_max_depth() -> u32 {
    gridlight_actors::state::RenderSettings::default().max_depth
}
fn default_spp() -> u32 {
    gridlight_actors::state::RenderSettings::default().spp
}

impl Default for RenderDesc {
    fn default() -> Self {
        Self {
            max_depth: default_max_depth(),
            spp: default_spp(),
            reconstruction: Default::default(),
            display: DisplayDesc::default(),
        }
    }
}

/// How a material scatters light (`kind = "diffuse"` …).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KindDesc {
    #[default]
    Diffuse,
    Conductor,
    Glossy,
    Dielectric,
    /// glTF 2.0 metallic-roughness.
    Pbr,
}

/// `alpha_mode = "opaque"` (default), `"mask"` or `"blend"`, as glTF's `alphaMode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AlphaModeDesc {
    #[default]
    Opaque,
    Mask,
    Blend,
}

/// `[[materials]]`: a named material that objects refer to.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialDesc {
    pub name: String,
    #[serde(default)]
    pub kind: KindDesc,
    /// Linear RGB albedo / reflectance.
    #[serde(default = "default_base_color")]
    pub base_color: [f32; 3],
    /// Asset path of an sRGB albedo texture that replaces `base_color`.
    pub texture: Option<String>,
    /// GGX roughness in [0, 1] (perceptual; squared to alpha).
    #[serde(default = "default_roughness")]
    pub roughness: f32,
    /// Index of refraction (dielectric, and the coat of glossy).
    #[serde(default = "default_ior")]
    pub ior: f32,
    /// Emitted radiance (linear RGB).
    #[serde(default)]
    pub emission: [f32; 3],
    /// Multiplies `emission`; default 1.
    pub emission_strength: Option<f32>,
    /// `pbr`: 0 (default) a non-metal, 1 a metal.
    pub metallic: Option<f32>,
    /// `pbr`: share of the non-metal's diffuse base replaced by rough glass; default 0.
    pub transmission: Option<f32>,
    /// `pbr`: asset path of a linear map, B × `metallic`, G × `roughness`.
    pub metallic_roughness_map: Option<String>,
    /// `pbr`: asset path of a tangent-space normal map (linear, +y up: glTF's, OpenGL's).
    pub normal_map: Option<String>,
    /// `pbr`: the normal map's xy scale; default 1.
    pub normal_scale: Option<f32>,
    /// `pbr`: asset path of an sRGB map multiplying `emission` (× `emission_strength`).
    pub emissive_map: Option<String>,
    /// Coverage in [0, 1]; default 1 (anything else is not rendered yet: a warning).
    pub alpha: Option<f32>,
    #[serde(default)]
    pub alpha_mode: AlphaModeDesc,
    /// `alpha_mode = "mask"`: covered where alpha ≥ this; default 0.5.
    pub alpha_cutoff: Option<f32>,
    /// glTF's `doubleSided`; default true (gridlight shades both sides either way).
    pub double_sided: Option<bool>,
}

fn default_base_color() -> [f32; 3] {
    [0.8, 0.8, 0.8]
}
fn default_roughness() -> f32 {
    0.3
}
fn default_ior() -> f32 {
    1.5
}

/// Built-in shapes (`shape = "quad"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ShapeDesc {
    /// Unit square in the xz-plane, normal +y.
    Quad,
    /// Unit cube centred at the origin.
    Cube,
    /// Unit-radius icosphere.
    Sphere,
}

/// Default icosphere subdivision level.
pub const DEFAULT_SPHERE_SUBDIVISIONS: u32 = 4;

/// `[[objects]]`: one placed mesh or built-in shape.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectDesc {
    /// Unique name; defaults to the mesh's file stem or the shape, plus the index.
    pub name: Option<String>,
    /// Asset path of a Wavefront OBJ (with its MTL) or a glTF 2.0 file (`.gltf`, `.glb`:
    /// its default scene, node transforms applied). Exactly one of `mesh` and `shape`.
    pub mesh: Option<String>,
    pub shape: Option<ShapeDesc>,
    /// Icosphere subdivisions (`shape = "sphere"` only).
    pub subdivisions: Option<u32>,
    #[serde(default)]
    pub transform: TransformDesc,
    /// Named material for every slot (built-in shapes need one unless the default grey does).
    pub material: Option<String>,
    /// Overrides per MTL or glTF material name: `{ "leaf" = "my_leaf" }`.
    #[serde(default)]
    pub materials: BTreeMap<String, String>,
    #[serde(default = "default_true")]
    pub visible: bool,
}

fn default_true() -> bool {
    true
}

/// `transform = { ... }`: applied as scale, then rotation, then translation.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransformDesc {
    #[serde(default)]
    pub translation: [f32; 3],
    /// Euler angles in degrees, applied about x, then y, then z (fixed axes).
    pub rotation: Option<[f32; 3]>,
    /// Rotation axis, with `angle` (degrees); an alternative to `rotation`.
    pub axis: Option<[f32; 3]>,
    pub angle: Option<f32>,
    /// Uniform (`2.0`) or per-axis (`[1, 2, 1]`) scale.
    #[serde(default)]
    pub scale: ScaleDesc,
}

/// A uniform or per-axis scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScaleDesc(pub [f32; 3]);

impl Default for ScaleDesc {
    fn default() -> Self {
        Self([1.0; 3])
    }
}

impl<'de> Deserialize<'de> for ScaleDesc {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ScaleVisitor;
        impl<'de> Visitor<'de> for ScaleVisitor {
            type Value = ScaleDesc;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number (uniform scale) or an array of three numbers")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ScaleDesc, E> {
                Ok(ScaleDesc([v as f32; 3]))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ScaleDesc, E> {
                Ok(ScaleDesc([v as f32; 3]))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ScaleDesc, E> {
                Ok(ScaleDesc([v as f32; 3]))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<ScaleDesc, A::Error> {
                let mut out = [0.0f32; 3];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot =
                        seq.next_element()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<f32>()?.is_some() {
                    return Err(de::Error::invalid_length(4, &self));
                }
                Ok(ScaleDesc(out))
            }
        }
        deserializer.deserialize_any(ScaleVisitor)
    }
}

/// `[[lights]]`: lights that are not emissive geometry (`kind = "point"` …).
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum LightDesc {
    /// Isotropic point light; `intensity` in W/sr.
    Point { position: [f32; 3], intensity: [f32; 3] },
    /// Spot light aimed at `look_at`, full intensity inside `inner`, none outside `outer`
    /// (half-angles in degrees).
    Spot { position: [f32; 3], look_at: [f32; 3], intensity: [f32; 3], inner: f32, outer: f32 },
    /// A distant sun disc. `direction` points from the scene towards the sun; `irradiance`
    /// is what a surface facing the sun receives (converted to disc radiance on build).
    Sun {
        direction: [f32; 3],
        irradiance: [f32; 3],
        #[serde(default = "default_sun_radius")]
        angular_radius: f32,
    },
    /// One-sided emissive parallelogram `corner + u*edge_u + v*edge_v`, emitting towards
    /// `edge_u × edge_v`.
    Quad { corner: [f32; 3], edge_u: [f32; 3], edge_v: [f32; 3], radiance: [f32; 3] },
}

/// The real sun's angular radius in degrees.
pub const SUN_ANGULAR_RADIUS_DEG: f32 = 0.265;

fn default_sun_radius() -> f32 {
    SUN_ANGULAR_RADIUS_DEG
}

/// `[environment]`: an equirectangular HDR map (times `color` and `intensity`) or, without
/// `map`, the constant radiance `color * intensity`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentDesc {
    pub map: Option<String>,
    #[serde(default = "default_white")]
    pub color: [f32; 3],
    #[serde(default = "default_one")]
    pub intensity: f32,
    /// Rotation about +y in degrees.
    #[serde(default)]
    pub rotation: f32,
}

fn default_white() -> [f32; 3] {
    [1.0; 3]
}
fn default_one() -> f32 {
    1.0
}
