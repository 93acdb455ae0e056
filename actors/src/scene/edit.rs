//! Edits of the scene state: the one vocabulary for interaction scripts and live
//! editing (camera moves, object moves, material, light and environment changes).
//!
//! An edit names what it changes (objects and materials by name, lights by index)
//! and carries only the fields it changes; [`apply`] checks the target exists and the
//! values are sane before touching the state, so a bad edit leaves it unchanged.
//!
//! The window's controls make `WindowEdit`s (whole parts by index, for the window's own
//! copy of the state) and turn each into an [`Edit`] before it reaches the master: the
//! master, scripts and tests know only [`Edit`] and [`EditError`].

use glam::{EulerRot, Quat, Vec3};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::scene::state::{
    Camera, Environment, Light, MaterialKind, RenderSettings, Resolution, SceneState,
};

/// One change of the scene state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Edit {
    /// Move or re-aim the camera.
    Camera(CameraEdit),
    /// Move, turn, scale, show or hide an object.
    Object(ObjectEdit),
    /// Change a material's parameters.
    Material(MaterialEdit),
    /// Replace light `index`.
    Light { index: usize, light: Light },
    /// Change the environment (creating a black one first when there is none).
    Environment(EnvironmentEdit),
    /// Remove the environment (black).
    ClearEnvironment,
    /// Change path-tracing settings.
    Render(RenderSettings),
    /// Render at another image size (a resized window): the frames after it have the new
    /// size and the pixel sets follow; the master refuses a size with fewer pixels than S.
    Resolution(Resolution),
}

/// Fields of the camera to change.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEdit {
    pub position: Option<Vec3>,
    pub look_at: Option<Vec3>,
    pub up: Option<Vec3>,
    pub vfov_deg: Option<f32>,
    pub aperture: Option<f32>,
    pub focus_distance: Option<f32>,
}

/// Fields of an object to change.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectEdit {
    pub name: String,
    pub translation: Option<Vec3>,
    pub rotation: Option<Quat>,
    /// Rotation as Euler angles in degrees (Y, then X, then Z); overrides `rotation`.
    pub rotation_deg: Option<Vec3>,
    pub scale: Option<Vec3>,
    pub visible: Option<bool>,
}

/// Fields of a material to change.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialEdit {
    pub name: String,
    pub kind: Option<MaterialKind>,
    pub base_color: Option<Vec3>,
    pub roughness: Option<f32>,
    pub ior: Option<f32>,
    pub emission: Option<Vec3>,
    /// glTF's `KHR_materials_emissive_strength`: a factor on `emission`.
    pub emission_strength: Option<f32>,
    /// `Pbr`: 0 dielectric, 1 metal.
    pub metallic: Option<f32>,
    /// `Pbr`: the share of the dielectric base that refracts.
    pub transmission: Option<f32>,
}

/// Fields of the environment to change.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentEdit {
    pub map: Option<String>,
    pub color: Option<Vec3>,
    pub intensity: Option<f32>,
    pub rotation_deg: Option<f32>,
}

/// Why an edit was refused.
#[derive(Debug, Error, PartialEq)]
pub enum EditError {
    #[error("no object named {0:?}")]
    NoObject(String),
    #[error("no material named {0:?}")]
    NoMaterial(String),
    #[error("no light {index} (the scene has {count})")]
    NoLight { index: usize, count: usize },
    #[error("{field} must be {expected}, got {value}")]
    BadValue { field: &'static str, expected: &'static str, value: String },
    #[error("the master cannot render {width}x{height}: {why}")]
    Resolution { width: u32, height: u32, why: String },
}

