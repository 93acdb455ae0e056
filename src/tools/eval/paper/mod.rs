//! `gridlight eval paper` and its experiments (`eval fig3`, `fig5`, `table1`, `fig8`,
//! `fig9`, `fig10`, `lan`): the paper's section 6 reproduced beside the paper's own figures.
//!
//! Grids larger than this machine are simulated (`crate::simgrid`): the master, the
//! network path, the wait heuristic and reconstruction are real; render time and
//! availability are modelled. Each experiment returns a [`Section`]: the paper's finding
//! in words and numbers, ours, where they agree or differ, its plots and images, its
//! numbers, and checked claims. [`report`] writes them as `report.md`, `index.html` and
//! `results.json`.
//!
//! - [`context`]: options, scenes and the modelled cores shared by the experiments.
//! - [`grid`]: one run of the master with a simulated grid.
//! - [`offline`]: Figures 3 and 9 (reconstruction of complete path-traced frames).
//! - [`fig5`], [`table1`], [`fig8`], [`fig10`]: runs on a simulated grid; [`lan`]:
//!   the same across rate-limited links between network namespaces.
//! - [`gold`]: Figure 8's gold standard, rendered once and cached.
//! - [`plot`]: PNG line plots. [`stats`]: correlation and medians.

pub mod context;
pub mod fig10;
pub mod fig5;
pub mod fig8;
pub mod gold;
pub mod grid;
pub mod lan;
pub mod offline;
pub mod plot;
pub mod report;
pub mod stats;
pub mod table1;

use serde::Serialize;

pub use context::{Context, Options};

/// A statement the report makes, checked against our numbers.
#[derive(Clone, Debug, Serialize)]
pub struct Claim {
    pub text: String,
    pub holds: bool,
}

impl Claim {
    pub fn new(text: impl Into<String>, holds: bool) -> Self {
        Self { text: text.into(), holds }
    }
}

/// One experiment's part of the report.
#[derive(Clone, Debug, Serialize)]
pub struct Section {
    /// Short name: `fig3`, `fig5`, ...
    pub id: String,
    pub title: String,
    /// What the paper shows, in its words and numbers.
    pub paper: String,
    /// What we did and measured (Markdown).
    pub ours: String,
    /// Where they agree, where and why they differ.
    pub comparison: String,
    /// PNG files in the output directory: plots, then images with captions.
    pub plots: Vec<String>,
    pub images: Vec<(String, String)>,
    pub claims: Vec<Claim>,
    /// Every number behind the section.
    pub data: serde_json::Value,
    /// Wall time the experiment took.
    pub seconds: f64,
}

/// Every experiment, in the report's order.
pub const EXPERIMENTS: [&str; 7] = ["fig3", "fig5", "table1", "fig8", "fig9", "fig10", "lan"];

/// Runs every experiment and writes the report into `ctx`'s output directory.
pub fn run_all(ctx: &mut Context) -> anyhow::Result<Vec<Section>> {
    let mut sections = Vec::new();
    for id in EXPERIMENTS {
        sections.push(run_one(ctx, id)?);
    }
    report::write(ctx, &sections)?;
    Ok(sections)
}

/// Runs one experiment by name.
pub fn run_one(ctx: &mut Context, id: &str) -> anyhow::Result<Section> {
    ctx.progress.set_message(id.to_string());
    let started = std::time::Instant::now();
    let mut section = match id {
        "fig3" => offline::fig3(ctx, &ctx.fig3.clone())?,
        "fig9" => offline::fig9(ctx, &ctx.fig9.clone())?,
        "fig5" => fig5::run(ctx, &ctx.fig5.clone())?,
        "table1" => table1::run(ctx, &ctx.table1.clone())?,
        "fig8" => fig8::run(ctx, &ctx.fig8.clone())?,
        "fig10" => fig10::run(ctx, &ctx.fig10.clone())?,
        "lan" => lan::run(ctx, &ctx.lan.clone())?,
        other => anyhow::bail!("no experiment `{other}` (known: {})", EXPERIMENTS.join(", ")),
    };
    section.seconds = started.elapsed().as_secs_f64();
    ctx.progress.inc(1);
    Ok(section)
}
