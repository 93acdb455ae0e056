//! Beyond the paper: the same runs with the master and the simulated grid on separate
//! network hosts (`tools::lan`: namespaces around a bridge, every link limited by a token
//! bucket) at 100 Mbit/s and 1 Gbit/s, beside loopback. The paper's grid had a 100 Mbit/s
//! network, which bounded its master at 55–60 fps with free rendering.
//!
//! Needs root and iproute2; without them the section says why and measures loopback only.

use std::sync::Arc;

use gridlight_actors::master::{Heuristic, Pacing};
use serde_json::json;

use super::context::{Context, Cores, Lan};
use super::grid::{self, Outcome, PathPacing, Run};
use super::plot::{self, Chart, Series};
use super::table1::PAPER_RATES;
use super::{Claim, Section};
use crate::simgrid::{availability::PAPER_PERIOD, Availability, Curve};
use crate::tools::lan::{Testbed, TestbedSpec};

pub fn run(ctx: &mut Context, p: &Lan) -> anyhow::Result<Section> {
    let prepared = ctx
        .prepared("cornell-box", false, Cores::Paper)?
        .ok_or_else(|| anyhow::anyhow!("no Cornell box"))?;
    let unavailable = Testbed::unavailable();
    let mut links: Vec<Option<u32>> = vec![None];
    if unavailable.is_none() {
        links.extend(p.links_mbit.iter().map(|&m| Some(m)));
    }
    let fixed = PAPER_RATES[0].2;
    let mut rows = Vec::new();
    for &link in &links {
        for &n in &p.workers {
            for (mode, pacing) in [
                ("heuristic".to_string(), Pacing::Heuristic(Heuristic::default())),
                (format!("fixed {fixed} fps"), Pacing::FixedFps(fixed)),
            ] {
                let label = link.map_or("loopback".to_string(), |m| format!("{m} Mbit/s"));
                ctx.step(format!("lan: {label}, {n} workers, {mode}"));
                // A testbed per run: its namespaces go when the run ends.
                let network = match link {
                    Some(link_mbit) => {
                        Some(Arc::new(Testbed::build(TestbedSpec { worker_hosts: 1, link_mbit })?))
                    }
                    None => None,
                };
                let out = grid::run(
                    &ctx.exe,
                    &prepared,
                    &Run {
                        availability: Availability {
                            curve: Curve::Constant,
                            n,
                            period: PAPER_PERIOD,
                        },
                        pacing,
                        seconds: p.seconds,
                        path: Vec::new(),
                        path_pacing: PathPacing::Timed,
                        pipeline: gridlight_actors::master::DEFAULT_PIPELINE,
                        network: network.clone(),
                        gold: None,
                    },
                )?;
                rows.push(row(&label, link, n, &mode, &out));
            }
        }
    }
    let series = |mode: &str, key: &str| -> Vec<Series> {
        links
            .iter()
            .map(|link| {
                let label = link.map_or("loopback".to_string(), |m| format!("{m} Mbit/s"));
                let points = rows
                    .iter()
                    .filter(|r| {
                        r["link"] == label
                            && r["mode"].as_str().is_some_and(|m| m.starts_with(mode))
                    })
                    .map(|r| (r["workers"].as_f64().unwrap_or(0.0), r[key].as_f64().unwrap_or(0.0)))
                    .collect();
                Series::new(label, points)
            })
            .collect()
    };
    plot::draw(
        &ctx.out.join("lan.png"),
        &[
            Chart {
                title: "Beyond the paper: frames per second, wait heuristic".into(),
                x_label: "workers".into(),
                y_label: "frames per second".into(),
                series: series("heuristic", "frames_per_second"),
                y_range: None,
            },
            Chart {
                title: format!("Beyond the paper: mean Q_t at a fixed {fixed} fps"),
                x_label: "workers".into(),
                y_label: "mean Q_t".into(),
                series: series("fixed", "mean_q"),
                y_range: Some((0.0, 1.05)),
            },
        ],
    )?;
    let table = rows
        .iter()
        .map(|r| {
            format!(
                "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {} |",
                r["link"].as_str().unwrap_or(""),
                r["workers"],
                r["mode"].as_str().unwrap_or(""),
                r["frames_per_second"].as_f64().unwrap_or(0.0),
                r["mean_q"].as_f64().unwrap_or(0.0),
                r["useful_fraction"].as_f64().unwrap_or(0.0),
                r["master_in_mbit_s"].as_f64().map_or("–".into(), |v| format!("{v:.1}")),
            )
        })
        .collect::<Vec<_>>()
        .join("\n");
    // Each link rate against loopback, same grid and mode: the useful results per second
    // kept (counted over whole frames; a short window's frame count moves by one frame).
    let kept = |mbit: u32| -> Option<f64> {
        let label = format!("{mbit} Mbit/s");
        rows.iter()
            .filter(|r| r["link"] == label)
            .filter_map(|r| {
                let base = rows.iter().find(|b| {
                    b["link"] == "loopback"
                        && b["workers"] == r["workers"]
                        && b["mode"] == r["mode"]
                })?;
                let (a, b) = (r["used_per_second"].as_f64()?, base["used_per_second"].as_f64()?);
                (b > 0.0).then_some(a / b)
            })
            .reduce(f64::min)
    };
    let gigabit = p.links_mbit.iter().copied().max().and_then(kept);
    let note = match &unavailable {
        Some(why) => format!(
            "**Skipped on this machine**: {why}. Only the loopback rows below were measured; \
             run as root with iproute2 (`ip netns`, `tc`) for the links."
        ),
        None => format!(
            "Each link row builds a testbed: the master's host and one worker host, each on a \
             link limited to the rate in both directions by `tc tbf`, joined by a bridge; the \
             grid's process runs in the worker host's namespace and reaches the master over \
             TCP through both links. {} workers per grid size, {:.0} s per run.",
            p.workers.iter().map(u32::to_string).collect::<Vec<_>>().join(" and "),
            p.seconds
        ),
    };
    let w = prepared.state.resolution.width;
    let h = prepared.state.resolution.height;
    Ok(Section {
        id: "lan".into(),
        title: "Beyond the paper: 100 Mbit/s and 1 Gbit/s links".into(),
        paper: "The paper's desktop grid was connected by a 100 Mbit/s network; with the render \
                cost set to zero its master reached 55–60 fps, which it names as the upper bound \
                the network's bandwidth sets. Its measurements were all on that one network."
            .into(),
        ours: format!(
            "{note}\n\n| link | workers | mode | fps | mean Q_t | useful fraction | master's \
             link in (Mbit/s) |\n|---|---|---|---|---|---|---|\n{table}\n\nResults carry the \
             cached {w}×{h} frames' pixels (4 bytes each), a quarter of the bytes of the \
             paper's 640×480 frames whose render time the jobs model: at 640×480 the same \
             frame rate needs four times the master's link rate shown here."
        ),
        comparison: match (&unavailable, gigabit) {
            (Some(_), _) => "Not compared on this machine (no testbed).".into(),
            (None, Some(k)) if k >= 0.9 => format!(
                "At 1 Gbit/s the runs keep at least {:.0} % of their loopback rate of useful results: \
                 rendering, not the network, bounds them, as the paper found on its 100 Mbit/s \
                 network for real render costs. At 100 Mbit/s the master's inbound traffic \
                 (column above) shows how much of the link the grid uses.",
                k * 100.0
            ),
            (None, Some(k)) => format!(
                "At 1 Gbit/s the runs keep only {:.0} % of their loopback rate of useful results in the \
                 worst cell: on this machine the namespaces' links and the extra hops cost more \
                 than loopback.",
                k * 100.0
            ),
            (None, None) => "No link rows were measured.".into(),
        },
        plots: vec!["lan.png".into()],
        images: Vec::new(),
        claims: vec![Claim::new(
            "on separate hosts linked at 1 Gbit/s the runs keep ≥ 90 % of their loopback \
             rate of useful results (measured only with root and iproute2)",
            gigabit.is_some_and(|k| k >= 0.9),
        )],
        data: json!({
            "rows": rows, "links_mbit": p.links_mbit, "skipped": unavailable.map(|e| e.to_string()),
            "workers": p.workers, "seconds": p.seconds,
        }),
        seconds: 0.0,
    })
}

/// One run's numbers.
fn row(label: &str, link: Option<u32>, n: u32, mode: &str, out: &Outcome) -> serde_json::Value {
    let mbit = |bytes: Option<u64>| bytes.map(|b| b as f64 * 8.0 / 1e6 / out.seconds.max(1e-9));
    json!({
        "link": label, "link_mbit": link, "workers": n, "mode": mode,
        "frames_per_second": out.frames_per_second, "mean_q": out.mean_q,
        "useful_fraction": out.useful_fraction, "used_per_second": out.used_per_second(),
        "master_in_mbit_s": mbit(out.link_rx_bytes), "master_out_mbit_s": mbit(out.link_tx_bytes),
        "seconds": out.seconds,
    })
}
