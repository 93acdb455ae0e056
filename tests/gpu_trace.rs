//! The GPU path tracer (`render::gpu`, `shaders/trace/`) against the CPU one, on
//! whatever adapter wgpu finds (Mesa's lavapipe on machines without a GPU): the built-in
//! scenes agree in mean radiance within 0.5 % and in FLIP, and the CPU tracer's
//! known-answer tests (white furnaces, the closed furnace, NEE against BSDF sampling)
//! have GPU twins. Images are tiny and sample counts small so that lavapipe on 2 cores
//! stays fast. Both tracers draw the same random numbers, so their noise is correlated
//! and a difference in the mean shows a bias, not noise.

use std::sync::{Arc, OnceLock};

use glam::{DVec3, Vec3};
use gridlight::assets::Assets;
use gridlight::gpu::GpuContext;
use gridlight::image_io::display_pixel;
use gridlight::render::gpu::{GpuTracer, PixelBatch};
use gridlight::render::testscenes::{cornell_box, furnace, material};
use gridlight::render::{primary_hit, render_pixels_counted, PixelSample, RenderScene, Strategy};
use gridlight::scene::{self, AssetSearchPath, SceneSource};
use gridlight::shapes;
use gridlight::testing::{skip, Missing};
use gridlight::tools::eval::flip::{flip, DEFAULT_PPD};
use gridlight_actors::state::{Geometry, MaterialKind, SceneState, Transform};

/// The tracer on the default adapter, compiled once for all tests (lavapipe takes seconds
/// to compile the pass), or `None` after saying why the test is skipped.
fn tracer(test: &str) -> Option<&'static GpuTracer> {
    static TRACER: OnceLock<Result<GpuTracer, String>> = OnceLock::new();
    let made = TRACER.get_or_init(|| {
        GpuContext::new().map(|ctx| GpuTracer::new(ctx.shared())).map_err(|e| e.to_string())
    });
    match made {
        Ok(t) => Some(t),
        Err(err) => {
            skip(test, Missing::Adapter, err);
            None
        }
    }
}

fn all_pixels(state: &SceneState) -> Vec<u32> {
    (0..state.resolution.pixels() as u32).collect()
}

fn gpu_image(
    t: &GpuTracer,
    scene: &RenderScene,
    frame: u64,
    strategy: Strategy,
) -> Vec<PixelSample> {
    let pixels = all_pixels(scene.state());
    let uploaded = t.upload(scene).expect("upload");
    let mut out = Vec::new();
    let stats = t
        .render(&uploaded, &[PixelBatch { frame, pixels: &pixels }], strategy, &mut out)
        .expect("GPU render");
    assert_eq!(out.len(), pixels.len());
    assert!(stats.rays >= stats.samples, "{stats:?}");
    out
}

fn cpu_image(scene: &RenderScene, frame: u64, strategy: Strategy) -> Vec<PixelSample> {
    let mut out = Vec::new();
    render_pixels_counted(scene, frame, &all_pixels(scene.state()), &mut out, strategy);
    out
}

fn colour(s: &PixelSample) -> Vec3 {
    s.reflected + s.emission
}

fn mean(img: &[PixelSample]) -> DVec3 {
    img.iter().map(|s| colour(s).as_dvec3()).sum::<DVec3>() / img.len() as f64
}

fn display(img: &[PixelSample]) -> Vec<Vec3> {
    img.iter()
        .map(|s| Vec3::from_array(display_pixel(colour(s), 0.0).map(|c| c as f32 / 255.0)))
        .collect()
}

fn builtin(name: &str, width: u32, height: u32, spp: u32) -> RenderScene {
    let source = SceneSource::Builtin(scene::builtin::builtin(name).expect("built-in scene"));
    let loaded = scene::load_source(&source, &AssetSearchPath::from_dirs(vec![])).expect(name);
    let mut state = loaded.state;
    state.resolution.width = width;
    state.resolution.height = height;
    state.render.spp = spp;
    RenderScene::new(Arc::new(loaded.assets), &state).expect("render scene")
}

