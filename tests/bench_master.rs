//! `gridlight bench master` as a user runs it: real null-render worker processes on
//! loopback, one JSON line per connection count. Asserts what the lines say (frames
//! assembled, bytes per pixel of RGB9E5 on the wire, the authentication mode), never
//! how fast: speed is the benchmark's to report, not a test's to judge.

use std::process::Command;

use serde_json::Value;

fn bench(extra: &[&str]) -> Vec<Value> {
    let out = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .args(["bench", "master", "--json", "--connections", "1,3", "--seconds", "0.5"])
        .args(extra)
        .env("RUST_LOG", "warn")
        .output()
        .expect("gridlight runs");
    assert!(out.status.success(), "bench master failed: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .expect("UTF-8 output")
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON ({e}): {l}")))
        .collect()
}

fn check(lines: &[Value], authenticated: bool) {
    let connections: Vec<u64> = lines.iter().map(|l| l["connections"].as_u64().unwrap()).collect();
    assert_eq!(connections, [1, 3]);
    for l in lines {
        assert!(l["frames"].as_u64().unwrap() > 0, "no frame assembled: {l}");
        assert!(l["frames_per_second"].as_f64().unwrap() > 0.0, "{l}");
        assert!(l["master_cpu_us_per_job"].as_f64().unwrap() > 0.0, "{l}");
        // 4 bytes of RGB9E5 per pixel, plus framing, tags and the jobs going out.
        let bpp = l["bytes_per_pixel"].as_f64().unwrap();
        assert!((4.0..4.2).contains(&bpp), "bytes per pixel {bpp}: {l}");
        assert_eq!(l["authenticated"].as_bool(), Some(authenticated), "{l}");
        assert_eq!(
            (l["width"].as_u64(), l["height"].as_u64(), l["sets"].as_u64()),
            (Some(640), Some(480), Some(64))
        );
    }
}

#[test]
fn open_workers_assemble_frames() {
    check(&bench(&[]), false);
}

#[test]
fn authenticated_workers_assemble_frames() {
    check(&bench(&["--secret"]), true);
}
