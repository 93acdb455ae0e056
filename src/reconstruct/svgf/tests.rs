//! Behaviour of the SVGF reconstruction on the Cornell box's real G-buffers.

use std::sync::Arc;

use glam::{Quat, Vec3};
use gridlight_actors::state::SceneState;

use super::atrous;
use super::edges::Edges;
use super::*;
use crate::assets::Assets;
use crate::gbuffer::GBuffer;
use crate::reconstruct::pass::testing::{image, planes};
use crate::reconstruct::FrameInputs;
use crate::render::RenderScene;

const W: u32 = 64;
const H: u32 = 48;

fn cornell() -> (Arc<Assets>, SceneState) {
    crate::render::testscenes::cornell_box(W, H)
}

fn gbuffer(assets: &Arc<Assets>, state: &SceneState) -> GBuffer {
    let scene = RenderScene::new(Arc::clone(assets), state).expect("a scene");
    GBuffer::from_scene(&scene, crate::gbuffer::scene_scale(state, assets))
}

/// Demodulated radiance that names the object: 1 + its index.
fn by_object(g: &GBuffer) -> Vec<Vec3> {
    g.object.iter().map(|&o| Vec3::splat(1.0 + o as f32)).collect()
}

fn svgf_params() -> ReconstructParams {
    ReconstructParams { method: Method::Svgf, ..Default::default() }
}

/// Frames `first..first + count` of `state` with every pixel sampled (`full`) or none.
fn run(
    r: &mut SvgfReconstructor,
    state: &SceneState,
    g: &GBuffer,
    radiance: &[Vec3],
    frames: std::ops::Range<u64>,
    full: bool,
) {
    let mask = vec![full; g.len()];
    for (k, frame) in frames.enumerate() {
        let inputs = FrameInputs {
            frame,
            state_version: state.version,
            accumulated_frames: k as u32 + 1,
            radiance,
            mask: &mask,
            gbuffer: g,
            scene: Some(state),
        };
        r.reconstruct(&inputs).expect("a frame");
    }
}

/// The history's mean and count of each pixel.
fn history(r: &SvgfReconstructor) -> Vec<(Vec3, f32)> {
    r.history.iter().map(|m| (m.sum.truncate() / m.sum.w.max(1e-9), m.sum.w)).collect()
}

#[test]
fn a_camera_pan_keeps_the_samples_of_surfaces_still_in_sight() {
    let (assets, a) = cornell();
    let mut b = a.clone();
    b.version = a.version + 1;
    let turn = Quat::from_rotation_y(3f32.to_radians());
    b.camera.position = b.camera.look_at + turn * (b.camera.position - b.camera.look_at);
    let (ga, gb) = (gbuffer(&assets, &a), gbuffer(&assets, &b));
    let mut r = SvgfReconstructor::new(W, H, svgf_params()).expect("valid");
    run(&mut r, &a, &ga, &by_object(&ga), 1..5, true);
    run(&mut r, &b, &gb, &by_object(&gb), 5..6, false);
    let surface: Vec<usize> = (0..gb.len()).filter(|&i| gb.object[i] != NO_OBJECT).collect();
    let h = history(&r);
    let kept = surface.iter().filter(|&&i| h[i].1 >= 4.0 - 1e-3).count();
    assert!(kept * 10 >= surface.len() * 8, "{kept} of {} pixels kept 4 samples", surface.len());
    let empty = surface.iter().filter(|&&i| h[i].1 == 0.0).count();
    assert!(empty > 0, "the pan brings pixels into view that have no history");
    for &i in &surface {
        let (mean, n) = h[i];
        if n > 0.0 {
            let want = Vec3::splat(1.0 + gb.object[i] as f32);
            assert!((mean - want).abs().max_element() < 1e-4, "pixel {i}: {mean} of {want}");
        }
    }
}

#[test]
fn a_moved_object_takes_its_history_along_and_leaves_disocclusions_empty() {
    let (assets, a) = cornell();
    let mut b = a.clone();
    b.version = a.version + 1;
    let moved = b.objects.iter().position(|o| o.name == "small-box").expect("a box");
    b.objects[moved].transform.translation += Vec3::new(0.15, 0.0, 0.0);
    let (ga, gb) = (gbuffer(&assets, &a), gbuffer(&assets, &b));
    let mut r = SvgfReconstructor::new(W, H, svgf_params()).expect("valid");
    run(&mut r, &a, &ga, &by_object(&ga), 1..4, true);
    run(&mut r, &b, &gb, &by_object(&gb), 4..5, false);
    let h = history(&r);
    let (mut uncovered, mut on_box, mut box_kept) = (0, 0, 0);
    for (i, &o) in gb.object.iter().enumerate() {
        if o == moved as u32 {
            on_box += 1;
            box_kept += (h[i].1 > 0.0) as usize;
        } else if o != NO_OBJECT && ga.object[i] == moved as u32 {
            // The box stood here: what shows now was hidden.
            uncovered += 1;
            assert_eq!(h[i].1, 0.0, "pixel {i} was behind the box");
        }
    }
    assert!(uncovered > 0, "the move uncovers pixels");
    assert!(box_kept * 10 >= on_box * 7, "{box_kept} of {on_box} box pixels kept history");
}

