//! The layout's one-way dependencies inside the root crate (ARCHITECTURE.md, "Code map"),
//! checked on the sources so that a stray `use` fails here rather than in a review:
//!
//! - `gpu/` is device plumbing: it names no pass, no G-buffer, no master glue;
//! - `gbuffer/` does not use `reconstruct/` (reconstruction reads G-buffers, not the
//!   reverse);
//! - the core does not use `tools/` (benchmarks, evaluation, fault injection, the LAN
//!   testbed sit on top of it); only the command line and unit tests reach them.
//!
//! Unit-test modules (from `#[cfg(test)]` on) are not scanned: tests may borrow fixtures.

use std::path::{Path, PathBuf};

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Lines of the non-test part of every `.rs` file under `src/<dir>` that mention one of
/// `forbidden`, as `file:line: text`.
fn uses(dir: &str, forbidden: &[&str]) -> Vec<String> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src.join(dir), &mut files);
    assert!(!files.is_empty(), "src/{dir} has no Rust files");
    let mut found = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).expect("readable source");
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("#[cfg(test)]") {
                break;
            }
            let code = line.split("//").next().unwrap_or("");
            if forbidden.iter().any(|f| code.contains(f)) {
                found.push(format!("{}:{}: {}", file.display(), n + 1, line.trim()));
            }
        }
    }
    found
}

#[test]
fn gpu_is_device_plumbing_only() {
    let found = uses(
        "gpu",
        &[
            "crate::reconstruct",
            "crate::gbuffer",
            "crate::master",
            "crate::window",
            "crate::render",
        ],
    );
    assert!(found.is_empty(), "gpu/ uses what sits on top of it:\n{}", found.join("\n"));
}

#[test]
fn the_gbuffer_does_not_use_reconstruction() {
    let found = uses("gbuffer", &["crate::reconstruct", "super::reconstruct"]);
    assert!(found.is_empty(), "gbuffer/ uses reconstruct/:\n{}", found.join("\n"));
}

#[test]
fn the_core_does_not_use_the_tools() {
    for dir in ["gpu", "gbuffer", "reconstruct", "render", "scene", "worker", "master", "window"] {
        let found = uses(dir, &["crate::tools"]);
        assert!(found.is_empty(), "{dir}/ uses tools/:\n{}", found.join("\n"));
    }
}
