//! The stream kernel: sixteen camera paths advance side by side, their state held lane
//! by lane (structure of arrays), and the shading of their diffuse and glossy vertices
//! runs as sixteen-lane vector code: one AVX-512 register in the x86-64-v4 build, two
//! AVX2 halves in the v3 build, four SSE2 quarters in the baseline build
//! ([`super::lanes`]). It is every build's kernel for every scene; the
//! one-path kernel it replaced (`integrator::trace_path`) is kept only as the reference
//! the tests compare it with.
//!
//! Three designs were on the table. pbrt-v4's wavefront integrator keeps millions of
//! paths in per-stage queues (camera rays, closest hit, per-material shading, shadow
//! rays), which suits a GPU's thread count but makes a CPU core stream every path's state
//! through memory at every stage. Embree's ray streams trace many rays per call, but after
//! the first bounce the rays of neighbouring paths diverge and a packet of incoherent rays
//! visits the union of their nodes, which is why Embree's own answer for incoherent rays
//! is one ray against a wide node (our [`super::accel`] traversal). Mitsuba's LLVM
//! variant is a megakernel: one wide loop over paths whose every operation is a vector
//! operation with masks. This kernel is that megakernel's shape at the width of one
//! AVX-512 register, with refill: sixteen lanes, each holding one path; a lane whose path ends
//! takes the next (pixel, sample) of the job at once, so lanes stay busy until the job's
//! tail (the camera rays of the lanes refilled together are made together, in lanes:
//! `Group::start`); one that ends at its hit is refilled and its camera ray traced before the
//! vector stage runs, which keeps that stage's lanes 99 % busy on the Cornell box (81 %
//! when refilled only after it, 6 % fewer samples per second; both figures of eight
//! lanes). Per bounce, each lane's
//! ray (and the shadow ray its last vertex left) is traced on its own and the hit is
//! resolved per lane (materials and textures are data-dependent,
//! [`super::integrator::arrive`], shared with the one-path kernel); then every lane goes
//! through one vector stage: both 4-D sample draws, the light sample, the
//! BSDF's value, MIS, the shadow ray's set-up, BSDF sampling, the throughput
//! update and Russian roulette. That stage takes every diffuse and glossy vertex when
//! next-event estimation is on (the glossy coat's lobes, [`super::glossy_lanes`], are
//! computed only in rounds that hold a glossy lane and blended into those lanes); its
//! light sample is vector code where the scene is lit by area
//! emitters only and [`super::lights::Lights::sample`] lane by lane otherwise (the sun,
//! the sky, point lights: which strategy a lane draws is data-dependent, and the rest of
//! the stage stays vector code: Sponza 1.04×, glossy-glass 1.14×, envmap-object parity
//! within noise against lanes that took the one-path step there). Glass and
//! conductor vertices, and the BSDF-only strategy, take the one-path step
//! ([`super::integrator::scatter`]) in their lane. Scenes with such vertices run as fast
//! as with the one-path kernel or a little faster (medians of 5 on an Intel Xeon: bunny
//! 1.13×, Sponza 1.00×; of 7 on an AMD EPYC: 1.03×, 0.96×, within that VM's spread), so
//! one kernel serves every scene. An earlier measurement that had them slower (0.93×,
//! 0.82×) was of a build whose end-of-path step was a closure compiled out of line,
//! without AVX.
//!
//! An earlier version kept each lane's state as a scalar struct and gathered it into
//! vectors per stage: the gathers cost what the vector stage saved (parity on the Cornell
//! box). Here the state stays in lanes, and the lane types are registers of the build's
//! instruction set ([`super::lanes`]): the kernel is generic over the build's [`Isa`],
//! and takes the [`Cpu`] that proves this CPU runs it.
//!
//! Sixteen lanes rather than eight since the x86-64-v4 build (one AVX-512 register;
//! [`super::lanes`] says why every build has the same width): on an AMD EPYC Zen 4,
//! paired medians of 25 alternating rounds against the eight-lane v3 build, Cornell box
//! 1.035×, bunny 0.99×, Sponza 1.03×; lanes 98–99 % busy. The gain is small because the
//! rest of a frame is one path at a time. Since then camera rays are made in lanes and
//! geometric normals are looked up instead of computed at each hit
//! ([`super::accel::Tlas::geometric_normal`]), and the v4 build's profile (perf, Cornell
//! box) has each lane's BVH walk at about three fifths of the samples, the vector stage
//! and the camera rays at about a sixth together, hit resolution and lane traffic at most
//! of the rest.
//!
//! The pictures are the one-path kernel's, bit for bit: every lane computes the scalar
//! code's operations in its order, each path keeps its own sample stream, and the samples
//! of a pixel are summed in sample order whatever order they finish in.
//!
//! Files: this one holds the loop (refill, trace and arrive per lane, the vector stage,
//! a path's end); `group.rs` the sixteen paths' state in lanes, `vector.rs` the vector
//! stage (light sampling, BSDF evaluation and sampling, roulette in lanes).

