//! A glTF file as a whole scene: its camera, lights and a sky when it has no light, as a
//! [`SceneFile`] whose one object is the file's mesh (the TOML path then builds it, so a
//! `.glb` is checked exactly like a scene file).
//!
//! **Camera.** The file's first camera (lowest index that a node of the scene places):
//! vertical field of view and aspect ratio kept; 640×480 for a 4:3 camera, else 480 high
//! and as wide as the aspect ratio says; 640×480 without an aspect ratio. An orthographic
//! camera (warned about) or none gives a framing camera: [`FRAMING_VFOV_DEG`], looking
//! slightly down at the centre of the scene's bounds from the +z side, far enough for the
//! bounding sphere to fit.
//!
//! **Light units.** glTF gives point and spot intensities in candela (lm/sr) and
//! directional ones in lux (lm/m²); gridlight's point and spot intensities are in W/sr
//! and the sun's irradiance in W/m², with no exposure control. The numbers are taken
//! **1:1** (1 cd → 1 W/sr, 1 lux → 1 W/m²), not through the 683 lm/W luminous efficacy:
//! files are authored for viewers that use them directly (three.js, Babylon.js and
//! Filament without an exposure setting treat 1 lux as irradiance 1), so a directional
//! light of intensity 3 gives the brightness the author saw, where 1/683 of it would
//! render black. `range` is ignored (warned): lights fall off with the inverse square.
//! Spot cone angles are half-angles in radians in glTF and in degrees in gridlight.
//!
//! **Sky.** A file with no light and no emissive material would render black; it gets a
//! constant white environment of radiance [`DEFAULT_SKY_RADIANCE`] (a white diffuse
//! surface under it shows about its albedo).

use glam::{Mat4, Vec3};
use gltf::camera::Projection;
use gltf::khr_lights_punctual::Kind;

use super::{GltfData, Warnings};
use crate::scene::description::*;

/// Vertical field of view of the framing camera, degrees (a 50 mm lens on 35 mm film).
pub const FRAMING_VFOV_DEG: f32 = 39.6;
/// Radiance of the sky a file without lights gets.
pub const DEFAULT_SKY_RADIANCE: f32 = 1.0;
/// Image height for cameras whose aspect ratio is not 4:3.
const HEIGHT: u32 = DEFAULT_HEIGHT;

/// A camera a node places.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedCamera {
    /// Index in the file's `cameras`.
    pub index: usize,
    pub world: Mat4,
    /// Vertical field of view (radians) and aspect ratio; `None` for orthographic.
    pub perspective: Option<(f32, Option<f32>)>,
}

impl PlacedCamera {
    pub(crate) fn new(camera: &gltf::Camera, world: Mat4) -> Self {
        let perspective = match camera.projection() {
            Projection::Perspective(p) => Some((p.yfov(), p.aspect_ratio())),
            Projection::Orthographic(_) => None,
        };
        Self { index: camera.index(), world, perspective }
    }
}

/// A KHR_lights_punctual light a node places.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedLight {
    pub kind: LightKind,
    /// Linear colour times intensity (candela or lux, see the module doc).
    pub intensity: Vec3,
    pub range: Option<f32>,
    pub world: Mat4,
}

/// The kind of a punctual light; spot cone half-angles in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LightKind {
    Point,
    Spot { inner: f32, outer: f32 },
    Directional,
}

impl PlacedLight {
    pub(crate) fn new(light: &gltf::khr_lights_punctual::Light, world: Mat4) -> Self {
        let kind = match light.kind() {
            Kind::Point => LightKind::Point,
            Kind::Spot { inner_cone_angle, outer_cone_angle } => {
                LightKind::Spot { inner: inner_cone_angle, outer: outer_cone_angle }
            }
            Kind::Directional => LightKind::Directional,
        };
        let intensity = Vec3::from(light.color()) * light.intensity();
        Self { kind, intensity, range: light.range(), world }
    }

    /// The light as a scene file describes it.
    fn desc(&self) -> LightDesc {
        let position = self.world.transform_point3(Vec3::ZERO);
        // Lights shine along their node's -z; scale is ignored.
        let forward = self.world.transform_vector3(Vec3::NEG_Z).normalize_or_zero();
        let intensity = self.intensity.to_array();
        match self.kind {
            LightKind::Point => LightDesc::Point { position: position.to_array(), intensity },
            LightKind::Spot { inner, outer } => LightDesc::Spot {
                position: position.to_array(),
                look_at: (position + forward).to_array(),
                intensity,
                inner: inner.to_degrees(),
                outer: outer.to_degrees(),
            },
            LightKind::Directional => LightDesc::Sun {
                direction: (-forward).to_array(),
                irradiance: intensity,
                angular_radius: SUN_ANGULAR_RADIUS_DEG,
            },
        }
    }
}