#[test]
fn an_edit_of_the_lighting_caps_the_history() {
    let (assets, a) = cornell();
    let mut b = a.clone();
    b.version = a.version + 1;
    b.materials[0].base_color *= 0.5;
    let g = gbuffer(&assets, &a);
    let mut r = SvgfReconstructor::new(W, H, svgf_params()).expect("valid");
    run(&mut r, &a, &g, &by_object(&g), 1..11, true);
    run(&mut r, &b, &g, &by_object(&g), 11..12, false);
    let most = history(&r).iter().map(|h| h.1).fold(0.0, f32::max);
    let cap = svgf_params().svgf.edit_samples;
    assert!((most - cap).abs() < 1e-4, "the most samples kept is {most}, the cap {cap}");
}

#[test]
fn a_resting_view_converges_to_each_pixels_mean() {
    let (assets, a) = cornell();
    let g = gbuffer(&assets, &a);
    let mut r = SvgfReconstructor::new(W, H, svgf_params()).expect("valid");
    let mut sum = vec![Vec3::ZERO; g.len()];
    let surface: Vec<usize> = (0..g.len()).filter(|&i| g.object[i] != NO_OBJECT).collect();
    // (mean, largest) relative distance of the filtered pixels from their sample means.
    let mut errors = Vec::new();
    for frame in 1..=200u64 {
        // Noise of ±50 % around a pattern with sharp steps within surfaces.
        let radiance: Vec<Vec3> = (0..g.len())
            .map(|i| {
                let base = if (i / 4) % 2 == 0 { 1.0 } else { 0.3 };
                let hash = ((i as u64 * 2654435761 + frame * 40503) % 1000) as f32 / 1000.0;
                Vec3::splat(base * (0.5 + hash))
            })
            .collect();
        for (s, v) in sum.iter_mut().zip(&radiance) {
            *s += *v;
        }
        let mask = vec![true; g.len()];
        let inputs = FrameInputs {
            frame,
            state_version: a.version,
            accumulated_frames: frame as u32,
            radiance: &radiance,
            mask: &mask,
            gbuffer: &g,
            scene: Some(&a),
        };
        let out = r.reconstruct(&inputs).expect("a frame");
        if frame == 20 || frame == 200 {
            let e: Vec<f32> = surface
                .iter()
                .map(|&i| {
                    let mean = sum[i] / frame as f32;
                    ((out.radiance[i] - mean) / mean).abs().max_element()
                })
                .collect();
            errors.push((
                e.iter().sum::<f32>() / e.len() as f32,
                e.iter().copied().fold(0.0, f32::max),
            ));
        }
    }
    let [(mean20, _), (mean200, max200)] = errors[..] else { panic!("two measurements") };
    assert!(mean200 < 0.5 * mean20, "the distance falls as samples accumulate: {errors:?}");
    // What is left is the blend of equal neighbours within the remaining noise (measured
    // 1.0 % mean, 2.4 % at most after 200 frames).
    assert!(mean200 < 0.015 && max200 < 0.05, "{errors:?}");
}

#[test]
fn atrous_smooths_noise_but_keeps_edges() {
    let (w, h) = (32u32, 32u32);
    let n = (w * h) as usize;
    // Two walls meeting at a crease (normals Z and X), lit 1.0 and 0.2, with ±30 % noise.
    let normal: Vec<Vec3> = (0..n).map(|i| if i % 32 < 16 { Vec3::Z } else { Vec3::X }).collect();
    let position: Vec<Vec3> = (0..n)
        .map(|i| {
            let (x, y) = ((i % 32) as f32 * 0.01, (i / 32) as f32 * 0.01);
            if i % 32 < 16 {
                Vec3::new(x, y, 0.0)
            } else {
                Vec3::new(0.16, y, x - 0.16)
            }
        })
        .collect();
    let truth = |i: usize| if i % 32 < 16 { 1.0 } else { 0.2 };
    let noisy: Vec<Vec3> = (0..n)
        .map(|i| {
            let hash = ((i as u64 * 2654435761) % 1000) as f32 / 1000.0 - 0.5;
            Vec3::splat(truth(i) * (1.0 + 0.6 * hash))
        })
        .collect();
    let layout = Layout::new(w, h, 16);
    let mut guide = GuidePlanes::new(&layout);
    guide.split(&normal, &position, &layout);
    let mut colour = planes(&noisy, &layout);
    let mut var = Plane::zeroed(layout.plane_len());
    // One sample's variance: (0.6 · truth)² / 12.
    for i in 0..n {
        var[layout.index(i % 32, i / 32)] = (0.6 * truth(i)).powi(2) / 12.0;
    }
    let edges = Edges::new(64, 0.1, 1.0);
    let (mut out, mut out_var) = (layout.zeroed3(), Plane::zeroed(layout.plane_len()));
    for k in 0..5 {
        atrous::iteration(
            &colour,
            &var,
            &guide,
            edges,
            4.0,
            1 << k,
            &layout,
            (&mut out, &mut out_var),
        );
        std::mem::swap(&mut colour, &mut out);
        std::mem::swap(&mut var, &mut out_var);
    }
    let result = image(&colour, &layout);
    let error = |img: &[Vec3]| -> f32 {
        (0..n).map(|i| (img[i].x - truth(i)).powi(2)).sum::<f32>() / n as f32
    };
    assert!(error(&result) * 4.0 < error(&noisy), "{} vs {}", error(&result), error(&noisy));
    for y in 0..32 {
        // Beside the crease each side keeps its own level.
        let (left, right) = (result[y * 32 + 15].x, result[y * 32 + 16].x);
        assert!((left - 1.0).abs() < 0.15 && (right - 0.2).abs() < 0.05, "{left} {right}");
    }
}