/// Applies `edit` to `state` (the version is the holder's business, not bumped here).
pub fn apply(state: &mut SceneState, edit: &Edit) -> Result<(), EditError> {
    match edit {
        Edit::Camera(c) => apply_camera(&mut state.camera, c),
        Edit::Object(o) => {
            check_vec("object translation", o.translation)?;
            check_vec("object scale", o.scale)?;
            let obj = state
                .objects
                .iter_mut()
                .find(|x| x.name == o.name)
                .ok_or_else(|| EditError::NoObject(o.name.clone()))?;
            set(&mut obj.transform.translation, o.translation);
            set(&mut obj.transform.scale, o.scale);
            if let Some(q) = o.rotation {
                obj.transform.rotation = q.normalize();
            }
            if let Some(d) = o.rotation_deg {
                let r = d * std::f32::consts::PI / 180.0;
                obj.transform.rotation = Quat::from_euler(EulerRot::YXZ, r.y, r.x, r.z);
            }
            set(&mut obj.visible, o.visible);
            Ok(())
        }
        Edit::Material(m) => {
            check_vec("material base_color", m.base_color)?;
            check_vec("material emission", m.emission)?;
            if let Some(r) = m.roughness.filter(|r| !(0.0..=1.0).contains(r)) {
                return Err(bad("material roughness", "in 0..=1", r));
            }
            if let Some(i) = m.ior.filter(|i| !(i.is_finite() && *i >= 1.0)) {
                return Err(bad("material ior", "at least 1", i));
            }
            for (field, value) in
                [("material metallic", m.metallic), ("material transmission", m.transmission)]
            {
                if let Some(v) = value.filter(|v| !(0.0..=1.0).contains(v)) {
                    return Err(bad(field, "in 0..=1", v));
                }
            }
            if let Some(s) = m.emission_strength.filter(|s| !(s.is_finite() && *s >= 0.0)) {
                return Err(bad("material emission_strength", "finite and non-negative", s));
            }
            let mat = state
                .materials
                .iter_mut()
                .find(|x| x.name == m.name)
                .ok_or_else(|| EditError::NoMaterial(m.name.clone()))?;
            set(&mut mat.kind, m.kind);
            set(&mut mat.base_color, m.base_color);
            set(&mut mat.roughness, m.roughness);
            set(&mut mat.ior, m.ior);
            set(&mut mat.emission, m.emission);
            set(&mut mat.emission_strength, m.emission_strength);
            set(&mut mat.metallic, m.metallic);
            set(&mut mat.transmission, m.transmission);
            Ok(())
        }
        Edit::Light { index, light } => {
            let count = state.lights.len();
            let slot =
                state.lights.get_mut(*index).ok_or(EditError::NoLight { index: *index, count })?;
            *slot = *light;
            Ok(())
        }
        Edit::Environment(e) => {
            check_vec("environment color", e.color)?;
            if let Some(i) = e.intensity.filter(|i| !(i.is_finite() && *i >= 0.0)) {
                return Err(bad("environment intensity", "finite and non-negative", i));
            }
            let env = state.environment.get_or_insert(Environment {
                map: None,
                color: Vec3::ZERO,
                intensity: 1.0,
                rotation_deg: 0.0,
            });
            if e.map.is_some() {
                env.map = e.map.clone();
            }
            set(&mut env.color, e.color);
            set(&mut env.intensity, e.intensity);
            set(&mut env.rotation_deg, e.rotation_deg);
            Ok(())
        }
        Edit::ClearEnvironment => {
            state.environment = None;
            Ok(())
        }
        Edit::Render(r) => {
            if r.spp == 0 || r.max_depth == 0 {
                return Err(bad(
                    "render settings",
                    "spp >= 1 and max_depth >= 1",
                    format!("{r:?}"),
                ));
            }
            state.render = *r;
            Ok(())
        }
        Edit::Resolution(r) => {
            let max = Resolution::MAX_SIDE;
            if !(1..=max).contains(&r.width) || !(1..=max).contains(&r.height) {
                let why = format!("each side must be in 1..={max} pixels");
                return Err(EditError::Resolution { width: r.width, height: r.height, why });
            }
            state.resolution = *r;
            Ok(())
        }
    }
}

fn apply_camera(cam: &mut Camera, c: &CameraEdit) -> Result<(), EditError> {
    check_vec("camera position", c.position)?;
    check_vec("camera look_at", c.look_at)?;
    check_vec("camera up", c.up)?;
    if let Some(f) = c.vfov_deg.filter(|f| !(*f > 0.0 && *f < 180.0)) {
        return Err(bad("camera vfov_deg", "in (0, 180)", f));
    }
    let mut next = *cam;
    set(&mut next.position, c.position);
    set(&mut next.look_at, c.look_at);
    set(&mut next.up, c.up);
    set(&mut next.vfov_deg, c.vfov_deg);
    set(&mut next.aperture, c.aperture);
    set(&mut next.focus_distance, c.focus_distance);
    let dir = next.look_at - next.position;
    if dir.length_squared() == 0.0 || dir.cross(next.up).length_squared() == 0.0 {
        return Err(bad(
            "camera",
            "a look_at away from the position, not along up",
            format!("{next:?}"),
        ));
    }
    *cam = next;
    Ok(())
}

fn set<T>(dst: &mut T, src: Option<T>) {
    if let Some(v) = src {
        *dst = v;
    }
}

fn check_vec(field: &'static str, v: Option<Vec3>) -> Result<(), EditError> {
    match v {
        Some(v) if !v.is_finite() => Err(bad(field, "finite", v)),
        _ => Ok(()),
    }
}

