//! The build step: a parsed [`SceneFile`] becomes a [`SceneState`] plus its loaded [`Assets`].
//!
//! Every value is checked here (finite, in range, names that exist), so that each error can
//! name the key it came from. Mesh files (OBJ, glTF) are read once each; their materials
//! (MTL or glTF) are appended to the state's materials after the scene's named ones, unless
//! an object overrides them.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{EulerRot, Quat, Vec3};
use gridlight_actors::state::{
    AlphaMode, Camera, Environment, Geometry, Light, Material, MaterialId, MaterialKind, Object,
    RenderSettings, Resolution, SceneState, TextureUse, Transform,
};

use super::description::*;
use super::error::{AssetError, Problem, SceneError};
use super::gltf::{is_gltf, Warnings};
use super::loader::{load_environment, load_texture};
use super::loader::{read_mesh_file, MeshFile};
use super::search::{check_asset_path, AssetResolver};
use super::LoadedScene;
use crate::assets::Assets;
use crate::reconstruct::ReconstructError;
use crate::shapes;

/// Largest accepted image side in pixels.
pub const MAX_RESOLUTION: u32 = Resolution::MAX_SIDE;
/// Largest accepted path length.
pub const MAX_DEPTH: u32 = 1024;
/// Name of the material given to faces and shapes that have none.
pub const DEFAULT_MATERIAL: &str = "default";

/// Builds the state and loads its assets; `path` is the scene file (for messages).
pub fn build(
    file: &SceneFile,
    path: &Path,
    resolver: &dyn AssetResolver,
) -> Result<LoadedScene, SceneError> {
    build_with(file, path, resolver, None, Warnings::default())
}

/// [`build`], with the mesh file `preloaded` (asset path, data) already read and
/// `warnings` already found (a glTF scene reads its file before it has a description).
pub(super) fn build_with(
    file: &SceneFile,
    path: &Path,
    resolver: &dyn AssetResolver,
    preloaded: Option<(String, MeshFile)>,
    warnings: Warnings,
) -> Result<LoadedScene, SceneError> {
    let mut b = Builder {
        path,
        resolver,
        assets: Assets::default(),
        materials: Vec::new(),
        preloaded,
        warnings,
    };
    let resolution = b.resolution(&file.resolution)?;
    let camera = b.camera(&file.camera)?;
    let render = b.render(&file.render)?;
    b.master_settings(&file.render)?;
    let mut names = HashMap::new();
    for (i, m) in file.materials.iter().enumerate() {
        let key = format!("materials[{i}]");
        let material = b.material(m, &key)?;
        if names.insert(material.name.clone(), b.materials.len() as MaterialId).is_some() {
            return Err(
                b.invalid(format!("{key}.name"), format!("duplicate material name `{}`", m.name))
            );
        }
        b.materials.push((material, Origin::Table(key)));
    }
    let mut objects = Vec::with_capacity(file.objects.len());
    let mut mtl_ids: HashMap<String, Vec<MaterialId>> = HashMap::new();
    for (i, o) in file.objects.iter().enumerate() {
        let object = b.object(o, i, &mut names, &mut mtl_ids)?;
        if objects.iter().any(|x: &Object| x.name == object.name) {
            return Err(b.invalid(
                format!("objects[{i}].name"),
                format!("duplicate object name `{}`", object.name),
            ));
        }
        objects.push(object);
    }
    let lights = file
        .lights
        .iter()
        .enumerate()
        .map(|(i, l)| b.light(l, &format!("lights[{i}]")))
        .collect::<Result<Vec<_>, _>>()?;
    let environment = file.environment.as_ref().map(|e| b.environment(e)).transpose()?;
    b.load_textures()?;
    let state = SceneState {
        version: 0,
        seed: file.seed,
        resolution,
        camera,
        objects,
        materials: b.materials.into_iter().map(|(m, _)| m).collect(),
        lights,
        environment,
        render,
    };
    Ok(LoadedScene {
        state,
        assets: b.assets,
        reconstruction: file.render.reconstruction,
        display: file.render.display,
        warnings: b.warnings.into_vec(),
    })
}

