//! The path loop: unidirectional path tracing with next-event estimation,
//! multiple importance sampling (power heuristic) and Russian roulette, plus the
//! G-buffer probe (`primary_hit`) and picking.
//!
//! Depth counts path segments: `max_depth` 5 is the camera ray plus four bounces
//! (Mitsuba's convention), so light is sampled at vertices 1..max_depth-1 and
//! emitters are seen up to segment `max_depth`.

use glam::{Vec2, Vec3};

use super::accel::{Lanes, Sse};
use super::bsdf::Bsdf;
use super::lights::AreaLight;
use super::microfacet::Frame;
use super::sampler::SampleStream;
use super::RenderScene;
use super::{MaterialData, PixelSample};

/// Paths survive Russian roulette unconditionally up to this many segments.
pub(super) const RR_START_DEPTH: u32 = 3;
/// Smallest albedo divided out by demodulation.
const MIN_ALBEDO: f32 = 1e-3;

/// Work counters of one `render_pixels_counted` call.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RenderStats {
    /// Camera paths traced.
    pub samples: u64,
    /// Rays cast: closest-hit and shadow rays.
    pub rays: u64,
    /// Times the stream kernel's sixteen-lane vector stage ran, path vertices it shaded,
    /// and vertices shaded by the one-path step in a lane (zero in the one-path test
    /// reference).
    pub vector_stages: u64,
    pub vector_vertices: u64,
    pub lane_vertices: u64,
}

impl RenderStats {
    /// Share of the vector stage's lanes that held a vertex to shade, if it ran.
    pub fn vector_lane_occupancy(&self) -> Option<f64> {
        (self.vector_stages > 0).then(|| {
            self.vector_vertices as f64 / (self.vector_stages * super::lanes::WIDTH as u64) as f64
        })
    }

    /// Share of the stream kernel's path vertices that the vector stage shaded, if that
    /// kernel ran.
    pub fn vector_vertex_share(&self) -> Option<f64> {
        let all = self.vector_vertices + self.lane_vertices;
        (all > 0).then(|| self.vector_vertices as f64 / all as f64)
    }
}

/// How paths gather light: both reference strategies must agree on the mean.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Strategy {
    /// Next-event estimation and BSDF sampling combined with MIS (the default).
    #[default]
    NeeMis,
    /// BSDF sampling only; light is found by hitting emitters (for validation).
    BsdfOnly,
}

/// What a ray hit.
enum Hit<'a> {
    Surface(Surface<'a>),
    Light(&'a AreaLight, f32),
}

/// A resolved surface hit in world space.
pub(super) struct Surface<'a> {
    pub(super) p: Vec3,
    /// Unit geometric normal on the triangle's front (winding) side.
    pub(super) ng: Vec3,
    /// Unit shading normal, on the same side as `ng`.
    pub(super) ns: Vec3,
    /// Texture coordinates; zero unless the material is textured.
    pub(super) uv: Vec2,
    pub(super) material: &'a MaterialData,
    pub(super) object: u32,
}

#[inline(always)]
fn closest<'a, L: Lanes>(lanes: L, scene: &'a RenderScene, o: Vec3, d: Vec3) -> Option<Hit<'a>> {
    resolve(scene, o, d, scene.tlas.intersect_with(lanes, o, d, f32::INFINITY))
}

