//! Errors of scene loading: every one names the scene file, the key and what is wrong.

use std::path::PathBuf;

use super::search::ResolveError;

/// A scene file that cannot be loaded. Displays as `FILE: KEY: PROBLEM`, for example
/// `scenes/x.toml: objects[2].transform.translation: value is not finite (NaN or infinity)`.
#[derive(Debug, thiserror::Error)]
#[error("{}: {key}: {problem}", path.display())]
pub struct SceneError {
    /// The scene file.
    pub path: PathBuf,
    /// Where in the file, as a path of keys (`objects[2].transform.translation`); `(file)`
    /// when the whole file is concerned.
    pub key: String,
    /// Boxed: errors travel through many `?`s and should stay small.
    pub problem: Box<Problem>,
}

/// What is wrong.
#[derive(Debug, thiserror::Error)]
pub enum Problem {
    #[error("cannot read the file: {0}")]
    Read(std::io::Error),
    #[error("TOML syntax error at line {line}, column {column}: {message}")]
    Syntax { line: usize, column: usize, message: String },
    /// A key that the format does not know, a wrong type or a missing required key.
    #[error("{message} (line {line})")]
    Schema { line: usize, message: String },
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Asset(#[from] AssetError),
}

/// A problem with an asset file (mesh, material library, texture, environment map).
#[derive(Debug, thiserror::Error)]
pub enum AssetError {
    #[error(transparent)]
    Resolve(#[from] ResolveError),
    #[error("cannot read `{}`: {source}", file.display())]
    Read { file: PathBuf, source: std::io::Error },
    #[error("cannot load OBJ `{}`: {source}", file.display())]
    Obj { file: PathBuf, source: tobj::LoadError },
    #[error("cannot load material library `{mtl}` of `{}`: {source}", file.display())]
    Mtl { file: PathBuf, mtl: String, source: Box<AssetError> },
    #[error("cannot load glTF `{}`: {source}", file.display())]
    Gltf { file: PathBuf, source: super::gltf::GltfError },
    #[error("OBJ `{}` has no triangles", file.display())]
    EmptyMesh { file: PathBuf },
    #[error("OBJ `{}` is malformed: {reason}", file.display())]
    BadMesh { file: PathBuf, reason: String },
    #[error("cannot decode image `{}`: {source}", file.display())]
    Image { file: PathBuf, source: image::ImageError },
    #[error("mesh `{0}` is in the scene state but was not loaded with it")]
    NotLoaded(String),
}

impl SceneError {
    pub(crate) fn new(path: impl Into<PathBuf>, key: impl Into<String>, problem: Problem) -> Self {
        Self { path: path.into(), key: key.into(), problem: Box::new(problem) }
    }
}
