//! Criterion benchmarks of the master's per-result and per-frame work that
//! `gridlight bench master` measures end to end: checking a result's checksum (once per
//! result, on the actor thread), decoding its words off the wire, an encrypted
//! channel's result sealed, opened and decoded, and unpacking a
//! shown frame (once per frame, on the sink thread). 640×480, S = 64, as the benchmark.

use std::sync::Arc;

use bytes::BytesMut;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use gridlight_actors::channel::Psk;
use gridlight_actors::channel_codec::loopback_pair;
use gridlight_actors::codec::{MasterCodec, WorkerCodec};
use gridlight_actors::integrity::ResultKey;
use gridlight_actors::packed_frame::PackedFrame;
use gridlight_actors::packing::encode_rgb9e5;
use gridlight_actors::protocol::{PackedRadiance, Partition, SetsConfig, WorkerMsg};
use gridlight_actors::sets::SetTable;
use gridlight_actors::state::Resolution;
use tokio_util::codec::{Decoder, Encoder};

const RES: Resolution = Resolution { width: 640, height: 480 };
const SETS: u32 = 64;

fn table() -> Arc<SetTable> {
    Arc::new(
        SetTable::new(RES, SetsConfig { sets: SETS, partition: Partition::QuasiRandom })
            .expect("64 sets of 640×480"),
    )
}

/// Words that vary per pixel, over many exponents.
fn words(set: u32, len: usize) -> Vec<u32> {
    (0..len)
        .map(|k| encode_rgb9e5(Vec3::new(k as f32 * 0.01, set as f32, 0.5 + k as f32)))
        .collect()
}

fn unpack(c: &mut Criterion) {
    let sets = table();
    let mut frame = PackedFrame::new(sets.clone());
    for s in 0..SETS {
        frame.insert(s, words(s, sets.set_len(s)));
    }
    let mut group = c.benchmark_group("frame");
    group.throughput(Throughput::Elements(RES.pixels() as u64));
    group.bench_function("unpack_640x480_complete", |b| b.iter(|| frame.unpack().0.len()));
    group.finish();
}

fn result(c: &mut Criterion) {
    let sets = table();
    let len = sets.set_len(0);
    let radiance = PackedRadiance::Rgb9e5(words(0, len));
    let mut group = c.benchmark_group("result");
    group.throughput(Throughput::Bytes(len as u64 * 4));
    let key = ResultKey::checksum(&[7; 32]);
    let r = key.seal(3, 0, 1, radiance.clone(), 0);
    group.bench_function("verify_checksum", |b| b.iter(|| key.verify(&r)));
    let mut wire = BytesMut::new();
    WorkerCodec::new().encode(WorkerMsg::Result(r), &mut wire).expect("encode");
    group.bench_function("decode", |b| {
        b.iter(|| MasterCodec::new().decode(&mut wire.clone()).expect("decode").is_some())
    });
    // An encrypted channel's result: sealed (the worker's cost) and opened and decoded
    // (the master's), one after the other; record nonces advance, so each is fresh.
    let (mut worker, mut master) = loopback_pair(&Psk::derive(b"secret")).expect("handshake");
    let sealed = WorkerMsg::Result(ResultKey::Channel.seal(3, 0, 1, radiance, 0));
    group.bench_function("channel_seal_open_decode", |b| {
        b.iter(|| {
            let mut wire = BytesMut::new();
            worker.encode(&sealed, &mut wire).expect("seal");
            master.decode(&mut wire).expect("open").is_some()
        })
    });
    group.finish();
}

criterion_group!(benches, unpack, result);
criterion_main!(benches);