/// What the ray `o + t d` reaches given the geometry's closest `hit`: an area light in
/// front of it, or the hit surface with its shading data.
#[inline(always)]
fn resolve<'a>(
    scene: &'a RenderScene,
    o: Vec3,
    d: Vec3,
    hit: Option<super::accel::Hit>,
) -> Option<Hit<'a>> {
    let mut tmax = hit.map_or(f32::INFINITY, |h| h.t);
    let mut light = None;
    for q in scene.lights.quads() {
        let edges = super::accel::TriEdges { v0: q.v0.into(), e1: q.e1.into(), e2: q.e2.into() };
        if let Some((t, ..)) = edges.intersect_parallelogram(o.into(), d.into(), tmax) {
            tmax = t;
            light = Some(q);
        }
    }
    if let Some(q) = light {
        return Some(Hit::Light(q, tmax));
    }
    let hit = hit?;
    let inst = &scene.tlas.instances[hit.instance as usize];
    let blas = &*inst.blas;
    let leaf = blas.leaf(hit.prim);
    let mesh = &*blas.mesh;
    let material_id = scene.slot_materials[(inst.material_base + leaf.slot) as usize];
    let material = &scene.materials[material_id as usize];
    let (u, v) = (hit.u, hit.v);
    let w = 1.0 - u - v;
    let ng = scene.tlas.geometric_normal(&hit);
    // Vertex data is read only where it can change the result.
    let idx =
        (!leaf.flat || material.texture.is_some()).then(|| mesh.indices[leaf.original as usize]);
    let mut ns = match idx {
        Some(idx) if !leaf.flat => {
            let [a, b, c] = idx.map(|i| mesh.normals[i as usize]);
            inst.normal_to_world.mul_vec3(a * w + b * u + c * v).normalize_or(ng)
        }
        _ => ng,
    };
    if ns.dot(ng) < 0.0 {
        ns = -ns;
    }
    let uv = match idx {
        Some(idx) if material.texture.is_some() && !mesh.uvs.is_empty() => {
            let [a, b, c] = idx.map(|i| mesh.uvs[i as usize]);
            a * w + b * u + c * v
        }
        _ => Vec2::ZERO,
    };
    Some(Hit::Surface(Surface { p: o + d * hit.t, ng, ns, uv, material, object: inst.object }))
}

/// Offsets a ray origin off the surface to the side `dir` leaves towards (public for the
/// stage benchmarks, which cast the kernel's rays).
#[inline]
pub fn offset(p: Vec3, ng: Vec3, dir: Vec3) -> Vec3 {
    let eps = 1e-4 * (1.0 + p.abs().max_element());
    if ng.dot(dir) >= 0.0 {
        p + ng * eps
    } else {
        p - ng * eps
    }
}

