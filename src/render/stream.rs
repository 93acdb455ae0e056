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
//! instruction set ([`super::lanes`]): the kernel is generic over the build's
//! [`Lanes`] token, whose `Simd` type names them.
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

use glam::Vec3;
use gridlight_actors::state::MaterialKind;

use super::accel::Lanes;
use super::bsdf::Bsdf;
use super::glossy_lanes::Glossy;
use super::integrator::{
    arrive, scatter, trace, PathState, RenderStats, ShadowRay, Strategy, Surface, EMPTY_SAMPLE,
    RR_START_DEPTH,
};
use super::lanes::{F32s, Isa, Mask, U32s, Vec3s, WIDTH};
use super::lights::Lights;
use super::sampler::{next4_lanes, SampleStream};
use super::trig::sin_cos_lanes;
use super::{MaterialData, PixelSample, RenderScene};

/// Pixels whose samples all finish before the next pixels start: bounds the per-sample
/// buffer, at the cost of a ragged tail of lanes per chunk.
const CHUNK: usize = 256;

/// Sixteen paths in flight, lane by lane.
#[derive(Default)]
struct Group<I> {
    o: Vec3s<I>,
    d: Vec3s<I>,
    throughput: Vec3s<I>,
    indirect: Vec3s<I>,
    prev_pdf: F32s<I>,
    depth: U32s<I>,
    /// The sample streams' fields ([`SampleStream`]).
    seed: U32s<I>,
    index: U32s<I>,
    draw: U32s<I>,
    /// Lanes whose previous bounce was a delta choice (camera rays count as one).
    prev_delta: u32,
    /// The vertex each lane of the vector stage scatters at: position, geometric and
    /// shading normals (front side), albedo, and for glossy ones the coat's roughness
    /// and index of refraction.
    p: Vec3s<I>,
    ng: Vec3s<I>,
    ns: Vec3s<I>,
    color: Vec3s<I>,
    alpha: F32s<I>,
    eta: F32s<I>,
    /// Pending shadow rays (lanes in `shadow`), traced with the lane's next ray.
    sh_o: Vec3s<I>,
    sh_d: Vec3s<I>,
    sh_tmax: F32s<I>,
    sh_c: Vec3s<I>,
    shadow: u32,
    /// Job (pixel × spp + sample) and G-buffer values of each lane's path.
    job: [usize; WIDTH],
    out: [PixelSample; WIDTH],
}

impl<I: Isa> Group<I> {
    /// Lane `l`'s path state.
    #[inline(always)]
    fn path(&self, l: usize) -> PathState {
        PathState {
            stream: SampleStream {
                pixel_seed: self.seed.0[l],
                index_reversed: self.index.0[l],
                draw: self.draw.0[l],
            },
            throughput: self.throughput.lane(l),
            indirect: self.indirect.lane(l),
            prev_pdf: self.prev_pdf.0[l],
            prev_delta: self.prev_delta & (1 << l) != 0,
            depth: self.depth.0[l],
        }
    }

    /// Stores `path` as lane `l`'s state.
    #[inline(always)]
    fn set_path(&mut self, l: usize, path: &PathState) {
        self.seed.0[l] = path.stream.pixel_seed;
        self.index.0[l] = path.stream.index_reversed;
        self.draw.0[l] = path.stream.draw;
        self.throughput.set_lane(l, path.throughput);
        self.indirect.set_lane(l, path.indirect);
        self.prev_pdf.0[l] = path.prev_pdf;
        self.prev_delta = (self.prev_delta & !(1 << l)) | (u32::from(path.prev_delta) << l);
        self.depth.0[l] = path.depth;
    }

