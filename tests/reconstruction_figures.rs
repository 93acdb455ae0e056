//! The paper's findings, reproduced on small images (96×72).
//!
//! Frames come from the analytic scene with per-frame noise standing in for 4-spp path
//! tracing (`eval::SyntheticSource`), so these run in milliseconds and need no renderer.
//! With 96×72 pixels we use S = 16 sets: the tiles are then 24×18 pixels, larger than
//! twice the fill radius, as 64 tiles of 80×60 are at the paper's 640×480.

use gridlight::reconstruct::ReconstructParams;
use gridlight::tools::eval::{loss, sequence, FrameSource, SyntheticSource};

const W: u32 = 96;
const H: u32 = 72;
const SETS: u32 = 16;
/// The loss test at 160×120 with 4 sets: tiles of 80×60, the paper's tile size (640×480, 64).
const LOSS_W: u32 = 160;
const LOSS_H: u32 = 120;
const LOSS_SETS: u32 = 4;

#[test]
fn quasi_random_loss_is_much_closer_to_the_complete_frame_than_tiles() {
    let mut source = SyntheticSource::new(LOSS_W, LOSS_H);
    let frame = source.frame(0, 1).expect("frame");
    for loss_level in [0.25, 0.5] {
        let out = loss::run(&frame, LOSS_SETS, loss_level, ReconstructParams::default(), 0.0, 42)
            .expect("loss run");
        let ratio = out.tiles.flip / out.quasi_random.flip;
        println!(
            "loss {loss_level}: FLIP quasi-random {:.4} tiles {:.4} (ratio {ratio:.2}); RMSE {:.4} vs {:.4}; SSIM {:.4} vs {:.4}",
            out.quasi_random.flip, out.tiles.flip, out.quasi_random.rmse, out.tiles.rmse, out.quasi_random.ssim, out.tiles.ssim
        );
        assert!(
            ratio > 2.0,
            "tiles should be at least twice as far from the complete frame (ratio {ratio})"
        );
        assert!(out.tiles.rmse > 2.0 * out.quasi_random.rmse);
        assert!(out.quasi_random.ssim > out.tiles.ssim);
    }
}

#[test]
fn spatio_temporal_beats_spatial_only_during_interaction() {
    let mut source = SyntheticSource::new(W, H);
    let points = sequence::interaction(&mut source, 8, SETS, 0.5, ReconstructParams::default())
        .expect("sequence");
    let mean = |f: &dyn Fn(&sequence::InteractionPoint) -> f64| {
        points[1..].iter().map(f).sum::<f64>() / (points.len() - 1) as f64
    };
    let (st, sp) = (mean(&|p| p.spatio_temporal.flip), mean(&|p| p.spatial.flip));
    for p in &points {
        println!(
            "frame {}: spatio-temporal {:.4} spatial {:.4} (vs no-loss {:.4} {:.4}; no-loss itself {:.4})",
            p.frame, p.spatio_temporal.flip, p.spatial.flip, p.spatio_temporal_vs_no_loss.flip, p.spatial_vs_no_loss.flip, p.no_loss.flip
        );
    }
    // The first frame has no history: both are the same there.
    assert_eq!(points[0].spatio_temporal, points[0].spatial);
    assert!(st < 0.9 * sp, "spatio-temporal {st} should be clearly below spatial-only {sp}");
}

#[test]
fn static_view_converges_as_frames_accumulate() {
    let mut source = SyntheticSource::new(W, H);
    let points = sequence::convergence(&mut source, 12, SETS, 0.25, ReconstructParams::default())
        .expect("sequence");
    for p in &points {
        println!("frame {}: FLIP {:.4} RMSE {:.4}", p.frame, p.errors.flip, p.errors.rmse);
    }
    let first = points[1].errors; // the first accumulating frame (frame 1 is filtered)
    let last = points[points.len() - 1].errors;
    assert!(last.flip < 0.7 * first.flip, "FLIP {} → {}", first.flip, last.flip);
    assert!(last.rmse < 0.5 * first.rmse, "RMSE {} → {}", first.rmse, last.rmse);
    for w in points[1..].windows(3) {
        assert!(w[2].errors.rmse < w[0].errors.rmse, "error falls over every two frames");
    }
}