/// Power heuristic with β = 2.
#[inline]
fn mis(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

#[inline]
fn albedo_of(material: &MaterialData, uv: Vec2) -> Vec3 {
    match &material.texture {
        Some(t) => t.sample(uv) * material.base_color,
        None => material.base_color,
    }
}

/// What a camera path carries from one vertex to the next (besides its ray).
#[derive(Clone, Copy, Debug)]
pub(super) struct PathState {
    pub(super) stream: SampleStream,
    pub(super) throughput: Vec3,
    pub(super) indirect: Vec3,
    pub(super) prev_pdf: f32,
    /// Whether the previous bounce was a delta choice (the camera ray counts as one).
    pub(super) prev_delta: bool,
    /// Segments so far, the one being traced included.
    pub(super) depth: u32,
}

impl PathState {
    /// A path whose camera ray is being traced.
    #[inline(always)]
    pub(super) fn start(stream: SampleStream) -> Self {
        Self {
            stream,
            throughput: Vec3::ONE,
            indirect: Vec3::ZERO,
            prev_pdf: 0.0,
            prev_delta: true,
            depth: 1,
        }
    }
}

/// The G-buffer values of a path before its first vertex.
pub(super) const EMPTY_SAMPLE: PixelSample = PixelSample {
    reflected: Vec3::ZERO,
    emission: Vec3::ZERO,
    albedo: Vec3::ONE,
    normal: Vec3::ZERO,
    position: Vec3::ZERO,
    object: u32::MAX,
};

/// One camera path: its reflected radiance and G-buffer values (the one-path kernel).
#[cfg(test)]
fn trace_path<L: Lanes>(
    lanes: L,
    scene: &RenderScene,
    stream: SampleStream,
    pixel_pos: Vec2,
    max_depth: u32,
    strategy: Strategy,
    rays: &mut u64,
) -> PixelSample {
    let nee = strategy == Strategy::NeeMis;
    let mut path = PathState::start(stream);
    let (mut o, mut d) = camera_ray(scene, &mut path.stream, pixel_pos);
    let mut out = EMPTY_SAMPLE;
    // The last vertex's shadow ray, traced together with the next bounce's ray.
    let mut shadow: Option<ShadowRay> = None;
    loop {
        *rays += 1;
        let hit = trace(lanes, scene, (o, d), shadow.take(), &mut path.indirect);
        let arrived = arrive(scene, &mut path, (o, d), hit, max_depth, nee, &mut out);
        let Some((surface, albedo)) = arrived else { break };
        let (alive, s) = scatter(scene, &mut path, (&mut o, &mut d), &surface, albedo, nee, rays);
        shadow = s;
        if !alive {
            break;
        }
    }
    if let Some(s) = shadow {
        s.settle(lanes, scene, &mut path.indirect);
    }
    out.reflected = path.indirect;
    out
}

/// The closest hit of the ray `(o, d)`; a pending `shadow` ray is traced together with it
/// (the two walks in turns) and its contribution added to `indirect` unless blocked.
#[inline(always)]
pub(super) fn trace<L: Lanes>(
    lanes: L,
    scene: &RenderScene,
    (o, d): (Vec3, Vec3),
    shadow: Option<ShadowRay>,
    indirect: &mut Vec3,
) -> Option<super::accel::Hit> {
    let Some(s) = shadow else { return scene.tlas.intersect_with(lanes, o, d, f32::INFINITY) };
    let (hit, blocked) = scene.tlas.intersect_and_occluded_with(
        lanes,
        (o, d, f32::INFINITY),
        (s.origin, s.dir, s.tmax),
    );
    if !blocked {
        *indirect += s.contribution;
    }
    hit
}

/// A path's camera ray through `pixel_pos`, from its sample stream's first draw (the
/// stream kernel makes sixteen at once, `stream::Group::start`).
#[cfg(test)]
fn camera_ray(scene: &RenderScene, stream: &mut SampleStream, pixel_pos: Vec2) -> (Vec3, Vec3) {
    let cam = stream.next4();
    scene.camera.ray(pixel_pos + Vec2::new(cam[0], cam[1]), Vec2::new(cam[2], cam[3]))
}

/// What the ray `(o, d)` found (`hit`, the geometry's closest): adds the emission it
/// reached, MIS-weighted against light sampling unless the previous bounce could not have
/// sampled a light, and records the G-buffer at the first vertex. Returns the surface and
/// its albedo where the path scatters on; `None` when it ends.
#[inline(always)]
pub(super) fn arrive<'a>(
    scene: &'a RenderScene,
    path: &mut PathState,
    (o, d): (Vec3, Vec3),
    hit: Option<super::accel::Hit>,
    max_depth: u32,
    nee: bool,
    out: &mut PixelSample,
) -> Option<(Surface<'a>, Vec3)> {
    let lights = &scene.lights;
    let emit = |radiance: Vec3, light_pdf: f32, path: &mut PathState, out: &mut PixelSample| {
        if path.depth == 1 {
            out.emission += radiance;
        } else {
            let w = if path.prev_delta || !nee { 1.0 } else { mis(path.prev_pdf, light_pdf) };
            path.indirect += path.throughput * radiance * w;
        }
    };
    let surface = match resolve(scene, o, d, hit) {
        None => {
            for (radiance, pdf) in lights.escaped(d) {
                if radiance != Vec3::ZERO {
                    emit(radiance, pdf, path, out);
                }
            }
            return None;
        }
        Some(Hit::Light(q, t)) => {
            let cos = -d.dot(q.normal);
            if cos > 0.0 {
                emit(q.radiance, lights.area_pdf(q.radiance, t * t, cos), path, out);
            }
            if path.depth == 1 {
                out.normal = q.normal;
                out.position = o + d * t;
            }
            return None;
        }
        Some(Hit::Surface(s)) => s,
    };
    let material = surface.material;
    if material.is_emissive() {
        let cos = (-d).dot(surface.ng);
        if cos > 0.0 {
            let dist2 = (surface.p - o).length_squared();
            let pdf = lights.area_pdf(material.emission, dist2, cos);
            emit(material.emission, pdf, path, out);
        }
    }
    let albedo = albedo_of(material, surface.uv);
    if path.depth == 1 {
        out.albedo = albedo.max(Vec3::splat(MIN_ALBEDO));
        out.normal = surface.ns;
        out.position = surface.p;
        out.object = surface.object;
    }
    (path.depth < max_depth).then_some((surface, albedo))
}