    /// Starts the paths of the `fresh` lanes, whose sample streams are set, at pixel
    /// positions `(px, py)`: [`PathState::start`] and the test reference's `camera_ray`
    /// in lanes (the same bits).
    #[inline(always)]
    fn start(&mut self, scene: &RenderScene, fresh: u32, (px, py): (F32s<I>, F32s<I>)) {
        let m = U32s::from_bitmask(fresh);
        let cam = next4_lanes(self.seed, self.index, self.draw);
        let (o, d) = scene.camera.ray_lanes((px + cam[0], py + cam[1]), (cam[2], cam[3]));
        // The path fields other than the stream, which are the same for every path.
        let start = PathState::start(SampleStream { pixel_seed: 0, index_reversed: 0, draw: 0 });
        self.o = Vec3s::select(m, o, self.o);
        self.d = Vec3s::select(m, d, self.d);
        self.draw = U32s::select(m, self.draw.wrapping_add(U32s::splat(1)), self.draw);
        self.throughput = Vec3s::select(m, Vec3s::splat(start.throughput), self.throughput);
        self.indirect = Vec3s::select(m, Vec3s::splat(start.indirect), self.indirect);
        self.prev_pdf = F32s::select(m, F32s::splat(start.prev_pdf), self.prev_pdf);
        self.depth = U32s::select(m, U32s::splat(start.depth), self.depth);
        self.prev_delta = (self.prev_delta & !fresh) | if start.prev_delta { fresh } else { 0 };
    }

    /// Makes `s` lane `l`'s pending shadow ray.
    #[inline(always)]
    fn set_shadow(&mut self, l: usize, s: &ShadowRay) {
        self.sh_o.set_lane(l, s.origin);
        self.sh_d.set_lane(l, s.dir);
        self.sh_tmax.0[l] = s.tmax;
        self.sh_c.set_lane(l, s.contribution);
        self.shadow |= 1 << l;
    }

    /// Lane `l`'s pending shadow ray, if any (no longer pending).
    #[inline(always)]
    fn take_shadow(&mut self, l: usize) -> Option<ShadowRay> {
        if self.shadow & (1 << l) == 0 {
            return None;
        }
        self.shadow &= !(1 << l);
        Some(ShadowRay {
            contribution: self.sh_c.lane(l),
            origin: self.sh_o.lane(l),
            dir: self.sh_d.lane(l),
            tmax: self.sh_tmax.0[l],
        })
    }
}

