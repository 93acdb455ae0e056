//! Criterion benchmark of the render kernel: one job of the built-in Cornell box (a
//! quasi-random pixel set of a 640×480 frame split into 64 sets, 4 spp, max depth 5) on
//! one thread, as a worker renders it. `gridlight bench trace` measures whole frames.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use gridlight::render::{render_pixels, testscenes, RenderScene};
use gridlight_actors::protocol::{Partition, SetsConfig};
use gridlight_actors::sets::SetTable;

fn kernel(c: &mut Criterion) {
    let (assets, state) = testscenes::cornell_box(640, 480);
    let scene = RenderScene::new(assets, &state).expect("the Cornell box builds");
    let sets =
        SetTable::new(state.resolution, SetsConfig { sets: 64, partition: Partition::QuasiRandom })
            .expect("64 sets");
    let pixels = sets.pixels(0).expect("set 0").to_vec();
    let mut out = Vec::with_capacity(pixels.len());
    let mut group = c.benchmark_group("kernel");
    group.throughput(Throughput::Elements(pixels.len() as u64 * u64::from(state.render.spp)));
    let mut frame = 0;
    group.bench_function("cornell_box_one_job", |b| {
        b.iter(|| {
            frame += 1;
            render_pixels(&scene, frame, &pixels, &mut out);
            out.len()
        })
    });
    group.finish();
}

criterion_group!(benches, kernel);
criterion_main!(benches);
