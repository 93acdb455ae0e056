//! Figure 5: an interactive session at a fixed frame rate on a grid whose resources
//! follow `R_i = N − (N/4)·sin(2πi/period)`; Q_t per frame beside R_i.

use gridlight_actors::master::Pacing;
use serde_json::json;

use super::context::{Context, Cores, Fig5};
use super::grid::{run_session, FrameRecord, PathPacing, Session};
use super::plot::{self, Chart, Series};
use super::stats::correlation;
use super::{Claim, Section};
use crate::simgrid::Availability;

/// Frames of the moving average of Q_t.
const SMOOTH: usize = 5;

/// Centred moving average of `points`' y over `n` frames (fewer at the ends).
fn moving_average(points: &[(f64, f64)], n: usize) -> Vec<(f64, f64)> {
    let half = n / 2;
    (0..points.len())
        .map(|i| {
            let window = &points[i.saturating_sub(half)..(i + half + 1).min(points.len())];
            (points[i].0, window.iter().map(|p| p.1).sum::<f64>() / window.len() as f64)
        })
        .collect()
}

/// Seconds the session runs past the camera path's last edit.
const HOLD_SECONDS: f64 = 1.0;

pub fn run(ctx: &mut Context, p: &Fig5) -> anyhow::Result<Section> {
    ctx.step("fig5: preparing the camera path");
    let prepared = ctx
        .prepared("cornell-box", true, Cores::Paper)?
        .ok_or_else(|| anyhow::anyhow!("no Cornell box"))?;
    let path = ctx.path()?;
    // The view holds until the path's first edit, then one edit per shown frame.
    let fps = f64::from(p.fps);
    let seconds = path.first().map_or(0.0, |(at, _)| at.as_secs_f64())
        + path.len() as f64 / fps
        + HOLD_SECONDS;
    let availability = Availability { curve: p.curve, n: p.workers, period: p.period };
    ctx.step(format!("fig5: {seconds:.0} s session, {} workers varying", p.workers));
    let session = Session {
        availability,
        pacing: Pacing::FixedFps(p.fps),
        seconds,
        path: path.clone(),
        path_pacing: PathPacing::PerFrame,
        pipeline: gridlight_actors::master::DEFAULT_PIPELINE,
        network: None,
        gold: None,
    };
    let out = run_session(&ctx.exe, &prepared, &session)?;
    // Like with like: the frames of the newest view, each given its fixed period. A frame
    // an edit outdated is shown at once with what it has (the display never waits for an
    // older view), so its Q_t measures the edit's timing, not the resources.
    let current: Vec<&FrameRecord> = out.frames.iter().filter(|f| f.current).collect();
    let outdated = out.frames.len() - current.len();
    // Shown frame i of the measured sequence; the master's resources are the live
    // workers it counted when it showed the frame (R_i as the grid delivered it).
    let q: Vec<(f64, f64)> = current.iter().enumerate().map(|(i, f)| (i as f64, f.q)).collect();
    let live: Vec<(f64, f64)> =
        current.iter().enumerate().map(|(i, f)| (i as f64, f.workers as f64)).collect();
    let pairs: Vec<(f64, f64)> = q.iter().zip(&live).map(|(a, b)| (a.1, b.1)).collect();
    let rho_raw = correlation(&pairs);
    // A moving average over SMOOTH frames shows the trend under the per-frame noise of
    // the modelled job times.
    let q_smooth = moving_average(&q, SMOOTH);
    let smooth_pairs: Vec<(f64, f64)> =
        q_smooth.iter().zip(&live).map(|(a, b)| (a.1, b.1)).collect();
    let rho = correlation(&smooth_pairs);
    // Still (before the first edit) and moving (from it on) apart.
    let first_version = current.first().map_or(0, |f| f.version);
    let still = current.iter().take_while(|f| f.version == first_version).count();
    let rho_still = correlation(&smooth_pairs[..still]);
    let rho_moving = correlation(&smooth_pairs[still..]);
    let rho_moving_raw = correlation(&pairs[still..]);
    let mean_q_still = super::grid::mean(current[..still].iter().map(|f| f.q));
    let mean_q_moving = super::grid::mean(current[still..].iter().map(|f| f.q));
    // The curve itself at each frame's time (the grid follows it by its own clock, which
    // started a fraction of a second earlier).
    let r: Vec<(f64, f64)> = current
        .iter()
        .enumerate()
        .map(|(i, f)| (i as f64, f64::from(availability.at((f.t * fps) as u64))))
        .collect();
    plot::draw(
        &ctx.out.join("fig5.png"),
        &[
            Chart {
                title: format!("Figure 5: Q_t at a fixed {} fps while resources vary (Cornell box, camera path)", p.fps),
                x_label: "shown frame".into(),
                y_label: "Q_t (jobs back / jobs)".into(),
                series: vec![
                    Series::new("Q_t", q.clone()),
                    Series::new(format!("Q_t, mean of {SMOOTH} frames"), q_smooth.clone()),
                ],
                y_range: Some((0.0, 1.05)),
            },
            Chart {
                title: format!("R_i = {0} − ({0}/4)·sin(2πi/{1})", p.workers, p.period),
                x_label: "shown frame".into(),
                y_label: "workers".into(),
                series: vec![
                    Series::new("R_i (the curve, by time)", r),
                    Series::new("live workers when the frame was shown", live),
                ],
                y_range: None,
            },
        ],
    )?;
    let rho_text = rho.map_or("undefined (Q_t constant)".to_string(), |v| format!("{v:.2}"));
    let mean_q = out.mean_q;
    Ok(Section {
        id: "fig5".into(),
        title: "Figure 5: quality at a fixed frame rate with varying resources".into(),
        paper: "Figure 5 plots VDP (probability of detection > 75 %) per frame of interactive \
                sequences at the fixed rates of Table 1, with 32, 64 and 96 resources and with \
                variable resources R_i = 96 − 24·sin(2πi/100); fewer resources give fewer results \
                per frame and more reconstruction, so the error rises, and the variable series \
                moves with R_i. No correlation is given; the curves track each other."
            .into(),
        ours: format!(
            "The Cornell box with the recorded camera path `{}` ({} edits, at most one per \
             frame period of the fixed rate), fixed {} fps, {} simulated workers varying as R_i \
             (curve {:?}, period {} frames; {} connections open, those above R_i paused by the \
             clock at the fixed rate). As in the paper's sequences the camera moves once per \
             frame: the view holds still for {:.0} s, then the next edit is made as soon as a \
             frame of the newest view is shown, so each view has one whole frame period on the \
             grid (at a fixed rate the display waits its period for the new view's frames too, \
             paper §4.3). Every edit still discards the older view's queued jobs, and a frame \
             the edit outdated is shown at once with what it has: {outdated} such frames are \
             left out of Q_t below (compared like with like: each frame of the view the user \
             sees, against the resources of its period). {} frames of the current view shown, \
             mean Q_t {mean_q_still:.2} still and {mean_q_moving:.2} moving, useful fraction \
             {:.2}. Correlation of Q_t with the live workers the master counted: {} frame by \
             frame, **{rho_text}** for Q_t averaged over {SMOOTH} frames; while the view is \
             still (the first {still} frames) **{}**, while the camera moves **{}** ({} frame \
             by frame).",
            p.path.display(),
            path.len(),
            p.fps,
            p.workers,
            p.curve,
            p.period,
            availability.peak(),
            path.first().map_or(0.0, |(at, _)| at.as_secs_f64()),
            current.len(),
            out.useful_fraction,
            rho_raw.map_or("undefined".to_string(), |v| format!("{v:.2}")),
            rho_still.map_or("undefined".to_string(), |v| format!("{v:.2}")),
            rho_moving.map_or("undefined".to_string(), |v| format!("{v:.2}")),
            rho_moving_raw.map_or("undefined".to_string(), |v| format!("{v:.2}")),
        ),
        comparison: format!(
            "{} Q_t while moving is lower than still: after each edit the workers first finish \
             the job they are rendering (of the older view) before the new view's jobs reach \
             them. We plot Q_t (the quantity the fixed rate trades away) rather than VDP \
             against a 96-worker gold sequence. The fixed rate is chosen so that the grid \
             cannot finish a frame in time (else Q_t would be 1 throughout): the paper's cores \
             were slower than ours, see the note on modelled cores.",
            match (rho_still, rho_moving) {
                (Some(a), Some(b)) if a > 0.5 && b > 0.5 => "Agrees: Q_t follows the resources, still and moving.",
                (Some(a), _) if a > 0.5 => "Agrees while the view is still: Q_t follows the resources; while the camera moves it follows them less closely in this run.",
                _ => "Differs: Q_t does not follow the resources in this run.",
            }
        ),
        plots: vec!["fig5.png".into()],
        images: Vec::new(),
        claims: vec![
            Claim::new(
                format!("while the view is still, Q_t ({SMOOTH}-frame mean) follows the resources (r > 0.5)"),
                rho_still.is_some_and(|v| v > 0.5),
            ),
            Claim::new(
                format!("while the camera moves, Q_t ({SMOOTH}-frame mean) follows the resources (r > 0.5)"),
                rho_moving.is_some_and(|v| v > 0.5),
            ),
        ],
        data: json!({
            "workers": p.workers, "fps": p.fps, "curve": p.curve, "period": p.period,
            "correlation_q_r": rho, "correlation_q_r_raw": rho_raw, "smooth_frames": SMOOTH,
            "correlation_still": rho_still, "correlation_moving": rho_moving, "still_frames": still,
            "mean_q": mean_q, "mean_q_still": mean_q_still, "mean_q_moving": mean_q_moving,
            "correlation_moving_raw": rho_moving_raw, "outdated_frames": outdated,
            "useful_fraction": out.useful_fraction, "frames": out.frames,
            "path_edits": path.len(), "seconds": seconds,
        }),
        seconds: 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_moving_average_is_centred_and_shrinks_at_the_ends() {
        let p: Vec<(f64, f64)> =
            [0.0, 1.0, 0.0, 1.0, 0.0].iter().enumerate().map(|(i, &y)| (i as f64, y)).collect();
        let m: Vec<f64> = moving_average(&p, 3).iter().map(|p| p.1).collect();
        assert_eq!(m, [0.5, 1.0 / 3.0, 2.0 / 3.0, 1.0 / 3.0, 0.5]);
    }
}