/// Path-traces `pixels` as [`super::integrator::render_pixels_counted`] specifies.
#[inline(always)]
pub(super) fn render<L: Lanes>(
    lanes: L,
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
    let mut g = Group::<L::Simd>::default();
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
                        arrive_lane(lanes, scene, &mut g, l, max_depth, nee, &mut stats.rays);
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
                        finish(lanes, scene, &mut g, l, &mut sums, gbuffer, spp);
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
                    finish(lanes, scene, &mut g, l, &mut sums, gbuffer, spp);
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
fn finish<L: Lanes>(
    lanes: L,
    scene: &RenderScene,
    g: &mut Group<L::Simd>,
    l: usize,
    sums: &mut [(Vec3, Vec3)],
    gbuffer: &mut [PixelSample],
    spp: usize,
) {
    if let Some(s) = g.take_shadow(l) {
        let mut indirect = g.indirect.lane(l);
        s.settle(lanes, scene, &mut indirect);
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
fn arrive_lane<'a, L: Lanes>(
    lanes: L,
    scene: &'a RenderScene,
    g: &mut Group<L::Simd>,
    l: usize,
    max_depth: u32,
    nee: bool,
    rays: &mut u64,
) -> Option<(Surface<'a>, Vec3)> {
    let (o, d) = (g.o.lane(l), g.d.lane(l));
    *rays += 1;
    let mut path = g.path(l);
    let hit = trace(lanes, scene, (o, d), g.take_shadow(l), &mut path.indirect);
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

/// [`super::microfacet::Frame`] of sixteen normals: tangents `s`, `t`.
#[inline(always)]
fn frame<I: Isa>(n: Vec3s<I>) -> (Vec3s<I>, Vec3s<I>) {
    let one = F32s::splat(1.0);
    let sign = F32s::from_bits(one.to_bits() | (n.z.to_bits() & U32s::splat(0x8000_0000)));
    let a = -one / (sign + n.z);
    let b = n.x * n.y * a;
    let s = Vec3s { x: one + sign * n.x * n.x * a, y: sign * b, z: -sign * n.x };
    let t = Vec3s { x: b, y: sign + n.y * n.y * a, z: -n.y };
    (s, t)
}

/// [`super::integrator::offset`] in lanes.
#[inline(always)]
fn offset<I: Isa>(p: Vec3s<I>, ng: Vec3s<I>, dir: Vec3s<I>) -> Vec3s<I> {
    let eps = F32s::splat(1e-4) * (F32s::splat(1.0) + p.abs().max_element());
    Vec3s::select(ng.dot(dir).ge(F32s::splat(0.0)), p + ng.scale(eps), p - ng.scale(eps))
}

/// [`super::microfacet::cosine_hemisphere`] in lanes.
#[inline(always)]
pub(super) fn cosine_hemisphere<I: Isa>(u1: F32s<I>, u2: F32s<I>) -> Vec3s<I> {
    use std::f32::consts::PI;
    let (one, zero) = (F32s::splat(1.0), F32s::splat(0.0));
    let (ax, ay) = (F32s::splat(2.0) * u1 - one, F32s::splat(2.0) * u2 - one);
    let centre = ax.eq(zero) & ay.eq(zero);
    let x_major = ax.abs().gt(ay.abs());
    let r = F32s::select(x_major, ax, ay);
    let phi = F32s::select(
        x_major,
        F32s::splat(PI / 4.0) * (ay / ax),
        F32s::splat(PI / 2.0) - F32s::splat(PI / 4.0) * (ax / ay),
    );
    let (s, c) = sin_cos_lanes(phi);
    let (x, y) = (r * c, r * s);
    let z = (one - x * x - y * y).max(zero).sqrt();
    Vec3s::select(centre, Vec3s { x: zero, y: zero, z: one }, Vec3s { x, y, z })
}

/// Power heuristic with β = 2 in lanes.
#[inline(always)]
fn mis_lanes<I: Isa>(a: F32s<I>, b: F32s<I>) -> F32s<I> {
    let (a2, b2) = (a * a, b * b);
    let zero = F32s::splat(0.0);
    F32s::select((a2 + b2).gt(zero), a2 / (a2 + b2), zero)
}

/// Sixteen lanes' light samples.
struct LightSamples<I> {
    wi: Vec3s<I>,
    dist: F32s<I>,
    radiance: Vec3s<I>,
    /// Solid-angle pdf.
    pdf: F32s<I>,
    /// Lanes where a sample was drawn.
    sampled: Mask<I>,
}

/// Light samples of sixteen lanes in a scene lit by area emitters only, as
/// [`super::lights::Lights::sample`] draws them: an emitter by power, then a point on
/// it.
#[inline(always)]
fn sample_area_lanes<I: Isa>(
    lights: &Lights,
    p: Vec3s<I>,
    u_light: &[F32s<I>; 4],
) -> LightSamples<I> {
    let (zero, one) = (F32s::splat(0.0), F32s::splat(1.0));
    let mut v0 = Vec3s::default();
    let mut e1 = Vec3s::default();
    let mut e2 = Vec3s::default();
    let mut normal = Vec3s::default();
    let mut radiance = Vec3s::default();
    let mut parallelogram = U32s::default();
    for l in 0..WIDTH {
        let a = &lights.areas[lights.pick_area(lights.area_u(u_light[0].0[l], 0))];
        v0.set_lane(l, a.v0);
        e1.set_lane(l, a.e1);
        e2.set_lane(l, a.e2);
        normal.set_lane(l, a.normal);
        radiance.set_lane(l, a.radiance);
        parallelogram.0[l] = if a.parallelogram { u32::MAX } else { 0 };
    }
    let r = u_light[1].sqrt();
    let s = F32s::select(parallelogram, u_light[1], one - r);
    let t = F32s::select(parallelogram, u_light[2], u_light[2] * r);
    let q = v0 + e1.scale(s) + e2.scale(t);
    let d = q - p;
    let dist2 = d.dot(d);
    let dist = dist2.sqrt();
    let wi = d.div_by(dist);
    let cos_light = -wi.dot(normal);
    let sampled = !(cos_light.le(zero) | dist2.eq(zero));
    let per_area = (radiance.x + radiance.y + radiance.z) / F32s::splat(lights.area_power);
    let light_pdf = F32s::splat(lights.strategy_pmf) * per_area * dist2 / cos_light;
    LightSamples { wi, dist, radiance, pdf: light_pdf, sampled }
}

/// The same for the `group` lanes of a scene with other lights (the sun, the sky,
/// point lights, or several kinds): [`super::lights::Lights::sample`] lane by lane,
/// whose choice among strategies and their sampling are data-dependent.
#[inline(always)]
fn sample_lights_per_lane<I: Isa>(
    lights: &Lights,
    p: Vec3s<I>,
    u_light: &[F32s<I>; 4],
    group: u32,
) -> LightSamples<I> {
    let (mut wi, mut dist, mut radiance) = (Vec3s::default(), F32s::splat(0.0), Vec3s::default());
    let (mut pdf, mut sampled) = (F32s::splat(0.0), 0u32);
    let mut left = group;
    while left != 0 {
        let l = left.trailing_zeros() as usize;
        left &= left - 1;
        let u = [u_light[0].0[l], u_light[1].0[l], u_light[2].0[l]];
        if let Some(ls) = lights.sample(p.lane(l), u) {
            wi.set_lane(l, ls.wi);
            dist.0[l] = ls.dist;
            radiance.set_lane(l, ls.radiance);
            pdf.0[l] = ls.pdf;
            sampled |= 1 << l;
        }
    }
    LightSamples { wi, dist, radiance, pdf, sampled: U32s::from_bitmask(sampled) }
}

/// Whether a vertex of this material takes the vector stage (with next-event estimation).
#[inline(always)]
fn in_vector_stage(material: &MaterialData) -> bool {
    matches!(material.kind, MaterialKind::Diffuse | MaterialKind::Glossy)
}

/// Next-event estimation and BSDF sampling of the `group` lanes, at diffuse vertices and
/// at the `glossy` ones among them; returns the lanes whose paths ended (their pending
/// shadow rays still to be traced). The glossy lobes are computed only in rounds that
/// have a glossy lane, and blended in there.
#[inline(always)]
fn scatter_vector<I: Isa>(
    scene: &RenderScene,
    g: &mut Group<I>,
    group: u32,
    glossy: u32,
    rays: &mut u64,
) -> u32 {
    use std::f32::consts::FRAC_1_PI;
    let lights = &scene.lights;
    let zero = F32s::splat(0.0);
    let gm = U32s::from_bitmask(group);

    let u_light = next4_lanes(g.seed, g.index, g.draw);
    let u = next4_lanes(g.seed, g.index, g.draw.wrapping_add(U32s::splat(1)));

    // Two-sided: flip the normals to the viewer's side, then the shading frame (the
    // geometric one where the shading normal faces away).
    let wo_world = -g.d;
    let flip = g.ng.dot(wo_world).lt(zero);
    let ng = Vec3s::select(flip, -g.ng, g.ng);
    let ns = Vec3s::select(flip, -g.ns, g.ns);
    let (s1, t1) = frame(ns);
    let wo1 = Vec3s { x: wo_world.dot(s1), y: wo_world.dot(t1), z: wo_world.dot(ns) };
    let (s2, t2) = frame(ng);
    let wo2 = Vec3s { x: wo_world.dot(s2), y: wo_world.dot(t2), z: wo_world.dot(ng) };
    let geo = wo1.z.le(zero);
    let fs = Vec3s::select(geo, s2, s1);
    let ft = Vec3s::select(geo, t2, t1);
    let fn_ = Vec3s::select(geo, ng, ns);
    let wo = Vec3s::select(geo, wo2, wo1);
    let p = g.p;
    let color = g.color;
    let coated = Glossy { alpha: g.alpha, eta: g.eta, color };
    let glossy_mask = U32s::from_bitmask(glossy);
    let seen = (glossy != 0).then(|| coated.seen_from(wo));

    let LightSamples { wi, dist, radiance, pdf: light_pdf, sampled } = if lights.area_only() {
        sample_area_lanes(lights, p, &u_light)
    } else {
        sample_lights_per_lane(lights, p, &u_light, group)
    };

    // The BSDF's value and pdf there.
    let wl = Vec3s { x: wi.dot(fs), y: wi.dot(ft), z: wi.dot(fn_) };
    let above = !(wl.z.le(zero) | wo.z.le(zero));
    let cos_pi = wl.z * F32s::splat(FRAC_1_PI);
    let mut f = Vec3s::select(above, color.scale(cos_pi), Vec3s::default());
    let mut bsdf_pdf = F32s::select(above, cos_pi, zero);
    if let Some(seen) = &seen {
        let (fg, pdf_g) = coated.eval(seen, wl);
        f = Vec3s::select(glossy_mask, fg, f);
        bsdf_pdf = F32s::select(glossy_mask, pdf_g, bsdf_pdf);
    }
    let lit = gm & sampled & !(f.eq(Vec3s::default()) | radiance.eq(Vec3s::default()));

    let origin = offset(p, ng, wi);
    let tmax = F32s::select(
        dist.abs().lt(F32s::splat(f32::INFINITY)),
        (dist * F32s::splat(1.0 - 1e-3)).max(zero),
        F32s::splat(f32::INFINITY),
    );
    let fl = f * radiance;
    let c =
        Vec3s::select(light_pdf.eq(zero), fl, fl.scale(mis_lanes(light_pdf, bsdf_pdf) / light_pdf));
    let mut throughput = g.throughput;
    g.sh_o = Vec3s::select(lit, origin, g.sh_o);
    g.sh_d = Vec3s::select(lit, wi, g.sh_d);
    g.sh_tmax = F32s::select(lit, tmax, g.sh_tmax);
    g.sh_c = Vec3s::select(lit, throughput * c, g.sh_c);
    let lit = lit.bitmask();
    g.shadow |= lit;
    *rays += lit.count_ones() as u64;

    // The continuation (cosine-weighted, or the glossy lobes' choice weighted by their
    // value over their pdf, where that is positive), then Russian roulette.
    let mut alive = !wo.z.le(zero);
    let mut wi = cosine_hemisphere(u[1], u[2]);
    let mut pdf = wi.z * F32s::splat(FRAC_1_PI);
    let mut weight = color;
    if let Some(seen) = &seen {
        let wg = coated.sample(seen, [u[0], u[1], u[2]], wi);
        let (fg, pdf_g) = coated.eval(seen, wg);
        alive = alive & !(glossy_mask & !pdf_g.gt(zero));
        wi = Vec3s::select(glossy_mask, wg, wi);
        pdf = F32s::select(glossy_mask, pdf_g, pdf);
        weight = Vec3s::select(glossy_mask, fg.div_by(pdf_g), weight);
    }
    let dir = fs.scale(wi.x) + ft.scale(wi.y) + fn_.scale(wi.z);
    throughput = throughput * weight;
    let o = offset(p, ng, dir);
    let depth = g.depth.wrapping_add(U32s::splat(1));
    let roulette = depth.gt_i32(U32s::splat(RR_START_DEPTH));
    let rq = throughput.max_element().min(F32s::splat(0.95));
    let killed = roulette & u[3].ge(rq);
    throughput = Vec3s::select(roulette, throughput.div_by(rq), throughput);
    let live: Mask<I> = alive & !killed & !throughput.eq(Vec3s::default());

    g.draw = U32s::select(gm, g.draw.wrapping_add(U32s::splat(2)), g.draw);
    g.throughput = Vec3s::select(gm, throughput, g.throughput);
    g.prev_pdf = F32s::select(gm, pdf, g.prev_pdf);
    g.prev_delta &= !group;
    g.o = Vec3s::select(gm, o, g.o);
    g.d = Vec3s::select(gm, dir, g.d);
    g.depth = U32s::select(gm, depth, g.depth);
    group & !live.bitmask()
}
