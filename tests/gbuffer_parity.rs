//! The raster G-buffer (`gbuffer::GpuGBuffer`) agrees with the CPU path (`primary_hit` per
//! pixel centre) on the Cornell box and on a scene with an albedo texture, a moved, rotated
//! and non-uniformly scaled object, a two-slot mesh without normals whose uvs wrap, a quad
//! light and a coloured environment; and moving an object changes the GPU G-buffer.
//!
//! Tolerances. Object ids: ≥ 99 % of pixels equal, and every pixel whose ids differ lies
//! next to an object edge (another id in its 3×3 neighbourhood of the CPU G-buffer). A
//! rasteriser snaps vertices to its sub-pixel grid (Vulkan: at least 1/256 pixel) and
//! applies tie-breaking rules on edges, and the ray-triangle test makes its own rounding
//! there, so a pixel centre very close to a silhouette may land on the other side of it;
//! lavapipe differs on 0.05 % of the Cornell box's pixels, all of them on edges, and 1 %
//! leaves room for rasterisers with coarser snapping. The same snapping moves the sample point
//! inside a triangle by ≤ 1/512 pixel, and where two triangles of one object meet (a cube's
//! edge) the ids agree but the normals need not, so values are compared on interior pixels:
//! those whose 3×3 neighbourhood has one object id and one triangle plane in the CPU
//! G-buffer. There, positions differ by at most the snapping times the pixel footprint (here
//! ~1e-5 scene units, more at grazing angles), so 1e-3 × scene scale holds with a wide
//! margin; normals are interpolations of the same vertex normals with the same barycentrics
//! up to that shift (cos ≥ 0.999); albedo is the same bilinear lookup in f32 (≤ 1/255).
//!
//! Where no adapter exists the GPU half says it is skipped and why; the CPU half runs.

use std::path::Path;
use std::sync::Arc;

use glam::{Quat, Vec2, Vec3};
use gridlight::assets::{Assets, Mesh, Texture};
use gridlight::gbuffer::{GBuffer, GBufferSource, GpuGBuffer, NO_OBJECT};
use gridlight::gpu::{Backend, GpuContext};
use gridlight::scene::{self, AssetSearchPath};
use gridlight::testing::{skip, Missing};
use gridlight_actors::state::{Environment, Geometry, Light, Object, SceneState, Transform};

fn cornell() -> (Arc<Assets>, SceneState) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.toml");
    let loaded = scene::load(&path, &AssetSearchPath::from_dirs(vec![])).expect("cornell box");
    (Arc::new(loaded.assets), loaded.state)
}

/// A 16×16 linear texture with a different value in every texel and channel, so that a
/// wrong texel, flip or filter shows.
fn noise_texture() -> Texture {
    let (w, h) = (16u32, 16u32);
    let texels = (0..w * h)
        .map(|i| {
            let f = |k: u32| ((i.wrapping_mul(2654435761).wrapping_add(k * 40503)) % 997) as f32;
            Vec3::new(f(1), f(2), f(3)) / 997.0 * 0.9 + Vec3::splat(0.05)
        })
        .collect();
    Texture::linear(w, h, texels)
}

/// A quad in the xy-plane, facing +z, split into two material slots, without normals and
/// with uvs from -1 to 2 (so the lookup wraps).
fn tiled_quad() -> Mesh {
    let positions = vec![
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.5, 0.0),
        Vec3::new(0.0, -0.5, 0.0),
        Vec3::new(0.0, 0.5, 0.0),
    ];
    let uvs = positions.iter().map(|p| Vec2::new(p.x * 3.0 + 0.5, p.y * 3.0 + 0.5)).collect();
    Mesh {
        positions,
        normals: Vec::new(),
        uvs,
        indices: vec![[0, 4, 5], [0, 5, 3], [4, 1, 2], [4, 2, 5]],
        slots: vec![0, 0, 1, 1],
        slot_count: 2,
    }
}

