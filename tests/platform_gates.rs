//! Every use of `libc` is compiled on Unix only, so that the binary (and the test suite)
//! builds for the desks most offices have, Windows included: `libc` is a
//! `[target.'cfg(unix)'.dependencies]` dependency, and no other target's standard library
//! is installed here to prove it by building, so it is proved on the sources.
//!
//! How a use is judged: comments, strings and character literals are blanked, then every
//! word `libc` must lie inside an item, block, statement or field that a `#[cfg(...)]`
//! (or a `#![cfg(...)]` of its module or file) switches off on Windows, or in a file whose
//! `mod` declarations are all so switched off. A predicate is evaluated for Windows with
//! three values: `unix`, `target_family = "unix"`, a `target_os` other than `"windows"` and
//! `target_vendor = "apple"` are false; `windows` and their Windows values true; anything
//! else (`test`, `target_arch`, features) unknown; `all`, `any` and `not` combine them.
//! A use is gated only where the predicate is false; `cfg!(...)` in an `if` does not gate
//! (both branches compile). An attribute covers what follows up to the `;` or `,` ending
//! it (a comma inside angle brackets is a generic argument's), or the `}` closing the
//! block it opens.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A `cfg` predicate's value on Windows: known true, known false, or unknown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Tri {
    True,
    False,
    Unknown,
}

/// Evaluates one predicate from `s` (leading spaces allowed); returns it and the rest.
fn predicate(s: &str) -> (Tri, &str) {
    let s = s.trim_start();
    let end = s.find(|c: char| !(c.is_alphanumeric() || c == '_')).unwrap_or(s.len());
    let (name, rest) = s.split_at(end);
    let rest = rest.trim_start();
    if let Some(mut list) = rest.strip_prefix('(') {
        let mut values = Vec::new();
        loop {
            list = list.trim_start();
            if let Some(after) = list.strip_prefix(')') {
                list = after;
                break;
            }
            let (v, after) = predicate(list);
            values.push(v);
            list = after.trim_start().strip_prefix(',').unwrap_or(after);
        }
        let has = |t| values.contains(&t);
        let value = match name {
            "cfg" | "all" if has(Tri::False) => Tri::False,
            "cfg" | "all" if values.iter().all(|&v| v == Tri::True) => Tri::True,
            "any" if has(Tri::True) => Tri::True,
            "any" if values.iter().all(|&v| v == Tri::False) => Tri::False,
            "not" => match values.first() {
                Some(Tri::True) => Tri::False,
                Some(Tri::False) => Tri::True,
                _ => Tri::Unknown,
            },
            _ => Tri::Unknown,
        };
        return (value, list);
    }
    if let Some(after) = rest.strip_prefix('=') {
        let after = after.trim_start().strip_prefix('"').expect("a quoted cfg value");
        let close = after.find('"').expect("a closed cfg value");
        let value = &after[..close];
        let windows = match name {
            "target_os" => Some(value == "windows"),
            "target_family" => Some(value == "windows"),
            "target_vendor" if value == "apple" => Some(false),
            _ => None,
        };
        let tri = windows.map_or(Tri::Unknown, |w| if w { Tri::True } else { Tri::False });
        return (tri, &after[close + 1..]);
    }
    let tri = match name {
        "unix" => Tri::False,
        "windows" => Tri::True,
        _ => Tri::Unknown,
    };
    (tri, rest)
}

/// Whether the attribute text (inside `#[...]`) is a `cfg` that is false on Windows.
fn off_on_windows(attribute: &str) -> bool {
    let a = attribute.trim();
    a.strip_prefix("cfg").is_some_and(|r| r.trim_start().starts_with('('))
        && predicate(a).0 == Tri::False
}

/// `text` with comments, strings and character literals replaced by spaces (line breaks
/// kept, so that line numbers stay).
fn blank(text: &str) -> String {
    let c: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < c.len() {
        let start = i;
        if c[i] == '/' && c.get(i + 1) == Some(&'/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if c[i] == '/' && c.get(i + 1) == Some(&'*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if c[i] == 'r'
            && matches!(c.get(i + 1), Some('"') | Some('#'))
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
        {
            let hashes = c[i + 1..].iter().take_while(|&&ch| ch == '#').count();
            if c.get(i + 1 + hashes) != Some(&'"') {
                out.push(c[i]);
                i += 1;
                continue;
            }
            i += 2 + hashes;
            while i < c.len() && !(c[i] == '"' && c[i + 1..].iter().take(hashes).all(|&h| h == '#'))
            {
                i += 1;
            }
            i = (i + 1 + hashes).min(c.len());
        } else if c[i] == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i = (i + 1).min(c.len());
        } else if c[i] == '\'' && (c.get(i + 1) == Some(&'\\') || c.get(i + 2) == Some(&'\'')) {
            i += 1;
            while i < c.len() && c[i] != '\'' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i = (i + 1).min(c.len());
        } else {
            out.push(c[i]);
            i += 1;
            continue;
        }
        out.extend(c[start..i.min(c.len())].iter().map(|&ch| if ch == '\n' { '\n' } else { ' ' }));
    }
    out
}