use glam::Vec3;
use gridlight_actors::state::MaterialKind;

use super::bsdf::Bsdf;
use super::integrator::{arrive, scatter, trace, RenderStats, Strategy, Surface, EMPTY_SAMPLE};
use super::isa::{Cpu, Isa};
use super::lanes::{F32s, WIDTH};
use super::sampler::SampleStream;
use super::{MaterialData, PixelSample, RenderScene};

mod group;
mod vector;

use group::Group;
#[cfg(test)]
pub(super) use vector::cosine_hemisphere;
use vector::scatter_vector;

/// Pixels whose samples all finish before the next pixels start: bounds the per-sample
/// buffer, at the cost of a ragged tail of lanes per chunk.
const CHUNK: usize = 256;

/// Path-traces `pixels` as [`super::integrator::render_pixels_counted`] specifies.
#[inline(always)]
pub(super) fn render<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    out.clear();
    out.resize(pixels.len(), PixelSample::default());
    let state = scene.state();
    let width = state.resolution.width.max(1);
    let spp = state.render.spp.max(1) as usize;
    let inv = 1.0 / spp as f32;
    let max_depth = state.render.max_depth;
    // With next-event estimation diffuse vertices take the vector stage, which samples
    // lights; without it every vertex takes the one-path step.
    let nee = strategy == Strategy::NeeMis;
    let mut stats = RenderStats::default();
    // (reflected, emission) of each sample of the chunk, by (pixel, sample index).
    let mut sums = Vec::with_capacity(CHUNK * spp);
    let mut g = Group::<I>::default();
    for (c, chunk) in pixels.chunks(CHUNK).enumerate() {
        let gbuffer = &mut out[c * CHUNK..c * CHUNK + chunk.len()];
        sums.clear();
        sums.resize(chunk.len() * spp, (Vec3::ZERO, Vec3::ZERO));
        let jobs = chunk.len() * spp;
        let mut next = 0;
        // Lanes holding a path; idle lanes keep stale values, computed on and ignored.
        let mut active = 0u32;
        loop {
            // Lanes in the vector stage this round, and those of them at glossy vertices.
            let (mut group, mut glossy) = (0u32, 0u32);
            // Lanes whose ray is to be traced: all those holding a path, then those
            // refilled because their path ended at its hit, so that the vector stage
            // runs on as many lanes as there are paths left.
            let mut trace_lanes = active;
            loop {
                // Idle lanes take the next jobs; their camera rays are made together.
                let mut fresh = 0u32;
                let (mut px, mut py) = (F32s::splat(0.0), F32s::splat(0.0));
                while active | fresh != (1 << WIDTH) - 1 && next < jobs {
                    let l = (!(active | fresh)).trailing_zeros() as usize;
                    let pixel = chunk[next / spp];
                    (px.0[l], py.0[l]) = ((pixel % width) as f32, (pixel / width) as f32);
                    let stream = SampleStream::new(state.seed, frame, pixel, (next % spp) as u32);
                    g.seed.0[l] = stream.pixel_seed;
                    g.index.0[l] = stream.index_reversed;
                    g.draw.0[l] = stream.draw;
                    g.job[l] = next;
                    g.out[l] = EMPTY_SAMPLE;
                    fresh |= 1 << l;
                    next += 1;
                }
                if fresh != 0 {
                    g.start(scene, fresh, (px, py));
                    active |= fresh;
                    trace_lanes |= fresh;
                }
                if trace_lanes == 0 {
                    break;
                }
                while trace_lanes != 0 {
                    let l = trace_lanes.trailing_zeros() as usize;
                    trace_lanes &= trace_lanes - 1;
                    let arrived =
                        arrive_lane(cpu, scene, &mut g, l, max_depth, nee, &mut stats.rays);
                    let alive = match arrived {
                        None => false,
                        Some((surface, albedo)) if nee && in_vector_stage(surface.material) => {
                            g.p.set_lane(l, surface.p);
                            g.ng.set_lane(l, surface.ng);
                            g.ns.set_lane(l, surface.ns);
                            g.color.set_lane(l, albedo);
                            let m = surface.material;
                            if m.kind == MaterialKind::Glossy {
                                let bsdf = Bsdf::new(m.kind, albedo, m.roughness, m.ior);
                                g.alpha.0[l] = bsdf.ggx.alpha;
                                g.eta.0[l] = bsdf.eta;
                                glossy |= 1 << l;
                            }
                            group |= 1 << l;
                            true
                        }
                        Some((surface, albedo)) => {
                            stats.lane_vertices += 1;
                            scatter_lane(scene, &mut g, l, &surface, albedo, nee, &mut stats.rays)
                        }
                    };
                    if !alive {
                        finish(cpu, scene, &mut g, l, &mut sums, gbuffer, spp);
                        active &= !(1 << l);
                    }
                }
            }
            if active == 0 {
                break;
            }
            if group != 0 {
                stats.vector_stages += 1;
                stats.vector_vertices += u64::from(group.count_ones());
                let mut ended = scatter_vector(scene, &mut g, group, glossy, &mut stats.rays);
                active &= !ended;
                while ended != 0 {
                    let l = ended.trailing_zeros() as usize;
                    ended &= ended - 1;
                    finish(cpu, scene, &mut g, l, &mut sums, gbuffer, spp);
                }
            }
        }
        for (b, samples) in gbuffer.iter_mut().zip(sums.chunks(spp)) {
            let (mut reflected, mut emission) = (Vec3::ZERO, Vec3::ZERO);
            for &(r, e) in samples {
                reflected += r;
                emission += e;
            }
            b.reflected = reflected * inv;
            b.emission = emission * inv;
        }
    }
    stats.samples = pixels.len() as u64 * spp as u64;
    stats
}

