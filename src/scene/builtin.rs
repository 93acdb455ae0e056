//! Built-in scenes: scene files compiled into the binary, so that `gridlight demo` and
//! `gridlight render cornell-box` work from any directory after `cargo install`.
//!
//! Only scenes that need no asset files are built in (their objects are built-in shapes);
//! the files under `scenes/` stay the source of truth and are embedded as they are.
//! [`SceneSource`] is how a command-line scene argument becomes scene text: an existing
//! file, else a built-in scene's name, else `NAME.toml` (or `NAME`, e.g. `model.glb`) in a
//! directory of the asset search path or in `scenes/` ([`scene_dirs`]).

use std::borrow::Cow;
use std::fmt;
use std::path::{Path, PathBuf};

use super::error::{Problem, SceneError};
use super::gltf::is_gltf;
use super::search::AssetSearchPath;

/// One scene compiled into the binary.
#[derive(Debug, PartialEq, Eq)]
pub struct Builtin {
    /// What the command line calls it (`cornell-box`).
    pub name: &'static str,
    /// One line about it, for `gridlight scenes`.
    pub about: &'static str,
    /// The scene file's text.
    pub text: &'static str,
}

/// Every built-in scene; the first is the demo's.
pub const BUILTINS: &[Builtin] = &[
    Builtin {
        name: "cornell-box",
        about: "the Cornell box of Mitsuba 3 (area light, two boxes)",
        text: include_str!("../../scenes/cornell-box.toml"),
    },
    Builtin {
        name: "glossy-glass",
        about: "glass, rough glass, gold and glossy plastic spheres in the Cornell room",
        text: include_str!("../../scenes/glossy-glass.toml"),
    },
];

/// The built-in scene called `name` (`cornell-box` or `cornell-box.toml`).
pub fn builtin(name: &str) -> Option<&'static Builtin> {
    let name = name.strip_suffix(".toml").unwrap_or(name);
    BUILTINS.iter().find(|b| b.name == name)
}

/// Where a scene's text comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SceneSource {
    /// A scene compiled into the binary.
    Builtin(&'static Builtin),
    /// A scene file on disk.
    File(PathBuf),
}

impl SceneSource {
    /// The scene the command line names: an existing file, else a built-in scene, else
    /// `NAME.toml` (or `NAME`) in one of `search_dirs` (the asset search path).
    pub fn find(arg: &Path, search_dirs: &[PathBuf]) -> Result<Self, SceneError> {
        if arg.is_file() {
            return Ok(Self::File(arg.to_path_buf()));
        }
        if let Some(b) = arg.to_str().and_then(builtin) {
            return Ok(Self::Builtin(b));
        }
        let single = arg.components().count() == 1;
        if single {
            let with_ext = arg.with_extension("toml");
            for dir in search_dirs {
                for candidate in [dir.join(&with_ext), dir.join(arg)] {
                    if candidate.is_file() {
                        return Ok(Self::File(candidate));
                    }
                }
            }
        }
        let names: Vec<&str> = BUILTINS.iter().map(|b| b.name).collect();
        let what = format!(
            "no such scene file, and not a built-in scene ({}); `gridlight scenes` lists the scenes it can find",
            names.join(", ")
        );
        Err(SceneError::new(arg, "(file)", Problem::Invalid(what)))
    }

    /// [`SceneSource::find`] over the asset search path (`--assets` dirs, then
    /// `GRIDLIGHT_ASSETS`, …), and the search path for the scene's assets.
    pub fn find_with_assets(
        arg: &Path,
        cli_assets: &[PathBuf],
    ) -> Result<(Self, AssetSearchPath), SceneError> {
        let source = Self::find(arg, &scene_dirs(cli_assets))?;
        let search = source.search_path(cli_assets);
        Ok((source, search))
    }

    /// The asset search path for this scene (a file's folder is part of it; a glTF
    /// file's own folder comes first, since the file is its own first asset).
    pub fn search_path(&self, cli_assets: &[PathBuf]) -> AssetSearchPath {
        let search = AssetSearchPath::from_env(cli_assets, self.file());
        match (self.gltf_asset(), self.file().and_then(Path::parent)) {
            (Some(_), Some(dir)) => {
                let dir = if dir.as_os_str().is_empty() { Path::new(".") } else { dir };
                search.with_first(dir.to_path_buf())
            }
            _ => search,
        }
    }

    /// For a glTF file (`.gltf`, `.glb`), its asset path: its file name, found in its
    /// folder through [`SceneSource::search_path`].
    pub fn gltf_asset(&self) -> Option<String> {
        let name = self.file()?.file_name()?.to_str()?;
        is_gltf(name).then(|| name.to_owned())
    }