/// What scanning one file found: its unguarded `libc` lines (1-based), and the modules
/// it declares with `mod NAME;`, each with whether the declaration is switched off on
/// Windows.
#[derive(Debug, Default, PartialEq)]
struct Scan {
    unguarded: Vec<usize>,
    modules: Vec<(String, bool)>,
}

/// Scans one file's text; `gated` says the whole file is off on Windows already.
fn scan(text: &str, gated: bool) -> Scan {
    let c: Vec<char> = blank(text).chars().collect();
    // `blank` keeps every character's place: attributes are read from the original text.
    let original: Vec<char> = text.chars().collect();
    let word_at = |i: usize, w: &str| {
        let n = w.chars().count();
        c.len() >= i + n
            && c[i..i + n].iter().copied().eq(w.chars())
            && (i == 0 || !(c[i - 1].is_alphanumeric() || c[i - 1] == '_'))
            && c.get(i + n).is_none_or(|&ch| !(ch.is_alphanumeric() || ch == '_'))
    };
    // Per open brace, parenthesis or bracket: (everything in it is off on Windows, an
    // attribute switched the next statement or field in it off, open angle brackets).
    let mut frames: Vec<(bool, bool, i32)> = vec![(gated, false, 0)];
    let mut out = Scan::default();
    let (mut i, mut line) = (0, 1);
    while i < c.len() {
        let top = *frames.last().expect("a frame");
        let here = top.0 || top.1;
        match c[i] {
            '\n' => line += 1,
            '#' => {
                let inner = c.get(i + 1) == Some(&'!');
                let open = i + 1 + usize::from(inner);
                if c.get(open) == Some(&'[') {
                    let (mut depth, mut j) = (0, open);
                    while j < c.len() {
                        depth += match c[j] {
                            '[' => 1,
                            ']' => -1,
                            _ => 0,
                        };
                        if depth == 0 {
                            break;
                        }
                        j += 1;
                    }
                    let attribute: String = original[open + 1..j.min(c.len())].iter().collect();
                    line += attribute.matches('\n').count();
                    if off_on_windows(&attribute) {
                        let frame = frames.last_mut().expect("a frame");
                        if inner {
                            frame.0 = true;
                        } else {
                            frame.1 = true;
                        }
                    }
                    i = j + 1;
                    continue;
                }
            }
            '{' | '(' | '[' => frames.push((here, false, 0)),
            '}' | ')' | ']' => {
                frames.pop();
                if frames.is_empty() {
                    frames.push((gated, false, 0));
                }
                if c[i] == '}' {
                    frames.last_mut().expect("a frame").1 = false;
                }
            }
            // A comma ends a field or an arm, not a generic argument (`Result<T, E>`).
            ',' if top.2 == 0 => frames.last_mut().expect("a frame").1 = false,
            ';' => {
                let frame = frames.last_mut().expect("a frame");
                (frame.1, frame.2) = (false, 0);
            }
            '<' if c.get(i + 1) != Some(&'=') => frames.last_mut().expect("a frame").2 += 1,
            '>' if i > 0 && !matches!(c[i - 1], '-' | '=') && c.get(i + 1) != Some(&'=') => {
                let frame = frames.last_mut().expect("a frame");
                frame.2 = (frame.2 - 1).max(0);
            }
            _ if word_at(i, "libc") => {
                if !here {
                    out.unguarded.push(line);
                }
                i += 4;
                continue;
            }
            _ if word_at(i, "mod") => {
                let rest: String = c[i + 3..].iter().take(200).collect();
                let name: String = rest
                    .trim_start()
                    .chars()
                    .take_while(|&ch| ch.is_alphanumeric() || ch == '_')
                    .collect();
                let after = rest.trim_start()[name.len()..].trim_start();
                if !name.is_empty() && after.starts_with(';') {
                    out.modules.push((name, here));
                }
            }
            _ => {}
        }
        i += 1;
    }
    out
}

