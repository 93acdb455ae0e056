//! Every WGSL file under `shaders/` (laid out like the Rust that binds it) parses and validates
//! with naga (STYLE.md item 11), on every test run and without a GPU. Reconstruction
//! passes are validated as they are compiled: prefixed with their `common.wgsl`.

use std::path::{Path, PathBuf};

fn validate(name: &str, source: &str) {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name} does not parse:\n{}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::all(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name} does not validate: {e:?}"));
}

/// Every `.wgsl` file below `dir`.
fn wgsl_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("readable directory") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            wgsl_files(&path, out);
        } else if path.extension().and_then(|e| e.to_str()) == Some("wgsl") {
            out.push(path);
        }
    }
}

#[test]
fn every_wgsl_file_validates() {
    let mut files = Vec::new();
    wgsl_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders"), &mut files);
    let common = gridlight::reconstruct::pass::COMMON_WGSL;
    let mut checked = 0;
    for path in &files {
        let name = path.display().to_string();
        let source = std::fs::read_to_string(path).expect("readable shader");
        // Files that declare their own entry point and bindings are standalone (the raster
        // pass, the window's blit); reconstruction passes need the common block.
        if path.parent().is_some_and(|p| p.ends_with("trace")) {
            // The path tracer's files are parts of one module: validated assembled below.
        } else if path.parent().is_some_and(|p| p.ends_with("svgf")) {
            // SVGF's passes follow both common blocks; its own common follows the first.
            if path.file_name().is_some_and(|n| n == "common.wgsl") {
                validate(&name, &format!("{common}\n{source}"));
            } else {
                validate(&name, &gridlight::reconstruct::svgf::gpu::with_common(&source));
            }
        } else if path.file_name().is_some_and(|n| n == "common.wgsl")
            || source.contains("// standalone")
        {
            validate(&name, &source);
        } else {
            validate(&name, &format!("{common}\n{source}"));
        }
        checked += 1;
    }
    validate("shaders/trace (assembled)", gridlight::render::gpu::WGSL);
    // common, five passes, the G-buffer raster pass and the blit.
    assert!(checked >= 8, "expected at least 8 WGSL files, found {checked}: {files:?}");
}

#[test]
fn compiled_in_sources_are_the_files() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/reconstruct");
    for (name, source) in gridlight::reconstruct::pass::WGSL {
        let on_disk = std::fs::read_to_string(dir.join(name)).expect("pass file exists");
        assert_eq!(on_disk, source, "{name}");
    }
    let svgf = dir.join("svgf");
    let common = std::fs::read_to_string(svgf.join("common.wgsl")).expect("svgf common");
    assert_eq!(common, gridlight::reconstruct::svgf::gpu::COMMON_WGSL);
    for (name, source) in gridlight::reconstruct::svgf::gpu::WGSL {
        let on_disk = std::fs::read_to_string(svgf.join(name)).expect("svgf pass file exists");
        assert_eq!(on_disk, source, "svgf/{name}");
    }
}

#[test]
fn the_path_tracer_is_its_files_in_order() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders/trace");
    let files: String = gridlight::render::gpu::WGSL_FILES
        .iter()
        .map(|name| std::fs::read_to_string(dir.join(name)).expect("trace file exists"))
        .collect();
    assert_eq!(files, gridlight::render::gpu::WGSL);
    let on_disk = std::fs::read_dir(&dir).expect("shaders/trace").count();
    assert_eq!(
        on_disk,
        gridlight::render::gpu::WGSL_FILES.len(),
        "a trace file is not compiled in"
    );
}
