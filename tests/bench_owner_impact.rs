//! `gridlight bench owner-impact` as a user runs it, shortened: a real master, a real
//! worker process rendering the Cornell box, the owner's busy loop alone and beside it.
//! Asserts what the JSON says (one ratio per pair of runs, throughputs measured, the
//! worker rendering), never how large the ratio is: that is the benchmark's to report.

use std::process::Command;

use serde_json::Value;

#[test]
fn one_pair_of_runs_gives_a_ratio_and_the_worker_renders() {
    let out = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["bench", "owner-impact", "--json", "--runs", "1", "--seconds", "0.5"])
        // Normal priority and one thread each: the worker must warm up even while the
        // rest of the suite keeps this machine's CPUs busy.
        .args(["--priority", "normal", "--worker-threads", "1", "--busy-threads", "1"])
        .env("RUST_LOG", "warn")
        .output()
        .expect("gridlight runs");
    assert!(out.status.success(), "bench failed: {}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let list = |k: &str| -> Vec<f64> {
        v[k].as_array()
            .unwrap_or_else(|| panic!("`{k}` missing: {v}"))
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (alone, beside, ratios) =
        (list("alone_iterations_per_second"), list("beside_iterations_per_second"), list("ratios"));
    assert_eq!((alone.len(), beside.len(), ratios.len()), (1, 1, 1), "{v}");
    assert!(alone[0] > 0.0 && beside[0] > 0.0, "{v}");
    assert!((ratios[0] - beside[0] / alone[0]).abs() < 1e-9, "{v}");
    assert_eq!(v["median_ratio"].as_f64(), Some(ratios[0]));
    assert_eq!(v["priority"], "normal");
    assert!(list("worker_jobs_per_second_beside")[0] >= 0.0, "{v}");
}