/// Next-event estimation (its shadow ray returned, to be traced) and BSDF sampling at
/// `surface`, reached along `d`: moves the ray `(o, d)` on and says whether the path
/// lives.
#[inline(always)]
pub(super) fn scatter(
    scene: &RenderScene,
    path: &mut PathState,
    (o, d): (&mut Vec3, &mut Vec3),
    surface: &Surface,
    albedo: Vec3,
    nee: bool,
    rays: &mut u64,
) -> (bool, Option<ShadowRay>) {
    let material = surface.material;
    let wo_world = -*d;
    let bsdf = Bsdf::new(material.kind, albedo, material.roughness, material.ior);
    let (mut ng, mut ns) = (surface.ng, surface.ns);
    if bsdf.two_sided() && ng.dot(wo_world) < 0.0 {
        ng = -ng;
        ns = -ns;
    }
    let mut frame = Frame::new(ns);
    let mut wo = frame.to_local(wo_world);
    if bsdf.two_sided() && wo.z <= 0.0 {
        // The shading normal faces away from the viewer: fall back to geometry.
        frame = Frame::new(ng);
        wo = frame.to_local(wo_world);
    }

    // Next-event estimation; its random numbers are drawn either way, so that the
    // stream's indices do not depend on the strategy or the material.
    let u_light = path.stream.next4();
    let mut shadow = None;
    if nee && !bsdf.is_delta() {
        let u = [u_light[0], u_light[1], u_light[2]];
        shadow = next_event(scene, &bsdf, (&frame, wo), (surface.p, ng), u, rays)
            .map(|s| ShadowRay { contribution: path.throughput * s.contribution, ..s });
    }

    // Continue the path by sampling the BSDF.
    let u = path.stream.next4();
    let Some(sample) = bsdf.sample(wo, [u[0], u[1], u[2]]) else { return (false, shadow) };
    let wi = frame.to_world(sample.wi);
    path.throughput *= sample.weight;
    path.prev_pdf = sample.pdf;
    path.prev_delta = sample.delta;
    *o = offset(surface.p, ng, wi);
    *d = wi;
    path.depth += 1;
    if path.depth > RR_START_DEPTH {
        let q = path.throughput.max_element().min(0.95);
        if u[3] >= q {
            return (false, shadow);
        }
        path.throughput /= q;
    }
    (path.throughput != Vec3::ZERO, shadow)
}

/// A light sample's contribution, to be added unless its shadow ray is blocked.
#[derive(Clone, Copy, Debug)]
pub(super) struct ShadowRay {
    pub(super) contribution: Vec3,
    pub(super) origin: Vec3,
    pub(super) dir: Vec3,
    pub(super) tmax: f32,
}

impl ShadowRay {
    /// Traces this shadow ray alone (its path has no next ray to go with): adds its
    /// contribution to `indirect` unless blocked.
    #[inline(always)]
    pub(super) fn settle<L: Lanes>(&self, lanes: L, scene: &RenderScene, indirect: &mut Vec3) {
        if !scene.tlas.occluded_with(lanes, self.origin, self.dir, self.tmax) {
            *indirect += self.contribution;
        }
    }
}

/// Next-event estimation at a surface point `at` = (position, geometric normal), seen
/// along `wo` in the shading `frame`: one light sample, MIS-weighted against the BSDF,
/// and the shadow ray (counted in `rays`) that decides whether it counts; `None` when
/// it adds nothing. The contribution still has to be multiplied by the path throughput.
#[inline(always)]
fn next_event(
    scene: &RenderScene,
    bsdf: &Bsdf,
    (frame, wo): (&Frame, Vec3),
    (p, ng): (Vec3, Vec3),
    u: [f32; 3],
    rays: &mut u64,
) -> Option<ShadowRay> {
    let ls = scene.lights.sample(p, u)?;
    let (f, bsdf_pdf) = bsdf.eval(wo, frame.to_local(ls.wi));
    if f == Vec3::ZERO || ls.radiance == Vec3::ZERO {
        return None;
    }
    let origin = offset(p, ng, ls.wi);
    let tmax = if ls.dist.is_finite() { (ls.dist * (1.0 - 1e-3)).max(0.0) } else { f32::INFINITY };
    *rays += 1;
    let contribution = if ls.pdf == 0.0 {
        f * ls.radiance
    } else {
        f * ls.radiance * (mis(ls.pdf, bsdf_pdf) / ls.pdf)
    };
    Some(ShadowRay { contribution, origin, dir: ls.wi, tmax })
}