fn bad(field: &'static str, expected: &'static str, value: impl std::fmt::Debug) -> EditError {
    EditError::BadValue { field, expected, value: format!("{value:?}") }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::state::{Geometry, Material, Object};

    fn scene() -> SceneState {
        let camera = Camera::pinhole(Vec3::Z, Vec3::ZERO, 45.0);
        let white = Material { roughness: 0.5, ..Material::diffuse("white", Vec3::splat(0.8)) };
        SceneState::empty(Resolution { width: 8, height: 8 }, camera)
            .with_object(Object::new("box", Geometry::Cube), white)
    }

    #[test]
    fn edits_change_only_what_they_name() {
        let mut s = scene();
        let before = s.clone();
        apply(
            &mut s,
            &Edit::Object(ObjectEdit {
                name: "box".into(),
                translation: Some(Vec3::X),
                ..Default::default()
            }),
        )
        .expect("edit");
        assert_eq!(s.objects[0].transform.translation, Vec3::X);
        assert_eq!(s.objects[0].transform.scale, before.objects[0].transform.scale);
        apply(
            &mut s,
            &Edit::Camera(CameraEdit {
                position: Some(Vec3::new(0.0, 0.0, 5.0)),
                ..Default::default()
            }),
        )
        .expect("camera");
        assert_eq!(s.camera.position.z, 5.0);
        assert_eq!(s.camera.look_at, before.camera.look_at);
    }

    #[test]
    fn pbr_parameters_and_the_resolution_are_edited_and_checked() {
        let mut s = scene();
        let pbr = |metallic, transmission, emission_strength| {
            Edit::Material(MaterialEdit {
                name: "white".into(),
                kind: Some(MaterialKind::Pbr),
                metallic: Some(metallic),
                transmission: Some(transmission),
                emission_strength: Some(emission_strength),
                ..Default::default()
            })
        };
        apply(&mut s, &pbr(1.0, 0.25, 3.0)).expect("a metal");
        let m = &s.materials[0];
        assert_eq!(
            (m.kind, m.metallic, m.transmission, m.emission_strength),
            (MaterialKind::Pbr, 1.0, 0.25, 3.0)
        );
        let before = s.clone();
        for bad_edit in [pbr(1.5, 0.0, 1.0), pbr(0.0, -0.1, 1.0), pbr(0.0, 0.0, f32::NAN)] {
            assert!(matches!(apply(&mut s, &bad_edit), Err(EditError::BadValue { .. })));
        }
        let size = Resolution { width: 1920, height: 1080 };
        apply(&mut s, &Edit::Resolution(size)).expect("1080p");
        assert_eq!(s.resolution, size);
        for bad_size in [(0, 10), (10, Resolution::MAX_SIDE + 1)] {
            let r = Resolution { width: bad_size.0, height: bad_size.1 };
            assert!(matches!(
                apply(&mut s, &Edit::Resolution(r)),
                Err(EditError::Resolution { .. })
            ));
        }
        assert_eq!(s, SceneState { resolution: size, ..before });
    }

    #[test]
    fn bad_edits_are_refused_and_leave_the_state_alone() {
        let mut s = scene();
        let before = s.clone();
        let e = Edit::Object(ObjectEdit { name: "nope".into(), ..Default::default() });
        assert_eq!(apply(&mut s, &e), Err(EditError::NoObject("nope".into())));
        let e = Edit::Material(MaterialEdit {
            name: "white".into(),
            roughness: Some(2.0),
            ..Default::default()
        });
        assert!(matches!(apply(&mut s, &e), Err(EditError::BadValue { .. })));
        let e = Edit::Camera(CameraEdit { look_at: Some(Vec3::Z), ..Default::default() });
        assert!(apply(&mut s, &e).is_err(), "look_at == position accepted");
        assert!(matches!(
            apply(
                &mut s,
                &Edit::Light {
                    index: 0,
                    light: Light::Point { position: Vec3::ZERO, intensity: Vec3::ONE }
                }
            ),
            Err(EditError::NoLight { index: 0, count: 0 })
        ));
        assert_eq!(s, before);
    }

    #[test]
    fn environment_edit_creates_one_when_missing() {
        let mut s = scene();
        apply(
            &mut s,
            &Edit::Environment(EnvironmentEdit { color: Some(Vec3::ONE), ..Default::default() }),
        )
        .expect("env");
        let env = s.environment.clone().expect("environment");
        assert_eq!((env.color, env.intensity), (Vec3::ONE, 1.0));
        apply(&mut s, &Edit::ClearEnvironment).expect("clear");
        assert!(s.environment.is_none());
    }
}
