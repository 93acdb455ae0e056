//! gridlight across separate network hosts (Linux network namespaces around a bridge, each
//! link rate-limited by `tbf`), not loopback: `gridlight bench lan` run as a user runs it,
//! on links slow enough to be saturated, must show results from every host, the master
//! counting every worker connection, and no link carrying more than its rate; and a testbed
//! must vanish when dropped, even by a panic. Needs root and iproute2; skipped, saying why,
//! elsewhere (failing under `CI=true` where iproute2 is missing).

#![cfg(target_os = "linux")]

use std::process::Command;

use gridlight::testing::Missing;
use gridlight::tools::lan::{LanError, Testbed, TestbedSpec};
use serde_json::Value;

/// Why this machine cannot build testbeds, printed as the test's skip message: a missing
/// `ip` or `tc` fails the test under `CI=true` (`.ci/run` installs iproute2), no root or
/// no right to make namespaces (a container's) does not.
fn skipped(test: &str) -> bool {
    match Testbed::unavailable() {
        Some(why) => {
            let missing = match why {
                LanError::MissingTool(_) => Missing::Tool,
                _ => Missing::System,
            };
            gridlight::testing::skip(test, missing, why);
            true
        }
        None => false,
    }
}

fn namespaces() -> String {
    let out = Command::new("ip").args(["netns", "list"]).output().expect("ip runs");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn bench_lan_gets_frames_from_every_host_within_each_link_rate() {
    if skipped("bench lan across namespace hosts") {
        return;
    }
    // 20 Mbit/s is far below what 2 hosts × 2 connections can fill (about 2 frames per
    // second of bandwidth against 6 of compute), so every link test is a saturated one.
    let (hosts, threads, mbit) = (2u64, 2u64, 20u64);
    let out = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .args([
            "bench",
            "lan",
            "--json",
            "--links",
            &mbit.to_string(),
            "--hosts",
            &hosts.to_string(),
        ])
        .args(["--threads", &threads.to_string(), "--render-ms", "10", "--seconds", "3"])
        .env("RUST_LOG", "warn")
        .output()
        .expect("gridlight runs");
    assert!(out.status.success(), "bench lan failed: {}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<Value> =
        stdout.lines().map(|l| serde_json::from_str(l).expect("JSON")).collect();
    assert_eq!(lines.len(), 1, "{stdout}");
    let r = &lines[0];
    eprintln!("{r}");
    for key in ["link_mbit", "hosts", "frames_per_second", "bytes_per_frame", "bandwidth_bound_fps"]
    {
        assert!(!r[key].is_null(), "no `{key}` in {r}");
    }
    assert_eq!((r["link_mbit"].as_u64(), r["hosts"].as_u64()), (Some(mbit), Some(hosts)));

    // Results came from every host, and the master counted every connection.
    let by_host = r["results_by_host"].as_object().unwrap();
    for h in 0..hosts {
        let n = by_host.get(&format!("host-{h}")).and_then(Value::as_u64).unwrap_or(0);
        assert!(n > 0, "no result from host-{h}: {r}");
    }
    assert_eq!(r["workers"].as_u64(), Some(hosts * threads), "{r}");
    assert!(r["frames"].as_u64().unwrap() > 0, "{r}");

    // No link carried more than its rate (plus one token bucket) in either direction.
    let limit = r["link_limit_bytes_per_second"].as_f64().unwrap();
    assert_eq!(limit, mbit as f64 * 1e6 / 8.0);
    let burst = r["burst_bytes"].as_f64().unwrap();
    let links = r["links"].as_array().unwrap();
    assert_eq!(links.len() as u64, hosts + 1, "the master's link and one per host");
    for link in links {
        let allowed = limit * link["max_seconds"].as_f64().unwrap() + burst;
        for dir in ["rx_bytes", "tx_bytes"] {
            let bytes = link[dir].as_f64().unwrap();
            assert!(bytes <= allowed, "{} {dir}: {bytes} > {allowed} allowed: {r}", link["host"]);
        }
    }
    // Frames cost at least their radiance (RGB9E5, 4 bytes a pixel) on the master's link,
    // and the frame rate cannot beat the bound that bandwidth sets.
    let min_frame = 640.0 * 480.0 * 4.0;
    assert!(r["bytes_in_per_frame"].as_f64().unwrap() >= min_frame, "{r}");
    // One frame of slack: a frame whose bytes arrived before the window may complete in it.
    let (fps, bound) =
        (r["frames_per_second"].as_f64().unwrap(), r["bandwidth_bound_fps"].as_f64().unwrap());
    let seconds = r["seconds"].as_f64().unwrap();
    assert!(
        fps * seconds <= bound * seconds * 1.05 + 1.0,
        "{fps} frames/s beat the bandwidth bound {bound}: {r}"
    );
    // Saturated: the links, not the workers, set the pace.
    assert!(bound < r["compute_bound_fps"].as_f64().unwrap(), "{r}");
}

#[test]
fn a_testbed_is_torn_down_even_when_its_user_panics() {
    if skipped("testbed teardown") {
        return;
    }
    let bed = Testbed::build(TestbedSpec { worker_hosts: 2, link_mbit: 10 }).expect("testbed");
    let names = bed.namespaces().to_vec();
    assert_eq!(names.len(), 4, "switch, master and two hosts: {names:?}");
    let listed = namespaces();
    assert!(names.iter().all(|n| listed.contains(n.as_str())), "{names:?} not in {listed}");
    // Each host's link is up, addressed, and limited in both directions.
    let host = &bed.workers()[1];
    let qdisc = Command::new("tc")
        .args(["-n", &host.namespace, "qdisc", "show", "dev", "eth0"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&qdisc.stdout).contains("tbf"), "no tbf on {}", host.name);
    assert_eq!(host.address.to_string(), "10.77.0.11");

    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(move || {
        let _bed = bed;
        panic!("a test failing half-way");
    }));
    assert!(result.is_err());
    let listed = namespaces();
    for name in &names {
        assert!(!listed.contains(name.as_str()), "{name} left behind: {listed}");
    }
}

#[test]
fn impossible_testbeds_are_refused_before_anything_is_built() {
    for (worker_hosts, link_mbit) in [(0, 100), (241, 100), (2, 0)] {
        let err = Testbed::build(TestbedSpec { worker_hosts, link_mbit }).unwrap_err();
        assert!(err.to_string().starts_with("bad testbed:"), "{err}");
    }
}
