// The path loop (src/render/integrator.rs `trace_path` and `next_event`): unidirectional
// path tracing with next-event estimation, MIS (power heuristic) and Russian roulette;
// one invocation per pixel, its samples in order, the pixel's sampler seed from the CPU.

const MATERIAL_WORDS: u32 = 16u;
const RR_START_DEPTH: u32 = 3u;

fn camera_ray(pixel: vec2<f32>, lens: vec2<f32>) -> array<vec3<f32>, 2> {
    let x = (2.0 * pixel.x * params.cam_inv.x - 1.0) * params.cam_right.w;
    let y = (1.0 - 2.0 * pixel.y * params.cam_inv.y) * params.cam_up.w;
    let forward = params.cam_forward.xyz;
    let dir = normalize(forward + params.cam_right.xyz * x + params.cam_up.xyz * y);
    let aperture = params.cam_origin.w;
    if (aperture == 0.0) {
        return array<vec3<f32>, 2>(params.cam_origin.xyz, dir);
    }
    let r = aperture * sqrt(lens.x);
    let phi = 2.0 * PI * lens.y;
    let offset = params.cam_right.xyz * (r * cos(phi)) + params.cam_up.xyz * (r * sin(phi));
    let focus = params.cam_origin.xyz + dir * (params.cam_forward.w / dot(dir, forward));
    let origin = params.cam_origin.xyz + offset;
    return array<vec3<f32>, 2>(origin, normalize(focus - origin));
}

// What a ray hit: nothing, a quad light (`light`, at `t`) or a surface.
const MISS: u32 = 0u;
const LIGHT: u32 = 1u;
const SURFACE: u32 = 2u;

struct Found {
    kind: u32,
    t: f32,
    light: u32,
    p: vec3<f32>,
    ng: vec3<f32>,
    ns: vec3<f32>,
    uv: vec2<f32>,
    material: u32,
}

