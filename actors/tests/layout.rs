//! The actors crate's layout, checked on the sources (ARCHITECTURE.md, "Code map") so that a
//! stray `crate::` path fails here rather than in a review:
//!
//! - no two top-level modules of `actors/src` name each other (a two-way folder cycle:
//!   neither can be read, tested or moved without the other);
//! - an actor's folder names no other actor's folder: the messages between actors live in
//!   `messages/`, the values several of them share in `shared/`. The one exception is the
//!   listener, which makes connection actors (it is their supervisor).
//!
//! Unit-test modules (from `#[cfg(test)]` on) are not scanned: tests may borrow fixtures.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The folders that hold an actor (in its `mod.rs`) and its pure partners.
const ACTOR_FOLDERS: &[&str] =
    &["listener", "connection", "scheduler", "assembler", "presenter", "scene_holder", "discovery"];

/// (from, to): an actor folder that may name another's, and why.
const ALLOWED: &[(&str, &str, &str)] =
    &[("listener", "connection", "the listener makes and supervises connection actors")];

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

/// The top-level module of `crate::` a source file belongs to (`scheduler` for
/// `src/scheduler/job_queue.rs`, `master` for `src/master.rs`).
fn module_of(src: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(src).expect("under src");
    let first = rel.components().next().expect("a path").as_os_str().to_string_lossy();
    first.trim_end_matches(".rs").to_owned()
}

/// The top-level modules a statement names as `crate::<module>`: a group
/// (`use crate::{a::X, b::{Y, Z}}`) names each of its first-level heads.
fn named_modules(code: &str) -> Vec<String> {
    let mut found = Vec::new();
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        match rest.strip_prefix('{') {
            Some(group) => found.extend(group_heads(group)),
            None => found.push(ident(rest)),
        }
    }
    found.retain(|m| !m.is_empty());
    found
}

/// The first identifier of each item of a `{...}` group at its own level (`group` starts
/// after the opening brace).
fn group_heads(group: &str) -> Vec<String> {
    let (mut heads, mut depth, mut start) = (Vec::new(), 0usize, 0usize);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                heads.push(ident(&group[start..i]));
                break;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                heads.push(ident(&group[start..i]));
                start = i + 1;
            }
            _ => {}
        }
    }
    heads
}

fn ident(s: &str) -> String {
    s.trim_start().chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect()
}

/// For each top-level module, the other top-level modules it names, each with the first
/// line that does (`file:line: text`).
fn graph() -> BTreeMap<String, BTreeMap<String, String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    files.sort();
    let mut graph: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    for file in files {
        let from = module_of(&src, &file);
        let text = std::fs::read_to_string(&file).expect("readable source");
        // A `use crate::{...}` group may span lines: read statements, not lines.
        let mut statement = String::new();
        let mut first_line = 0;
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("#[cfg(test)]") {
                break;
            }
            let code = line.split("//").next().unwrap_or("");
            if statement.is_empty() {
                first_line = n + 1;
            }
            statement.push_str(code.trim());
            let is_use = statement.starts_with("use ") || statement.starts_with("pub use ");
            if is_use && !statement.ends_with(';') {
                continue;
            }
            for to in named_modules(&statement) {
                if to != from {
                    let at = format!("{}:{first_line}: {}", file.display(), statement);
                    graph.entry(from.clone()).or_default().entry(to).or_insert(at);
                }
            }
            statement.clear();
        }
    }
    graph
}

#[test]
fn no_two_modules_name_each_other() {
    let graph = graph();
    let mut cycles = Vec::new();
    for (a, to) in &graph {
        for (b, at) in to {
            let back = graph.get(b).and_then(|m| m.get(a));
            if let (true, Some(back)) = (a < b, back) {
                cycles.push(format!("{a} ⇄ {b}\n  {at}\n  {back}"));
            }
        }
    }
    assert!(cycles.is_empty(), "two-way folder cycles in actors/src:\n{}", cycles.join("\n"));
}

#[test]
fn an_actor_folder_names_no_other_actor_folder() {
    let graph = graph();
    let allowed: BTreeSet<(&str, &str)> = ALLOWED.iter().map(|(a, b, _)| (*a, *b)).collect();
    let mut found = Vec::new();
    for actor in ACTOR_FOLDERS {
        assert!(graph.contains_key(*actor), "no actor folder {actor}/ in actors/src");
        for (to, at) in &graph[*actor] {
            if ACTOR_FOLDERS.contains(&to.as_str()) && !allowed.contains(&(*actor, to.as_str())) {
                found.push(format!("{actor}/ names {to}/: {at}"));
            }
        }
    }
    assert!(
        found.is_empty(),
        "an actor folder imports another's (messages belong in messages/, shared values in \
         shared/):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_scanner_reads_groups_and_paths_in_code() {
    let group = "use crate::{messages::{Kill, Shutdown}, shared::sets::SetTable};";
    assert_eq!(named_modules(group), ["messages", "shared"]);
    assert_eq!(named_modules("pub paused: Vec<crate::shared::workers::PausedWorker>,"), ["shared"]);
    assert!(named_modules("use super::Action;").is_empty());
}
