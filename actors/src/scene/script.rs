//! Interaction scripts: a TOML file of timed edits, replayed by the scene-state holder.
//!
//! ```toml
//! [[edit]]
//! at = 0.5                       # seconds after the start
//! camera = { position = [0.0, 1.0, 4.0] }
//!
//! [[edit]]
//! at = 1.0
//! object = { name = "tall_box", translation = [0.2, 0.0, 0.1], rotation_deg = [0.0, 30.0, 0.0] }
//!
//! [[edit]]
//! at = 1.5
//! material = { name = "red", base_color = [0.1, 0.6, 0.1] }
//! ```
//! Each entry has `at` and exactly one edit key (`camera`, `object`, `material`,
//! `light`, `environment`, `clear_environment`, `render`) spelled as [`Edit`].

use std::path::Path;
use std::time::Duration;

use serde::Deserialize;
use thiserror::Error;

use crate::scene::edit::Edit;

/// Why a script could not be read.
#[derive(Debug, Error)]
pub enum ScriptError {
    #[error("cannot read interaction script {path}: {source}")]
    Read { path: String, source: std::io::Error },
    #[error("interaction script {path}: {message}")]
    Parse { path: String, message: String },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ScriptFile {
    #[serde(default)]
    edit: Vec<Entry>,
}

#[derive(Deserialize)]
struct Entry {
    at: f64,
    #[serde(flatten)]
    edit: Edit,
}

/// Parses script text (`path` only names it in errors); edits come sorted by time.
pub fn parse(text: &str, path: &str) -> Result<Vec<(Duration, Edit)>, ScriptError> {
    let err = |message: String| ScriptError::Parse { path: path.to_owned(), message };
    let file: ScriptFile = toml::from_str(text).map_err(|e| err(e.to_string()))?;
    let mut out = Vec::with_capacity(file.edit.len());
    for (i, e) in file.edit.into_iter().enumerate() {
        if !(e.at.is_finite() && e.at >= 0.0) {
            return Err(err(format!(
                "edit {}: `at` must be a non-negative number of seconds, got {}",
                i + 1,
                e.at
            )));
        }
        out.push((Duration::from_secs_f64(e.at), e.edit));
    }
    out.sort_by_key(|(t, _)| *t);
    Ok(out)
}

/// Reads and parses a script file.
pub fn load(path: &Path) -> Result<Vec<(Duration, Edit)>, ScriptError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path)
        .map_err(|source| ScriptError::Read { path: name.clone(), source })?;
    parse(&text, &name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::edit::{CameraEdit, ObjectEdit};
    use glam::Vec3;

    #[test]
    fn parses_timed_edits_in_time_order() {
        let text = r#"
            [[edit]]
            at = 1.0
            object = { name = "box", translation = [0.0, 1.0, 0.0] }

            [[edit]]
            at = 0.25
            camera = { position = [0.0, 1.0, 4.0] }

            [[edit]]
            at = 2
            clear_environment = {}
        "#;
        let s = parse(text, "t.toml").expect("script");
        assert_eq!(s.len(), 3);
        assert_eq!(s[0].0, Duration::from_millis(250));
        assert_eq!(
            s[0].1,
            Edit::Camera(CameraEdit {
                position: Some(Vec3::new(0.0, 1.0, 4.0)),
                ..Default::default()
            })
        );
        assert_eq!(
            s[1].1,
            Edit::Object(ObjectEdit {
                name: "box".into(),
                translation: Some(Vec3::Y),
                ..Default::default()
            })
        );
    }

    #[test]
    fn errors_name_the_file_and_the_problem() {
        let e = parse("[[edit]]\nat = -1\ncamera = {}\n", "s.toml").unwrap_err().to_string();
        assert!(e.contains("s.toml") && e.contains("at"), "{e}");
        let e = parse("[[edit]]\nat = 1\nteleport = {}\n", "s.toml").unwrap_err().to_string();
        assert!(e.contains("s.toml"), "{e}");
        assert!(load(Path::new("/nonexistent/script.toml")).is_err());
    }
}
