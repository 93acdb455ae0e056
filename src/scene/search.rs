//! The asset search path: how an asset path named by a scene becomes a file on disk.
//!
//! Scenes and scene states name assets by relative paths (`bunny/stanford-bunny.obj`), never
//! by file-system paths, so that a worker can resolve the same names against its own cache.
//! [`AssetResolver`] is that mapping; [`AssetSearchPath`] is the master's and the CLI's
//! implementation: `--assets DIR` (in order), then `GRIDLIGHT_ASSETS` (colon-separated), then
//! `assets/` beside the scene file, then `scenes/assets/` in the current directory.

use std::borrow::Cow;
use std::ffi::OsStr;
use std::fmt;
use std::path::{Component, Path, PathBuf};

use super::error::AssetError;

/// Name of the environment variable holding extra asset directories.
pub const ASSETS_ENV: &str = "GRIDLIGHT_ASSETS";

/// Maps an asset path (relative, `/`-separated) to a readable file.
pub trait AssetResolver {
    /// The file holding `asset`, or why there is none.
    fn resolve(&self, asset: &str) -> Result<PathBuf, ResolveError>;

    /// The bytes of `asset`: by default the file [`AssetResolver::resolve`] names. A
    /// resolver that holds assets in memory (a worker with `--cache none`) overrides it.
    fn read(&self, asset: &str) -> Result<AssetBytes<'_>, AssetError> {
        read_file(self.resolve(asset)?)
    }
}

/// The bytes of a resolved asset file.
pub fn read_file(file: PathBuf) -> Result<AssetBytes<'static>, AssetError> {
    let bytes =
        std::fs::read(&file).map_err(|source| AssetError::Read { file: file.clone(), source })?;
    Ok(AssetBytes { file, bytes: Cow::Owned(bytes) })
}

/// An asset's bytes, and the name its errors give it (its file, or its asset path).
#[derive(Debug)]
pub struct AssetBytes<'a> {
    pub file: PathBuf,
    pub bytes: Cow<'a, [u8]>,
}

impl AssetBytes<'_> {
    /// The image format its name says, else the one its first bytes say.
    pub fn decode_image(&self) -> Result<image::DynamicImage, AssetError> {
        let cursor = std::io::Cursor::new(&self.bytes[..]);
        let reader = match image::ImageFormat::from_path(&self.file) {
            Ok(format) => image::ImageReader::with_format(cursor, format),
            Err(_) => image::ImageReader::new(cursor)
                .with_guessed_format()
                .map_err(|source| AssetError::Read { file: self.file.clone(), source })?,
        };
        reader.decode().map_err(|source| AssetError::Image { file: self.file.clone(), source })
    }
}

/// Why an asset path could not be resolved.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResolveError {
    /// No directory of the search path holds the file.
    #[error("asset `{asset}` not found; searched: {}", list(.searched))]
    NotFound { asset: String, searched: Vec<PathBuf> },
    /// The name is absolute, empty or climbs out of the asset root with `..`.
    #[error("asset path `{asset}` must be relative, without `..`")]
    BadPath { asset: String },
    /// A resolver over something other than directories (e.g. a worker's cache).
    #[error("asset `{asset}`: {reason}")]
    Unavailable { asset: String, reason: String },
}

fn list(dirs: &[PathBuf]) -> String {
    if dirs.is_empty() {
        return "(no asset directories: use --assets DIR or GRIDLIGHT_ASSETS)".to_owned();
    }
    dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", ")
}

/// Checks that `asset` is a relative path that stays inside an asset root.
pub fn check_asset_path(asset: &str) -> Result<(), ResolveError> {
    let bad = || ResolveError::BadPath { asset: asset.to_owned() };
    if asset.is_empty() {
        return Err(bad());
    }
    for component in Path::new(asset).components() {
        match component {
            Component::Normal(_) | Component::CurDir => {}
            _ => return Err(bad()),
        }
    }
    Ok(())
}

/// Joins an asset path relative to the directory of another asset (`dir/of/x.obj` + `t.png`
/// → `dir/of/t.png`), normalising `\` and `./` as MTL files written on Windows need.
pub fn sibling_asset(of: &str, name: &str) -> String {
    let name = name.replace('\\', "/");
    let name = name.trim_start_matches("./");
    match of.rfind('/') {
        Some(slash) => format!("{}/{}", &of[..slash], name),
        None => name.to_owned(),
    }
}

/// Directories searched in order for asset files.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct AssetSearchPath {
    dirs: Vec<PathBuf>,
}

