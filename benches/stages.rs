//! Criterion benchmarks of the path tracer's stages, one query at a time on one thread as
//! the kernel runs them, so that the next person sees where a frame's time goes:
//!
//! - `closest_camera`: closest hit of camera rays (coherent);
//! - `closest_bounce`: closest hit of cosine-distributed rays leaving the camera rays' hit
//!   points (incoherent, what every later segment of a path traces);
//! - `shadow`: any-hit tests of shadow rays from those points towards a light sample;
//! - `nee`: a whole next-event estimate (light sample, BSDF evaluation, shadow ray);
//! - `bsdf`: BSDF sampling and evaluation per material kind;
//! - `texture`: a bilinear texture lookup;
//! - `sampler`: a sample stream's set-up and the three 4-D draws of one bounce.
//!
//! Scenes: the built-in Cornell box always, the bunny and Sponza when their assets are on
//! the search path (`GRIDLIGHT_ASSETS`). `gridlight bench trace` measures whole frames.

use std::path::Path;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use glam::{Vec2, Vec3};
use gridlight::assets::Texture;
use gridlight::render::bsdf::Bsdf;
use gridlight::render::integrator::offset;
use gridlight::render::microfacet::{cosine_hemisphere, Frame};
use gridlight::render::sampler::SampleStream;
use gridlight::render::{primary_hit, testscenes, RenderScene};
use gridlight::scene::{self, AssetSearchPath};
use gridlight_actors::state::MaterialKind;
use std::hint::black_box;

/// One in this many pixels of the 640×480 frame gives a hit point.
const PIXEL_STRIDE: u32 = 37;

/// A ray as the kernel casts it.
#[derive(Clone, Copy)]
struct Ray {
    o: Vec3,
    d: Vec3,
    tmax: f32,
}

/// A camera ray's surface hit.
#[derive(Clone, Copy)]
struct Point {
    p: Vec3,
    n: Vec3,
}

/// The inputs of every stage for one scene.
struct Workload {
    name: String,
    scene: RenderScene,
    camera: Vec<Ray>,
    points: Vec<Point>,
    bounce: Vec<Ray>,
    shadow: Vec<Ray>,
}

fn workload(name: &str, scene: RenderScene) -> Workload {
    let res = scene.state().resolution;
    let eye = scene.state().camera.position;
    let (mut camera, mut points, mut bounce, mut shadow) = (vec![], vec![], vec![], vec![]);
    for pixel in (0..res.pixels() as u32).step_by(PIXEL_STRIDE as usize) {
        let hit = primary_hit(&scene, pixel);
        if hit.normal == Vec3::ZERO || hit.object == u32::MAX {
            continue;
        }
        camera.push(Ray { o: eye, d: (hit.position - eye).normalize(), tmax: f32::INFINITY });
        let point = Point { p: hit.position, n: hit.normal };
        points.push(point);
        let mut stream = SampleStream::new(1, 0, pixel, 0);
        let u = stream.next4();
        let d = Frame::new(point.n).to_world(cosine_hemisphere(Vec2::new(u[0], u[1])));
        bounce.push(Ray { o: offset(point.p, point.n, d), d, tmax: f32::INFINITY });
        if let Some(ls) = scene.lights().sample(point.p, [u[2], u[3], stream.next4()[0]]) {
            let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-3) } else { f32::INFINITY };
            shadow.push(Ray { o: offset(point.p, point.n, ls.wi), d: ls.wi, tmax });
        }
    }
    Workload { name: name.to_string(), scene, camera, points, bounce, shadow }
}

/// The Cornell box, then the asset scenes found on the search path.
fn workloads() -> Vec<Workload> {
    let (assets, state) = testscenes::cornell_box(640, 480);
    let mut out = vec![workload("cornell-box", RenderScene::new(assets, &state).expect("builds"))];
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for name in ["bunny", "sponza"] {
        let file = dir.join(format!("{name}.toml"));
        let resolver = AssetSearchPath::from_env(&[], Some(&file));
        let Ok(loaded) = scene::load(&file, &resolver) else {
            eprintln!("stages: skipping {name}: its assets are not on the search path");
            continue;
        };
        let mut state = loaded.state;
        state.resolution.width = 640;
        state.resolution.height = 480;
        let scene = RenderScene::new(loaded.assets.into(), &state).expect("scene builds");
        out.push(workload(name, scene));
    }
    out
}