/// The Cornell box with textures, a transformed sphere, the tiled quad, a quad light in
/// front of the back wall and a coloured environment around the open front.
fn textured() -> (Arc<Assets>, SceneState) {
    let (assets, mut state) = cornell();
    let mut assets = (*assets).clone();
    assets.textures.insert("test/noise.png".into(), Arc::new(noise_texture()));
    let tiled = Geometry::Obj { path: "test/tiled.obj".into() };
    assets.meshes.insert(tiled.clone(), Arc::new(tiled_quad()));
    let mut textured = state.materials[0].clone();
    textured.name = "textured".into();
    textured.base_color = Vec3::new(1.0, 0.8, 0.9);
    textured.base_color_texture = Some("test/noise.png".into());
    state.materials.push(textured);
    let tex = state.materials.len() as u32 - 1;
    let back = state.objects.iter_mut().find(|o| o.name == "back").expect("back wall");
    back.materials = vec![tex];
    state.objects.push(Object {
        name: "ball".into(),
        geometry: Geometry::Sphere { subdivisions: 4 },
        transform: Transform {
            translation: Vec3::new(-0.4, 0.2, 0.1),
            rotation: Quat::from_euler(glam::EulerRot::XYZ, 0.4, 1.1, -0.3),
            scale: Vec3::new(0.3, 0.45, 0.25),
        },
        materials: vec![tex],
        visible: true,
    });
    state.objects.push(Object {
        name: "tiles".into(),
        geometry: tiled,
        transform: Transform {
            translation: Vec3::new(0.45, 0.45, 0.2),
            rotation: Quat::from_rotation_y(-0.5) * Quat::from_rotation_x(0.3),
            scale: Vec3::splat(0.6),
        },
        materials: vec![tex, 2],
        visible: true,
    });
    state.lights.push(Light::Quad {
        corner: Vec3::new(-0.9, -0.6, -0.95),
        edge_u: Vec3::new(0.3, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.3, 0.0),
        radiance: Vec3::new(5.0, 4.0, 3.0),
    });
    state.environment = Some(Environment {
        map: None,
        color: Vec3::new(0.2, 0.3, 0.4),
        intensity: 1.5,
        rotation_deg: 0.0,
    });
    state.version += 1;
    (Arc::new(assets), state)
}

fn cpu_gbuffer(assets: &Arc<Assets>, state: &SceneState) -> Arc<GBuffer> {
    let mut source = GBufferSource::new(assets.clone(), state, Backend::Cpu).expect("cpu");
    assert!(!source.is_gpu());
    source.get(state).expect("cpu G-buffer")
}

/// The GPU half's context, or `None` after saying why it is skipped.
fn gpu_context(test: &str) -> Option<Arc<GpuContext>> {
    match GpuContext::new() {
        Ok(ctx) => {
            println!(
                "{test}: GPU adapter {} ({:?})",
                ctx.adapter_info.name, ctx.adapter_info.backend
            );
            Some(ctx.shared())
        }
        Err(err) => {
            skip(&format!("{test} (GPU half)"), Missing::Adapter, err);
            None
        }
    }
}

/// Interior pixels: the 3×3 neighbourhood has one id and one plane in `g`.
fn interior(g: &GBuffer) -> Vec<bool> {
    let (w, h) = (g.width as i64, g.height as i64);
    (0..g.len())
        .map(|i| {
            let (x, y) = (i as i64 % w, i as i64 / w);
            if x == 0 || y == 0 || x == w - 1 || y == h - 1 || g.object[i] == NO_OBJECT {
                return false;
            }
            (-1..=1).all(|dy| {
                (-1..=1).all(|dx| {
                    let j = ((y + dy) * w + x + dx) as usize;
                    let off_plane = (g.position[j] - g.position[i]).dot(g.normal[i]).abs();
                    g.object[j] == g.object[i]
                        && g.normal[j].dot(g.normal[i]) > 0.99
                        && off_plane < 1e-3 * g.scene_scale
                })
            })
        })
        .collect()
}

/// Pixels with another object id (or a miss) in their 3×3 neighbourhood in `g`.
fn on_id_edge(g: &GBuffer, i: usize) -> bool {
    let (w, h) = (g.width as i64, g.height as i64);
    let (x, y) = (i as i64 % w, i as i64 / w);
    (-1..=1).any(|dy| {
        (-1..=1).any(|dx| {
            let (nx, ny) = (x + dx, y + dy);
            (0..w).contains(&nx)
                && (0..h).contains(&ny)
                && g.object[(ny * w + nx) as usize] != g.object[i]
        })
    })
}

/// Agreement figures of two G-buffers.
#[derive(Debug, Default)]
struct Agreement {
    ids_equal: f64,
    /// Pixels whose ids differ although no other id is next to them in the CPU G-buffer.
    ids_off_edges: usize,
    interior: usize,
    misses: usize,
    max_normal: f32,
    min_cos: f32,
    max_position: f32,
    max_albedo: f32,
    max_emission: f32,
}