#[test]
fn built_in_scenes_agree_with_the_cpu_in_mean_radiance_and_flip() {
    let Some(t) = tracer("built_in_scenes_agree_with_the_cpu") else { return };
    for name in ["cornell-box", "glossy-glass"] {
        let (w, h) = (64, 48);
        let scene = builtin(name, w, h, 64);
        let cpu = cpu_image(&scene, 0, Strategy::NeeMis);
        let gpu = gpu_image(t, &scene, 0, Strategy::NeeMis);
        let (mc, mg) = (mean(&cpu), mean(&gpu));
        let rel = ((mg - mc) / mc).abs().max_element();
        eprintln!("{name}: CPU mean {mc:.5}, GPU mean {mg:.5} ({:.3} %)", rel * 100.0);
        assert!(rel < 0.005, "{name}: GPU mean {mg} vs CPU {mc}");
        // FLIP of the GPU image against the CPU's, against that of an independent CPU
        // image (another frame's samples) of the same sample count: the GPU image may
        // differ from the CPU's no more than the CPU's own noise does.
        let peer = cpu_image(&scene, 1, Strategy::NeeMis);
        let (w, h) = (w as usize, h as usize);
        let gpu_flip = flip(&display(&cpu), &display(&gpu), w, h, DEFAULT_PPD).mean;
        let noise_flip = flip(&display(&cpu), &display(&peer), w, h, DEFAULT_PPD).mean;
        eprintln!(
            "{name}: FLIP GPU vs CPU {gpu_flip:.4}, CPU vs CPU (other samples) {noise_flip:.4}"
        );
        assert!(gpu_flip <= noise_flip, "{name}: FLIP {gpu_flip} above the noise's {noise_flip}");
    }
}

/// Mean colour over the pixels whose camera ray hits object 0 with no sample escaping.
fn mean_on_object(scene: &RenderScene, img: &[PixelSample]) -> (Vec3, usize) {
    let hits: Vec<Vec3> = img
        .iter()
        .enumerate()
        .filter(|(i, s)| primary_hit(scene, *i as u32).object == 0 && s.emission == Vec3::ZERO)
        .map(|(_, s)| colour(s))
        .collect();
    (hits.iter().sum::<Vec3>() / hits.len().max(1) as f32, hits.len())
}

#[test]
fn gpu_white_furnaces_keep_energy() {
    let Some(t) = tracer("gpu_white_furnaces_keep_energy") else { return };
    for albedo in [1.0f32, 0.5] {
        let m = material("m", MaterialKind::Diffuse, Vec3::splat(albedo), 1.0);
        let (assets, state) = furnace(m, Vec3::splat(0.8), 8, 16);
        let scene = RenderScene::new(assets, &state).unwrap();
        let (mean, n) = mean_on_object(&scene, &gpu_image(t, &scene, 0, Strategy::NeeMis));
        assert!(n > 20, "the sphere covers too few pixels ({n})");
        let expected = albedo * 0.8;
        assert!(
            (mean - Vec3::splat(expected)).abs().max_element() < 0.01 * expected + 1e-3,
            "diffuse ρ {albedo}: {mean}"
        );
    }
    let cases = [
        (MaterialKind::Dielectric, 0.0, 32, 0.97, 1.03),
        (MaterialKind::Dielectric, 0.3, 32, 0.85, 1.02),
        (MaterialKind::Conductor, 0.3, 8, 0.9, 1.01),
        (MaterialKind::Glossy, 0.3, 8, 0.85, 1.01),
    ];
    for (kind, roughness, spp, lo, hi) in cases {
        let m = material("m", kind, Vec3::ONE, roughness);
        let (assets, state) = furnace(m, Vec3::ONE, spp, spp.max(16));
        let scene = RenderScene::new(assets, &state).unwrap();
        let (mean, _) = mean_on_object(&scene, &gpu_image(t, &scene, 0, Strategy::NeeMis));
        assert!(mean.max_element() < hi && mean.min_element() > lo, "{kind:?} {roughness}: {mean}");
    }
}

