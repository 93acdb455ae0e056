//! `gridlight eval paper --quick`: the whole evaluation on simulated grids, as a reviewer
//! runs it. Checks the report's structure (every figure's section with the paper's side,
//! ours and the comparison; plots and images that exist and are PNGs; results.json with
//! every section's numbers) and the claims that do not depend on this machine's load.
//! Claims about rates and efficiencies are measured and reported, not asserted: on a
//! shared 2-core machine they move with everything else running.

use std::process::Command;
use std::time::Instant;

use gridlight::testing::Missing;
use gridlight::tools::lan::{LanError, Testbed};
use serde_json::Value;

const SECTIONS: [(&str, &str); 7] = [
    ("fig3", "## Figure 3"),
    ("fig5", "## Figure 5"),
    ("table1", "## Table 1"),
    ("fig8", "## Figure 8"),
    ("fig9", "## Figure 9"),
    ("fig10", "## Figure 10"),
    ("lan", "## Beyond the paper"),
];

#[test]
fn the_quick_evaluation_writes_a_complete_report_whose_stable_claims_hold() {
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("report");
    let started = Instant::now();
    let run = Command::new(env!("CARGO_BIN_EXE_gridlight"))
        .args(["eval", "paper", "--quick", "--out"])
        .arg(&out)
        .output()
        .expect("running gridlight eval paper");
    let stdout = String::from_utf8_lossy(&run.stdout);
    println!("{stdout}\n(took {:.0} s)", started.elapsed().as_secs_f64());
    assert!(run.status.success(), "eval paper failed: {}", String::from_utf8_lossy(&run.stderr));

    let md = std::fs::read_to_string(out.join("report.md")).expect("report.md");
    let html = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    for (_, heading) in SECTIONS {
        assert!(md.contains(heading), "report.md lacks `{heading}`");
        assert!(html.contains(&format!("<h2>{}", &heading[3..])), "index.html lacks `{heading}`");
    }
    for part in [
        "## What is real and what is modelled",
        "## Closing note",
        "Figure 10 efficiencies",
        "Figure 5: correlation",
        "Table 1 (paper: Cornell Box 6.66",
    ] {
        assert!(md.contains(part), "report.md lacks `{part}`");
    }
    assert_eq!(md.matches("### The paper").count(), SECTIONS.len());
    assert_eq!(md.matches("### Agreement").count(), SECTIONS.len());

    let results: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("results.json")).expect("results.json"),
    )
    .expect("results.json is JSON");
    let sections = results["sections"].as_array().expect("sections");
    let ids: Vec<&str> = sections.iter().filter_map(|s| s["id"].as_str()).collect();
    assert_eq!(ids, SECTIONS.map(|(id, _)| id));
    for s in sections {
        let claims = s["claims"].as_array().expect("claims");
        assert!(!claims.is_empty(), "{} states no claim", s["id"]);
        for file in s["plots"]
            .as_array()
            .into_iter()
            .flatten()
            .chain(s["images"].as_array().into_iter().flatten().filter_map(|pair| pair.get(1)))
        {
            let name = file.as_str().expect("a file name");
            let img = image::open(out.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(img.width() > 0 && img.height() > 0);
            assert!(md.contains(&format!("({name})")), "report.md does not show {name}");
        }
    }
    let section = |id: &str| sections.iter().find(|s| s["id"] == id).expect(id);
    let claim = |id: &str, i: usize| section(id)["claims"][i]["holds"].as_bool().expect("holds");

    // Figure 3: the partition's effect is large and deterministic.
    assert!(claim("fig3", 0), "tiles should lose more than quasi-random sets at every loss");
    assert_eq!(section("fig3")["images"].as_array().map(Vec::len), Some(1 + 3 * 4));
    // Figure 9: deterministic offline reconstruction.
    assert!(claim("fig9", 0), "spatio-temporal should be closer to the converged image");

    // Grid experiments measured real runs: frames shown and useful fractions in range.
    let rows = section("fig10")["data"]["rows"].as_array().expect("fig10 rows");
    assert_eq!(rows.len(), 2 * 4, "paper's and this machine's cores at 8, 32, 128, 256");
    for r in rows {
        let e = r["efficiency"].as_f64().expect("efficiency");
        let u = r["useful_fraction"].as_f64().expect("useful fraction");
        assert!(e > 0.0 && e < 1.2, "efficiency {e} out of range: {r}");
        assert!((0.0..=1.0).contains(&u), "useful fraction {u}: {r}");
    }
    let t1 = section("table1")["data"]["rows"].as_array().expect("table1 rows");
    assert_eq!(t1.len(), 3 * 2, "Cornell box at 32, 96 and variable 96, heuristic and fixed");
    assert!(t1.iter().all(|r| r["frames_per_second"].as_f64() > Some(0.0)));
    let fig5 = &section("fig5")["data"];
    assert!(fig5["frames"].as_array().is_some_and(|f| f.len() > 20), "fig5 showed too few frames");
    let workers: Vec<u64> = fig5["frames"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|f| f["workers"].as_u64())
        .collect();
    let (lo, hi) = (workers.iter().min().copied(), workers.iter().max().copied());
    assert!(hi > lo, "the simulated grid's resources should vary ({lo:?}..{hi:?})");
    let fig8 = section("fig8")["data"]["rows"].as_array().expect("fig8 rows");
    assert!(fig8.iter().all(|r| r["frames"].as_u64() > Some(0)), "every fig8 grid showed frames");
    assert!(
        fig8.iter().all(|r| r["final_hdr_flip"].as_f64().is_some_and(|e| e > 0.0 && e < 1.0)),
        "every fig8 grid has an HDR-FLIP"
    );
    // Figure 5 plays the path twice: as the paper's sequence (every frame with its own
    // camera) and in the interactive default (frames of the current view compared).
    assert!(fig5["path_edits"].as_u64() > Some(10), "the camera path should move: {fig5}");
    let moving = |frames: &Value, current_only: bool| {
        frames
            .as_array()
            .into_iter()
            .flatten()
            .filter(|f| (f["current"] == true || !current_only) && f["version"].as_u64() > Some(1))
            .count()
    };
    let seq = moving(&fig5["frames"], false);
    assert!(seq > 10, "fig5's sequence showed {seq} frames of a moving view");
    let versions: std::collections::BTreeSet<u64> = fig5["frames"]
        .as_array()
        .into_iter()
        .flatten()
        .filter_map(|f| f["version"].as_u64())
        .collect();
    assert!(versions.len() > 10, "fig5's sequence should carry one camera per frame: {versions:?}");
    let int = moving(&fig5["interactive"]["frames"], true);
    assert!(int > 10, "fig5's interactive run showed {int} frames of a moving view");

    // Beyond the paper: loopback always; the links where namespaces can be made (root).
    let lan = &section("lan")["data"];
    let links: Vec<&str> =
        lan["rows"].as_array().into_iter().flatten().filter_map(|r| r["link"].as_str()).collect();
    assert!(links.iter().filter(|l| **l == "loopback").count() >= 2, "lan: {lan}");
    match lan["skipped"].as_str() {
        Some(why) => {
            // The same probe the evaluation ran, for what it lacked: iproute2 (which CI
            // installs) or root and namespaces (which CI cannot promise).
            let missing = match Testbed::unavailable() {
                Some(LanError::MissingTool(_)) => Missing::Tool,
                _ => Missing::System,
            };
            gridlight::testing::skip("eval paper's links", missing, why)
        }
        None => {
            assert!(links.contains(&"100 Mbit/s") && links.contains(&"1000 Mbit/s"), "{lan}");
            assert!(lan["rows"].as_array().into_iter().flatten().all(|r| r["link"] == "loopback"
                || r["master_in_mbit_s"].as_f64().is_some_and(|v| v > 0.0)));
        }
    }
}
