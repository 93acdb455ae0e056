//! Our LDR-FLIP (`tools::eval::flip`) against NVIDIA's reference implementation.
//!
//! The fixtures in `tests/fixtures/flip/` are small 8-bit sRGB image pairs and the FLIP
//! maps and means that `flip-evaluator` 1.7 (NVIDIA's Python package) computed for them
//! at 67 pixels per degree; `scripts/flip_fixtures.py` made them. Tolerances: the mean
//! within 1e-3 and every pixel within 1e-3 (measured: means agree to 1e-6, pixels to
//! 1e-4; both filter in float32, in different orders). Until the borders were clamped as
//! the reference clamps them (they were mirrored), means differed by up to 5e-3 and
//! pixels by 0.09.

use std::path::{Path, PathBuf};

use glam::Vec3;
use gridlight::tools::eval::flip::flip;
use gridlight::tools::eval::hdr_flip::hdr_flip;
use serde_json::Value;

const MEAN_TOLERANCE: f64 = 1e-3;
const PIXEL_MAX: f64 = 1e-3;

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
        println!(
            "{name}: mean ours {:.6} NVIDIA {mean:.6} (Δ {:.2e}); per pixel worst Δ {worst:.2e}",
            got.mean,
            (got.mean - mean).abs(),
        );
        assert!(
            (got.mean - mean).abs() <= MEAN_TOLERANCE,
            "{name}: mean {} vs NVIDIA's {mean}",
            got.mean
        );
        assert!(worst <= PIXEL_MAX, "{name}: a pixel differs by {worst}");
    }
}

/// HDR-FLIP's fixtures (`tests/fixtures/flip-hdr/`, from the same script): linear image
/// pairs with a range of 50:1 and more, their maps, means and the exposures the reference
/// chose. Same tolerances as LDR; the exposure range within 1e-4 stops.
#[test]
fn our_hdr_flip_matches_nvidias_on_every_fixture() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/flip-hdr");
    let index: Vec<String> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("index.json")).expect("index.json"))
            .expect("index is a list");
    assert!(index.len() >= 3, "fixtures missing");
    let floats = |v: &Value, key: &str| -> Vec<f64> {
        v[key].as_array().expect(key).iter().filter_map(Value::as_f64).collect()
    };
    for name in index {
        let want: Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(format!("{name}.json"))).expect("fixture json"),
        )
        .expect("fixture is JSON");
        let (w, h) = (
            want["width"].as_u64().expect("w") as usize,
            want["height"].as_u64().expect("h") as usize,
        );
        let image = |key: &str| -> Vec<Vec3> {
            floats(&want, key)
                .chunks(3)
                .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                .collect()
        };
        let (r, t) = (image("reference"), image("test"));
        assert_eq!(r.len(), w * h);
        let got = hdr_flip(&r, &t, w, h, want["ppd"].as_f64().expect("ppd") as f32);
        let start = want["start_exposure"].as_f64().expect("start");
        let stop = want["stop_exposure"].as_f64().expect("stop");
        assert!((f64::from(got.exposures.start) - start).abs() < 1e-4, "{name}: start {got:?}");
        assert!((f64::from(got.exposures.stop) - stop).abs() < 1e-4, "{name}: stop");
        assert_eq!(u64::from(got.exposures.count), want["exposures"].as_u64().expect("count"));
        let mean = want["mean"].as_f64().expect("mean");
        let map = floats(&want, "map");
        let worst =
            got.map.iter().zip(&map).map(|(a, b)| (f64::from(*a) - b).abs()).fold(0.0, f64::max);
        println!(
            "{name} (HDR): mean ours {:.6} NVIDIA {mean:.6} (Δ {:.2e}); per pixel worst Δ {worst:.2e}",
            got.mean,
            (got.mean - mean).abs(),
        );
        assert!((got.mean - mean).abs() <= MEAN_TOLERANCE, "{name}: mean {} vs {mean}", got.mean);
        assert!(worst <= PIXEL_MAX, "{name}: a pixel differs by {worst}");
    }
}