/// Where a material's textures were named, for errors: its own `[[materials]]` table
/// (`materials[2]`, each map by its key), or a mesh file (the object's `mesh` key).
enum Origin {
    Table(String),
    Mesh(String),
}

impl Origin {
    /// The key that named the texture of this use.
    fn key(&self, usage: TextureUse) -> String {
        match self {
            Self::Table(table) => {
                let field = match usage {
                    TextureUse::Color => "texture",
                    TextureUse::Data => "metallic_roughness_map",
                    TextureUse::Normal => "normal_map",
                    TextureUse::Emission => "emissive_map",
                };
                format!("{table}.{field}")
            }
            Self::Mesh(key) => key.clone(),
        }
    }
}

struct Builder<'a> {
    path: &'a Path,
    resolver: &'a dyn AssetResolver,
    assets: Assets,
    /// The state's materials, each with where its textures were named.
    materials: Vec<(Material, Origin)>,
    /// A mesh file read before the build (see [`build_with`]).
    preloaded: Option<(String, MeshFile)>,
    /// What the scene asks that is not rendered, each once.
    warnings: Warnings,
}

impl Builder<'_> {
    fn invalid(&self, key: impl Into<String>, what: impl Into<String>) -> SceneError {
        SceneError::new(self.path, key, Problem::Invalid(what.into()))
    }

    fn asset(&self, key: impl Into<String>, err: impl Into<AssetError>) -> SceneError {
        SceneError::new(self.path, key, Problem::Asset(err.into()))
    }

    fn vec3(&self, v: [f32; 3], key: &str) -> Result<Vec3, SceneError> {
        let v = Vec3::from(v);
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(key, "value is not finite (NaN or infinity)"))
        }
    }

    fn scalar(&self, v: f32, key: &str) -> Result<f32, SceneError> {
        if v.is_finite() {
            Ok(v)
        } else {
            Err(self.invalid(key, "value is not finite (NaN or infinity)"))
        }
    }

    fn colour(&self, v: [f32; 3], key: &str) -> Result<Vec3, SceneError> {
        let v = self.vec3(v, key)?;
        if v.min_element() < 0.0 {
            return Err(self.invalid(key, format!("colour {v} has a negative component")));
        }
        Ok(v)
    }

    fn direction(&self, v: [f32; 3], key: &str) -> Result<Vec3, SceneError> {
        self.vec3(v, key)?
            .try_normalize()
            .ok_or_else(|| self.invalid(key, "direction has zero length"))
    }

    fn resolution(&self, r: &ResolutionDesc) -> Result<Resolution, SceneError> {
        for (v, key) in [(r.width, "resolution.width"), (r.height, "resolution.height")] {
            if v == 0 || v > MAX_RESOLUTION {
                return Err(self.invalid(key, format!("{v} is not in 1..={MAX_RESOLUTION}")));
            }
        }
        Ok(Resolution { width: r.width, height: r.height })
    }

    fn camera(&self, c: &CameraDesc) -> Result<Camera, SceneError> {
        let position = self.vec3(c.position, "camera.position")?;
        let look_at = self.vec3(c.look_at, "camera.look_at")?;
        let up = self.direction(c.up, "camera.up")?;
        let view = (look_at - position)
            .try_normalize()
            .ok_or_else(|| self.invalid("camera.look_at", "equals camera.position"))?;
        if view.cross(up).length() < 1e-4 {
            return Err(self.invalid("camera.up", "is parallel to the viewing direction"));
        }
        let vfov = self.scalar(c.vfov, "camera.vfov")?;
        if !(vfov > 0.0 && vfov < 180.0) {
            return Err(self.invalid("camera.vfov", format!("{vfov} degrees is not in (0, 180)")));
        }
        let aperture = self.scalar(c.aperture, "camera.aperture")?;
        if aperture < 0.0 {
            return Err(self.invalid("camera.aperture", "must not be negative"));
        }
        let focus_distance = match c.focus_distance {
            Some(d) if self.scalar(d, "camera.focus_distance")? <= 0.0 => {
                return Err(self.invalid("camera.focus_distance", "must be positive"));
            }
            Some(d) => d,
            None => (look_at - position).length(),
        };
        Ok(Camera { position, look_at, up, vfov_deg: vfov, aperture, focus_distance })
    }

    fn render(&self, r: &RenderDesc) -> Result<RenderSettings, SceneError> {
        if r.max_depth == 0 || r.max_depth > MAX_DEPTH {
            return Err(self.invalid(
                "render.max_depth",
                format!("{} is not in 1..={MAX_DEPTH}", r.max_depth),
            ));
        }
        if r.spp == 0 {
            return Err(self.invalid("render.spp", "must be at least 1"));
        }
        Ok(RenderSettings { max_depth: r.max_depth, spp: r.spp })
    }

    /// Checks the master-only settings (reconstruction, display pacing).
    fn master_settings(&self, r: &RenderDesc) -> Result<(), SceneError> {
        if let Err(ReconstructError::BadParam { name, why }) = r.reconstruction.validate() {
            return Err(self.invalid(format!("render.reconstruction.{name}"), why));
        }
        let d = &r.display;
        if d.fps.is_some() && [d.q_min, d.q_max, d.i_min, d.i_max].iter().any(Option::is_some) {
            return Err(self.invalid(
                "render.display",
                "give either `fps` or the wait heuristic's bounds, not both",
            ));
        }
        if let Err(why) = super::display_pacing(d, &Default::default()).validate() {
            return Err(self.invalid("render.display", why.to_string()));
        }
        Ok(())
    }

    fn material(&mut self, m: &MaterialDesc, key: &str) -> Result<Material, SceneError> {
        if m.name.trim().is_empty() {
            return Err(self.invalid(format!("{key}.name"), "must not be empty"));
        }
        let base_color = self.colour(m.base_color, &format!("{key}.base_color"))?;
        let emission = self.colour(m.emission, &format!("{key}.emission"))?;
        let roughness = self.unit(m.roughness, &format!("{key}.roughness"))?;
        let ior = self.scalar(m.ior, &format!("{key}.ior"))?;
        if !(1.0..=4.0).contains(&ior) {
            return Err(self.invalid(format!("{key}.ior"), format!("{ior} is not in [1, 4]")));
        }
        let kind = match m.kind {
            KindDesc::Diffuse => MaterialKind::Diffuse,
            KindDesc::Conductor => MaterialKind::Conductor,
            KindDesc::Glossy => MaterialKind::Glossy,
            KindDesc::Dielectric => MaterialKind::Dielectric,
            KindDesc::Pbr => MaterialKind::Pbr,
        };
        // The glTF parameters mean nothing to the other kinds: refused there, not ignored.
        let pbr_only = [
            ("metallic", m.metallic.is_some()),
            ("transmission", m.transmission.is_some()),
            ("metallic_roughness_map", m.metallic_roughness_map.is_some()),
            ("normal_map", m.normal_map.is_some()),
            ("normal_scale", m.normal_scale.is_some()),
            ("emissive_map", m.emissive_map.is_some()),
        ];
        if let Some((name, _)) = pbr_only.iter().find(|(_, set)| *set && kind != MaterialKind::Pbr)
        {
            return Err(self.invalid(format!("{key}.{name}"), "needs kind = \"pbr\""));
        }
        for (name, path) in [
            ("texture", &m.texture),
            ("metallic_roughness_map", &m.metallic_roughness_map),
            ("normal_map", &m.normal_map),
            ("emissive_map", &m.emissive_map),
        ] {
            if let Some(t) = path {
                check_asset_path(t).map_err(|e| self.asset(format!("{key}.{name}"), e))?;
            }
        }
        let strength_key = format!("{key}.emission_strength");
        let emission_strength = self.scalar(m.emission_strength.unwrap_or(1.0), &strength_key)?;
        if emission_strength < 0.0 {
            return Err(self.invalid(strength_key, "must not be negative"));
        }
        let alpha = self.unit(m.alpha.unwrap_or(1.0), &format!("{key}.alpha"))?;
        let alpha_cutoff =
            self.unit(m.alpha_cutoff.unwrap_or(0.5), &format!("{key}.alpha_cutoff"))?;
        let alpha_mode = match m.alpha_mode {
            AlphaModeDesc::Opaque => AlphaMode::Opaque,
            AlphaModeDesc::Mask => AlphaMode::Mask,
            AlphaModeDesc::Blend => AlphaMode::Blend,
        };
        Ok(Material {
            name: m.name.clone(),
            kind,
            base_color,
            base_color_texture: m.texture.clone(),
            roughness,
            ior,
            emission,
            emission_strength,
            metallic: self.unit(m.metallic.unwrap_or(0.0), &format!("{key}.metallic"))?,
            transmission: self
                .unit(m.transmission.unwrap_or(0.0), &format!("{key}.transmission"))?,
            alpha,
            alpha_mode,
            alpha_cutoff,
            double_sided: m.double_sided.unwrap_or(true),
            metallic_roughness_texture: m.metallic_roughness_map.clone(),
            normal_texture: m.normal_map.clone(),
            normal_scale: self
                .scalar(m.normal_scale.unwrap_or(1.0), &format!("{key}.normal_scale"))?,
            emissive_texture: m.emissive_map.clone(),
            lookups: Default::default(),
        })
    }

    /// A finite value in [0, 1].
    fn unit(&self, v: f32, key: &str) -> Result<f32, SceneError> {
        let v = self.scalar(v, key)?;
        if !(0.0..=1.0).contains(&v) {
            return Err(self.invalid(key, format!("{v} is not in [0, 1]")));
        }
        Ok(v)
    }

    /// The id of the default grey material, added on first use.
    fn default_material(&mut self, names: &mut HashMap<String, MaterialId>) -> MaterialId {
        *names.entry(DEFAULT_MATERIAL.to_owned()).or_insert_with(|| {
            let material = Material::diffuse(DEFAULT_MATERIAL, Vec3::splat(0.8));
            self.materials.push((material, Origin::Mesh(String::new())));
            self.materials.len() as MaterialId - 1
        })
    }

    fn object(
        &mut self,
        o: &ObjectDesc,
        i: usize,
        names: &mut HashMap<String, MaterialId>,
        mtl_ids: &mut HashMap<String, Vec<MaterialId>>,
    ) -> Result<Object, SceneError> {
        let key = format!("objects[{i}]");
        let whole = o
            .material
            .as_deref()
            .map(|m| self.named(names, m, format!("{key}.material")))
            .transpose()?;
        let transform = self.transform(&o.transform, &format!("{key}.transform"))?;
        let (geometry, materials, default_name) = match (&o.mesh, o.shape) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(self.invalid(
                    key,
                    "give exactly one of `mesh` (an OBJ or glTF asset) and `shape`",
                ));
            }
            (None, Some(shape)) => {
                if !o.materials.is_empty() {
                    return Err(self.invalid(
                        format!("{key}.materials"),
                        "built-in shapes have no MTL materials to override; use `material`",
                    ));
                }
                let geometry = match shape {
                    ShapeDesc::Quad => Geometry::Quad,
                    ShapeDesc::Cube => Geometry::Cube,
                    ShapeDesc::Sphere => {
                        let subdivisions = o.subdivisions.unwrap_or(DEFAULT_SPHERE_SUBDIVISIONS);
                        if subdivisions > shapes::MAX_SPHERE_SUBDIVISIONS {
                            return Err(self.invalid(
                                format!("{key}.subdivisions"),
                                format!(
                                    "{subdivisions} is above the maximum {}",
                                    shapes::MAX_SPHERE_SUBDIVISIONS
                                ),
                            ));
                        }
                        Geometry::Sphere { subdivisions }
                    }
                };
                if o.subdivisions.is_some() && shape != ShapeDesc::Sphere {
                    return Err(self
                        .invalid(format!("{key}.subdivisions"), "only spheres have subdivisions"));
                }
                if !self.assets.meshes.contains_key(&geometry) {
                    let mesh = shapes::mesh(&geometry).expect("built-in shape");
                    self.assets.meshes.insert(geometry.clone(), Arc::new(mesh));
                }
                let id = match whole {
                    Some(id) => id,
                    None => self.default_material(names),
                };
                let name = format!("{}{i}", format!("{shape:?}").to_lowercase());
                (geometry, vec![id], name)
            }
            (Some(mesh), None) => {
                if o.subdivisions.is_some() {
                    return Err(self
                        .invalid(format!("{key}.subdivisions"), "only spheres have subdivisions"));
                }
                let mesh_key = format!("{key}.mesh");
                let geometry = if is_gltf(mesh) {
                    Geometry::Gltf { path: mesh.clone() }
                } else {
                    Geometry::Obj { path: mesh.clone() }
                };
                if !mtl_ids.contains_key(mesh) {
                    let data = match self.preloaded.take_if(|p| p.0 == *mesh) {
                        Some((_, data)) => data,
                        None => read_mesh_file(mesh, self.resolver)
                            .map_err(|e| self.asset(&mesh_key, e))?,
                    };
                    let mut ids = Vec::with_capacity(data.materials.len());
                    for m in data.materials {
                        self.materials.push((m, Origin::Mesh(mesh_key.clone())));
                        ids.push(self.materials.len() as MaterialId - 1);
                    }
                    mtl_ids.insert(mesh.clone(), ids);
                    for w in data.warnings {
                        self.warnings.push(format!("{mesh}: {w}"));
                    }
                    for (texture_key, usage, texture) in data.textures {
                        self.assets.insert_texture(texture_key, usage, Arc::new(texture));
                    }
                    self.assets.mesh_companions.insert(mesh.clone(), data.companions);
                    self.assets.meshes.insert(geometry.clone(), Arc::new(data.mesh));
                }
                let file_ids = &mtl_ids[mesh];
                let mtl_names: Vec<String> =
                    file_ids.iter().map(|&id| self.materials[id as usize].0.name.clone()).collect();
                let mut slots: Vec<MaterialId> = match whole {
                    Some(id) => vec![id; file_ids.len() + 1],
                    None => {
                        let mut s = file_ids.clone();
                        s.push(self.default_material(names));
                        s
                    }
                };
                for (mtl_name, target) in &o.materials {
                    let k = format!("{key}.materials.{mtl_name}");
                    let slot = mtl_names
                        .iter()
                        .position(|n| {
                            n.strip_prefix(mesh.as_str()).and_then(|n| n.strip_prefix(':'))
                                == Some(mtl_name.as_str())
                        })
                        .ok_or_else(|| {
                            self.invalid(
                                k.clone(),
                                format!("`{mesh}` has no material `{mtl_name}`"),
                            )
                        })?;
                    slots[slot] = self.named(names, target, k)?;
                }
                let file_name = mesh.rsplit('/').next().unwrap_or(mesh);
                let stem = file_name.rsplit_once('.').map_or(file_name, |(s, _)| s).to_owned();
                (geometry, slots, stem)
            }
        };
        Ok(Object {
            name: o.name.clone().unwrap_or(default_name),
            geometry,
            transform,
            materials,
            visible: o.visible,
        })
    }

    /// The id of the scene material called `name`.
    fn named(
        &self,
        names: &HashMap<String, MaterialId>,
        name: &str,
        key: String,
    ) -> Result<MaterialId, SceneError> {
        names.get(name).copied().ok_or_else(|| {
            let mut known: Vec<_> = names.keys().map(String::as_str).collect();
            known.sort_unstable();
            self.invalid(
                key,
                format!("unknown material `{name}` (scene materials: {})", known.join(", ")),
            )
        })
    }

    fn transform(&self, t: &TransformDesc, key: &str) -> Result<Transform, SceneError> {
        let translation = self.vec3(t.translation, &format!("{key}.translation"))?;
        let rotation = match (t.rotation, t.axis, t.angle) {
            (None, None, None) => Quat::IDENTITY,
            (Some(euler), None, None) => {
                let [x, y, z] =
                    self.vec3(euler, &format!("{key}.rotation"))?.to_array().map(f32::to_radians);
                Quat::from_euler(EulerRot::ZYX, z, y, x)
            }
            (None, Some(axis), Some(angle)) => {
                let axis = self.direction(axis, &format!("{key}.axis"))?;
                Quat::from_axis_angle(
                    axis,
                    self.scalar(angle, &format!("{key}.angle"))?.to_radians(),
                )
            }
            _ => {
                return Err(self.invalid(
                    key,
                    "give either `rotation` (Euler degrees) or both `axis` and `angle`",
                ));
            }
        };
        let scale_key = format!("{key}.scale");
        let scale = self.vec3(t.scale.0, &scale_key)?;
        if scale.abs().min_element() < 1e-12 {
            return Err(self.invalid(scale_key, "scale must not be zero"));
        }
        Ok(Transform { translation, rotation, scale })
    }

    fn light(&self, l: &LightDesc, key: &str) -> Result<Light, SceneError> {
        let k = |field: &str| format!("{key}.{field}");
        Ok(match *l {
            LightDesc::Point { position, intensity } => Light::Point {
                position: self.vec3(position, &k("position"))?,
                intensity: self.colour(intensity, &k("intensity"))?,
            },
            LightDesc::Spot { position, look_at, intensity, inner, outer } => {
                let position = self.vec3(position, &k("position"))?;
                let target = self.vec3(look_at, &k("look_at"))?;
                let direction = (target - position)
                    .try_normalize()
                    .ok_or_else(|| self.invalid(k("look_at"), "equals the light's position"))?;
                let inner = self.scalar(inner, &k("inner"))?;
                let outer = self.scalar(outer, &k("outer"))?;
                if !(0.0 <= inner && inner <= outer && outer > 0.0 && outer < 180.0) {
                    return Err(self.invalid(
                        k("outer"),
                        format!("cone angles need 0 <= inner ({inner}) <= outer ({outer}) < 180"),
                    ));
                }
                Light::Spot {
                    position,
                    direction,
                    intensity: self.colour(intensity, &k("intensity"))?,
                    inner_deg: inner,
                    outer_deg: outer,
                }
            }
            LightDesc::Sun { direction, irradiance, angular_radius } => {
                let radius = self.scalar(angular_radius, &k("angular_radius"))?;
                if !(radius > 0.0 && radius <= 45.0) {
                    return Err(self.invalid(
                        k("angular_radius"),
                        format!("{radius} degrees is not in (0, 45]"),
                    ));
                }
                // Radiance of a uniform disc that delivers `irradiance` at normal incidence.
                let solid_angle = std::f32::consts::TAU * (1.0 - radius.to_radians().cos());
                Light::Sun {
                    direction: self.direction(direction, &k("direction"))?,
                    radiance: self.colour(irradiance, &k("irradiance"))? / solid_angle,
                    angular_radius_deg: radius,
                }
            }
            LightDesc::Quad { corner, edge_u, edge_v, radiance } => {
                let edge_u = self.vec3(edge_u, &k("edge_u"))?;
                let edge_v = self.vec3(edge_v, &k("edge_v"))?;
                if edge_u.cross(edge_v).length() < 1e-12 {
                    return Err(self
                        .invalid(k("edge_v"), "edges are zero or parallel: the quad has no area"));
                }
                Light::Quad {
                    corner: self.vec3(corner, &k("corner"))?,
                    edge_u,
                    edge_v,
                    radiance: self.colour(radiance, &k("radiance"))?,
                }
            }
        })
    }

    fn environment(&mut self, e: &EnvironmentDesc) -> Result<Environment, SceneError> {
        let color = self.colour(e.color, "environment.color")?;
        let intensity = self.scalar(e.intensity, "environment.intensity")?;
        if intensity < 0.0 {
            return Err(self.invalid("environment.intensity", "must not be negative"));
        }
        let rotation_deg = self.scalar(e.rotation, "environment.rotation")?;
        if let Some(map) = &e.map {
            let texture = load_environment(map, self.resolver)
                .map_err(|err| self.asset("environment.map", err))?;
            self.assets.environments.insert(map.clone(), Arc::new(texture));
        }
        Ok(Environment { map: e.map.clone(), color, intensity, rotation_deg })
    }

    /// Loads every material's textures; errors name the key the texture came from.
    fn load_textures(&mut self) -> Result<(), SceneError> {
        for (material, origin) in &self.materials {
            for (path, usage) in material.textures() {
                if self.assets.texture(path, usage).is_some() {
                    continue;
                }
                let texture = load_texture(path, usage, self.resolver).map_err(|err| {
                    let what = format!("material `{}`: texture `{path}`: {err}", material.name);
                    SceneError::new(self.path, origin.key(usage), Problem::Invalid(what))
                })?;
                self.assets.insert_texture(path.to_owned(), usage, Arc::new(texture));
            }
        }
        Ok(())
    }
}
