//! Writes the report: `report.md`, `index.html` (the same text as HTML) and
//! `results.json` (every number), beside the plots and images the experiments wrote.

use std::fmt::Write as _;

use anyhow::Context as _;
use serde_json::json;

use super::context::{Context, PAPER_CORE_SAMPLES_PER_SECOND};
use super::stats::two_places;
use super::Section;

/// Writes the three files for `sections` into the context's output directory.
pub fn write(ctx: &Context, sections: &[Section]) -> anyhow::Result<()> {
    let md = markdown(ctx, sections);
    let out = &ctx.out;
    std::fs::write(out.join("report.md"), &md).context("writing report.md")?;
    std::fs::write(out.join("index.html"), html(&md)).context("writing index.html")?;
    let results = json!({
        "options": ctx.opts,
        "timing": ctx.timing,
        "paper_core_samples_per_second": PAPER_CORE_SAMPLES_PER_SECOND,
        "scenes": ctx.prepared.iter().map(|(k, p)| (k.clone(), json!({
            "cost": p.cost, "job_ms": p.job_time().as_secs_f64() * 1e3, "sets": p.sets,
        }))).collect::<serde_json::Map<_, _>>(),
        "sections": sections,
    });
    std::fs::write(out.join("results.json"), serde_json::to_string_pretty(&results)?)
        .context("writing results.json")
}

