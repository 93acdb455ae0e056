//! The GPU's SVGF passes compute what the CPU's `SvgfReconstructor` computes.
//!
//! Both run the same frames of the Cornell box (its real G-buffers and scene states): a
//! resting view with partial frames, a camera pan (reprojection through the camera), a
//! moved box (through the object's motion, disocclusions), and a halved light (the temporal
//! gradient rescales the history), on synthetic noisy radiance. Tolerance: both evaluate
//! the same f32 expressions in the same order, so the values differ by the GPU's rounding
//! (division 2.5 ULP, fused multiply-adds) carried through five à-trous iterations, whose
//! luminance weights amplify a difference relative to the pixel's deviation: we allow
//! 1e-3 relative to max(1, |value|) for the demodulated radiance and the colour. A
//! reprojection test or a history-length branch that a rounding tips the other way changes
//! one pixel's history outright, so up to 0.1 % of the pixels may differ more (measured: none
//! on lavapipe); the 8-bit display may differ by one step where the colour sits on a
//! rounding boundary, elsewhere as the colour does.
//!
//! Where no adapter exists the GPU half says it is skipped and why.

use std::sync::Arc;

use glam::{Quat, Vec3};
use gridlight::gbuffer::{scene_scale, GBuffer};
use gridlight::reconstruct::synthetic;
use gridlight::reconstruct::{
    FrameInputs, GpuReconstructor, Method, ReconstructParams, Reconstructed, SvgfReconstructor,
};
use gridlight::render::RenderScene;
use gridlight_actors::accumulation::Accumulation;
use gridlight_actors::state::SceneState;

const W: u32 = 96;
const H: u32 = 72;

struct Frame {
    frame: u64,
    state: Arc<SceneState>,
    accumulated: u32,
    radiance: Vec<glam::Vec3>,
    mask: Vec<bool>,
    gbuffer: Arc<GBuffer>,
}

/// Rest, pan, a moved box, a halved light: each state's frames with the fraction of pixels
/// calculated.
fn sequence() -> Vec<Frame> {
    let (assets, base) = gridlight::render::testscenes::cornell_box(W, H);
    let mut states = vec![base.clone()];
    let mut next = |edit: &dyn Fn(&mut SceneState)| {
        let mut s = states.last().expect("a state").clone();
        edit(&mut s);
        s.version += 1;
        states.push(s);
    };
    next(&|s| {
        let turn = Quat::from_rotation_y(4f32.to_radians());
        s.camera.position = s.camera.look_at + turn * (s.camera.position - s.camera.look_at);
    });
    next(&|s| {
        let moved = s.objects.iter().position(|o| o.name == "small-box").expect("a box");
        s.objects[moved].transform.translation += Vec3::new(0.1, 0.0, 0.0);
    });
    next(&|s| {
        for m in &mut s.materials {
            m.emission *= 0.5;
        }
    });
    // (state, fraction calculated, radiance scale)
    let plan = [
        (0, 0.5, 1.0),
        (0, 0.75, 1.0),
        (0, 0.5, 1.0),
        (1, 0.1, 1.0),
        (1, 0.5, 1.0),
        (2, 0.05, 1.0),
        (3, 0.05, 0.5),
        (3, 0.25, 0.5),
    ];
    let mut accumulation = Accumulation::default();
    let mut gbuffers: Vec<Option<Arc<GBuffer>>> = vec![None; states.len()];
    plan.iter()
        .enumerate()
        .map(|(k, &(s, keep, scale))| {
            let state = Arc::new(states[s].clone());
            let g = gbuffers[s]
                .get_or_insert_with(|| {
                    let scene = RenderScene::new(Arc::clone(&assets), &state).expect("a scene");
                    Arc::new(GBuffer::from_scene(&scene, scene_scale(&state, &assets)))
                })
                .clone();
            let frame = k as u64 + 1;
            let clean: Vec<Vec3> =
                synthetic::clean_radiance(&g).iter().map(|&v| v * scale).collect();
            Frame {
                frame,
                accumulated: accumulation.add(state.version),
                radiance: synthetic::noisy_radiance(&clean, 0.6, 7, frame),
                mask: synthetic::random_mask(g.len(), keep, 7, frame),
                gbuffer: g,
                state,
            }
        })
        .collect()
}