    /// The default scene of the demo.
    pub fn default_builtin() -> Self {
        Self::Builtin(&BUILTINS[0])
    }

    /// The file, for scenes on disk (its folder is part of the asset search path).
    pub fn file(&self) -> Option<&Path> {
        match self {
            Self::Builtin(_) => None,
            Self::File(path) => Some(path),
        }
    }

    /// The name error messages use for the scene: its path, or `built-in:NAME`.
    pub fn label(&self) -> PathBuf {
        match self {
            Self::Builtin(b) => PathBuf::from(format!("built-in:{}", b.name)),
            Self::File(path) => path.clone(),
        }
    }

    /// The short name (file stem or built-in name), e.g. for benchmark reports.
    pub fn name(&self) -> String {
        match self {
            Self::Builtin(b) => b.name.to_owned(),
            Self::File(path) => path
                .file_stem()
                .map_or_else(|| path.display().to_string(), |s| s.to_string_lossy().into_owned()),
        }
    }

    /// The scene's TOML text.
    pub fn text(&self) -> Result<Cow<'static, str>, SceneError> {
        match self {
            Self::Builtin(b) => Ok(Cow::Borrowed(b.text)),
            Self::File(path) => std::fs::read_to_string(path)
                .map(Cow::Owned)
                .map_err(|e| SceneError::new(path, "(file)", Problem::Read(e))),
        }
    }
}

impl fmt::Display for SceneSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.label().display())
    }
}

/// Folders searched for scenes named without a path: the asset search path (without a
/// scene file), then `scenes/` in the current directory.
pub fn scene_dirs(cli_assets: &[PathBuf]) -> Vec<PathBuf> {
    let mut dirs = AssetSearchPath::from_env(cli_assets, None).dirs().to_vec();
    dirs.push(PathBuf::from("scenes"));
    dirs
}

/// Scene files (`*.toml`, `*.gltf`, `*.glb`) directly inside each of `dirs`, sorted,
/// each once.
pub fn scene_files_in(dirs: &[PathBuf]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(dir) else { continue };
        let mut files: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let scene =
                    p.extension().is_some_and(|e| e == "toml") || p.to_str().is_some_and(is_gltf);
                scene && p.is_file()
            })
            .collect();
        files.sort();
        for f in files {
            if !found.contains(&f) {
                found.push(f);
            }
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_builtin_scene_loads_without_asset_files() {
        for b in BUILTINS {
            let source = SceneSource::Builtin(b);
            let loaded = crate::scene::load_source(&source, &AssetSearchPath::from_dirs(vec![]))
                .unwrap_or_else(|e| panic!("{}: {e}", b.name));
            assert!(!loaded.state.objects.is_empty(), "{} has objects", b.name);
        }
    }

    #[test]
    fn names_resolve_with_or_without_the_extension_and_files_win() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(SceneSource::find(Path::new("cornell-box"), &[]).unwrap().name(), "cornell-box");
        assert_eq!(
            SceneSource::find(Path::new("glossy-glass.toml"), &[]).unwrap(),
            SceneSource::Builtin(&BUILTINS[1])
        );
        // A file of that name in the current directory is what the user means.
        let file = dir.path().join("cornell-box");
        std::fs::write(&file, "").unwrap();
        assert_eq!(SceneSource::find(&file, &[]).unwrap(), SceneSource::File(file));
    }

    #[test]
    fn scenes_on_the_search_path_are_found_by_name_and_listed() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("room.toml"), "").unwrap();
        std::fs::write(dir.path().join("notes.txt"), "").unwrap();
        let dirs = vec![dir.path().to_path_buf(), PathBuf::from("/nonexistent")];
        let found = SceneSource::find(Path::new("room"), &dirs).unwrap();
        assert_eq!(found, SceneSource::File(dir.path().join("room.toml")));
        assert_eq!(scene_files_in(&dirs), vec![dir.path().join("room.toml")]);
        // glTF files are scenes too, found by their full name.
        std::fs::write(dir.path().join("model.glb"), "").unwrap();
        let found = SceneSource::find(Path::new("model.glb"), &dirs).unwrap();
        assert_eq!(found.gltf_asset().as_deref(), Some("model.glb"));
        assert_eq!(found.search_path(&[]).dirs()[0], dir.path());
        let listed = scene_files_in(&dirs);
        assert_eq!(listed, vec![dir.path().join("model.glb"), dir.path().join("room.toml")]);
    }

    #[test]
    fn an_unknown_scene_names_the_builtins() {
        let err = SceneSource::find(Path::new("nope"), &[]).unwrap_err().to_string();
        assert!(err.contains("nope") && err.contains("cornell-box"), "{err}");
        assert!(err.contains("gridlight scenes"), "{err}");
    }
}
