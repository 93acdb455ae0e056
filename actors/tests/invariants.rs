//! ARCHITECTURE.md's invariants about the actors crate, each as a test that fails when
//! the invariant breaks: "`gridlight-actors` never depends on the renderer", "pixel
//! indices never travel" and "the actor thread does no pixel work".

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Sender};
use std::sync::Arc;
use std::time::Duration;

use common::*;
use gridlight_actors::asset_store::AssetStore;
use gridlight_actors::codec::to_frame;
use gridlight_actors::edit::{CameraEdit, Edit};
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::master::{start, ShownFrame, SinkError};
use gridlight_actors::protocol::{MasterMsg, PackedRadiance, WorkerMsg};
use gridlight_actors::sink::{FrameSink, Preparer};

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
    let job = |set| {
        to_frame(&MasterMsg::Job { frame: 1, set, state_version: 1, spp: 4 }).expect("job").len()
    };
    assert_eq!(job(0), job(1));
    // A result carries one packed radiance word per pixel of its set and nothing per
    // pixel besides: n more pixels cost 4·n bytes, give or take the length header.
    let key = ResultKey::checksum(&[7; 32]);
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

/// Tells the test on which thread each unpacked frame arrives, and on which thread the
/// actors tell it about a new scene state (the control: that one is the actor thread).
struct ThreadProbe(Sender<(&'static str, String)>);

fn thread_name() -> String {
    std::thread::current().name().unwrap_or("unnamed").to_owned()
}

impl FrameSink for ThreadProbe {
    fn show(&mut self, frame: ShownFrame) -> Result<(), SinkError> {
        assert_eq!(frame.current.len(), (W * H) as usize, "the sink gets unpacked pixels");
        self.0.send(("show", thread_name())).map_err(|_| SinkError::Closed)
    }

    fn preparer(&mut self) -> Option<Preparer> {
        let tx = self.0.clone();
        Some(Box::new(move |_| {
            let _ = tx.send(("prepare", thread_name()));
        }))
    }
}

#[test]
fn the_actor_thread_does_no_pixel_work() {
    // Dynamically: frames reach the sink unpacked on the sink thread, never on the
    // actors' thread (which the preparer, called by the presenter, runs on).
    let (tx, rx) = channel();
    let m = start(config(), scene(), AssetStore::new(), Box::new(ThreadProbe(tx))).expect("start");
    let stop = Arc::new(AtomicBool::new(false));
    let worker = {
        let (addr, stop) = (m.local_addr(), stop.clone());
        std::thread::spawn(move || {
            let table = table();
            let mut p = Peer::connect(addr);
            p.handshake(None).expect("handshake");
            p.send(&WorkerMsg::Ready { credits: 2 });
            while !stop.load(Ordering::Relaxed) {
                let Ok((frame, set, version, _)) = p.next_job() else { break };
                if !p.answer(&table, frame, set, version, frame_value(frame))
                    || !p.try_send(&WorkerMsg::Ready { credits: 1 })
                {
                    break;
                }
            }
        })
    };
    assert!(m.wait_for_frames(2, Duration::from_secs(20)), "no frames");
    let moved = Edit::Camera(CameraEdit { look_at: Some(glam::Vec3::X), ..Default::default() });
    m.edit(moved).expect("edit");
    let seen = m.report().shown;
    assert!(m.wait_for_frames(seen + 2, Duration::from_secs(20)), "no frames after the edit");
    stop.store(true, Ordering::Relaxed);
    drop(m);
    let _ = worker.join();
    let calls: Vec<_> = rx.try_iter().collect();
    let on = |what| calls.iter().filter(move |(w, _)| *w == what).map(|(_, t)| t.as_str());
    assert!(
        on("prepare").count() >= 1 && on("prepare").all(|t| t == "gridlight-master"),
        "{calls:?}"
    );
    assert!(on("show").count() >= 4 && on("show").all(|t| t == "gridlight-sink"), "{calls:?}");

    // Statically: outside their tests, only the sink thread's loop (`presenter/sink.rs`)
    // unpacks a frame, and no actor decodes a result's pixels (`packing::unpack`).
    let src = concat!(env!("CARGO_MANIFEST_DIR"), "/src");
    let mut unpackers = Vec::new();
    let mut dirs = vec![std::path::PathBuf::from(src)];
    while let Some(dir) = dirs.pop() {
        for path in std::fs::read_dir(&dir).expect("src").flatten().map(|e| e.path()) {
            if path.is_dir() {
                dirs.push(path);
                continue;
            }
            let text = std::fs::read_to_string(&path).expect("source");
            let code = text.split("#[cfg(test)]").next().unwrap_or_default();
            if code.contains(".unpack(") || code.contains("packing::unpack") {
                unpackers.push(path.strip_prefix(src).expect("under src").display().to_string());
            }
        }
    }
    assert_eq!(unpackers, ["presenter/sink.rs"]);
}
