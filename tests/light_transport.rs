//! Light-transport tests of the path tracer with known answers: furnaces,
//! NEE against pure BSDF sampling, determinism, demodulation and scene errors.
//! Images are tiny and sample counts small so the suite stays fast on 2 cores.

use std::sync::Arc;

use glam::Vec3;
use gridlight::assets::Assets;
use gridlight::render::testscenes::{cornell_box, furnace, material};
use gridlight::render::{
    pick, primary_hit, render_pixels, render_pixels_counted, PixelSample, RenderError, RenderScene,
    Strategy,
};
use gridlight::shapes;
use gridlight_actors::state::{Geometry, MaterialKind, SceneState, Transform};

fn all_pixels(state: &SceneState) -> Vec<u32> {
    (0..state.resolution.pixels() as u32).collect()
}

/// Final colour as the master composes it (it divides by and multiplies with the same
/// G-buffer albedo, which cancel).
fn colour(s: &PixelSample) -> Vec3 {
    s.reflected + s.emission
}

fn mean_colour(scene: &RenderScene, frame: u64, strategy: Strategy) -> Vec3 {
    let pixels = all_pixels(scene.state());
    let mut out = Vec::new();
    render_pixels_counted(scene, frame, &pixels, &mut out, strategy);
    out.iter().map(colour).sum::<Vec3>() / out.len() as f32
}

/// Mean colour over the pixels whose camera ray hits the object.
fn mean_on_object(scene: &RenderScene) -> (Vec3, usize) {
    let pixels = all_pixels(scene.state());
    let mut out = Vec::new();
    render_pixels(scene, 0, &pixels, &mut out);
    // Only pixels whose every sample hit the object (no environment seen).
    let hits: Vec<Vec3> =
        out.iter().filter(|s| s.object == 0 && s.emission == Vec3::ZERO).map(colour).collect();
    (hits.iter().sum::<Vec3>() / hits.len().max(1) as f32, hits.len())
}

#[test]
fn white_furnace_diffuse_sphere_matches_environment() {
    for albedo in [1.0f32, 0.5] {
        let m = material("m", MaterialKind::Diffuse, Vec3::splat(albedo), 1.0);
        let (assets, state) = furnace(m, Vec3::splat(0.8), 8, 16);
        let scene = RenderScene::new(assets, &state).unwrap();
        let (mean, n) = mean_on_object(&scene);
        assert!(n > 20, "the sphere covers too few pixels ({n})");
        // A convex object: one bounce, then every ray escapes: L = ρ · L_env.
        let expected = albedo * 0.8;
        assert!(
            (mean - Vec3::splat(expected)).abs().max_element() < 0.01 * expected + 1e-3,
            "ρ {albedo}: {mean}"
        );
    }
}

#[test]
fn white_furnace_glass_and_metal_keep_energy() {
    let glass = material("glass", MaterialKind::Dielectric, Vec3::ONE, 0.0);
    let (assets, state) = furnace(glass, Vec3::ONE, 32, 32);
    let (mean, _) = mean_on_object(&RenderScene::new(assets, &state).unwrap());
    assert!((mean - Vec3::ONE).abs().max_element() < 0.03, "smooth glass: {mean}");

    let rough = material("rough glass", MaterialKind::Dielectric, Vec3::ONE, 0.3);
    let (assets, state) = furnace(rough, Vec3::ONE, 32, 32);
    let (mean, _) = mean_on_object(&RenderScene::new(assets, &state).unwrap());
    // Single-scattering microfacets lose some energy, never gain any.
    assert!(mean.max_element() < 1.02 && mean.min_element() > 0.85, "rough glass: {mean}");

    let metal = material("metal", MaterialKind::Conductor, Vec3::ONE, 0.3);
    let (assets, state) = furnace(metal, Vec3::ONE, 8, 16);
    let (mean, _) = mean_on_object(&RenderScene::new(assets, &state).unwrap());
    assert!(mean.max_element() < 1.01 && mean.min_element() > 0.9, "metal: {mean}");

    let glossy = material("glossy", MaterialKind::Glossy, Vec3::ONE, 0.3);
    let (assets, state) = furnace(glossy, Vec3::ONE, 8, 16);
    let (mean, _) = mean_on_object(&RenderScene::new(assets, &state).unwrap());
    assert!(mean.max_element() < 1.01 && mean.min_element() > 0.85, "glossy: {mean}");
}