/// Where `mod name;` declared in `file` lives: beside a crate root (`lib.rs`, `main.rs`,
/// a file directly in `tests/` or `benches/`) or `mod.rs`, else in the folder named after
/// the file.
fn module_file(file: &Path, name: &str) -> Option<PathBuf> {
    let stem = file.file_stem()?.to_str()?;
    let dir = file.parent()?;
    let roots = ["tests", "benches", "actors/tests", "actors/benches"].map(|d| repo().join(d));
    let dir = if ["mod", "lib", "main"].contains(&stem) || roots.iter().any(|r| r == dir) {
        dir.to_path_buf()
    } else {
        dir.join(stem)
    };
    [dir.join(format!("{name}.rs")), dir.join(name).join("mod.rs")]
        .into_iter()
        .find(|p| p.is_file())
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("a source folder").flatten() {
        let path = entry.path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Every unguarded `libc` line of the workspace's sources, tests and benches.
fn unguarded_uses() -> Vec<String> {
    let mut files = Vec::new();
    for dir in ["src", "actors/src", "tests", "benches", "actors/tests", "actors/benches"] {
        let dir = repo().join(dir);
        if dir.is_dir() {
            rust_files(&dir, &mut files);
        }
    }
    let texts: BTreeMap<PathBuf, String> = files
        .into_iter()
        .map(|f| {
            let text = std::fs::read_to_string(&f).expect("a readable source");
            (f, text)
        })
        .collect();
    // Which files a switched-off `mod` declaration leaves out on Windows: a file several
    // crates declare (`tests/support/`) only where every declaration is off. Parents
    // before children, so repeat until nothing changes.
    let mut gated: BTreeMap<PathBuf, bool> = texts.keys().map(|f| (f.clone(), false)).collect();
    loop {
        let mut declared: BTreeMap<PathBuf, bool> = BTreeMap::new();
        for (file, text) in &texts {
            for (name, off) in scan(text, gated[file]).modules {
                if let Some(child) = module_file(file, &name) {
                    *declared.entry(child).or_insert(true) &= off || gated[file];
                }
            }
        }
        let mut changed = false;
        for (child, off) in declared {
            if off && !gated.get(&child).copied().unwrap_or(true) {
                gated.insert(child, true);
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    let mut found = Vec::new();
    for (file, text) in &texts {
        for line in scan(text, gated[file]).unguarded {
            let shown = file.strip_prefix(repo()).unwrap_or(file).display().to_string();
            let code = text.lines().nth(line - 1).unwrap_or("").trim();
            found.push(format!("{shown}:{line}: {code}"));
        }
    }
    found
}

#[test]
fn every_libc_use_is_compiled_on_unix_only() {
    let found = unguarded_uses();
    assert!(
        found.is_empty(),
        "libc used outside a cfg(unix) or cfg(target_os = ...) item (gate it, with a \
         portable fallback or an error that names the platform):\n{}",
        found.join("\n")
    );
}

#[test]
fn the_scanner_tells_gated_from_unguarded_uses() {
    let src = r#"
// libc in a comment, "libc::kill" in a string, '{' a brace in a character.
#[cfg(unix)]
fn a() { unsafe { libc::kill(0, 0) }; }
fn b() { unsafe { libc::kill(0, 0) }; }
#[cfg(not(unix))]
fn c() { libc::abort() }
#[cfg(all(test, unix))]
mod d { fn e() { libc::abort() } }
#[cfg(any(unix, windows))]
fn f() { libc::abort() }
#[cfg(target_os = "linux")]
use libc::c_int;
fn g<'a>(x: &'a str) {
    #[cfg(target_os = "macos")]
    let y = libc::getpid();
    let z = libc::getpid();
    #[cfg(target_arch = "x86_64")]
    {
        libc::abort();
    }
}
#[cfg(unix)]
mod h;
mod i;
#[cfg(unix)]
fn j(a: u32, b: u32) -> Result<u32, u32> { if a < b { Ok(libc::getpid() as u32) } else { Err(b) } }
"#;
    let s = scan(src, false);
    assert_eq!(s.unguarded, vec![5, 7, 11, 17, 20]);
    assert_eq!(s.modules, vec![("h".into(), true), ("i".into(), false)]);
    assert!(scan("#![cfg(unix)]\nfn a() { libc::abort() }\n", false).unguarded.is_empty());
    assert_eq!(scan("fn a() { libc::abort() }\n", true).unguarded, Vec::<usize>::new());
}
