//! The repository stands alone, checked on its tracked files (`git ls-files`):
//!
//! - every image and relative link in README.md, ARCHITECTURE.md and `docs/*.md` names a
//!   file (or a folder of files) that is in the repository, so the front page renders with
//!   its pictures on any Git host (a `.gitignore` rule once kept `docs/images/` out);
//! - no tracked file cites the design document or the paper outside the repository: the
//!   decisions are in `docs/design.md`, the paper is cited by its title. The one exception
//!   is `.ci/run`, which finds the public test assets beside the clone.

use std::collections::BTreeSet;
use std::path::{Component, Path, PathBuf};
use std::process::Command;

use gridlight::testing::{skip, Missing};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The tracked files, relative to the repository root, or `None` (reported) without git.
fn tracked(test: &str) -> Option<BTreeSet<PathBuf>> {
    let out = Command::new("git").args(["ls-files", "-z"]).current_dir(repo()).output();
    match out {
        Ok(out) if out.status.success() => Some(
            out.stdout
                .split(|&b| b == 0)
                .filter(|name| !name.is_empty())
                .map(|name| PathBuf::from(String::from_utf8_lossy(name).into_owned()))
                .collect(),
        ),
        Ok(out) => {
            skip(test, Missing::System, String::from_utf8_lossy(&out.stderr).trim());
            None
        }
        Err(e) => {
            skip(test, Missing::System, format_args!("git ls-files: {e}"));
            None
        }
    }
}

/// The targets of the inline links and images of a Markdown text, outside code blocks and
/// code spans, with their line numbers.
fn link_targets(markdown: &str) -> Vec<(usize, String)> {
    let mut targets = Vec::new();
    let (mut in_fence, mut in_indented, mut after_blank) = (false, false, true);
    for (n, line) in markdown.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            in_fence = !in_fence;
            continue;
        }
        // An indented code block starts after a blank line (list items continue without one).
        in_indented = line.starts_with("    ") && (after_blank || in_indented);
        after_blank = line.trim().is_empty();
        if in_fence || in_indented {
            continue;
        }
        // Code spans are the odd pieces between backticks.
        for prose in line.split('`').step_by(2) {
            let mut rest = prose;
            while let Some(at) = rest.find("](") {
                let after = &rest[at + 2..];
                let Some(end) = after.find(')') else { break };
                targets.push((n + 1, after[..end].to_string()));
                rest = &after[end..];
            }
        }
    }
    targets
}

/// The repository path a relative link from `doc` names: anchor and title dropped, `..`
/// resolved; `None` for URLs and pure anchors.
fn resolve(doc: &Path, target: &str) -> Option<PathBuf> {
    let target = target.split_whitespace().next().unwrap_or("");
    let path = target.split('#').next().unwrap_or("");
    if path.is_empty() || path.contains("://") || path.starts_with("mailto:") {
        return None;
    }
    let mut out = PathBuf::new();
    for part in doc.parent().unwrap_or(Path::new("")).join(path).components() {
        match part {
            Component::ParentDir => {
                out.pop();
            }
            Component::Normal(p) => out.push(p),
            _ => {}
        }
    }
    Some(out)
}

/// The documents whose links are checked: README.md, ARCHITECTURE.md and docs/*.md.
fn documents(files: &BTreeSet<PathBuf>) -> Vec<PathBuf> {
    files
        .iter()
        .filter(|f| {
            let top = f.components().count() == 1;
            let name = f.to_string_lossy();
            (top && (name == "README.md" || name == "ARCHITECTURE.md"))
                || (f.parent() == Some(Path::new("docs")) && name.ends_with(".md"))
        })
        .cloned()
        .collect()
}

/// Whether `path` is neither a tracked file nor a folder holding one.
fn untracked(path: &Path, files: &BTreeSet<PathBuf>) -> bool {
    !files.contains(path) && !files.iter().any(|f| f.starts_with(path))
}

/// `doc:line: target` for every link of `docs` that names nothing tracked.
fn broken_links(docs: &[PathBuf], files: &BTreeSet<PathBuf>) -> Vec<String> {
    let mut broken = Vec::new();
    for doc in docs {
        let text = std::fs::read_to_string(repo().join(doc))
            .unwrap_or_else(|e| panic!("{}: {e}", doc.display()));
        for (line, target) in link_targets(&text) {
            let Some(path) = resolve(doc, &target) else { continue };
            if untracked(&path, files) {
                broken.push(format!("{}:{line}: {target}", doc.display()));
            }
        }
    }
    broken
}

#[test]
fn every_link_and_image_in_the_docs_names_a_tracked_file() {
    let Some(files) = tracked("every_link_and_image_in_the_docs_names_a_tracked_file") else {
        return;
    };
    let docs = documents(&files);
    assert!(docs.len() >= 3, "README.md, ARCHITECTURE.md and docs/ expected, found {docs:?}");
    let broken = broken_links(&docs, &files);
    assert!(broken.is_empty(), "links to files not in the repository:\n{}", broken.join("\n"));
}

#[test]
fn a_link_to_a_missing_or_untracked_file_is_found() {
    let files: BTreeSet<PathBuf> =
        ["README.md", "docs/a.md", "docs/images/window.png", "deploy/slurm/x.sbatch"]
            .into_iter()
            .map(PathBuf::from)
            .collect();
    let text = "![shot](images/window.png) [up](../README.md#try-it) [slurm](../deploy/slurm)\n\
                [web](https://example.org) [here](#top) `[code](nowhere.md)`\n\
                ![gone](images/gone.png) [untracked](b.md \"a title\")\n";
    let doc = Path::new("docs/a.md");
    let targets = link_targets(text);
    assert_eq!(targets.len(), 7, "{targets:?}");
    let broken: Vec<String> = targets
        .iter()
        .filter(|(_, t)| resolve(doc, t).is_some_and(|p| untracked(&p, &files)))
        .map(|(line, t)| format!("{line}: {t}"))
        .collect();
    assert_eq!(broken, ["3: images/gone.png", "3: b.md \"a title\""]);
}

#[test]
fn nothing_tracked_cites_the_design_document_or_paper_outside_the_repository() {
    let Some(files) =
        tracked("nothing_tracked_cites_the_design_document_or_paper_outside_the_repository")
    else {
        return;
    };
    // Built here so that this file does not cite them itself.
    let (shared, design) = ("../".to_string() + "shared/", "DESIGN".to_string() + ".md");
    let assets = shared.clone() + "assets";
    let mut found = Vec::new();
    for file in &files {
        let Ok(text) = std::fs::read_to_string(repo().join(file)) else { continue };
        for (n, line) in text.lines().enumerate() {
            let line =
                if file == Path::new(".ci/run") { line.replace(&assets, "") } else { line.into() };
            if line.contains(&shared) || line.contains(&design) {
                found.push(format!("{}:{}: {}", file.display(), n + 1, line.trim()));
            }
        }
    }
    assert!(
        found.is_empty(),
        "cite docs/design.md (or the paper by its title) instead:\n{}",
        found.join("\n")
    );
}