/// The camera inside a closed sphere whose walls emit Le and reflect ρ: with
/// paths of at most D segments the answer is Le (1 - ρ^D) / (1 - ρ). Exercises
/// emissive-triangle sampling, MIS and Russian roulette together.
fn closed_furnace(strategy: Strategy) -> Vec3 {
    let mut m = material("wall", MaterialKind::Diffuse, Vec3::splat(0.5), 1.0);
    m.emission = Vec3::splat(0.5);
    let (_, mut state) = furnace(m, Vec3::ZERO, 6, 8);
    state.environment = None;
    state.camera.position = Vec3::new(0.0, 0.0, 0.3);
    // A sphere turned inside out (reversed winding and normals), so that the
    // emitting front side faces the camera inside it.
    let mut mesh = shapes::sphere(2);
    mesh.indices.iter_mut().for_each(|t| t.swap(1, 2));
    mesh.normals.iter_mut().for_each(|n| *n = -*n);
    let geometry = Geometry::Obj { path: "inside-out-sphere.obj".into() };
    let mut assets = Assets::default();
    assets.meshes.insert(geometry.clone(), Arc::new(mesh));
    state.objects[0].geometry = geometry;
    state.objects[0].transform = Transform { scale: Vec3::splat(2.0), ..Transform::default() };
    let scene = RenderScene::new(Arc::new(assets), &state).unwrap();
    mean_colour(&scene, 0, strategy)
}

#[test]
fn closed_furnace_has_the_known_answer_with_nee_and_with_bsdf_sampling() {
    let expected = 1.0 - 0.5f32.powi(6);
    for strategy in [Strategy::NeeMis, Strategy::BsdfOnly] {
        let mean = closed_furnace(strategy);
        assert!((mean - Vec3::splat(expected)).abs().max_element() < 0.01, "{strategy:?}: {mean}");
    }
}

#[test]
fn nee_and_bsdf_sampling_agree_on_the_cornell_box() {
    // Pure BSDF sampling finds the small light rarely: it needs many paths.
    let (assets, mut state) = cornell_box(24, 18);
    state.render.spp = 256;
    let scene = RenderScene::new(assets, &state).unwrap();
    let nee = mean_colour(&scene, 1, Strategy::NeeMis);
    let bsdf = mean_colour(&scene, 1, Strategy::BsdfOnly);
    let rel = ((nee - bsdf) / nee).abs();
    assert!(rel.max_element() < 0.03, "NEE {nee} vs BSDF {bsdf}");
    assert!(nee.min_element() > 0.02, "the box is too dark: {nee}");
}

#[test]
fn rendering_is_deterministic_and_per_pixel() {
    let (assets, state) = cornell_box(16, 12);
    let scene = RenderScene::new(assets, &state).unwrap();
    let pixels = all_pixels(&state);
    let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
    render_pixels(&scene, 3, &pixels, &mut a);
    render_pixels(&scene, 3, &pixels, &mut b);
    assert_eq!(a, b);
    // A subset in another order gives the same bits for the same pixels.
    let subset = [77u32, 5, 150, 6];
    render_pixels(&scene, 3, &subset, &mut c);
    for (s, p) in c.iter().zip(subset) {
        assert_eq!(*s, a[p as usize]);
    }
    // Another frame gives other samples.
    render_pixels(&scene, 4, &pixels, &mut c);
    assert_ne!(a, c);
}

#[test]
fn g_buffer_values_follow_the_demodulation_convention() {
    let (assets, state) = cornell_box(24, 24);
    let scene = RenderScene::new(assets, &state).unwrap();
    let width = state.resolution.width;
    // The centre pixel sees the back wall (white) or a box (white).
    let centre = 12 * width + 12;
    let g = primary_hit(&scene, centre);
    assert_eq!(g.reflected, Vec3::ZERO);
    assert_eq!(g.albedo, state.materials[0].base_color);
    assert!(g.object != u32::MAX);
    assert!((g.normal.length() - 1.0).abs() < 1e-4);
    // Left edge, mid height: red wall; right edge: green wall.
    let left = primary_hit(&scene, 12 * width);
    let right = primary_hit(&scene, 12 * width + width - 1);
    assert_eq!(state.objects[left.object as usize].name, "red-wall");
    assert_eq!(state.objects[right.object as usize].name, "green-wall");
    assert_eq!(pick(&scene, 0.5, 12.5), Some(left.object));
    // The light seen directly: emission, and the surface's own (black) albedo.
    let light = state.objects.iter().position(|o| o.name == "light").unwrap() as u32;
    let light_px = (0..state.resolution.pixels() as u32)
        .find(|&p| primary_hit(&scene, p).object == light)
        .expect("the light is visible");
    let top = primary_hit(&scene, light_px);
    assert_eq!(top.emission, state.materials[3].emission);
    let mut out = Vec::new();
    render_pixels(&scene, 0, &[light_px], &mut out);
    assert!(out[0].emission.x > 1.0, "{:?}", out[0]);
}

