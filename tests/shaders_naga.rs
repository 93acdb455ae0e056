//! Every WGSL file in `shaders/` parses and validates with naga (STYLE.md item 11), on
//! every test run and without a GPU. Compute passes are validated as they are compiled:
//! prefixed with `shaders/common.wgsl`.

use std::path::Path;

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

#[test]
fn every_wgsl_file_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let common = std::fs::read_to_string(dir.join("common.wgsl")).expect("shaders/common.wgsl");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).expect("shaders/ exists") {
        let path = entry.expect("directory entry").path();
        if path.extension().and_then(|e| e.to_str()) != Some("wgsl") {
            continue;
        }
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("?").to_string();
        let source = std::fs::read_to_string(&path).expect("readable shader");
        // Files that declare their own entry point and bindings are standalone (the raster
        // pass); compute passes need the common block.
        if name == "common.wgsl" || source.contains("// standalone") {
            validate(&name, &source);
        } else {
            validate(&name, &format!("{common}\n{source}"));
        }
        checked += 1;
    }
    assert!(checked >= 6, "expected the common block and five passes, found {checked} files");
}

#[test]
fn compiled_in_sources_are_the_files() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    for (name, source) in gridlight::gpu::shaders::PASSES {
        let on_disk = std::fs::read_to_string(dir.join(name)).expect("pass file exists");
        assert_eq!(on_disk, source, "{name}");
    }
}
