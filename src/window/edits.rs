//! The window's edits: absolute new values for one part of the scene state, as the
//! controls and the panel produce them, and how they apply to the window's copy of the state.
//!
//! The window keeps its own copy of the scene state so that successive drags compose at
//! once, without waiting for the master to echo a new version; each edit also goes to the
//! master, which makes the new state version the workers render.
//!
//! A [`WindowEdit`] is not the master's `gridlight_actors::edit::Edit`, and the names
//! say so: a window edit replaces a whole part (a camera, a transform, a material)
//! addressed by its index in the window's own copy, and is checked for that index
//! only; an `Edit` is the one vocabulary the master,
//! interaction scripts and tests speak — only the fields it changes, objects and
//! materials by name, values checked before the state changes. The window turns each of
//! its edits into an `Edit` (`window::master_control::to_master_edit`); [`WindowEditError`] is
//! only "that index is not in my copy", `EditError` the master's refusal.

use std::time::Instant;

use glam::Vec3;
use gridlight_actors::state::{
    Camera, Environment, Light, Material, MaterialId, Resolution, SceneState, Transform,
};
use thiserror::Error;

/// One change to the window's copy of the scene state, as an absolute value for the part
/// it names by index (the master's counterpart is `Edit`; see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub enum WindowEdit {
    Camera(Camera),
    /// New transform of object `object` (index into `SceneState::objects`).
    ObjectTransform {
        object: u32,
        transform: Transform,
    },
    /// Boxed: a material (with its maps' lookups) is several times any other edit.
    Material {
        id: MaterialId,
        material: Box<Material>,
    },
    Light {
        index: u32,
        light: Light,
    },
    Environment(Option<Environment>),
    /// The render size (the window was resized under `--resolution window`).
    Resolution(Resolution),
}

/// A window edit that names an index the window's copy does not have.
#[derive(Debug, Error, PartialEq)]
pub enum WindowEditError {
    #[error("no object {0} in the scene")]
    NoObject(u32),
    #[error("no material {0} in the scene")]
    NoMaterial(MaterialId),
    #[error("no light {0} in the scene")]
    NoLight(u32),
}

impl WindowEdit {
    /// Applies the edit to `state` (the version is the master's business and stays).
    pub fn apply(&self, state: &mut SceneState) -> Result<(), WindowEditError> {
        match self {
            WindowEdit::Camera(camera) => state.camera = *camera,
            WindowEdit::ObjectTransform { object, transform } => {
                let slot = state
                    .objects
                    .get_mut(*object as usize)
                    .ok_or(WindowEditError::NoObject(*object))?;
                slot.transform = *transform;
            }
            WindowEdit::Material { id, material } => {
                let slot = state
                    .materials
                    .get_mut(*id as usize)
                    .ok_or(WindowEditError::NoMaterial(*id))?;
                *slot = (**material).clone();
            }
            WindowEdit::Light { index, light } => {
                let slot = state
                    .lights
                    .get_mut(*index as usize)
                    .ok_or(WindowEditError::NoLight(*index))?;
                *slot = *light;
            }
            WindowEdit::Environment(environment) => state.environment = environment.clone(),
            WindowEdit::Resolution(resolution) => state.resolution = *resolution,
        }
        Ok(())
    }
}

/// What an edit replaces; two edits with the same target coalesce into the later one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Target {
    Camera,
    Object(u32),
    Material(MaterialId),
    Light(u32),
    Environment,
    Resolution,
}

impl WindowEdit {
    fn target(&self) -> Target {
        match self {
            WindowEdit::Camera(_) => Target::Camera,
            WindowEdit::ObjectTransform { object, .. } => Target::Object(*object),
            WindowEdit::Material { id, .. } => Target::Material(*id),
            WindowEdit::Light { index, .. } => Target::Light(*index),
            WindowEdit::Environment(_) => Target::Environment,
            WindowEdit::Resolution(_) => Target::Resolution,
        }
    }
}

/// Edits waiting to be sent to the master. A mouse drag produces an edit per input event;
/// every edit the master receives makes a new scene state (and restarts accumulation), so
/// the window sends at most one edit per target per drawn frame: the newest. Each keeps
/// the instant of the first input event it stands for, so that the edit-to-display
/// latency counts from there.
#[derive(Clone, Debug, Default)]
pub struct EditQueue {
    pending: Vec<(WindowEdit, Instant)>,
}

impl EditQueue {
    /// Queues `edit` made at `at`, replacing a queued edit of the same target in place
    /// (which keeps its earlier instant).
    pub fn push(&mut self, edit: WindowEdit, at: Instant) {
        match self.pending.iter_mut().find(|(e, _)| e.target() == edit.target()) {
            Some((queued, _)) => *queued = edit,
            None => self.pending.push((edit, at)),
        }
    }