/// The scene of the glTF file at asset path `asset` (see the module doc).
pub fn describe(data: &GltfData, asset: &str, warnings: &mut Warnings) -> SceneFile {
    let (lo, hi) = data
        .mesh
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| (lo.min(p), hi.max(p)));
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-3);
    let first = data.cameras.iter().min_by_key(|c| c.index);
    if first.is_some_and(|c| c.perspective.is_none()) {
        warnings.push("orthographic cameras: not supported (a framing camera is used)");
    }
    let (camera, resolution) = match first.and_then(|c| file_camera(c, centre)) {
        Some(view) => view,
        None => (framing_camera(centre, radius), ResolutionDesc::default()),
    };
    if data.lights.iter().any(|l| l.range.is_some()) {
        warnings.push("KHR_lights_punctual range: ignored (inverse-square falloff, no cut-off)");
    }
    let emissive = data.materials.iter().any(|m| m.material.emission.max_element() > 0.0);
    let environment = (data.lights.is_empty() && !emissive).then_some(EnvironmentDesc {
        map: None,
        color: [1.0; 3],
        intensity: DEFAULT_SKY_RADIANCE,
        rotation: 0.0,
    });
    let stem = asset.rsplit('/').next().unwrap_or(asset);
    let stem = stem.rsplit_once('.').map_or(stem, |(s, _)| s);
    SceneFile {
        camera,
        resolution,
        seed: 0,
        render: RenderDesc::default(),
        materials: Vec::new(),
        objects: vec![ObjectDesc {
            name: Some(stem.to_owned()),
            mesh: Some(asset.to_owned()),
            shape: None,
            subdivisions: None,
            transform: TransformDesc::default(),
            material: None,
            materials: Default::default(),
            visible: true,
        }],
        lights: data.lights.iter().map(PlacedLight::desc).collect(),
        environment,
    }
}

/// The view of a perspective camera, `None` for orthographic or degenerate ones.
fn file_camera(c: &PlacedCamera, centre: Vec3) -> Option<(CameraDesc, ResolutionDesc)> {
    let (yfov, aspect) = c.perspective?;
    let position = c.world.transform_point3(Vec3::ZERO);
    let forward = c.world.transform_vector3(Vec3::NEG_Z).try_normalize()?;
    let up = c.world.transform_vector3(Vec3::Y).try_normalize()?;
    // Aim at the scene's centre depth so that orbiting turns about the model.
    let distance = (centre - position).length().max(1e-3);
    let camera = CameraDesc {
        position: position.to_array(),
        look_at: (position + forward * distance).to_array(),
        up: up.to_array(),
        vfov: yfov.to_degrees(),
        aperture: 0.0,
        focus_distance: None,
    };
    Some((camera, resolution_for(aspect)))
}

/// The image size for a camera's aspect ratio (module doc).
pub fn resolution_for(aspect: Option<f32>) -> ResolutionDesc {
    match aspect.filter(|a| a.is_finite() && *a > 0.0) {
        Some(a) if (a - 4.0 / 3.0).abs() > 1e-3 => {
            let max = crate::scene::build::MAX_RESOLUTION as f32;
            let width = (HEIGHT as f32 * a).round().clamp(1.0, max) as u32;
            ResolutionDesc { width, height: HEIGHT }
        }
        _ => ResolutionDesc::default(),
    }
}

/// A camera that sees the whole bounding sphere, from the front and a little above.
pub fn framing_camera(centre: Vec3, radius: f32) -> CameraDesc {
    let half = (FRAMING_VFOV_DEG * 0.5).to_radians();
    let distance = radius / half.sin() * 1.1;
    let direction = Vec3::new(0.0, 0.35, 1.0).normalize();
    CameraDesc {
        position: (centre + direction * distance).to_array(),
        look_at: centre.to_array(),
        up: [0.0, 1.0, 0.0],
        vfov: FRAMING_VFOV_DEG,
        aperture: 0.0,
        focus_distance: None,
    }
}
