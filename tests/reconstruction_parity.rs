//! The GPU passes compute what the CPU reference computes.
//!
//! Both run the same frame sequence (interacting, accumulating, a view change with
//! history, more loss) on the analytic scene. Tolerance: both sides evaluate the same f32
//! expressions in the same order, so differences come only from the GPU's freedom in
//! rounding — WGSL allows `exp`/`pow` a few ULP and division 2.5 ULP, and the shader
//! compiler may fuse multiply-adds — accumulated over at most 121 + 5 + 49 weighted terms.
//! That bounds the relative error of the demodulated radiance well below 1e-4 (we allow
//! 1e-4 relative to max(1, |value|)); the 8-bit display may differ by one step where a
//! value sits on a rounding boundary.
//!
//! Where no adapter exists the GPU half says it is skipped and why; the CPU half runs.

use glam::Vec3;
use gridlight::gbuffer::GBuffer;
use gridlight::reconstruct::synthetic::{self, SyntheticView};
use gridlight::reconstruct::{
    CpuReconstructor, FrameInputs, Mode, ReconstructParams, Reconstructed,
};
use gridlight_actors::accumulation::Accumulation;

const W: u32 = 96;
const H: u32 = 72;

struct Frame {
    frame: u64,
    version: u64,
    /// Shown frames of its version so far, as the frame assembler counts them.
    accumulated: u32,
    radiance: Vec<Vec3>,
    mask: Vec<bool>,
    gbuffer: std::sync::Arc<GBuffer>,
}

fn sequence() -> Vec<Frame> {
    let views = [SyntheticView::default(), SyntheticView { eye: Vec3::new(0.15, 0.25, 3.9) }];
    let gbuffers: Vec<_> =
        views.iter().map(|v| std::sync::Arc::new(synthetic::gbuffer(W, H, *v))).collect();
    // (frame, state version, view, fraction of pixels calculated)
    let plan = [
        (1, 1, 0, 0.5),
        (2, 1, 0, 0.75),
        (3, 1, 0, 0.5),
        (5, 2, 1, 0.5),
        (6, 3, 1, 0.25),
        (7, 3, 1, 0.75),
    ];
    let mut accumulation = Accumulation::default();
    plan.iter()
        .map(|&(frame, version, view, keep)| {
            let g = gbuffers[view].clone();
            let clean = synthetic::clean_radiance(&g);
            Frame {
                frame,
                version,
                accumulated: accumulation.add(version),
                radiance: synthetic::noisy_radiance(&clean, 0.6, 7, frame),
                mask: synthetic::random_mask(g.len(), keep, 7, frame),
                gbuffer: g,
            }
        })
        .collect()
}

fn inputs(f: &Frame) -> FrameInputs<'_> {
    FrameInputs {
        frame: f.frame,
        state_version: f.version,
        accumulated_frames: f.accumulated,
        radiance: &f.radiance,
        mask: &f.mask,
        gbuffer: &f.gbuffer,
        scene: None,
    }
}

fn run_cpu(frames: &[Frame]) -> Vec<Reconstructed> {
    let mut r = CpuReconstructor::new(W, H, ReconstructParams::default()).expect("valid params");
    frames.iter().map(|f| r.reconstruct(&inputs(f)).expect("valid inputs")).collect()
}

#[test]
fn cpu_reference_keeps_samples_and_fills_every_surface_pixel() {
    let frames = sequence();
    let out = run_cpu(&frames);
    assert_eq!(out[0].mode, Mode::Interacting);
    assert_eq!(out[2].mode, Mode::Accumulating { frames: 3 });
    assert_eq!(out[3].mode, Mode::Interacting);
    // Accumulating frame 2: pixels with samples in frame 1 or 2 hold their exact mean.
    let (a, b) = (&frames[0], &frames[1]);
    for i in 0..a.radiance.len() {
        let (n, sum) = match (a.mask[i], b.mask[i]) {
            (true, true) => (2.0, a.radiance[i] + b.radiance[i]),
            (true, false) => (1.0, a.radiance[i]),
            (false, true) => (1.0, b.radiance[i]),
            (false, false) => continue,
        };
        assert!((out[1].radiance[i] - sum / n).abs().max_element() < 1e-5, "pixel {i}");
    }
    // Every surface pixel of every frame gets a finite, non-negative value; the sky stays 0.
    for (f, o) in frames.iter().zip(&out) {
        for (i, v) in o.radiance.iter().enumerate() {
            assert!(v.is_finite() && v.min_element() >= 0.0);
            if f.gbuffer.normal[i] == Vec3::ZERO {
                assert_eq!(*v, Vec3::ZERO);
            }
        }
    }
}

#[test]
fn gpu_matches_cpu_reference() {
    let ctx = match gridlight::gpu::GpuContext::new() {
        Ok(ctx) => ctx,
        Err(err) => {
            let why = format!("the GPU half of the parity test needs a wgpu adapter ({err})");
            gridlight::testing::skip(
                "gpu_matches_cpu_reference",
                gridlight::testing::Missing::Adapter,
                why,
            );
            return;
        }
    };
    println!("GPU adapter: {} ({:?})", ctx.adapter_info.name, ctx.adapter_info.backend);
    let frames = sequence();
    let cpu = run_cpu(&frames);
    let mut gpu = gridlight::reconstruct::GpuReconstructor::new(
        ctx.shared(),
        W,
        H,
        ReconstructParams::default(),
    )
    .expect("GPU reconstructor");
    for (f, c) in frames.iter().zip(&cpu) {
        let g = gpu.reconstruct(&inputs(f)).expect("GPU frame");
        assert_eq!(g.mode, c.mode);
        let mut worst = 0.0f32;
        for (i, (a, b)) in g.radiance.iter().zip(&c.radiance).enumerate() {
            let err = (*a - *b).abs().max_element() / b.max_element().max(1.0);
            worst = worst.max(err);
            assert!(err <= 1e-4, "frame {} pixel {i}: gpu {a} cpu {b}", f.frame);
        }
        for (i, (a, b)) in g.colour.iter().zip(&c.colour).enumerate() {
            let err = (*a - *b).abs().max_element() / b.max_element().max(1.0);
            assert!(err <= 1e-4, "frame {} colour {i}: gpu {a} cpu {b}", f.frame);
        }
        for (i, (a, b)) in g.display.iter().zip(&c.display).enumerate() {
            for k in 0..4 {
                assert!(
                    a[k].abs_diff(b[k]) <= 1,
                    "frame {} display {i}: gpu {a:?} cpu {b:?}",
                    f.frame
                );
            }
        }
        println!("frame {}: worst relative radiance difference {worst:e}", f.frame);
    }
}
