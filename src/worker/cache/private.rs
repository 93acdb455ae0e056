//! Owner-only files for the asset cache: the scene's assets are the office's secrets at
//! rest, so the cache directory is `0700` and every blob `0600` (on Unix).
//!
//! A directory that already exists with wider permissions (made by an older gridlight, by
//! hand, or by a service manager's default) is tightened and a warning says so; one this
//! user may not change (owned by someone else) is a warning, not an error, so a shared
//! cache an administrator set up keeps working.

use std::fs;
use std::io;
use std::path::Path;

/// Creates `dir` and its missing parents owner-only, or tightens it when it exists with
/// wider permissions. Answers the mode it had when it was wider, for the caller's tests.
pub fn private_dir(dir: &Path) -> io::Result<Option<u32>> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::{DirBuilderExt, PermissionsExt};
        if !dir.is_dir() {
            fs::DirBuilder::new().recursive(true).mode(0o700).create(dir)?;
        }
        let mode = fs::metadata(dir)?.permissions().mode() & 0o777;
        if mode & 0o077 == 0 {
            return Ok(None);
        }
        match fs::set_permissions(dir, fs::Permissions::from_mode(0o700)) {
            Ok(()) => tracing::warn!(dir = %dir.display(), was = format!("{mode:o}"),
                "the asset cache was readable by other users: tightened to 0700"),
            Err(e) => tracing::warn!(dir = %dir.display(), mode = format!("{mode:o}"), cause = %e,
                "the asset cache is readable by other users and cannot be tightened: \
                 give the worker a directory of its own (--cache-dir) or --cache none"),
        }
        Ok(Some(mode))
    }
    #[cfg(not(unix))]
    {
        fs::create_dir_all(dir).map(|()| None)
    }
}

/// A new file only its owner may read; fails if `path` exists.
pub fn private_file(path: &Path) -> io::Result<fs::File> {
    let mut options = fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    options.open(path)
}

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use std::os::unix::fs::PermissionsExt;

    fn mode(p: &Path) -> u32 {
        fs::metadata(p).unwrap().permissions().mode() & 0o777
    }

    #[test]
    fn new_directories_and_files_are_owner_only() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("a/b");
        assert_eq!(private_dir(&dir).unwrap(), None);
        assert_eq!(mode(&dir), 0o700);
        private_file(&dir.join("f")).unwrap();
        assert_eq!(mode(&dir.join("f")), 0o600);
        assert!(private_file(&dir.join("f")).is_err(), "an existing file is never reused");
    }

    #[test]
    fn a_wider_existing_directory_is_tightened() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("cache");
        fs::create_dir(&dir).unwrap();
        fs::set_permissions(&dir, fs::Permissions::from_mode(0o755)).unwrap();
        assert_eq!(private_dir(&dir).unwrap(), Some(0o755));
        assert_eq!(mode(&dir), 0o700);
        assert_eq!(private_dir(&dir).unwrap(), None, "tight already");
    }
}
