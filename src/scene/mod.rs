//! Scene files: the TOML format, loading it into a scene state plus asset data, and the
//! asset plumbing the master and workers share.
//!
//! - [`description`]: serde types of the file (STYLE.md item 4: description, then build).
//! - [`build`]: checks every value and produces a [`SceneState`] and its [`Assets`].
//! - [`obj`], [`mtl`]: Wavefront OBJ/MTL through tobj, MTL → material heuristics.
//! - [`gltf`]: glTF 2.0 files, as meshes of a scene file or as whole scenes.
//! - [`loader`]: assets of a state alone (what a worker does with its cache).
//! - [`manifest`]: every file a state needs, hashed, for workers to fetch.
//! - [`search`]: the asset search path and the [`AssetResolver`] trait.
//! - [`error`]: [`SceneError`], which names the file, the key and the problem.
//! - [`builtin`]: scenes compiled into the binary, and [`SceneSource`] (file or built-in).

pub mod build;
pub mod builtin;
pub mod description;
pub mod error;
pub mod gltf;
pub mod loader;
pub mod manifest;
pub mod mtl;
pub mod obj;
pub mod pacing;
pub mod search;

use std::path::Path;

use gridlight_actors::state::SceneState;

use crate::assets::Assets;
pub use builtin::SceneSource;
pub use description::{DisplayDesc, SceneFile};
pub use error::{AssetError, Problem, SceneError};
pub use loader::load_assets;
pub use manifest::{asset_paths, manifest};
pub use pacing::{display_pacing, PacingOverrides};
pub use search::{AssetBytes, AssetResolver, AssetSearchPath, ResolveError};

/// A loaded scene: the state a worker renders and the asset data it names.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    pub state: SceneState,
    pub assets: Assets,
    /// `[render.reconstruction]`, checked.
    pub reconstruction: crate::reconstruct::ReconstructParams,
    /// `[render.display]`, checked.
    pub display: DisplayDesc,
    /// What the scene's files ask that gridlight does not render, one line per feature
    /// (already logged by [`load_source`]).
    pub warnings: Vec<String>,
}

/// Reads, parses and builds the scene file at `path`, finding assets through `resolver`.
pub fn load(path: &Path, resolver: &dyn AssetResolver) -> Result<LoadedScene, SceneError> {
    load_source(&SceneSource::File(path.to_path_buf()), resolver)
}

/// Reads, parses and builds a scene file, a glTF file or a built-in scene, and logs the
/// warnings of what it does not render.
pub fn load_source(
    source: &SceneSource,
    resolver: &dyn AssetResolver,
) -> Result<LoadedScene, SceneError> {
    let label = source.label();
    let loaded = match source.gltf_asset() {
        Some(asset) => load_gltf(&label, &asset, resolver)?,
        None => build::build(&parse(&label, &source.text()?)?, &label, resolver)?,
    };
    for warning in &loaded.warnings {
        tracing::warn!(scene = %label.display(), "{warning}");
    }
    Ok(loaded)
}

/// A glTF file as a whole scene: its description ([`gltf::view`]), built like a TOML one.
fn load_gltf(
    label: &Path,
    asset: &str,
    resolver: &dyn AssetResolver,
) -> Result<LoadedScene, SceneError> {
    let data = gltf::read_gltf(asset, resolver)
        .map_err(|e| SceneError::new(label, "(file)", Problem::Asset(e)))?;
    let mut warnings = gltf::Warnings::default();
    let file = gltf::view::describe(&data, asset, &mut warnings);
    let mesh = loader::gltf_mesh_file(asset, data);
    build::build_with(&file, label, resolver, Some((asset.to_owned(), mesh)), warnings)
}

/// Parses scene TOML; `path` is only used in error messages.
pub fn parse(path: &Path, text: &str) -> Result<SceneFile, SceneError> {
    // Syntax first, so that its errors say so and carry a line and column.
    if let Err(err) = text.parse::<toml::Table>() {
        let (line, column) = line_column(text, err.span().map_or(0, |s| s.start));
        let problem = Problem::Syntax { line, column, message: err.message().trim().to_owned() };
        return Err(SceneError::new(path, "(syntax)", problem));
    }
    serde_path_to_error::deserialize(toml::Deserializer::new(text)).map_err(|err| {
        let key = match err.path().to_string() {
            p if p == "." || p.is_empty() => "(top level)".to_owned(),
            p => p,
        };
        let inner = err.into_inner();
        let (line, _) = line_column(text, inner.span().map_or(0, |s| s.start));
        SceneError::new(
            path,
            key,
            Problem::Schema { line, message: inner.message().trim().to_owned() },
        )
    })
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}