fn traversal(c: &mut Criterion, w: &Workload) {
    let tlas = w.scene.tlas();
    let mut group = c.benchmark_group("traversal");
    for (stage, rays) in [("closest_camera", &w.camera), ("closest_bounce", &w.bounce)] {
        group.throughput(Throughput::Elements(rays.len() as u64));
        group.bench_function(BenchmarkId::new(stage, &w.name), |b| {
            b.iter(|| {
                rays.iter().filter_map(|r| black_box(tlas.intersect(r.o, r.d, r.tmax))).count()
            })
        });
    }
    group.throughput(Throughput::Elements(w.shadow.len() as u64));
    group.bench_function(BenchmarkId::new("shadow", &w.name), |b| {
        b.iter(|| w.shadow.iter().filter(|r| tlas.occluded(r.o, r.d, r.tmax)).count())
    });
    group.finish();
}

fn nee(c: &mut Criterion, w: &Workload) {
    let (tlas, lights) = (w.scene.tlas(), w.scene.lights());
    let bsdf = Bsdf::new(MaterialKind::Diffuse, Vec3::splat(0.5), 1.0, 1.5);
    let mut group = c.benchmark_group("nee");
    group.throughput(Throughput::Elements(w.points.len() as u64));
    group.bench_function(BenchmarkId::new("diffuse", &w.name), |b| {
        b.iter(|| {
            let mut sum = Vec3::ZERO;
            for (i, pt) in w.points.iter().enumerate() {
                let u = SampleStream::new(2, 0, i as u32, 0).next4();
                let Some(ls) = lights.sample(pt.p, [u[0], u[1], u[2]]) else { continue };
                let frame = Frame::new(pt.n);
                let (f, _) = bsdf.eval(Vec3::Z, frame.to_local(ls.wi));
                let tmax = if ls.dist.is_finite() { ls.dist * (1.0 - 1e-3) } else { f32::INFINITY };
                if !tlas.occluded(offset(pt.p, pt.n, ls.wi), ls.wi, tmax) {
                    sum += f * ls.radiance;
                }
            }
            sum
        })
    });
    group.finish();
}

/// Local outgoing directions and uniform numbers shared by the BSDF benchmarks.
fn shading_inputs(count: u32) -> Vec<(Vec3, [f32; 3])> {
    (0..count)
        .map(|i| {
            let mut s = SampleStream::new(3, 0, i, 0);
            let (a, b) = (s.next4(), s.next4());
            (cosine_hemisphere(Vec2::new(a[0], a[1])), [b[0], b[1], b[2]])
        })
        .collect()
}

fn shading(c: &mut Criterion) {
    let inputs = shading_inputs(4096);
    let kinds = [
        ("diffuse", MaterialKind::Diffuse, 1.0),
        ("glossy", MaterialKind::Glossy, 0.2),
        ("conductor", MaterialKind::Conductor, 0.3),
        ("dielectric", MaterialKind::Dielectric, 0.0),
    ];
    let mut group = c.benchmark_group("bsdf");
    group.throughput(Throughput::Elements(inputs.len() as u64));
    for (name, kind, roughness) in kinds {
        let bsdf = Bsdf::new(kind, Vec3::new(0.7, 0.5, 0.3), roughness, 1.5);
        group.bench_function(BenchmarkId::new("sample", name), |b| {
            // black_box keeps the sampled values alive (not only whether there is one).
            b.iter(|| inputs.iter().filter_map(|(wo, u)| black_box(bsdf.sample(*wo, *u))).count())
        });
        group.bench_function(BenchmarkId::new("eval", name), |b| {
            b.iter(|| {
                inputs.windows(2).map(|p| black_box(bsdf.eval(p[0].0, p[1].0)).1).sum::<f32>()
            })
        });
    }
    group.finish();

    let (w, h) = (1024u32, 1024u32);
    let texels = (0..w * h).map(|i| Vec3::splat((i % 251) as f32 / 251.0)).collect();
    let texture = Texture::linear(w, h, texels);
    let mut group = c.benchmark_group("texture");
    group.throughput(Throughput::Elements(inputs.len() as u64));
    group.bench_function("bilinear_wrap", |b| {
        // Coordinates over a few tiles either side of [0, 1), as tiled floors use them.
        b.iter(|| {
            inputs
                .iter()
                .map(|(_, u)| texture.sample(Vec2::new(u[0] * 6.0 - 3.0, u[1] * 6.0 - 3.0)))
                .sum::<Vec3>()
        })
    });
    group.finish();

    let mut group = c.benchmark_group("sampler");
    group.throughput(Throughput::Elements(4096));
    group.bench_function("stream_and_three_draws", |b| {
        b.iter(|| {
            (0..4096u32)
                .map(|i| {
                    let mut s = SampleStream::new(4, 0, black_box(i), 0);
                    s.next4()[0] + s.next4()[1] + s.next4()[2]
                })
                .sum::<f32>()
        })
    });
    group.finish();
}

fn stages(c: &mut Criterion) {
    for w in workloads() {
        traversal(c, &w);
        nee(c, &w);
    }
    shading(c);
}

criterion_group!(benches, stages);
criterion_main!(benches);