/// The camera inside a closed sphere whose walls emit 0.5 and reflect 0.5: with paths of
/// at most 6 segments the answer is 1 - 0.5^6 (the CPU's `closed_furnace`).
#[test]
fn gpu_closed_furnace_has_the_known_answer_with_nee_and_with_bsdf_sampling() {
    let Some(t) = tracer("gpu_closed_furnace") else { return };
    let mut m = material("wall", MaterialKind::Diffuse, Vec3::splat(0.5), 1.0);
    m.emission = Vec3::splat(0.5);
    let (_, mut state) = furnace(m, Vec3::ZERO, 6, 8);
    state.environment = None;
    state.camera.position = Vec3::new(0.0, 0.0, 0.3);
    let mut mesh = shapes::sphere(2);
    mesh.indices.iter_mut().for_each(|t| t.swap(1, 2));
    mesh.normals.iter_mut().for_each(|n| *n = -*n);
    let geometry = Geometry::Obj { path: "inside-out-sphere.obj".into() };
    let mut assets = Assets::default();
    assets.meshes.insert(geometry.clone(), Arc::new(mesh));
    state.objects[0].geometry = geometry;
    state.objects[0].transform = Transform { scale: Vec3::splat(2.0), ..Transform::default() };
    let scene = RenderScene::new(Arc::new(assets), &state).unwrap();
    let expected = 1.0 - 0.5f64.powi(6);
    for strategy in [Strategy::NeeMis, Strategy::BsdfOnly] {
        let m = mean(&gpu_image(t, &scene, 0, strategy));
        assert!((m - DVec3::splat(expected)).abs().max_element() < 0.01, "{strategy:?}: {m}");
    }
}

#[test]
fn gpu_nee_and_bsdf_sampling_agree_on_the_cornell_box() {
    let Some(t) = tracer("gpu_nee_and_bsdf_sampling_agree") else { return };
    let (assets, mut state) = cornell_box(24, 18);
    state.render.spp = 256;
    let scene = RenderScene::new(assets, &state).unwrap();
    let nee = mean(&gpu_image(t, &scene, 1, Strategy::NeeMis));
    let bsdf = mean(&gpu_image(t, &scene, 1, Strategy::BsdfOnly));
    let rel = ((nee - bsdf) / nee).abs();
    assert!(rel.max_element() < 0.03, "NEE {nee} vs BSDF {bsdf}");
    assert!(nee.min_element() > 0.02, "the box is too dark: {nee}");
}

#[test]
fn batches_of_several_frames_match_one_batch_each() {
    let Some(t) = tracer("batches_of_several_frames") else { return };
    let (assets, mut state) = cornell_box(16, 12);
    state.render.spp = 2;
    let scene = RenderScene::new(assets, &state).unwrap();
    let uploaded = t.upload(&scene).expect("upload");
    let (a, b): (Vec<u32>, Vec<u32>) = (0..16 * 12).partition(|p| p % 3 == 0);
    let mut together = Vec::new();
    let batches = [PixelBatch { frame: 4, pixels: &a }, PixelBatch { frame: 9, pixels: &b }];
    t.render(&uploaded, &batches, Strategy::NeeMis, &mut together).unwrap();
    let mut alone = Vec::new();
    for batch in batches {
        let mut out = Vec::new();
        t.render(&uploaded, &[batch], Strategy::NeeMis, &mut out).unwrap();
        alone.extend(out);
    }
    assert_eq!(together, alone, "a pixel's samples depend on its batch");
    // Different frames draw different samples.
    let mut other = Vec::new();
    t.render(&uploaded, &[PixelBatch { frame: 5, pixels: &a }], Strategy::NeeMis, &mut other)
        .unwrap();
    assert_ne!(&together[..a.len()], &other[..]);
}