// Parallelogram test (TriEdges::intersect_parallelogram): t or -1.
fn quad_test(a: u32, o: vec3<f32>, d: vec3<f32>, tmax: f32) -> f32 {
    let v0 = vec3_at(a);
    let e1 = vec3_at(a + 3u);
    let e2 = vec3_at(a + 6u);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if (abs(det) < 1e-12) {
        return -1.0;
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let u = dot(s, p) * inv;
    if (!(u >= 0.0 && u <= 1.0)) {
        return -1.0;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if (!(v >= 0.0 && v <= 1.0)) {
        return -1.0;
    }
    let t = dot(e2, q) * inv;
    return select(-1.0, t, t > 0.0 && t < tmax);
}

fn interpolate3(base: u32, idx: vec3<u32>, bary: vec3<f32>) -> vec3<f32> {
    return vec3_at(base + idx.x * 3u) * bary.x + vec3_at(base + idx.y * 3u) * bary.y
        + vec3_at(base + idx.z * 3u) * bary.z;
}

fn closest(o: vec3<f32>, d: vec3<f32>) -> Found {
    var found: Found;
    found.kind = MISS;
    let hit = trace_geometry(o, d, FAR, false);
    var tmax = select(FAR, hit.t, hit.instance != NONE);
    var light = NONE;
    for (var i = 0u; i < params.lights_a.w; i = i + 1u) {
        let q = scene[params.sec_d.z + i];
        let t = quad_test(area_base(q), o, d, tmax);
        if (t >= 0.0) {
            tmax = t;
            light = q;
        }
    }
    if (light != NONE) {
        found.kind = LIGHT;
        found.light = light;
        found.t = tmax;
        return found;
    }
    if (hit.instance == NONE) {
        return found;
    }
    let ib = params.sec_a.w + hit.instance * INSTANCE_WORDS;
    let k = scene[ib + 25u] + hit.prim;
    let tb = params.sec_a.y + k * 9u;
    let e1 = vec3_at(tb + 3u);
    let e2 = vec3_at(tb + 6u);
    let leaf = params.sec_a.z + k * 3u;
    let original = scene[leaf];
    let slot = scene[leaf + 1u];
    let flat = scene[leaf + 2u] != 0u;
    let material = scene[params.sec_c.z + scene[ib + 30u] + slot];
    let mb = params.sec_c.y + material * MATERIAL_WORDS;
    let textured = scene[mb + 12u] != 0u;
    let ng = normalize(row_transform(ib + 12u, cross(e1, e2), 0.0));
    let bary = vec3<f32>(1.0 - hit.u - hit.v, hit.u, hit.v);
    var ns = ng;
    var uv = vec2<f32>(0.0);
    if (!flat || textured) {
        let ix = params.sec_b.z + (scene[ib + 26u] + original) * 3u;
        let idx = vec3<u32>(scene[ix], scene[ix + 1u], scene[ix + 2u]);
        let vb = scene[ib + 27u];
        let flags = scene[ib + 28u];
        if (!flat) {
            let n = row_transform(ib + 12u, interpolate3(params.sec_b.w + vb * 3u, idx, bary), 0.0);
            let len = length(n);
            if (len > 0.0 && len < FAR) {
                ns = n / len;
            }
        }
        if (textured && (flags & 2u) != 0u) {
            let ub = params.sec_c.x + vb * 2u;
            let a = vec2<f32>(fword(ub + idx.x * 2u), fword(ub + idx.x * 2u + 1u));
            let b = vec2<f32>(fword(ub + idx.y * 2u), fword(ub + idx.y * 2u + 1u));
            let c = vec2<f32>(fword(ub + idx.z * 2u), fword(ub + idx.z * 2u + 1u));
            uv = a * bary.x + b * bary.y + c * bary.z;
        }
    }
    if (dot(ns, ng) < 0.0) {
        ns = -ns;
    }
    found.kind = SURFACE;
    found.t = hit.t;
    found.p = o + d * hit.t;
    found.ng = ng;
    found.ns = ns;
    found.uv = uv;
    found.material = mb;
    return found;
}

// Texture::sample: bilinear with wrap-around, uv (0, 0) at the bottom-left.
fn texel(base: u32, w: u32, h: u32, xi: f32, yi: f32) -> vec3<f32> {
    let x = u32(((i32(xi) % i32(w)) + i32(w)) % i32(w));
    let y = u32(((i32(yi) % i32(h)) + i32(h)) % i32(h));
    let k = base + (y * w + x) * 3u;
    return vec3<f32>(texels[k], texels[k + 1u], texels[k + 2u]);
}

fn albedo_of(mb: u32, uv: vec2<f32>) -> vec3<f32> {
    let base_color = vec3_at(mb + 4u);
    if (scene[mb + 12u] == 0u) {
        return base_color;
    }
    let base = scene[mb + 1u];
    let w = scene[mb + 2u];
    let h = scene[mb + 3u];
    let x = rem_euclid1(uv.x) * f32(w) - 0.5;
    let y = (1.0 - rem_euclid1(uv.y)) * f32(h) - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let top = mix(texel(base, w, h, x0, y0), texel(base, w, h, x0 + 1.0, y0), fx);
    let bottom = mix(texel(base, w, h, x0, y0 + 1.0), texel(base, w, h, x0 + 1.0, y0 + 1.0), fx);
    return mix(top, bottom, fy) * base_color;
}

fn mis(a: f32, b: f32) -> f32 {
    let a2 = a * a;
    let b2 = b * b;
    return select(0.0, a2 / (a2 + b2), a2 + b2 > 0.0);
}

fn offset_origin(p: vec3<f32>, ng: vec3<f32>, dir: vec3<f32>) -> vec3<f32> {
    let eps = 1e-4 * (1.0 + max3(abs(p)));
    return select(p - ng * eps, p + ng * eps, dot(ng, dir) >= 0.0);
}

// One light sample at p, shadow-tested and MIS-weighted (xyz); w is 1 when a shadow ray
// was cast.
fn next_event(b: Bsdf, f: Frame, p: vec3<f32>, ng: vec3<f32>, wo: vec3<f32>, u: vec3<f32>) -> vec4<f32> {
    let ls = sample_light(p, u);
    if (!ls.ok) {
        return vec4<f32>(0.0);
    }
    let e = bsdf_eval(b, wo, to_local(f, ls.wi));
    if (is_zero(e.xyz) || is_zero(ls.radiance)) {
        return vec4<f32>(0.0);
    }
    let origin = offset_origin(p, ng, ls.wi);
    var tmax = FAR;
    if (ls.dist < FAR) {
        tmax = max(ls.dist * (1.0 - 1e-3), 0.0);
    }
    if (occluded(origin, ls.wi, tmax)) {
        return vec4<f32>(0.0, 0.0, 0.0, 1.0);
    }
    if (ls.pdf == 0.0) {
        return vec4<f32>(e.xyz * ls.radiance, 1.0);
    }
    return vec4<f32>(e.xyz * ls.radiance * (mis(ls.pdf, e.w) / ls.pdf), 1.0);
}

struct PathOut {
    reflected: vec3<f32>,
    emission: vec3<f32>,
    rays: u32,
}

struct PathState {
    throughput: vec3<f32>,
    prev_pdf: f32,
    prev_delta: bool,
    depth: u32,
    nee: bool,
}

// Emitted radiance reached by the path: seen directly at depth 1, else MIS-weighted
// against light sampling unless the previous bounce could not have sampled a light.
fn emit(out: ptr<function, PathOut>, st: PathState, radiance: vec3<f32>, light_pdf: f32) {
    if (st.depth == 1u) {
        (*out).emission = (*out).emission + radiance;
    } else {
        var w = 1.0;
        if (!st.prev_delta && st.nee) {
            w = mis(st.prev_pdf, light_pdf);
        }
        (*out).reflected = (*out).reflected + st.throughput * radiance * w;
    }
}

fn trace_path(s: ptr<function, Stream>, pixel_pos: vec2<f32>, max_depth: u32, nee: bool) -> PathOut {
    let cam = next4(s);
    let ray = camera_ray(pixel_pos + cam.xy, cam.zw);
    var o = ray[0];
    var d = ray[1];
    var out = PathOut(vec3<f32>(0.0), vec3<f32>(0.0), 0u);
    var st = PathState(vec3<f32>(1.0), 0.0, true, 1u, nee);
    loop {
        out.rays = out.rays + 1u;
        let f = closest(o, d);
        if (f.kind == MISS) {
            let e = escaped(d);
            if (!is_zero(e.env.xyz)) {
                emit(&out, st, e.env.xyz, e.env.w);
            }
            if (!is_zero(e.sun.xyz)) {
                emit(&out, st, e.sun.xyz, e.sun.w);
            }
            break;
        }
        if (f.kind == LIGHT) {
            let a = area_base(f.light);
            let c = -dot(d, vec3_at(a + 9u));
            if (c > 0.0) {
                let radiance = vec3_at(a + 12u);
                emit(&out, st, radiance, area_pdf(radiance, f.t * f.t, c));
            }
            break;
        }
        let mb = f.material;
        let wo_world = -d;
        let emission = vec3_at(mb + 9u);
        if (max3(emission) > 0.0) {
            let c = dot(wo_world, f.ng);
            if (c > 0.0) {
                let v = f.p - o;
                emit(&out, st, emission, area_pdf(emission, dot(v, v), c));
            }
        }
        if (st.depth >= max_depth) {
            break;
        }
        let b = Bsdf(scene[mb], albedo_of(mb, f.uv), fword(mb + 7u), fword(mb + 8u));
        var ng = f.ng;
        var ns = f.ns;
        if (two_sided(b) && dot(ng, wo_world) < 0.0) {
            ng = -ng;
            ns = -ns;
        }
        var frame = make_frame(ns);
        var wo = to_local(frame, wo_world);
        if (two_sided(b) && wo.z <= 0.0) {
            frame = make_frame(ng);
            wo = to_local(frame, wo_world);
        }
        // Drawn either way, so that the stream's indices do not depend on the strategy.
        let u_light = next4(s);
        if (nee && !is_delta(b)) {
            let c = next_event(b, frame, f.p, ng, wo, u_light.xyz);
            out.rays = out.rays + u32(c.w);
            out.reflected = out.reflected + st.throughput * c.xyz;
        }
        let u = next4(s);
        let smp = bsdf_sample(b, wo, u.xyz);
        if (!smp.ok) {
            break;
        }
        let wi = to_world(frame, smp.wi);
        st.throughput = st.throughput * smp.weight;
        st.prev_pdf = smp.pdf;
        st.prev_delta = smp.delta;
        o = offset_origin(f.p, ng, wi);
        d = wi;
        st.depth = st.depth + 1u;
        if (st.depth > RR_START_DEPTH) {
            let q = min(max3(st.throughput), 0.95);
            if (u.w >= q) {
                break;
            }
            st.throughput = st.throughput / q;
        }
        if (is_zero(st.throughput)) {
            break;
        }
    }
    return out;
}

// Invocations per workgroup; the Rust side dispatches ceil(pixels / 64) groups in rows.
const GROUP: u32 = 64u;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * GROUP;
    if (i >= params.job.x) {
        return;
    }
    let px = pixels[i];
    let width = max(params.image.x, 1u);
    let pos = vec2<f32>(f32(px.x % width), f32(px.x / width));
    let spp = max(params.image.z, 1u);
    var reflected = vec3<f32>(0.0);
    var emission = vec3<f32>(0.0);
    var rays = 0u;
    for (var index = 0u; index < spp; index = index + 1u) {
        var s = Stream(px.y, reverseBits(index), 0u);
        let r = trace_path(&s, pos, params.image.w, params.job.y != 0u);
        reflected = reflected + r.reflected;
        emission = emission + r.emission;
        rays = rays + r.rays;
    }
    let inv = 1.0 / f32(spp);
    results[2u * i] = vec4<f32>(reflected * inv, bitcast<f32>(rays));
    results[2u * i + 1u] = vec4<f32>(emission * inv, 0.0);
}
