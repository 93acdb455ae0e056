//! `gridlight scenes`: the scenes this binary can render by name — the built-in ones, then
//! the scene files found in the asset search path and in `scenes/`.

use super::GlobalArgs;
use crate::scene::builtin::{scene_dirs, scene_files_in, BUILTINS};

/// Arguments of `gridlight scenes` (none besides the global `--assets`).
#[derive(Debug, Clone, clap::Args)]
pub struct Args {}

/// Runs `gridlight scenes`.
pub fn run(_args: Args, global: &GlobalArgs) -> anyhow::Result<()> {
    println!("built-in scenes (no files needed):");
    for b in BUILTINS {
        println!("  {:<14} {}", b.name, b.about);
    }
    let dirs = scene_dirs(&global.assets);
    let files = scene_files_in(&dirs);
    let searched: Vec<String> = dirs.iter().map(|d| d.display().to_string()).collect();
    println!("scene files found in {}:", searched.join(", "));
    if files.is_empty() {
        println!("  (none; add folders with --assets DIR or GRIDLIGHT_ASSETS)");
    }
    for f in files {
        println!("  {}", f.display());
    }
    Ok(())
}
