//! Figures 3 and 9: reconstruction of complete path-traced frames, no grid involved
//! (`eval::loss`, `eval::sequence`), moved into the report with their images.

use std::sync::Arc;

use serde_json::json;

use super::context::{Context, Fig3, Fig9};
use super::plot::{self, Chart, Series};
use super::{Claim, Section};
use crate::image_io;
use crate::reconstruct::ReconstructParams;
use crate::tools::eval::{loss, sequence, FrameSource, RenderSource};

/// Samples per pixel of the converged image the sequences are measured against.
const GOLD_SPP: u32 = 64;

fn source(ctx: &Context) -> anyhow::Result<RenderSource> {
    let (assets, state) =
        ctx.scene("cornell-box")?.ok_or_else(|| anyhow::anyhow!("no Cornell box"))?;
    RenderSource::new(Arc::clone(&assets), state, GOLD_SPP)
}

/// Figure 3: quasi-random sets against tiles, 25/50/75 % of the jobs lost.
pub fn fig3(ctx: &mut Context, p: &Fig3) -> anyhow::Result<Section> {
    ctx.step("fig3: quasi-random sets vs tiles");
    let mut src = source(ctx)?;
    let (w, h, e) = (src.width(), src.height(), src.exposure());
    let frame = src.frame(0, 1)?;
    let mut rows = Vec::new();
    let mut images = Vec::new();
    let params = ReconstructParams::default();
    image_io::write_png(&ctx.out.join("fig3-complete.png"), w, h, &frame.colour(), e)?;
    images.push(("complete frame (every job back)".to_string(), "fig3-complete.png".to_string()));
    for &l in &p.losses {
        let out = loss::run(&frame, ctx.opts.sets, l, params, e, 1)?;
        let pct = (l * 100.0).round() as u32;
        for (kind, holes, rec) in [
            ("quasi-random", &out.images.quasi_random_holes, &out.images.quasi_random),
            ("tiles", &out.images.tiles_holes, &out.images.tiles),
        ] {
            let partial = format!("fig3-loss{pct}-{kind}-partial.png");
            let reconstructed = format!("fig3-loss{pct}-{kind}.png");
            image_io::write_png(&ctx.out.join(&partial), w, h, holes, e)?;
            image_io::write_png(&ctx.out.join(&reconstructed), w, h, rec, e)?;
            images.push((format!("{pct} % lost, {kind}: partial"), partial));
            images.push((format!("{pct} % lost, {kind}: reconstructed"), reconstructed));
        }
        rows.push(json!({ "loss": l, "quasi_random": out.quasi_random, "tiles": out.tiles }));
    }
    let series = |key: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .map(|r| {
                (r["loss"].as_f64().unwrap_or(0.0) * 100.0, r[key]["flip"].as_f64().unwrap_or(0.0))
            })
            .collect()
    };
    plot::draw(
        &ctx.out.join("fig3.png"),
        &[Chart {
            title: "Figure 3: reconstruction error when jobs are lost (Cornell box)".into(),
            x_label: "jobs lost (%)".into(),
            y_label: "mean FLIP to the complete frame".into(),
            series: vec![
                Series::new("quasi-random sets", series("quasi_random")),
                Series::new("tiles", series("tiles")),
            ],
            y_range: None,
        }],
    )?;
    let wins = rows
        .iter()
        .filter(|r| r["tiles"]["flip"].as_f64() > r["quasi_random"]["flip"].as_f64())
        .count();
    let table = rows
        .iter()
        .map(|r| {
            format!(
                "| {:.0} % | {:.4} | {:.4} |",
                r["loss"].as_f64().unwrap_or(0.0) * 100.0,
                r["quasi_random"]["flip"].as_f64().unwrap_or(0.0),
                r["tiles"]["flip"].as_f64().unwrap_or(0.0)
            )
        })
        .collect::<Vec<_>>()
        .join("\n");
    Ok(Section {
        id: "fig3".into(),
        title: "Figure 3: quasi-random pixel sets against tiles".into(),
        paper: "Figure 3 shows a frame with 25 % and 50 % of its jobs lost, as tiles and as \
                quasi-random sets, and their reconstructions: tiles leave whole blocks that \
                reconstruction cannot fill, quasi-random sets leave scattered holes that it fills \
                almost invisibly. The paper gives images, no numbers."
            .into(),
        ours: format!(
            "One path-traced Cornell-box frame ({w}×{h}, {} sets, 4 spp) loses the same number of \
             jobs under each partition; each is reconstructed (fill, Gaussian; no history) and \
             compared with the complete frame reconstructed the same way.\n\n\
             | jobs lost | FLIP quasi-random | FLIP tiles |\n|---|---|---|\n{table}",
            ctx.opts.sets
        ),
        comparison: format!(
            "Agrees: tiles are worse at {wins} of {} loss levels, and the images show the \
             paper's blocks. The paper's figure has no numbers to compare; 75 % is beyond it.",
            rows.len()
        ),
        plots: vec!["fig3.png".into()],
        images,
        claims: vec![Claim::new(
            "tiles give a larger error than quasi-random sets at every loss level",
            wins == rows.len(),
        )],
        data: json!({ "width": w, "height": h, "sets": ctx.opts.sets, "rows": rows }),
        seconds: 0.0,
    })
}