/// Ends lane `l`'s path: its last shadow ray, then its sample's sums (and, for a pixel's
/// first sample, its G-buffer entry). A function, not a closure: called from two places,
/// a closure was left out of line, without the v3 build's features, and the AVX node
/// tests of its shadow ray became calls.
#[inline(always)]
fn finish<I: Isa>(
    cpu: Cpu<I>,
    scene: &RenderScene,
    g: &mut Group<I>,
    l: usize,
    sums: &mut [(Vec3, Vec3)],
    gbuffer: &mut [PixelSample],
    spp: usize,
) {
    if let Some(s) = g.take_shadow(l) {
        let mut indirect = g.indirect.lane(l);
        s.settle(cpu, scene, &mut indirect);
        g.indirect.set_lane(l, indirect);
    }
    let s = &g.out[l];
    let job = g.job[l];
    sums[job] = (g.indirect.lane(l), s.emission);
    if job.is_multiple_of(spp) {
        let b = &mut gbuffer[job / spp];
        (b.albedo, b.normal, b.position, b.object) = (s.albedo, s.normal, s.position, s.object);
    }
}

/// Traces lane `l`'s ray together with its pending shadow ray, then
/// [`super::integrator::arrive`]s: the surface where the path scatters on, if any.
#[inline(always)]
fn arrive_lane<'a, I: Isa>(
    cpu: Cpu<I>,
    scene: &'a RenderScene,
    g: &mut Group<I>,
    l: usize,
    max_depth: u32,
    nee: bool,
    rays: &mut u64,
) -> Option<(Surface<'a>, Vec3)> {
    let (o, d) = (g.o.lane(l), g.d.lane(l));
    *rays += 1;
    let mut path = g.path(l);
    let hit = trace(cpu, scene, (o, d), g.take_shadow(l), &mut path.indirect);
    let arrived = arrive(scene, &mut path, (o, d), hit, max_depth, nee, &mut g.out[l]);
    g.indirect.set_lane(l, path.indirect);
    arrived
}

/// [`super::integrator::scatter`] in lane `l` (a vertex the vector stage does not
/// handle): false when the path ends.
#[inline(always)]
fn scatter_lane<I: Isa>(
    scene: &RenderScene,
    g: &mut Group<I>,
    l: usize,
    surface: &Surface,
    albedo: Vec3,
    nee: bool,
    rays: &mut u64,
) -> bool {
    let mut path = g.path(l);
    let (mut o, mut d) = (g.o.lane(l), g.d.lane(l));
    let (alive, shadow) = scatter(scene, &mut path, (&mut o, &mut d), surface, albedo, nee, rays);
    g.set_path(l, &path);
    g.o.set_lane(l, o);
    g.d.set_lane(l, d);
    if let Some(s) = shadow {
        g.set_shadow(l, &s);
    }
    alive
}

/// Whether a vertex of this material takes the vector stage (with next-event estimation).
#[inline(always)]
fn in_vector_stage(material: &MaterialData) -> bool {
    matches!(material.kind, MaterialKind::Diffuse | MaterialKind::Glossy)
}
