use std::sync::Arc;

use glam::Quat;
use gridlight_actors::state::{
    Camera, Geometry, Light, Material, Object, RenderSettings, Resolution, SceneState, Transform,
};

use super::*;
use crate::assets::{Assets, Texture};
use crate::render::render_pixels;

/// A quad of the built-in shape (xz-plane, normal +y) turned to face +z, `size` wide,
/// centred at `z` on the view axis.
fn facing_camera(name: &str, material: u32, size: f32, z: f32) -> Object {
    Object {
        name: name.into(),
        geometry: Geometry::Quad,
        transform: Transform {
            translation: Vec3::new(0.0, 0.0, z),
            rotation: Quat::from_rotation_x(std::f32::consts::FRAC_PI_2),
            scale: Vec3::new(size, 1.0, size),
        },
        materials: vec![material],
        visible: true,
    }
}

/// A black veil (material 0, `alpha` blended) at z = 0 in front of a wall (material 1) at
/// z = −1, seen from `camera` looking at the wall's centre; 8×8 pixels.
fn veil_scene(alpha: f32, wall: Material, veil_size: f32, camera: Vec3) -> SceneState {
    let veil =
        Material { alpha, alpha_mode: AlphaMode::Blend, ..Material::diffuse("veil", Vec3::ZERO) };
    SceneState {
        version: 1,
        seed: 11,
        resolution: Resolution { width: 8, height: 8 },
        camera: Camera {
            position: camera,
            look_at: Vec3::new(0.0, 0.0, -1.0),
            up: Vec3::Y,
            vfov_deg: 8.0,
            aperture: 0.0,
            focus_distance: 0.0,
        },
        objects: vec![
            facing_camera("veil", 0, veil_size, 0.0),
            facing_camera("wall", 1, 8.0, -1.0),
        ],
        materials: vec![veil, wall],
        lights: Vec::new(),
        environment: None,
        render: RenderSettings { max_depth: 2, spp: 64 },
    }
}

/// Mean of `f` over every pixel of `state`'s image, rendered.
fn mean(state: &SceneState, f: impl Fn(&crate::render::PixelSample) -> f32) -> f32 {
    let scene = RenderScene::new(Arc::new(Assets::default()), state).unwrap();
    let pixels: Vec<u32> = (0..64).collect();
    let mut out = Vec::new();
    render_pixels(&scene, 0, &pixels, &mut out);
    out.iter().map(f).sum::<f32>() / out.len() as f32
}

/// A blended veil of alpha 0.5 lets through half the camera rays: the emitting wall behind
/// it is seen at half its radiance (4096 camera rays: σ = 0.008), all of it through alpha
/// 0 and none of it through alpha 1.
#[test]
fn a_blended_veil_of_alpha_one_half_shows_half_the_wall_behind_it() {
    let wall = Material { emission: Vec3::ONE, ..Material::diffuse("wall", Vec3::ZERO) };
    let seen = |alpha| {
        mean(&veil_scene(alpha, wall.clone(), 4.0, Vec3::new(0.0, 0.0, 3.0)), |s| s.emission.x)
    };
    let (clear, half, covered) = (seen(0.0), seen(0.5), seen(1.0));
    assert_eq!((clear, covered), (1.0, 0.0));
    assert!((half - 0.5).abs() < 0.05, "alpha 0.5 shows {half} of the wall");
}

/// Shadow rays too: a small blended veil between a point light and a white wall, seen from
/// the side (the camera's rays miss the veil), lets half the light through.
#[test]
fn a_blended_veil_of_alpha_one_half_casts_a_half_shadow() {
    let wall = Material::diffuse("wall", Vec3::ONE);
    let lit = |alpha| {
        let mut state = veil_scene(alpha, wall.clone(), 0.5, Vec3::new(3.0, 0.0, 3.0));
        state.render.spp = 256;
        // Every pixel's wall point in the veil's shadow.
        state.camera.vfov_deg = 4.0;
        state.lights =
            vec![Light::Point { position: Vec3::new(0.0, 0.0, 2.0), intensity: Vec3::splat(9.0) }];
        mean(&state, |s| s.reflected.x)
    };
    let (clear, half, covered) = (lit(0.0), lit(0.5), lit(1.0));
    assert!(clear > 0.1, "the wall is not lit: {clear}");
    assert_eq!(covered, 0.0, "an opaque veil casts a full shadow");
    let ratio = half / clear;
    assert!((ratio - 0.5).abs() < 0.06, "alpha 0.5 lets {ratio} of the light through");
}

#[test]
fn a_mask_cuts_where_factor_times_map_alpha_is_below_the_cutoff() {
    let texture = Texture::srgb8(2, 1, vec![[255; 3]; 2]).with_alpha(vec![0, 255]);
    let mut m = crate::render::MaterialData {
        kind: gridlight_actors::state::MaterialKind::Diffuse,
        base_color: Vec3::ONE,
        texture: Some(Arc::new(texture)),
        roughness: 1.0,
        ior: 1.5,
        emission: Vec3::ZERO,
        metallic: 0.0,
        transmission: 0.0,
        metallic_roughness: None,
        normal_map: None,
        normal_scale: 1.0,
        emission_map: None,
        lookups: Default::default(),
        alpha: 0.8,
        alpha_mode: AlphaMode::Mask,
        alpha_cutoff: 0.5,
        cutout: false,
    };
    let ray = (Vec3::ZERO, Vec3::Z);
    // Texel centres: u = 0.25 is the transparent texel, 0.75 the opaque one.
    let (cut, kept) = (Vec2::new(0.25, 0.5), Vec2::new(0.75, 0.5));
    assert!(can_let_through(&m));
    assert!(lets_through(&m, cut, ray, [0, 0]));
    assert!(!lets_through(&m, kept, ray, [0, 0]));
    // 0.8 × 1 is below a cutoff of 0.9: cut there too.
    m.alpha_cutoff = 0.9;
    assert!(lets_through(&m, kept, ray, [0, 0]));
    // Without a map alpha only the factor counts; opaque never cuts.
    m.texture = Some(Arc::new(Texture::srgb8(1, 1, vec![[255; 3]]).with_alpha(vec![255])));
    assert!(m.texture.as_ref().unwrap().alpha.is_none(), "opaque alpha is not stored");
    m.alpha_cutoff = 0.5;
    assert!(!can_let_through(&m));
    m.alpha_mode = AlphaMode::Opaque;
    m.alpha = 0.0;
    assert!(!can_let_through(&m) && !lets_through(&m, cut, ray, [0, 0]));
}