/// The report as Markdown.
pub fn markdown(ctx: &Context, sections: &[Section]) -> String {
    let mut s = String::new();
    let o = &ctx.opts;
    let _ = writeln!(s, "# gridlight: the paper's evaluation, reproduced\n");
    let _ = writeln!(
        s,
        "Aggarwal et al., *High-fidelity Interactive Rendering on Desktop Grids*, section 6, beside \
         our measurements. Run: `gridlight eval paper{}` ({} run).\n",
        if o.quick { " --quick" } else { "" },
        if o.quick { "quick, reduced" } else { "full" }
    );
    let _ = writeln!(s, "## What is real and what is modelled\n");
    let _ = writeln!(
        s,
        "- **Real**: the master (scheduler, wait heuristic, frame assembly, reconstruction), \
         every worker's protocol link and TCP connection (on loopback, and across \
         rate-limited links between network namespaces in the last section), and every pixel: \
         path-traced with the real renderer before the runs ({}×{}, 4 spp per frame, a \
         different sample seed per cached frame; {} frames per static view, one per state of \
         the camera path).\n\
         - **Modelled**: each job's render time and which workers are available. Simulated \
         workers run as tokio tasks in a few `gridlight simgrid` processes; a job takes \
         `pixels × spp ÷ throughput`, scaled by a normal factor of the measured spread.\n\
         - **The modelled cores** are the paper's: {:.0} samples per second each on the Cornell \
         box (640·480·4·6.66/96: Table 1's rate on 96 cores), other scenes in proportion to their \
         cost measured here. Jobs are timed as the paper's 640×480 jobs ({} sets per frame, so \
         that jobs per frame far exceed the workers, the paper's rule) while their pixels come \
         from the smaller cached frames. Figure 10 also uses this machine's \
         own cores.\n\
         - **This machine**: 2 cores shared with other work; the master and all simulated \
         workers share them, so results at large grids include that contention.\n",
        o.width, o.height, o.cached_frames, PAPER_CORE_SAMPLES_PER_SECOND, o.grid_sets
    );
    if let Some(t) = ctx.timing {
        let _ = writeln!(
            s,
            "Measured here: the Cornell box renders {:.0} samples per second per core \
             (so the paper's cores are modelled as {:.1}× slower).\n",
            t.reference_samples_per_second.unwrap_or(0.0),
            t.reference_samples_per_second.unwrap_or(0.0) / PAPER_CORE_SAMPLES_PER_SECOND
        );
    }
    for sec in sections {
        let _ = writeln!(s, "## {}\n", sec.title);
        let _ = writeln!(s, "### The paper\n\n{}\n", sec.paper);
        let _ = writeln!(s, "### Ours\n\n{}\n", sec.ours);
        for p in &sec.plots {
            let _ = writeln!(s, "![{}]({p})\n", sec.title);
        }
        if !sec.images.is_empty() {
            let _ = writeln!(s, "| image | |\n|---|---|");
            for (caption, file) in &sec.images {
                let _ = writeln!(s, "| {caption} | ![{caption}]({file}) |");
            }
            let _ = writeln!(s);
        }
        let _ = writeln!(s, "### Agreement\n\n{}\n", sec.comparison);
        for c in &sec.claims {
            let _ = writeln!(
                s,
                "- {} {}",
                if c.holds { "✔ holds:" } else { "✘ does not hold:" },
                c.text
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Closing note\n\n{}", closing(sections));
    s
}

/// The figures the issue asks to close on: Figure 10's efficiencies, Figure 5's
/// correlation, Table 1's numbers.
fn closing(sections: &[Section]) -> String {
    let mut s = String::new();
    for sec in sections {
        match sec.id.as_str() {
            "fig10" => {
                let effs: Vec<String> = sec.data["rows"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|r| {
                        format!(
                            "{} {}: {:.2}",
                            r["cores"].as_str().unwrap_or(""),
                            r["workers"],
                            r["efficiency"].as_f64().unwrap_or(0.0)
                        )
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    "- Figure 10 efficiencies (cores, workers: efficiency): {}.",
                    effs.join("; ")
                );
            }
            "fig5" => {
                let _ = writeln!(
                    s,
                    "- Figure 5: correlation of Q_t ({}-frame mean) with the resources in the \
                     paper's sequence {} over the whole run, {} while still, {} while moving \
                     (mean Q_t {:.2}); gridlight's interactive default (latency first) {} while \
                     moving (mean Q_t {:.2} moving).",
                    sec.data["smooth_frames"],
                    two_places(sec.data["correlation_q_r"].as_f64()),
                    two_places(sec.data["correlation_still"].as_f64()),
                    two_places(sec.data["correlation_moving"].as_f64()),
                    sec.data["mean_q"].as_f64().unwrap_or(0.0),
                    two_places(sec.data["interactive"]["correlation_moving"].as_f64()),
                    sec.data["interactive"]["mean_q_moving"].as_f64().unwrap_or(0.0)
                );
            }
            "fig8" => {
                let times: Vec<String> = sec.data["rows"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|r| {
                        format!(
                            "{}: {}",
                            r["grid"].as_str().unwrap_or(""),
                            r["time_to_threshold_s"]
                                .as_f64()
                                .map_or("not within the run".into(), |t| format!("{t:.1} s"))
                        )
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    "- Figure 8: time to mean FLIP {} (gold standard of {} frames): {}.",
                    sec.data["threshold"],
                    sec.data["gold_frames"],
                    times.join("; ")
                );
            }
            "table1" => {
                let cells: Vec<String> = sec.data["rows"]
                    .as_array()
                    .into_iter()
                    .flatten()
                    .map(|r| {
                        format!(
                            "{} {} {}: {:.2} fps, Q_t {:.2}",
                            r["scene"].as_str().unwrap_or(""),
                            r["grid"].as_str().unwrap_or(""),
                            r["mode"].as_str().unwrap_or(""),
                            r["frames_per_second"].as_f64().unwrap_or(0.0),
                            r["mean_q"].as_f64().unwrap_or(0.0)
                        )
                    })
                    .collect();
                let _ = writeln!(
                    s,
                    "- Table 1 (paper: Cornell Box 6.66, Kiti 6.00, Race Car 5.00, Sponza 2.50 fps): {}.",
                    cells.join("; ")
                );
            }
            _ => {}
        }
    }
    let failed: Vec<&str> = sections
        .iter()
        .flat_map(|s| &s.claims)
        .filter(|c| !c.holds)
        .map(|c| c.text.as_str())
        .collect();
    if failed.is_empty() {
        let _ = writeln!(s, "- Every claim above holds in this run.");
    } else {
        let _ = writeln!(s, "- Claims that do not hold in this run: {}.", failed.join("; "));
    }
    s
}

/// The subset of Markdown the report uses, as an HTML page.
pub fn html(md: &str) -> String {
    let mut body = String::new();
    let mut in_table = false;
    let mut in_list = false;
    for line in md.lines() {
        let is_row = line.starts_with('|');
        if in_table && !is_row {
            body.push_str("</table>\n");
            in_table = false;
        }
        let is_item = line.starts_with("- ");
        if in_list && !is_item {
            body.push_str("</ul>\n");
            in_list = false;
        }
        if is_row {
            if line.starts_with("|---") {
                continue;
            }
            if !in_table {
                body.push_str("<table>\n");
                in_table = true;
            }
            let cells: Vec<String> = line
                .trim_matches('|')
                .split('|')
                .map(|c| format!("<td>{}</td>", inline(c.trim())))
                .collect();
            let _ = writeln!(body, "<tr>{}</tr>", cells.concat());
        } else if let Some(item) = line.strip_prefix("- ") {
            if !in_list {
                body.push_str("<ul>\n");
                in_list = true;
            }
            let _ = writeln!(body, "<li>{}</li>", inline(item));
        } else if let Some(h) = line.strip_prefix("### ") {
            let _ = writeln!(body, "<h3>{}</h3>", inline(h));
        } else if let Some(h) = line.strip_prefix("## ") {
            let _ = writeln!(body, "<h2>{}</h2>", inline(h));
        } else if let Some(h) = line.strip_prefix("# ") {
            let _ = writeln!(body, "<h1>{}</h1>", inline(h));
        } else if !line.trim().is_empty() {
            let _ = writeln!(body, "<p>{}</p>", inline(line));
        }
    }
    if in_table {
        body.push_str("</table>\n");
    }
    if in_list {
        body.push_str("</ul>\n");
    }
    format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>gridlight: the paper's evaluation</title>\
         <style>body{{font-family:sans-serif;max-width:960px;margin:auto}}table{{border-collapse:collapse}}\
         td{{border:1px solid #ccc;padding:2px 6px}}img{{max-width:100%}}</style></head><body>\n{body}</body></html>\n"
    )
}

/// Escapes HTML, then turns `![alt](src)`, `**bold**` and `` `code` `` into tags.
fn inline(text: &str) -> String {
    let escaped = text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;");
    let mut out = String::new();
    let mut rest = escaped.as_str();
    while let Some(start) = rest.find("![") {
        let Some(mid) = rest[start..].find("](").map(|m| start + m) else { break };
        let Some(end) = rest[mid..].find(')').map(|e| mid + e) else { break };
        out.push_str(&rest[..start]);
        let _ =
            write!(out, "<img alt=\"{}\" src=\"{}\">", &rest[start + 2..mid], &rest[mid + 2..end]);
        rest = &rest[end + 1..];
    }
    out.push_str(rest);
    let mut result = String::new();
    for (i, part) in out.split("**").enumerate() {
        if i % 2 == 1 {
            let _ = write!(result, "<b>{part}</b>");
        } else {
            result.push_str(part);
        }
    }
    let mut code = String::new();
    for (i, part) in result.split('`').enumerate() {
        if i % 2 == 1 {
            let _ = write!(code, "<code>{part}</code>");
        } else {
            code.push_str(part);
        }
    }
    code
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn html_has_the_markdowns_headings_tables_images_and_lists() {
        let page = html(
            "# T\n\n## S\n\n| a | b |\n|---|---|\n| 1 | ![x](p.png) |\n\n- **y** `z`\n\ntext <&>\n",
        );
        for part in [
            "<h1>T</h1>",
            "<h2>S</h2>",
            "<td>a</td>",
            "<img alt=\"x\" src=\"p.png\">",
            "<li><b>y</b> <code>z</code></li>",
            "<p>text &lt;&amp;&gt;</p>",
            "</table>",
        ] {
            assert!(page.contains(part), "missing {part} in {page}");
        }
    }
}