fn compare(cpu: &GBuffer, gpu: &GBuffer) -> Agreement {
    assert_eq!((cpu.width, cpu.height), (gpu.width, gpu.height));
    assert_eq!(cpu.scene_scale, gpu.scene_scale);
    let equal = cpu.object.iter().zip(&gpu.object).filter(|(a, b)| a == b).count();
    let mut a = Agreement {
        ids_equal: equal as f64 / cpu.len() as f64,
        min_cos: 1.0,
        ..Default::default()
    };
    let inner = interior(cpu);
    a.ids_off_edges =
        (0..cpu.len()).filter(|&i| cpu.object[i] != gpu.object[i] && !on_id_edge(cpu, i)).count();
    for (i, &inside) in inner.iter().enumerate() {
        let both_missed = cpu.normal[i] == Vec3::ZERO && gpu.normal[i] == Vec3::ZERO;
        if both_missed {
            // Escaping rays: the same environment lookup on both sides.
            a.misses += 1;
            a.max_emission =
                a.max_emission.max((cpu.emission[i] - gpu.emission[i]).abs().max_element());
            assert_eq!(gpu.albedo[i], Vec3::ONE);
            assert_eq!(gpu.position[i], Vec3::ZERO);
        }
        if !inside || cpu.object[i] != gpu.object[i] {
            continue;
        }
        a.interior += 1;
        a.max_normal = a.max_normal.max((cpu.normal[i] - gpu.normal[i]).length());
        a.min_cos = a.min_cos.min(cpu.normal[i].dot(gpu.normal[i]));
        a.max_position = a.max_position.max((cpu.position[i] - gpu.position[i]).length());
        a.max_albedo = a.max_albedo.max((cpu.albedo[i] - gpu.albedo[i]).abs().max_element());
        let rel = (cpu.emission[i] - gpu.emission[i]).abs().max_element()
            / cpu.emission[i].max_element().max(1.0);
        a.max_emission = a.max_emission.max(rel);
    }
    a
}

fn assert_agree(name: &str, cpu: &GBuffer, gpu: &GBuffer) {
    let a = compare(cpu, gpu);
    println!("{name}: {a:?}");
    assert!(a.ids_equal >= 0.99, "{name}: only {:.4} of object ids agree", a.ids_equal);
    assert_eq!(a.ids_off_edges, 0, "{name}: ids differ away from object edges");
    assert!(a.interior as f64 > 0.5 * cpu.len() as f64, "{name}: too few interior pixels");
    assert!(a.min_cos >= 0.999, "{name}: normals differ (min cos {})", a.min_cos);
    assert!(
        a.max_position <= 1e-3 * cpu.scene_scale,
        "{name}: positions differ by {} (scale {})",
        a.max_position,
        cpu.scene_scale
    );
    assert!(a.max_albedo <= 1.0 / 255.0, "{name}: albedo differs by {}", a.max_albedo);
    assert!(a.max_emission <= 1e-4, "{name}: emission differs by {} (relative)", a.max_emission);
}

#[test]
fn cpu_gbuffer_sees_the_cornell_box() {
    let (assets, state) = cornell();
    let g = cpu_gbuffer(&assets, &state);
    g.validate(640, 480).expect("consistent planes");
    let centre = 240 * 640 + 320;
    assert_ne!(g.object[centre], NO_OBJECT);
    // The open front lets corner rays escape into the (black) environment.
    assert_eq!(g.object[0], NO_OBJECT);
    assert_eq!((g.normal[0], g.albedo[0], g.emission[0]), (Vec3::ZERO, Vec3::ONE, Vec3::ZERO));
    let light = state.objects.iter().position(|o| o.name == "light").expect("light") as u32;
    let lit = (0..g.len()).filter(|&i| g.object[i] == light && g.emission[i].x > 1.0).count();
    assert!(lit > 100, "the ceiling light is seen from below ({lit} pixels)");
}

#[test]
fn gpu_gbuffer_matches_cpu_on_the_cornell_box() {
    let (assets, state) = cornell();
    let cpu = cpu_gbuffer(&assets, &state);
    let Some(ctx) = gpu_context("cornell box") else { return };
    let mut gpu = GpuGBuffer::new(ctx, assets, &state).expect("GPU G-buffer");
    let g = gpu.compute(&state).expect("GPU G-buffer");
    println!("cornell box: GPU G-buffer {:.1} ms", gpu.last_ms().unwrap_or(f64::NAN));
    assert_agree("cornell box", &cpu, &g);
}