impl AssetSearchPath {
    /// A search path of exactly these directories.
    pub fn from_dirs(dirs: Vec<PathBuf>) -> Self {
        Self { dirs }
    }

    /// The full search path: `cli_dirs`, then the directories in `env` (the value of
    /// [`ASSETS_ENV`], colon-separated), then `assets/` beside `scene_file`, then
    /// `scenes/assets/` in the current directory. Duplicates are dropped.
    pub fn new(cli_dirs: &[PathBuf], env: Option<&OsStr>, scene_file: Option<&Path>) -> Self {
        let mut dirs: Vec<PathBuf> = cli_dirs.to_vec();
        if let Some(env) = env {
            dirs.extend(std::env::split_paths(env).filter(|d| !d.as_os_str().is_empty()));
        }
        if let Some(scene_dir) = scene_file.and_then(Path::parent) {
            let scene_dir =
                if scene_dir.as_os_str().is_empty() { Path::new(".") } else { scene_dir };
            dirs.push(scene_dir.join("assets"));
        }
        dirs.push(PathBuf::from("scenes").join("assets"));
        let mut unique = Vec::with_capacity(dirs.len());
        for dir in dirs {
            if !unique.contains(&dir) {
                unique.push(dir);
            }
        }
        Self { dirs: unique }
    }

    /// [`AssetSearchPath::new`] with `env` read from the process environment.
    pub fn from_env(cli_dirs: &[PathBuf], scene_file: Option<&Path>) -> Self {
        let env = std::env::var_os(ASSETS_ENV);
        Self::new(cli_dirs, env.as_deref(), scene_file)
    }

    /// This search path with `dir` searched first.
    pub fn with_first(mut self, dir: PathBuf) -> Self {
        self.dirs.retain(|d| *d != dir);
        self.dirs.insert(0, dir);
        self
    }

    /// The directories, in search order.
    pub fn dirs(&self) -> &[PathBuf] {
        &self.dirs
    }
}

impl AssetResolver for AssetSearchPath {
    fn resolve(&self, asset: &str) -> Result<PathBuf, ResolveError> {
        check_asset_path(asset)?;
        self.dirs.iter().map(|dir| dir.join(asset)).find(|file| file.is_file()).ok_or_else(|| {
            ResolveError::NotFound { asset: asset.to_owned(), searched: self.dirs.clone() }
        })
    }
}

impl fmt::Display for AssetSearchPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&list(&self.dirs))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_is_cli_then_env_then_scene_dir_then_cwd() {
        let path = AssetSearchPath::new(
            &[PathBuf::from("/cli")],
            Some(OsStr::new("/env1:/env2")),
            Some(Path::new("some/scenes/x.toml")),
        );
        let expected: Vec<PathBuf> =
            ["/cli", "/env1", "/env2", "some/scenes/assets", "scenes/assets"]
                .iter()
                .map(PathBuf::from)
                .collect();
        assert_eq!(path.dirs(), expected.as_slice());
    }

    #[test]
    fn finds_the_first_directory_holding_the_file_and_names_all_when_missing() {
        let a = tempfile::tempdir().expect("tempdir");
        let b = tempfile::tempdir().expect("tempdir");
        std::fs::create_dir_all(b.path().join("m")).expect("mkdir");
        std::fs::write(b.path().join("m/x.obj"), "v 0 0 0\n").expect("write");
        let path = AssetSearchPath::from_dirs(vec![a.path().into(), b.path().into()]);
        assert_eq!(path.resolve("m/x.obj").expect("found"), b.path().join("m/x.obj"));
        let err = path.resolve("m/y.obj").expect_err("missing").to_string();
        assert!(err.contains("m/y.obj"), "{err}");
        assert!(err.contains(&a.path().display().to_string()), "{err}");
        assert!(err.contains(&b.path().display().to_string()), "{err}");
    }

    #[test]
    fn rejects_paths_leaving_the_asset_root() {
        for bad in ["", "/etc/passwd", "../x.obj", "a/../../x.obj"] {
            assert!(check_asset_path(bad).is_err(), "{bad:?} accepted");
        }
        assert!(check_asset_path("a/./b.obj").is_ok());
    }

    #[test]
    fn sibling_assets_live_in_the_same_directory() {
        assert_eq!(sibling_asset("sponza/sponza.obj", "tex\\a.jpg"), "sponza/tex/a.jpg");
        assert_eq!(sibling_asset("x.obj", "./x.mtl"), "x.mtl");
    }
}