/// Renders the given pixels (index = y*width + x, y = 0 is the top row),
/// state.render.spp samples each, max depth state.render.max_depth;
/// single-threaded; deterministic for (state.seed, frame, pixel, sample index).
/// `out` is cleared and filled in pixel order.
pub fn render_pixels(scene: &RenderScene, frame: u64, pixels: &[u32], out: &mut Vec<PixelSample>) {
    render_pixels_counted(scene, frame, pixels, out, Strategy::NeeMis);
}

/// [`render_pixels`] with a choice of light-gathering strategy, also returning
/// how much work it did (for benchmarks and validation), in the best build this CPU
/// runs ([`KernelBuild::best`]).
pub fn render_pixels_counted(
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    render_pixels_in(KernelBuild::best(), scene, frame, pixels, out, strategy)
}

/// A compiled build of the stream kernel ([`super::stream`]). A baseline binary still
/// runs on every x86-64 CPU (the workers of a desktop grid are whatever machines an
/// office has), while those with AVX2 get the x86-64-v3 build and those with AVX-512 the
/// x86-64-v4 build. Every build gives the same pixels bit for bit (each lane operation is
/// one IEEE operation in the scalar code's order, and Rust never contracts or reorders
/// float arithmetic), so a grid may mix them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelBuild {
    /// x86-64-v4: paths in one AVX-512 register (F, VL, BW, DQ, CD enabled: EVEX
    /// encoding, 32 vector registers, mask registers for comparisons), node tests as v3.
    V4,
    /// x86-64-v3: paths in two AVX2 registers, node tests in one AVX register,
    /// TZCNT/LZCNT in traversal, VEX three-operand code.
    V3,
    /// Baseline x86-64: paths in four SSE2 quarters, node tests in two SSE halves (scalar
    /// code off x86-64).
    Baseline,
}

impl KernelBuild {
    /// Every build, fastest first.
    pub const ALL: [Self; 3] = [Self::V4, Self::V3, Self::Baseline];

    /// The fastest build this CPU runs.
    pub fn best() -> Self {
        Self::ALL.into_iter().find(|b| b.available()).unwrap_or(Self::Baseline)
    }

    /// Whether this CPU runs the build.
    pub fn available(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            Self::V4 => v4::available(),
            #[cfg(target_arch = "x86_64")]
            Self::V3 => v3::available(),
            #[cfg(not(target_arch = "x86_64"))]
            Self::V4 | Self::V3 => false,
            Self::Baseline => true,
        }
    }

    /// The instruction-set level the build is compiled for.
    pub fn name(self) -> &'static str {
        match self {
            Self::V4 => "x86-64-v4",
            Self::V3 => "x86-64-v3",
            Self::Baseline => "baseline",
        }
    }
}