#[test]
fn gpu_gbuffer_matches_cpu_with_textures_transforms_and_lights() {
    let (assets, state) = textured();
    let cpu = cpu_gbuffer(&assets, &state);
    // The scene exercises what it should: textured, quad-light and environment pixels.
    let ball = state.objects.iter().position(|o| o.name == "ball").expect("ball") as u32;
    let tiles = state.objects.iter().position(|o| o.name == "tiles").expect("tiles") as u32;
    for id in [ball, tiles] {
        assert!(cpu.object.iter().filter(|&&o| o == id).count() > 500, "object {id} in view");
    }
    let quad_light = (0..cpu.len())
        .filter(|&i| cpu.object[i] == NO_OBJECT && cpu.emission[i] == Vec3::new(5.0, 4.0, 3.0))
        .count();
    assert!(quad_light > 100, "quad light in view ({quad_light} pixels)");
    assert!(cpu.emission[0].z > 0.5, "the environment is seen through the open front");
    let Some(ctx) = gpu_context("textured") else { return };
    let mut gpu = GpuGBuffer::new(ctx, assets, &state).expect("GPU G-buffer");
    let g = gpu.compute(&state).expect("GPU G-buffer");
    assert_agree("textured", &cpu, &g);
}

/// Moves the small box of `state` and checks what `source` computes: the same version
/// comes from the cache, most of the box's old pixels change and nothing away from it
/// does: the same point, and the same object except at `ties` (a share of those pixels)
/// where two objects meet at that very point. Returns the G-buffer after the move.
fn check_moving(source: &mut GBufferSource, state: &mut SceneState, ties: f64) -> Arc<GBuffer> {
    let box_id = state.objects.iter().position(|o| o.name == "small-box").expect("box");
    let before = source.get(state).expect("before");
    // The same version is served from the cache.
    assert!(Arc::ptr_eq(&before, &source.get(state).expect("cached")));
    state.objects[box_id].transform.translation.x -= 0.6;
    state.version += 1;
    let after = source.get(state).expect("after");
    let id = box_id as u32;
    let was: Vec<usize> = (0..before.len()).filter(|&i| before.object[i] == id).collect();
    let left = was.iter().filter(|&&i| after.object[i] != id).count();
    assert!(was.len() > 1000, "the box is in view ({} pixels)", was.len());
    assert!(left as f64 > 0.3 * was.len() as f64, "only {left} of {} pixels changed", was.len());
    // Pixels that saw neither box position are untouched.
    let away: Vec<usize> =
        (0..before.len()).filter(|&i| before.object[i] != id && after.object[i] != id).collect();
    let moved = away.iter().filter(|&&i| before.position[i] != after.position[i]).count();
    let other_object = away.iter().filter(|&&i| before.object[i] != after.object[i]).count();
    assert_eq!(moved, 0, "{moved} pixels away from the box see another point");
    assert!(
        other_object as f64 <= ties * away.len() as f64,
        "{other_object} of {} pixels away from the box see another object at the same point",
        away.len()
    );
    after
}

#[test]
fn moving_an_object_changes_the_gbuffer_where_it_was_on_the_cpu() {
    let (assets, mut state) = cornell();
    let mut source = GBufferSource::new(assets, &state, Backend::Cpu).expect("CPU source");
    assert!(!source.is_gpu());
    // The CPU path's flattened BVH is rebuilt when the box moves, so where two objects
    // meet (a wall on the floor) a ray through that very point may find the other one
    // first: a few dozen pixels of the view (at most 0.1 %). The raster pass's depth test
    // is stable: no ties there.
    check_moving(&mut source, &mut state, 0.001);
}

#[test]
fn moving_an_object_changes_the_gpu_gbuffer_where_it_was() {
    let (assets, mut state) = cornell();
    let Some(ctx) = gpu_context("moving_an_object_changes_the_gpu_gbuffer_where_it_was") else {
        return;
    };
    let mut source = GBufferSource::with_context(assets.clone(), &state, Backend::Gpu, Some(ctx))
        .expect("GPU source");
    assert!(source.is_gpu());
    let after = check_moving(&mut source, &mut state, 0.0);
    assert_agree("moved", &cpu_gbuffer(&assets, &state), &after);
}
