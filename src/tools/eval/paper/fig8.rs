//! Figure 8: a static view converging on grids of 8, 32 and 96 workers and on variable
//! resources: FLIP to the gold standard against wall time, and the time until the error
//! falls below the threshold where the images look the same.

use std::sync::Arc;

use gridlight_actors::master::{Heuristic, Pacing};
use serde_json::json;

use super::context::{Context, Cores, Fig8};
use super::gold;
use super::grid::{self, PathPacing, Run};
use super::plot::{self, Chart, Series};
use super::{Claim, Section};
use crate::simgrid::{availability::PAPER_PERIOD, Availability, Curve};

pub fn run(ctx: &mut Context, p: &Fig8) -> anyhow::Result<Section> {
    let prepared = ctx
        .prepared("cornell-box", false, Cores::Paper)?
        .ok_or_else(|| anyhow::anyhow!("no Cornell box"))?;
    ctx.step(format!("fig8: the gold standard ({} frames, cached once)", p.gold_frames));
    let gold_made = gold::gold_standard(&prepared, p.gold_frames, &gold::cache_dir())?;
    let gold = Arc::new(gold_made.linear());
    let (w, h) = (prepared.state.resolution.width, prepared.state.resolution.height);
    crate::image_io::write_png(&ctx.out.join("fig8-gold.png"), w, h, &gold, 0.0)?;
    let grids = p
        .workers
        .iter()
        .map(|&n| {
            (
                format!("{n} workers"),
                Availability { curve: Curve::Constant, n, period: PAPER_PERIOD },
            )
        })
        .chain(std::iter::once((
            format!("variable {}", p.variable),
            Availability { curve: Curve::Sine, n: p.variable, period: PAPER_PERIOD },
        )))
        .collect::<Vec<_>>();
    let mut series = Vec::new();
    let mut hdr_series = Vec::new();
    let mut rows = Vec::new();
    for (label, availability) in grids {
        ctx.step(format!("fig8: converging with {label}"));
        let out = grid::run(
            &ctx.exe,
            &prepared,
            &Run {
                availability,
                pacing: Pacing::Heuristic(Heuristic::default()),
                seconds: p.seconds,
                path: Vec::new(),
                path_pacing: PathPacing::Timed,
                pipeline: gridlight_actors::master::DEFAULT_PIPELINE,
                network: None,
                gold: Some(Arc::clone(&gold)),
            },
        )?;
        // From the moment the grid had connected (the view restarted then): the warm-up
        // is part of converging.
        let points: Vec<(f64, f64)> = out
            .all_frames
            .iter()
            .filter(|f| f.current)
            .filter_map(|f| f.flip.map(|e| (f.t, e)))
            .collect();
        let below = points.iter().find(|(_, e)| *e < p.threshold).map(|(t, _)| *t);
        let hdr: Vec<(f64, f64)> = out
            .all_frames
            .iter()
            .filter(|f| f.current)
            .filter_map(|f| f.hdr_flip.map(|e| (f.t, e)))
            .collect();
        rows.push(json!({
            "grid": label, "time_to_threshold_s": below, "final_flip": points.last().map(|p| p.1),
            "frames": points.len(), "useful_fraction": out.useful_fraction, "points": points,
            "final_hdr_flip": hdr.last().map(|p| p.1), "hdr_points": hdr,
        }));
        hdr_series.push(Series::new(label.clone(), hdr));
        series.push(Series::new(label, points));
    }
    plot::draw(
        &ctx.out.join("fig8.png"),
        &[
            Chart {
                title: format!("Figure 8: a static view converging (threshold {})", p.threshold),
                x_label: "wall time since the grid connected (s)".into(),
                y_label: "mean FLIP to the gold standard".into(),
                series,
                y_range: None,
            },
            Chart {
                title: "the same in HDR-FLIP (linear radiance, exposures bracketed)".into(),
                x_label: "wall time since the grid connected (s)".into(),
                y_label: "mean HDR-FLIP to the gold standard".into(),
                series: hdr_series,
                y_range: None,
            },
        ],
    )?;
    let table = rows
        .iter()
        .map(|r| {
            format!(
                "| {} | {} | {:.4} | {:.4} | {:.2} |",
                r["grid"].as_str().unwrap_or(""),
                r["time_to_threshold_s"]
                    .as_f64()
                    .map_or("not within the run".into(), |t| format!("{t:.2} s")),
                r["final_flip"].as_f64().unwrap_or(f64::NAN),
                r["final_hdr_flip"].as_f64().unwrap_or(f64::NAN),
                r["useful_fraction"].as_f64().unwrap_or(0.0),
            )
        })
        .collect::<Vec<_>>()
        .join("\n");
    let times: Vec<Option<f64>> =
        rows.iter().take(p.workers.len()).map(|r| r["time_to_threshold_s"].as_f64()).collect();
    let faster_with_more = times.windows(2).all(|t| match (t[0], t[1]) {
        (Some(a), Some(b)) => b <= a,
        (None, _) => true,
        (Some(_), None) => false,
    });
    Ok(Section {
        id: "fig8".into(),
        title: "Figure 8: a static view converging".into(),
        paper: "Figure 8 plots VDP against time for a static view on different resources, against \
                the image converged over 200 frames; even in the best case (96 resources) it takes \
                about a second for VDP to fall below 3 %, where the images are taken to be the same."
            .into(),
        ours: format!(
            "The Cornell box's view held still; the master accumulates results (progressive \
             refinement). Every shown frame is kept and, after the run, reconstructed in \
             order as the display would show it and compared with the gold standard (so that \
             reconstruction on this machine's CPU neither paces the display nor takes the cores \
             the simulated grid runs on; the paper's master reconstructed on its GPU). The gold \
             standard: {} frames rendered independently of the workers' cached frames (their \
             own sample seeds; {} spp in all), accumulated by the same reconstruction; {}. The \
             workers cycle through {} cached frames, so a run can converge no further than \
             their mean. Threshold: mean FLIP {} (FLIP's mean error, not VDP's share of \
             pixels). The paper's images are HDR: the second plot measures the linear (unbounded) \
             images with HDR-FLIP (our implementation, checked against NVIDIA's), for {} frames \
             of each run.\n\n| grid | time to threshold | final FLIP | final HDR-FLIP | useful \
             fraction |\n|---|---|---|---|---|\n{table}",
            p.gold_frames,
            p.gold_frames * prepared.state.render.spp,
            if gold_made.cached {
                format!(
                    "loaded from `{}` (rendering and composing it took {:.0} s when it was made)",
                    gold_made.file.display(),
                    gold_made.seconds
                )
            } else {
                format!(
                    "rendered and composed in {:.0} s on this machine, once: it is cached in `{}` \
                     for later runs",
                    gold_made.seconds,
                    gold_made.file.display()
                )
            },
            ctx.opts.cached_frames,
            p.threshold,
            super::grid::HDR_POINTS,
        ),
        comparison: format!(
            "{} The metric differs (FLIP, not VDP), so only the shape and the ordering compare: \
             more workers converge sooner.",
            if faster_with_more {
                "Agrees: the error falls sooner with more workers."
            } else {
                "Differs in part: the times do not fall monotonically with the workers in this run."
            }
        ),
        plots: vec!["fig8.png".into()],
        images: vec![("gold standard".into(), "fig8-gold.png".into())],
        claims: vec![Claim::new("more workers reach the threshold no later", faster_with_more)],
        data: json!({
            "threshold": p.threshold, "gold_frames": p.gold_frames, "rows": rows,
            "gold_seconds": gold_made.seconds, "gold_cached": gold_made.cached,
        }),
        seconds: 0.0,
    })
}