/// [`render_pixels_counted`] in the given build.
///
/// # Panics
/// Where this CPU cannot run `build` (see [`KernelBuild::available`]).
pub fn render_pixels_in(
    build: KernelBuild,
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    assert!(build.available(), "this CPU cannot run the {} build of the kernel", build.name());
    match build {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the CPU has every feature the build is compiled with (asserted).
        KernelBuild::V4 => unsafe { v4::render_pixels(scene, frame, pixels, out, strategy) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as V4.
        KernelBuild::V3 => unsafe { v3::render_pixels(scene, frame, pixels, out, strategy) },
        #[cfg(not(target_arch = "x86_64"))]
        KernelBuild::V4 | KernelBuild::V3 => unreachable!("no SIMD build off x86-64"),
        KernelBuild::Baseline => super::stream::render(Sse, scene, frame, pixels, out, strategy),
    }
}

/// A module holding the kernel compiled with `#[target_feature]`s `$features` (one string
/// literal, as the attribute takes; `$f` the same features one by one, for detection),
/// its lanes named by the [`crate::render::accel::Lanes`] token `$lanes`: node tests in
/// one eight-lane AVX register, TZCNT/LZCNT in BVH traversal, and the paths' lanes in
/// two AVX2 halves (v3) or one AVX-512 register (v4). The same source for both builds.
#[cfg(target_arch = "x86_64")]
macro_rules! simd_build {
    ($(#[$doc:meta])* $name:ident, $lanes:ident, $features:literal, [$($f:tt),*]) => {
        $(#[$doc])*
        pub(crate) mod $name {
            use super::*;

            /// Whether this CPU can run [`render_pixels`] (cached by std after the first
            /// call).
            #[inline]
            pub fn available() -> bool {
                $(std::is_x86_feature_detected!($f))&&*
            }

            /// # Safety
            /// Only on a CPU for which [`available`] is true.
            #[target_feature(enable = $features)]
            pub unsafe fn render_pixels(
                scene: &RenderScene,
                frame: u64,
                pixels: &[u32],
                out: &mut Vec<PixelSample>,
                strategy: Strategy,
            ) -> RenderStats {
                // `available` checked every feature the token needs.
                let lanes = crate::render::accel::$lanes::detect().expect("the build's features");
                super::super::stream::render(lanes, scene, frame, pixels, out, strategy)
            }

            /// # Safety
            /// Only on a CPU for which [`available`] is true.
            #[target_feature(enable = $features)]
            pub unsafe fn primary_hits(scene: &RenderScene, first: u32, out: &mut [PixelSample]) {
                let lanes = crate::render::accel::$lanes::detect().expect("the build's features");
                primary_hits_with(lanes, scene, first, out)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
simd_build!(
    /// The kernel compiled for x86-64-v3.
    v3,
    Avx,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma",
    ["avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma"]
);

#[cfg(target_arch = "x86_64")]
simd_build!(
    /// The kernel compiled for x86-64-v4 (the v3 features and AVX-512 F/VL/BW/DQ/CD).
    v4,
    Avx512,
    "avx,avx2,bmi1,bmi2,lzcnt,popcnt,fma,avx512f,avx512vl,avx512bw,avx512dq,avx512cd",
    [
        "avx", "avx2", "bmi1", "bmi2", "lzcnt", "popcnt", "fma", "avx512f", "avx512vl",
        "avx512bw", "avx512dq", "avx512cd"
    ]
);

/// The one-path kernel: each camera path traced to its end before the next starts, in
/// the baseline build. The stream kernel replaced it; it stays as the reference the
/// stream kernel's bits are tested against.
#[cfg(test)]
pub(crate) fn render_pixels_one_path(
    scene: &RenderScene,
    frame: u64,
    pixels: &[u32],
    out: &mut Vec<PixelSample>,
    strategy: Strategy,
) -> RenderStats {
    out.clear();
    let state = scene.state();
    let width = state.resolution.width.max(1);
    let spp = state.render.spp.max(1);
    let inv = 1.0 / spp as f32;
    let mut stats = RenderStats::default();
    for &pixel in pixels {
        let pos = Vec2::new((pixel % width) as f32, (pixel / width) as f32);
        let mut acc = PixelSample::default();
        for index in 0..spp {
            let stream = SampleStream::new(state.seed, frame, pixel, index);
            let s = trace_path(
                Sse,
                scene,
                stream,
                pos,
                state.render.max_depth,
                strategy,
                &mut stats.rays,
            );
            acc.reflected += s.reflected;
            acc.emission += s.emission;
            if index == 0 {
                acc.albedo = s.albedo;
                acc.normal = s.normal;
                acc.position = s.position;
                acc.object = s.object;
            }
        }
        acc.reflected *= inv;
        acc.emission *= inv;
        out.push(acc);
    }
    stats.samples = pixels.len() as u64 * spp as u64;
    stats
}

/// G-buffer sample through the pixel centre (reflected radiance zero).
pub fn primary_hit(scene: &RenderScene, pixel: u32) -> PixelSample {
    primary_hit_with(Sse, scene, pixel)
}

/// [`primary_hit`] of pixels `first..first + out.len()` into `out`, in the kernel build
/// [`render_pixels_counted`] would pick (the same values bit for bit).
pub fn primary_hits(scene: &RenderScene, first: u32, out: &mut [PixelSample]) {
    match KernelBuild::best() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `best` picks only a build whose features the CPU has.
        KernelBuild::V4 => unsafe { v4::primary_hits(scene, first, out) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as V4.
        KernelBuild::V3 => unsafe { v3::primary_hits(scene, first, out) },
        _ => primary_hits_with(Sse, scene, first, out),
    }
}

#[inline(always)]
fn primary_hits_with<L: Lanes>(lanes: L, scene: &RenderScene, first: u32, out: &mut [PixelSample]) {
    for (pixel, s) in (first..).zip(out.iter_mut()) {
        *s = primary_hit_with(lanes, scene, pixel);
    }
}

#[inline(always)]
fn primary_hit_with<L: Lanes>(lanes: L, scene: &RenderScene, pixel: u32) -> PixelSample {
    let (o, d) = primary_ray(scene, pixel);
    let mut out = PixelSample { albedo: Vec3::ONE, object: u32::MAX, ..Default::default() };
    let hit = closest(lanes, scene, o, d);
    out.emission = seen_emission(scene, &hit, d);
    match hit {
        None => {}
        Some(Hit::Light(q, t)) => {
            out.normal = q.normal;
            out.position = o + d * t;
        }
        Some(Hit::Surface(s)) => {
            out.albedo = albedo_of(s.material, s.uv).max(Vec3::splat(MIN_ALBEDO));
            out.normal = s.ns;
            out.position = s.p;
            out.object = s.object;
        }
    }
    out
}

/// Directly seen emission averaged over `count` points of `pixel`'s square (lens centre):
/// what the pixel's samples see directly on average, where [`primary_hit`] sees its centre
/// only. They differ on a pixel that an emitter's edge crosses, and not by noise: the
/// Cornell box's light, a few pixels tall, came out 2 % too dark at 160×120 and 0.7–1 %
/// too bright at 640×480 from centres alone. The points are a Hammersley set: `count`
/// distinct rows and columns, so that an edge along a row or a column (the light's, seen
/// from the front) is located to 1/`count` of a pixel, where an n×n grid locates it to 1/n
/// (an 8×8 grid still left the light 1.6 % too bright).
pub fn area_emission(scene: &RenderScene, pixel: u32, count: u32) -> Vec3 {
    let width = scene.state().resolution.width.max(1);
    let corner = Vec2::new((pixel % width) as f32, (pixel / width) as f32);
    let count = count.max(1);
    let mut sum = Vec3::ZERO;
    for i in 0..count {
        let x = (i as f32 + 0.5) / count as f32;
        let y = (i.reverse_bits() as f64 / 4_294_967_296.0) as f32 + 0.5 / count as f32;
        let (o, d) = scene.camera.ray(corner + Vec2::new(x, y.min(0.999_999)), Vec2::splat(0.5));
        sum += seen_emission(scene, &closest(Sse, scene, o, d), d);
    }
    sum / count as f32
}

/// Emission a camera ray along `d` sees at its first hit (the environment if it escapes).
fn seen_emission(scene: &RenderScene, hit: &Option<Hit>, d: Vec3) -> Vec3 {
    match hit {
        None => escaped(scene, d),
        Some(Hit::Light(q, _)) if -d.dot(q.normal) > 0.0 => q.radiance,
        Some(Hit::Surface(s)) if s.material.is_emissive() && -d.dot(s.ng) > 0.0 => {
            s.material.emission
        }
        _ => Vec3::ZERO,
    }
}

/// The G-buffer's camera ray through the centre of `pixel` (lens centre for thin lenses).
fn primary_ray(scene: &RenderScene, pixel: u32) -> (Vec3, Vec3) {
    let width = scene.state().resolution.width.max(1);
    let pos = Vec2::new((pixel % width) as f32 + 0.5, (pixel / width) as f32 + 0.5);
    scene.camera.ray(pos, Vec2::splat(0.5))
}

/// Environment and sun radiance along an escaping ray.
fn escaped(scene: &RenderScene, d: Vec3) -> Vec3 {
    scene.lights.escaped(d).iter().map(|e| e.0).sum()
}

/// The emission [`primary_hit`] reports for `pixel` if its ray hits nothing, for
/// G-buffers that find the hits another way (the raster pass).
pub fn escaped_emission(scene: &RenderScene, pixel: u32) -> Vec3 {
    escaped(scene, primary_ray(scene, pixel).1)
}

/// Picking for the window: the object hit by the ray through (x, y) in pixels.
pub fn pick(scene: &RenderScene, x: f32, y: f32) -> Option<u32> {
    let (o, d) = scene.camera.ray(Vec2::new(x, y), Vec2::splat(0.5));
    match closest(Sse, scene, o, d)? {
        Hit::Surface(s) => Some(s.object),
        Hit::Light(..) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::testscenes;
    use gridlight_actors::state::MaterialKind;

    /// Every build of the stream kernel must give the one-path reference's results bit
    /// for bit, for every material kind (a grid mixes CPUs).
    #[test]
    fn every_kernel_build_matches_the_one_path_reference_bit_for_bit() {
        let test = "every_kernel_build_matches_the_one_path_reference_bit_for_bit";
        let (builds, missing): (Vec<_>, Vec<_>) =
            KernelBuild::ALL.into_iter().partition(|b| b.available());
        for build in missing {
            let why = format!("the CPU lacks {}, so that build was not checked", build.name());
            crate::testing::skip(test, crate::testing::Missing::CpuFeature, &why);
        }
        // The last case textures the walls (uvs 0..1 reach both ends of the texel wrap).
        let kinds = [
            (MaterialKind::Diffuse, 1.0, false),
            (MaterialKind::Conductor, 0.3, false),
            (MaterialKind::Glossy, 0.2, false),
            (MaterialKind::Dielectric, 0.0, false),
            (MaterialKind::Dielectric, 0.4, false),
            (MaterialKind::Diffuse, 1.0, true),
        ];
        // Diffuse and glossy vertices take the stream kernel's vector stage (the others
        // their lane's one-path step): lit by the box's area light alone, its light
        // samples are vector code; with an environment too, drawn lane by lane.
        let cases = kinds.into_iter().flat_map(|k| [(k, true), (k, false)]);
        for ((kind, roughness, textured), environment) in cases {
            let (assets, mut state) = testscenes::cornell_box(40, 30);
            state.materials[0].kind = kind;
            state.materials[0].roughness = roughness;
            let mut assets = (*assets).clone();
            if textured {
                let texels = (0..15).map(|i| Vec3::new(0.2, (i % 4) as f32 / 4.0, 0.7)).collect();
                let texture = crate::assets::Texture::linear(5, 3, texels);
                assets.textures.insert("checker.png".into(), std::sync::Arc::new(texture));
                state.materials[0].base_color_texture = Some("checker.png".into());
            }
            let assets = std::sync::Arc::new(assets);
            state.environment = environment.then_some(gridlight_actors::state::Environment {
                color: Vec3::new(0.3, 0.4, 0.5),
                intensity: 1.0,
                map: None,
                rotation_deg: 0.0,
            });
            // A thin lens in half the cases: camera rays are lane code too.
            state.camera.aperture = if environment { 0.05 } else { 0.0 };
            let scene = RenderScene::new(assets, &state).unwrap();
            assert_eq!(scene.lights.area_only(), !environment);
            let pixels: Vec<u32> = (0..40 * 30).collect();
            for strategy in [Strategy::NeeMis, Strategy::BsdfOnly] {
                let mut reference = Vec::new();
                let a = render_pixels_one_path(&scene, 3, &pixels, &mut reference, strategy);
                assert!(a.rays > a.samples, "{kind:?}: paths did not bounce");
                for &build in &builds {
                    let mut out = Vec::new();
                    let b = render_pixels_in(build, &scene, 3, &pixels, &mut out, strategy);
                    let case = format!("{kind:?}, {strategy:?}, {build:?}");
                    // The stream kernel's stage counters are its own.
                    let work = ((a.samples, a.rays), (b.samples, b.rays));
                    assert_eq!(work.0, work.1, "{case}: work counters differ");
                    for (i, (x, y)) in reference.iter().zip(&out).enumerate() {
                        assert_eq!(x, y, "{case}: pixel {i} differs");
                    }
                }
            }
            // The G-buffer's primary hits too (dispatched to v3 where the CPU has it).
            let mut hits = vec![PixelSample::default(); pixels.len()];
            primary_hits(&scene, 0, &mut hits);
            for (i, h) in hits.iter().enumerate() {
                assert_eq!(*h, primary_hit(&scene, i as u32), "{kind:?}: G-buffer pixel {i}");
            }
            assert!(hits.iter().any(|h| h.object != u32::MAX), "{kind:?}: no primary hit");
        }
    }
}
