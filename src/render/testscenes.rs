//! Scenes built in code for tests and benchmarks: Mitsuba 3's `cornell_box()`
//! (same geometry, camera, albedos and light) and furnace set-ups.
//!
//! They need no files, so the light-transport tests and `gridlight bench trace`
//! run on a fresh machine.

use std::sync::Arc;

use glam::{Quat, Vec3};
use gridlight_actors::state::{
    Camera, Environment, Geometry, Material, MaterialKind, Object, RenderSettings, Resolution,
    SceneState, Transform,
};

use crate::assets::Assets;

/// A material of the given kind and colour, no texture, no emission.
pub fn material(name: &str, kind: MaterialKind, base_color: Vec3, roughness: f32) -> Material {
    Material { kind, roughness, ..Material::diffuse(name, base_color) }
}

fn object(name: &str, geometry: Geometry, material: u32, transform: Transform) -> Object {
    Object { name: name.into(), geometry, transform, materials: vec![material], visible: true }
}

/// Our unit quad (xz-plane, normal +y) placed like Mitsuba's 2×2 `rectangle`
/// (xy-plane, normal +z) under `rotation` and `translation`, with half extents
/// `sx`, `sy` in the rectangle's own x and y.
fn rectangle(rotation: Quat, translation: Vec3, sx: f32, sy: f32) -> Transform {
    // Rotating +y onto +z first turns our quad into Mitsuba's rectangle.
    let to_rect = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2);
    Transform {
        translation,
        rotation: rotation * to_rect,
        scale: Vec3::new(2.0 * sx, 1.0, 2.0 * sy),
    }
}

/// Mitsuba 3's `cornell_box()` at the given resolution: a 39.3077° field of view
/// on the smaller image axis from (0, 0, 3.9), red wall on the left, green on the
/// right, one area light (white diffuse, emitting downwards) under the ceiling.
pub fn cornell_box(width: u32, height: u32) -> (Arc<Assets>, SceneState) {
    let white = Vec3::new(0.885809, 0.698859, 0.666422);
    let green = Vec3::new(0.105421, 0.37798, 0.076425);
    let red = Vec3::new(0.570068, 0.0430135, 0.0443706);
    let mut light = material("light", MaterialKind::Diffuse, white, 1.0);
    light.emission = Vec3::new(18.387, 13.9873, 6.75357);
    let materials = vec![
        material("white", MaterialKind::Diffuse, white, 1.0),
        material("green", MaterialKind::Diffuse, green, 1.0),
        material("red", MaterialKind::Diffuse, red, 1.0),
        light,
    ];
    let deg = |d: f32| d.to_radians();
    let rx = |d: f32| Quat::from_rotation_x(deg(d));
    let ry = |d: f32| Quat::from_rotation_y(deg(d));
    let objects = vec![
        object(
            "floor",
            Geometry::Quad,
            0,
            rectangle(rx(-90.0), Vec3::new(0.0, -1.0, 0.0), 1.0, 1.0),
        ),
        object(
            "ceiling",
            Geometry::Quad,
            0,
            rectangle(rx(90.0), Vec3::new(0.0, 1.0, 0.0), 1.0, 1.0),
        ),
        object(
            "back",
            Geometry::Quad,
            0,
            rectangle(Quat::IDENTITY, Vec3::new(0.0, 0.0, -1.0), 1.0, 1.0),
        ),
        object(
            "green-wall",
            Geometry::Quad,
            1,
            rectangle(ry(-90.0), Vec3::new(1.0, 0.0, 0.0), 1.0, 1.0),
        ),
        object(
            "red-wall",
            Geometry::Quad,
            2,
            rectangle(ry(90.0), Vec3::new(-1.0, 0.0, 0.0), 1.0, 1.0),
        ),
        object(
            "small-box",
            Geometry::Cube,
            0,
            Transform {
                translation: Vec3::new(0.335, -0.7, 0.38),
                rotation: ry(-17.0),
                scale: Vec3::splat(0.6),
            },
        ),
        object(
            "large-box",
            Geometry::Cube,
            0,
            Transform {
                translation: Vec3::new(-0.33, -0.4, -0.28),
                rotation: ry(18.25),
                scale: Vec3::new(0.6, 1.22, 0.6),
            },
        ),
        object(
            "light",
            Geometry::Quad,
            3,
            rectangle(rx(90.0), Vec3::new(0.0, 0.99, 0.01), 0.23, 0.19),
        ),
    ];
    // Mitsuba's fov applies to the smaller axis (fov_axis "smaller"); ours is vertical.
    let fov = 39.3077f32.to_radians();
    let vfov = if height <= width {
        fov
    } else {
        2.0 * ((fov * 0.5).tan() * height as f32 / width as f32).atan()
    };
    let state = SceneState {
        version: 1,
        seed: 0x5eed,
        resolution: Resolution { width, height },
        camera: Camera {
            position: Vec3::new(0.0, 0.0, 3.9),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: vfov.to_degrees(),
            aperture: 0.0,
            focus_distance: 0.0,
        },
        objects,
        materials,
        lights: Vec::new(),
        environment: None,
        render: RenderSettings { max_depth: 5, spp: 4 },
    };
    (Arc::new(Assets::default()), state)
}

/// A sphere of the given material, alone in a constant environment of radiance
/// `env`, seen from outside: the white-furnace set-up.
pub fn furnace(
    material: Material,
    env: Vec3,
    max_depth: u32,
    spp: u32,
) -> (Arc<Assets>, SceneState) {
    let state = SceneState {
        version: 1,
        seed: 7,
        resolution: Resolution { width: 16, height: 16 },
        camera: Camera {
            position: Vec3::new(0.0, 0.0, 4.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            vfov_deg: 30.0,
            aperture: 0.0,
            focus_distance: 0.0,
        },
        objects: vec![object(
            "ball",
            Geometry::Sphere { subdivisions: 4 },
            0,
            Transform::default(),
        )],
        materials: vec![material],
        lights: Vec::new(),
        environment: Some(Environment { map: None, color: env, intensity: 1.0, rotation_deg: 0.0 }),
        render: RenderSettings { max_depth, spp },
    };
    (Arc::new(Assets::default()), state)
}
