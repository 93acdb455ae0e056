//! ARCHITECTURE.md's invariants about the actors crate, each as a test that fails when
//! the invariant breaks: "`gridlight-actors` never depends on the renderer" and "pixel
//! indices never travel".

use gridlight_actors::codec::to_frame;
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::protocol::{MasterMsg, PackedRadiance, WorkerMsg};

/// Crates that render, open windows or drive a GPU; the actors crate names none of them.
const RENDERER_CRATES: [&str; 8] =
    ["gridlight", "wgpu", "winit", "egui", "egui-wgpu", "obvhs", "tobj", "image"];

#[test]
fn actors_never_depend_on_the_renderer() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/Cargo.toml");
    let text = std::fs::read_to_string(path).expect("actors/Cargo.toml");
    let manifest: toml::Table = text.parse().expect("a TOML manifest");
    let mut names = Vec::new();
    for section in ["dependencies", "dev-dependencies", "build-dependencies"] {
        if let Some(deps) = manifest.get(section).and_then(|d| d.as_table()) {
            names.extend(deps.keys().cloned());
        }
    }
    assert!(names.iter().any(|n| n == "actix"), "the manifest was not read: {names:?}");
    for forbidden in RENDERER_CRATES {
        assert!(!names.iter().any(|n| n == forbidden), "gridlight-actors depends on {forbidden}");
    }
}

#[test]
fn pixel_indices_never_travel() {
    // A job names its set, never its pixels: its size does not depend on the set's.
    let job =
        |set| to_frame(&MasterMsg::Job { frame: 1, set, state_version: 1 }).expect("job").len();
    assert_eq!(job(0), job(1));
    // A result carries one packed radiance word per pixel of its set and nothing per
    // pixel besides: n more pixels cost 4·n bytes, give or take the length header.
    let key = ResultKey::derive(None, &[7; 32]);
    let result = |n: usize| {
        let radiance = PackedRadiance::Rgb9e5(vec![0x1234_5678; n]);
        to_frame(&WorkerMsg::Result(key.seal(1, 0, 1, radiance, 1))).expect("result").len()
    };
    let (small, large) = (result(1000), result(2000));
    let extra = large.abs_diff(small);
    assert!(
        extra.abs_diff(4000) <= 8,
        "1000 more pixels cost {extra} bytes, not 4000: something besides the radiance travels"
    );
}