/// Figure 9: an interaction sequence, spatio-temporal against spatial-only.
pub fn fig9(ctx: &mut Context, p: &Fig9) -> anyhow::Result<Section> {
    ctx.step("fig9: spatio-temporal vs spatial-only");
    let mut src = source(ctx)?;
    let points = sequence::interaction(
        &mut src,
        p.frames,
        ctx.opts.sets,
        p.loss,
        ReconstructParams::default(),
    )?;
    let pick = |f: &dyn Fn(&sequence::InteractionPoint) -> f64| -> Vec<(f64, f64)> {
        points.iter().map(|pt| (pt.frame as f64, f(pt))).collect()
    };
    let st = pick(&|pt| pt.spatio_temporal_vs_no_loss.flip);
    let sp = pick(&|pt| pt.spatial_vs_no_loss.flip);
    let noise = pick(&|pt| pt.no_loss.flip);
    let st_gold = pick(&|pt| pt.spatio_temporal.flip);
    let sp_gold = pick(&|pt| pt.spatial.flip);
    plot::draw(
        &ctx.out.join("fig9.png"),
        &[
            Chart {
                title: format!(
                    "Figure 9: reconstruction during interaction ({:.0} % of jobs lost)",
                    p.loss * 100.0
                ),
                x_label: "frame".into(),
                y_label: "mean FLIP to the complete frame".into(),
                series: vec![
                    Series::new("spatio-temporal", st.clone()),
                    Series::new("spatial only", sp.clone()),
                ],
                y_range: None,
            },
            Chart {
                title: format!("against the converged image ({GOLD_SPP} spp)"),
                x_label: "frame".into(),
                y_label: "mean FLIP to the converged image".into(),
                series: vec![
                    Series::new("spatio-temporal", st_gold.clone()),
                    Series::new("spatial only", sp_gold.clone()),
                    Series::new(
                        "complete frame, no reconstruction (path-tracing noise)",
                        noise.clone(),
                    ),
                ],
                y_range: None,
            },
        ],
    )?;
    let m = |v: &[(f64, f64)]| super::grid::mean(v.iter().map(|p| p.1));
    let (mst, msp, mno) = (m(&st), m(&sp), m(&noise));
    let (gst, gsp) = (m(&st_gold), m(&sp_gold));
    Ok(Section {
        id: "fig9".into(),
        title: "Figure 9: spatio-temporal against spatial-only reconstruction".into(),
        paper: "Figure 9 plots VDP per frame over 200 frames of interactive sequences: \
                spatial-only reconstruction is close to spatio-temporal while the image \
                accumulates, and considerably worse while the user interacts; spatio-temporal \
                closely follows the 'no reconstruction' series (path-tracing noise)."
            .into(),
        ours: format!(
            "{} frames of the Cornell box with the camera turning every frame, {:.0} % of each \
             frame's jobs lost, reconstructed both ways and compared with the complete frame. \
             Mean FLIP to the complete frame (the paper's reference): spatio-temporal {mst:.4}, \
             spatial only {msp:.4}. Mean FLIP to the {GOLD_SPP}-spp converged image: \
             spatio-temporal {gst:.4}, spatial only {gsp:.4}, the complete frame itself {mno:.4} \
             (its path-tracing noise).",
            p.frames,
            p.loss * 100.0
        ),
        comparison: format!(
            "{} {} Our sequence is only the interaction part (the camera moves every frame), \
             short, and measured with FLIP instead of VDP.",
            if gst <= gsp {
                "Agrees against the converged image: the temporal pass lowers the error while the view moves, and below the complete frame's own noise."
            } else {
                "Differs: the temporal pass does not lower the error against the converged image in this run."
            },
            if mst <= msp {
                "Against the complete frame it lowers the error too."
            } else {
                "Against the complete frame (the paper's reference) spatial-only is closer: the complete frame carries this frame's 4-spp noise, which the temporal pass averages away with the history, so the 'error' it measures is partly noise removed."
            }
        ),
        plots: vec!["fig9.png".into()],
        images: Vec::new(),
        claims: vec![Claim::new(
            "spatio-temporal error to the converged image ≤ spatial-only error, on average",
            gst <= gsp,
        )],
        data: json!({ "loss": p.loss, "points": points }),
        seconds: 0.0,
    })
}
