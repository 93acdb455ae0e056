//! Our LDR-FLIP (`tools::eval::flip`) against NVIDIA's reference implementation.
//!
//! The fixtures in `tests/fixtures/flip/` are small 8-bit sRGB image pairs and the FLIP
//! maps and means that `flip-evaluator` 1.7 (NVIDIA's Python package) computed for them
//! at 67 pixels per degree; `scripts/flip_fixtures.py` made them. Tolerances: the mean
//! within 1e-3; per pixel, every value within 0.02 and 99 % within 0.005 (the reference
//! filters in float32 with its own kernel sizes at the borders).

use std::path::{Path, PathBuf};

use glam::Vec3;
use gridlight::tools::eval::flip::flip;
use serde_json::Value;

const MEAN_TOLERANCE: f64 = 1e-3;
const PIXEL_MAX: f64 = 0.02;
const PIXEL_TYPICAL: f64 = 0.005;
const TYPICAL_SHARE: f64 = 0.99;

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flip")
}

fn load(path: &Path) -> (Vec<Vec3>, usize, usize) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    let px =
        img.pixels().map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32) / 255.0).collect();
    (px, w as usize, h as usize)
}

#[test]
fn our_flip_matches_nvidias_on_every_fixture() {
    let index: Vec<String> = serde_json::from_str(
        &std::fs::read_to_string(dir().join("index.json")).expect("index.json"),
    )
    .expect("index is a list");
    assert!(index.len() >= 4, "fixtures missing");
    for name in index {
        let want: Value = serde_json::from_str(
            &std::fs::read_to_string(dir().join(format!("{name}.json"))).expect("fixture json"),
        )
        .expect("fixture is JSON");
        let (r, w, h) = load(&dir().join(format!("{name}-reference.png")));
        let (t, w2, h2) = load(&dir().join(format!("{name}-test.png")));
        assert_eq!((w, h), (w2, h2));
        assert_eq!(want["width"].as_u64(), Some(w as u64));
        let got = flip(&r, &t, w, h, want["ppd"].as_f64().expect("ppd") as f32);
        let mean = want["mean"].as_f64().expect("mean");
        let map: Vec<f64> =
            want["map"].as_array().expect("map").iter().filter_map(Value::as_f64).collect();
        assert_eq!(map.len(), w * h);
        let diffs: Vec<f64> =
            got.map.iter().zip(&map).map(|(a, b)| (f64::from(*a) - b).abs()).collect();
        let worst = diffs.iter().copied().fold(0.0, f64::max);
        let typical =
            diffs.iter().filter(|d| **d <= PIXEL_TYPICAL).count() as f64 / diffs.len() as f64;
        println!(
            "{name}: mean ours {:.6} NVIDIA {mean:.6} (Δ {:.2e}); per pixel worst Δ {worst:.4}, {:.1} % within {PIXEL_TYPICAL}",
            got.mean,
            (got.mean - mean).abs(),
            typical * 100.0
        );
        assert!(
            (got.mean - mean).abs() <= MEAN_TOLERANCE,
            "{name}: mean {} vs NVIDIA's {mean}",
            got.mean
        );
        assert!(worst <= PIXEL_MAX, "{name}: a pixel differs by {worst}");
        assert!(
            typical >= TYPICAL_SHARE,
            "{name}: only {:.1} % of pixels within {PIXEL_TYPICAL}",
            typical * 100.0
        );
    }
}