    /// Takes the queued edits with their first input instants, in the order their
    /// targets were first edited.
    pub fn drain(&mut self) -> Vec<(WindowEdit, Instant)> {
        std::mem::take(&mut self.pending)
    }

    /// True when nothing is queued.
    pub fn is_empty(&self) -> bool {
        self.pending.is_empty()
    }
}

/// Splits an RGB power into a colour whose largest channel is 1 and a scalar intensity, so
/// the panel can offer a colour picker and an intensity slider; black gives white × 0.
pub fn split_power(power: Vec3) -> (Vec3, f32) {
    let intensity = power.max_element();
    if intensity > 0.0 && intensity.is_finite() {
        (power / intensity, intensity)
    } else {
        (Vec3::ONE, 0.0)
    }
}

/// The RGB power of a colour at an intensity (inverse of [`split_power`]).
pub fn join_power(colour: Vec3, intensity: f32) -> Vec3 {
    colour * intensity.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use gridlight_actors::state::{Geometry, MaterialKind, Object, Resolution};

    fn state() -> SceneState {
        let camera = Camera::pinhole(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 40.0);
        let light = Light::Point { position: Vec3::Y, intensity: Vec3::splat(5.0) };
        let scene = SceneState {
            version: 3,
            seed: 1,
            ..SceneState::empty(Resolution { width: 8, height: 6 }, camera)
        }
        .with_object(
            Object::new("box", Geometry::Cube),
            Material::diffuse("white", Vec3::splat(0.8)),
        );
        SceneState { lights: vec![light], ..scene }
    }

    #[test]
    fn edits_replace_the_named_part_only() {
        let mut s = state();
        let moved = Transform { translation: Vec3::X, ..Transform::default() };
        WindowEdit::ObjectTransform { object: 0, transform: moved }
            .apply(&mut s)
            .expect("object 0");
        assert_eq!(s.objects[0].transform, moved);
        let mut glass = s.materials[0].clone();
        glass.kind = MaterialKind::Dielectric;
        WindowEdit::Material { id: 0, material: Box::new(glass.clone()) }
            .apply(&mut s)
            .expect("material 0");
        assert_eq!(s.materials[0], glass);
        let light = Light::Point { position: Vec3::ZERO, intensity: Vec3::ONE };
        WindowEdit::Light { index: 0, light }.apply(&mut s).expect("light 0");
        assert_eq!(s.lights[0], light);
        let cam = Camera { vfov_deg: 60.0, ..s.camera };
        WindowEdit::Camera(cam).apply(&mut s).expect("camera");
        assert_eq!(s.camera, cam);
        assert_eq!(s.version, 3, "only the master bumps versions");
        assert_eq!(s.objects[0].name, "box");
    }

    #[test]
    fn edits_naming_missing_parts_fail_and_change_nothing() {
        let mut s = state();
        let before = s.clone();
        let t = Transform::default();
        assert_eq!(
            WindowEdit::ObjectTransform { object: 5, transform: t }.apply(&mut s),
            Err(WindowEditError::NoObject(5))
        );
        let light = Light::Point { position: Vec3::ZERO, intensity: Vec3::ONE };
        assert_eq!(
            WindowEdit::Light { index: 1, light }.apply(&mut s),
            Err(WindowEditError::NoLight(1))
        );
        assert_eq!(s, before);
    }

    #[test]
    fn queue_keeps_the_newest_edit_per_target_in_first_edit_order() {
        let cam = |fov| WindowEdit::Camera(Camera { vfov_deg: fov, ..state().camera });
        let light = Light::Point { position: Vec3::ZERO, intensity: Vec3::ONE };
        let mut q = EditQueue::default();
        let t0 = Instant::now();
        let t = |ms| t0 + std::time::Duration::from_millis(ms);
        q.push(cam(30.0), t(0));
        q.push(WindowEdit::Light { index: 0, light }, t(1));
        q.push(cam(50.0), t(2));
        q.push(WindowEdit::Light { index: 1, light }, t(3));
        let drained = q.drain();
        assert_eq!(drained.len(), 3);
        // The newest camera, timed from the first camera input it replaced.
        assert_eq!(drained[0], (cam(50.0), t(0)));
        assert_eq!(drained[1], (WindowEdit::Light { index: 0, light }, t(1)));
        assert!(q.is_empty());
    }

    #[test]
    fn power_splits_and_joins_back() {
        let (colour, intensity) = split_power(Vec3::new(18.0, 9.0, 4.5));
        assert_eq!(intensity, 18.0);
        assert_eq!(colour, Vec3::new(1.0, 0.5, 0.25));
        assert_eq!(join_power(colour, intensity), Vec3::new(18.0, 9.0, 4.5));
        assert_eq!(split_power(Vec3::ZERO), (Vec3::ONE, 0.0));
        assert_eq!(join_power(Vec3::ONE, -2.0), Vec3::ZERO);
    }
}
