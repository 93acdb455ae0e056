//! `gridlight worker --config FILE`: a worker's settings in a TOML file, for the
//! administrator of many desks (one file in the machine image; a systemd unit or a grid
//! manager's job points at it). Each setting may also come from the command line or an
//! environment variable (`GRIDLIGHT_...`, listed in `--help`), which win over the file;
//! the file wins over the defaults. Relative paths are relative to the file's folder.
//!
//! ```toml
//! master = "render-master.lab:7840"   # absent: find a master on the LAN
//! master_name = "lab"                 # with several masters announcing
//! threads = 4
//! priority = "idle"                   # idle (default) | normal
//! when_idle = true
//! secret_file = "grid.secret"
//!
//! [idle]                              # when the desk's owner counts as active
//! cpu_percent = 25                    # other processes' share of all CPUs, %
//! cpu_window_s = 10
//! input_idle_s = 300                  # keyboard/mouse used less than this long ago
//! resume_after_s = 30
//! ```

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::worker::Priority;

/// The file's contents; every key optional, unknown keys refused.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WorkerFile {
    pub master: Option<String>,
    pub master_name: Option<String>,
    pub discovery_port: Option<u16>,
    pub discover_timeout_s: Option<f64>,
    pub threads: Option<usize>,
    pub name: Option<String>,
    pub secret_file: Option<PathBuf>,
    pub cache_dir: Option<PathBuf>,
    pub cache: Option<super::worker::CacheMode>,
    pub forget_on_exit: Option<bool>,
    pub priority: Option<Priority>,
    pub when_idle: Option<bool>,
    #[serde(default)]
    pub idle: IdleFile,
}

/// `[idle]`: the `--when-idle` thresholds.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdleFile {
    pub cpu_percent: Option<f32>,
    pub cpu_window_s: Option<f64>,
    pub input_idle_s: Option<f64>,
    pub resume_after_s: Option<f64>,
}

/// A config file that cannot be used: `FILE: KEY: PROBLEM`.
#[derive(Debug, thiserror::Error)]
#[error("{}: {key}: {problem}", path.display())]
pub struct WorkerFileError {
    pub path: PathBuf,
    pub key: String,
    pub problem: String,
}

impl WorkerFile {
    /// Reads and checks `path`; relative paths in it become relative to its folder.
    pub fn load(path: &Path) -> Result<Self, WorkerFileError> {
        let error = |key: &str, problem: String| WorkerFileError {
            path: path.to_path_buf(),
            key: key.to_owned(),
            problem,
        };
        let text = std::fs::read_to_string(path)
            .map_err(|e| error("(file)", format!("cannot read the file: {e}")))?;
        let mut file: WorkerFile = serde_path_to_error::deserialize(toml::Deserializer::new(&text))
            .map_err(|err| {
                let key = match err.path().to_string() {
                    p if p == "." || p.is_empty() => "(top level)".to_owned(),
                    p => p,
                };
                error(&key, err.into_inner().message().trim().to_owned())
            })?;
        let base = path.parent().unwrap_or(Path::new("."));
        for p in [&mut file.secret_file, &mut file.cache_dir].into_iter().flatten() {
            if p.is_relative() {
                *p = base.join(&*p);
            }
        }
        Ok(file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str) -> Result<WorkerFile, WorkerFileError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("worker.toml");
        std::fs::write(&path, text).unwrap();
        WorkerFile::load(&path)
    }

    #[test]
    fn every_setting_is_read_and_relative_paths_follow_the_file() {
        let f = load(
            "master = \"m:7840\"\nthreads = 3\npriority = \"normal\"\nwhen_idle = true\n\
             secret_file = \"grid.secret\"\n[idle]\ncpu_percent = 40\nresume_after_s = 5\n",
        )
        .unwrap();
        assert_eq!(f.master.as_deref(), Some("m:7840"));
        assert_eq!(
            (f.threads, f.priority, f.when_idle),
            (Some(3), Some(Priority::Normal), Some(true))
        );
        assert_eq!((f.idle.cpu_percent, f.idle.resume_after_s), (Some(40.0), Some(5.0)));
        let secret = f.secret_file.unwrap();
        assert!(secret.is_absolute() && secret.ends_with("grid.secret"), "{}", secret.display());
    }

    #[test]
    fn unknown_keys_and_wrong_types_name_the_key() {
        let err = load("[idle]\ncpu_percnt = 40\n").unwrap_err().to_string();
        assert!(err.contains("worker.toml") && err.contains("cpu_percnt"), "{err}");
        let err = load("priority = \"lowest\"\n").unwrap_err().to_string();
        assert!(err.contains("priority") && err.contains("idle"), "{err}");
    }
}