fn inputs(f: &Frame) -> FrameInputs<'_> {
    FrameInputs {
        frame: f.frame,
        state_version: f.state.version,
        accumulated_frames: f.accumulated,
        radiance: &f.radiance,
        mask: &f.mask,
        gbuffer: &f.gbuffer,
        scene: Some(&f.state),
    }
}

fn params() -> ReconstructParams {
    ReconstructParams { method: Method::Svgf, ..Default::default() }
}

fn run_cpu(frames: &[Frame]) -> Vec<Reconstructed> {
    let mut r = SvgfReconstructor::new(W, H, params()).expect("valid params");
    frames.iter().map(|f| r.reconstruct(&inputs(f)).expect("valid inputs")).collect()
}

/// Pixels whose values differ by more than `tolerance` relative to max(1, |cpu|).
fn beyond(gpu: &[Vec3], cpu: &[Vec3], tolerance: f32) -> Vec<(usize, Vec3, Vec3)> {
    gpu.iter()
        .zip(cpu)
        .enumerate()
        .filter(|(_, (a, b))| {
            (**a - **b).abs().max_element() / b.max_element().max(1.0) > tolerance
        })
        .map(|(i, (a, b))| (i, *a, *b))
        .collect()
}

#[test]
fn svgf_gpu_matches_the_cpu() {
    let ctx = match gridlight::gpu::GpuContext::new() {
        Ok(ctx) => ctx,
        Err(err) => {
            let why = format!("the GPU half of the SVGF parity test needs a wgpu adapter ({err})");
            gridlight::testing::skip(
                "svgf_gpu_matches_the_cpu",
                gridlight::testing::Missing::Adapter,
                why,
            );
            return;
        }
    };
    println!("GPU adapter: {} ({:?})", ctx.adapter_info.name, ctx.adapter_info.backend);
    let frames = sequence();
    let cpu = run_cpu(&frames);
    let mut gpu = GpuReconstructor::new(ctx.shared(), W, H, params()).expect("GPU reconstructor");
    let allowed = (W * H) as usize / 1000;
    for (f, c) in frames.iter().zip(&cpu) {
        let g = gpu.reconstruct(&inputs(f)).expect("GPU frame");
        assert_eq!(g.mode, c.mode);
        for (what, a, b) in
            [("radiance", &g.radiance, &c.radiance), ("colour", &g.colour, &c.colour)]
        {
            let off = beyond(a, b, 1e-3);
            println!("frame {}: {} {what} pixels beyond 1e-3", f.frame, off.len());
            assert!(
                off.len() <= allowed,
                "frame {} {what}: {:?}",
                f.frame,
                &off[..off.len().min(8)]
            );
        }
        let steps = g
            .display
            .iter()
            .zip(&c.display)
            .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 1))
            .count();
        assert!(steps <= allowed, "frame {}: {steps} display pixels off by more than 1", f.frame);
    }
}

#[test]
fn svgf_on_the_gpu_is_no_longer_refused() {
    // `--reconstruction svgf --reconstruct cpu` stays on the CPU; the GPU backend makes a
    // GPU reconstructor wherever an adapter exists (checked above), never a parameter error.
    let r = gridlight::reconstruct::Reconstructor::new(
        W,
        H,
        params(),
        gridlight::gpu::Backend::Cpu,
        None,
    )
    .expect("the CPU svgf");
    assert_eq!(r.describe(), "cpu (svgf)");
    match gridlight::reconstruct::Reconstructor::new(
        W,
        H,
        params(),
        gridlight::gpu::Backend::Gpu,
        None,
    ) {
        Ok(r) => assert!(matches!(r, gridlight::reconstruct::Reconstructor::Gpu(_))),
        Err(gridlight::reconstruct::ReconstructError::Gpu(_)) => {}
        Err(other) => panic!("svgf on the GPU refused: {other}"),
    }
}