#[test]
fn escaping_rays_report_the_environment_as_emission() {
    let m = material("m", MaterialKind::Diffuse, Vec3::ONE, 1.0);
    let (assets, state) = furnace(m, Vec3::new(0.1, 0.2, 0.3), 4, 2);
    let scene = RenderScene::new(assets, &state).unwrap();
    let mut out = Vec::new();
    render_pixels(&scene, 0, &[0], &mut out);
    let s = out[0];
    assert_eq!(s.object, u32::MAX);
    assert_eq!(s.albedo, Vec3::ONE);
    assert_eq!(s.normal, Vec3::ZERO);
    assert_eq!(s.reflected, Vec3::ZERO);
    assert!((s.emission - Vec3::new(0.1, 0.2, 0.3)).length() < 1e-6);
}

#[test]
fn new_states_move_objects_without_new_assets() {
    let (assets, mut state) = cornell_box(32, 24);
    let mut scene = RenderScene::new(assets, &state).unwrap();
    let triangles = scene.triangle_count();
    assert_eq!(triangles, 6 * 2 + 2 * 12);
    let small = state.objects.iter().position(|o| o.name == "small-box").unwrap() as u32;
    // The box's rightmost pixel: moving the box left uncovers it.
    let width = state.resolution.width;
    let probe = (0..state.resolution.pixels() as u32)
        .filter(|&p| primary_hit(&scene, p).object == small)
        .max_by_key(|p| p % width)
        .expect("the small box is visible");
    state.version += 1;
    state.objects[small as usize].transform.translation.x -= 0.6;
    scene.set_state(&state).unwrap();
    assert_eq!(scene.state().version, state.version);
    assert_ne!(primary_hit(&scene, probe).object, small, "the box did not move");
    assert_eq!(scene.triangle_count(), triangles);
    // Hiding an object removes it from the picture.
    state.objects[small as usize].visible = false;
    scene.set_state(&state).unwrap();
    assert!((0..state.resolution.pixels() as u32).all(|p| primary_hit(&scene, p).object != small));
}

#[test]
fn bad_states_are_rejected_with_the_name_of_what_is_missing() {
    let (assets, mut state) = cornell_box(8, 6);
    state.objects[0].geometry = Geometry::Obj { path: "meshes/missing.obj".into() };
    let err = RenderScene::new(assets.clone(), &state).err().expect("missing mesh accepted");
    assert!(matches!(err, RenderError::MissingMesh { .. }));
    assert!(err.to_string().contains("missing.obj"));

    let (_, mut state) = cornell_box(8, 6);
    state.materials[0].base_color_texture = Some("textures/nope.png".into());
    let err = RenderScene::new(assets.clone(), &state).err().expect("missing texture accepted");
    assert!(err.to_string().contains("nope.png"), "{err}");

    let (_, mut state) = cornell_box(8, 6);
    state.objects[1].materials = vec![99];
    assert!(matches!(
        RenderScene::new(assets.clone(), &state),
        Err(RenderError::MaterialOutOfRange { .. })
    ));

    let (_, mut state) = cornell_box(8, 6);
    state.objects[2].transform.translation.y = f32::NAN;
    assert!(matches!(
        RenderScene::new(assets.clone(), &state),
        Err(RenderError::BadTransform { .. })
    ));

    // A failed update keeps the previous state.
    let (_, good) = cornell_box(8, 6);
    let mut scene = RenderScene::new(Arc::new(Assets::default()), &good).unwrap();
    assert!(scene.set_state(&state).is_err());
    assert_eq!(scene.state(), &good);
}
