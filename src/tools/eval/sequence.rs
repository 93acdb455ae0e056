//! Figures 8 and 9: reconstruction over sequences of frames.
//!
//! - [`interaction`]: the camera moves every frame (a new scene state each time) and a
//!   fraction of the jobs is lost; spatio-temporal reconstruction is compared with
//!   spatial-only (history 0). The paper measures against the no-loss frames, which are
//!   themselves noisy (4 spp); a filter that removes noise is then penalised for the
//!   noise it did not copy, so we also measure against the converged image of each
//!   view (the frames with no missing pixels and no noise) and test on that.
//! - [`convergence`]: a static view; frames accumulate and the error against a converged
//!   image falls.

use serde::Serialize;

use super::loss::{dropped_sets, mask_without};
use super::{compare, Errors, FrameSource};
use crate::reconstruct::{CpuReconstructor, FrameInputs, ReconstructParams};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::Resolution;

/// Errors of one frame of an interaction sequence, against the converged image of the
/// frame's view (`gold`) and against the same frame with no loss and no reconstruction
/// (`no_loss`, noisy itself: the paper's choice).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct InteractionPoint {
    pub frame: u64,
    pub spatio_temporal: Errors,
    pub spatial: Errors,
    pub spatio_temporal_vs_no_loss: Errors,
    pub spatial_vs_no_loss: Errors,
    /// The no-loss frame itself against the gold standard: the path-tracing noise.
    pub no_loss: Errors,
}

/// Errors of one frame of a static view.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ConvergencePoint {
    pub frame: u64,
    pub errors: Errors,
}

fn table(source: &dyn FrameSource, sets: u32) -> anyhow::Result<SetTable> {
    let res = Resolution { width: source.width(), height: source.height() };
    Ok(SetTable::new(res, SetsConfig { sets, partition: Partition::QuasiRandom })?)
}

/// `frames` frames, view k at frame k + 1, each losing `loss` of its quasi-random sets.
pub fn interaction(
    source: &mut dyn FrameSource,
    frames: usize,
    sets: u32,
    loss: f64,
    params: ReconstructParams,
) -> anyhow::Result<Vec<InteractionPoint>> {
    let (w, h) = (source.width(), source.height());
    let table = table(source, sets)?;
    let mut full = CpuReconstructor::new(w, h, params)?;
    let mut spatial = CpuReconstructor::new(w, h, ReconstructParams { history: 0, ..params })?;
    let mut points = Vec::with_capacity(frames);
    for view in 0..frames {
        let frame = view as u64 + 1;
        let data = source.frame(view, frame)?;
        let mask = mask_without(&table, &dropped_sets(sets, loss, frame));
        let inputs = FrameInputs {
            frame,
            state_version: frame,
            accumulated_frames: 1,
            radiance: &data.radiance,
            mask: &mask,
            gbuffer: &data.gbuffer,
            scene: None,
        };
        let no_loss = data.colour();
        let gold = source.gold(view)?;
        let a = full.reconstruct(&inputs)?;
        let b = spatial.reconstruct(&inputs)?;
        let e = source.exposure();
        points.push(InteractionPoint {
            frame,
            spatio_temporal: compare(&gold, &a.colour, w, h, e),
            spatial: compare(&gold, &b.colour, w, h, e),
            spatio_temporal_vs_no_loss: compare(&no_loss, &a.colour, w, h, e),
            spatial_vs_no_loss: compare(&no_loss, &b.colour, w, h, e),
            no_loss: compare(&gold, &no_loss, w, h, e),
        });
    }
    Ok(points)
}

/// `frames` frames of view 0 with one scene state, each losing `loss` of its sets,
/// measured against the source's converged image.
pub fn convergence(
    source: &mut dyn FrameSource,
    frames: usize,
    sets: u32,
    loss: f64,
    params: ReconstructParams,
) -> anyhow::Result<Vec<ConvergencePoint>> {
    let (w, h) = (source.width(), source.height());
    let table = table(source, sets)?;
    let gold = source.gold(0)?;
    let mut r = CpuReconstructor::new(w, h, params)?;
    let mut points = Vec::with_capacity(frames);
    for k in 0..frames {
        let frame = k as u64 + 1;
        let data = source.frame(0, frame)?;
        let mask = mask_without(&table, &dropped_sets(sets, loss, frame));
        let out = r.reconstruct(&FrameInputs {
            frame,
            state_version: 1,
            accumulated_frames: k as u32 + 1,
            radiance: &data.radiance,
            mask: &mask,
            gbuffer: &data.gbuffer,
            scene: None,
        })?;
        points.push(ConvergencePoint {
            frame,
            errors: compare(&gold, &out.colour, w, h, source.exposure()),
        });
    }
    Ok(points)
}
