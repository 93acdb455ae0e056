// Next-event estimation's light table (src/render/lights.rs and envmap.rs): strategies
// chosen with equal probability (all area emitters by power, each point or spot light,
// the sun, the environment with its marginal/conditional CDFs); every pdf includes the
// strategy's probability so that the path loop can weigh it against BSDF sampling.

const AREA_WORDS: u32 = 16u;
const POINT_WORDS: u32 = 12u;

struct LightSample {
    wi: vec3<f32>,
    // FAR for the sun and the environment.
    dist: f32,
    radiance: vec3<f32>,
    // 0 marks a delta light whose radiance is already divided by its selection probability.
    pdf: f32,
    ok: bool,
}

fn no_light() -> LightSample {
    return LightSample(vec3<f32>(0.0), 0.0, vec3<f32>(0.0), 0.0, false);
}

// Number of entries of the ascending words [base, base + n) that are <= x.
fn count_le(base: u32, n: u32, x: f32) -> u32 {
    var lo = 0u;
    var hi = n;
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        if (fword(base + mid) <= x) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}

fn area_pdf(radiance: vec3<f32>, dist2: f32, cos_light: f32) -> f32 {
    let power = params.lights_b.x;
    if (power <= 0.0 || cos_light <= 0.0) {
        return 0.0;
    }
    let per_area = (radiance.x + radiance.y + radiance.z) / power;
    return params.lights_b.y * per_area * dist2 / cos_light;
}

fn area_base(i: u32) -> u32 {
    return params.sec_c.w + i * AREA_WORDS;
}

fn sample_area(p: vec3<f32>, u: f32, u2: vec2<f32>) -> LightSample {
    let n = params.lights_a.x;
    let target_power = u * params.lights_b.x;
    let i = min(count_le(params.sec_d.x, n, target_power), n - 1u);
    let a = area_base(i);
    var st = u2;
    if (scene[a + 15u] == 0u) {
        let r = sqrt(u2.x);
        st = vec2<f32>(1.0 - r, u2.y * r);
    }
    let q = vec3_at(a) + vec3_at(a + 3u) * st.x + vec3_at(a + 6u) * st.y;
    let d = q - p;
    let dist2 = dot(d, d);
    let dist = sqrt(dist2);
    let wi = d / dist;
    let cos_light = -dot(wi, vec3_at(a + 9u));
    if (cos_light <= 0.0 || dist2 == 0.0) {
        return no_light();
    }
    let radiance = vec3_at(a + 12u);
    return LightSample(wi, dist, radiance, area_pdf(radiance, dist2, cos_light), true);
}

fn sample_point(k: u32, p: vec3<f32>) -> LightSample {
    let b = params.sec_d.y + k * POINT_WORDS;
    let d = vec3_at(b) - p;
    let dist2 = max(dot(d, d), 1e-12);
    let dist = sqrt(dist2);
    let wi = d / dist;
    var radiance = vec3_at(b + 3u) / dist2;
    if (scene[b + 11u] != 0u) {
        let c = dot(-wi, vec3_at(b + 6u));
        let cos_inner = fword(b + 9u);
        let cos_outer = fword(b + 10u);
        var falloff = select(0.0, 1.0, c >= cos_outer);
        if (cos_inner > cos_outer) {
            let x = clamp((c - cos_outer) / (cos_inner - cos_outer), 0.0, 1.0);
            falloff = x * x * (3.0 - 2.0 * x);
        }
        radiance = radiance * falloff;
    }
    return LightSample(wi, dist, radiance / params.lights_b.y, 0.0, true);
}

fn sample_sun(u: vec2<f32>) -> LightSample {
    let cos_max = params.lights_b.z;
    let pmf = params.lights_b.y;
    if (cos_max >= 1.0) {
        return LightSample(params.sun_dir.xyz, FAR, params.sun_radiance.xyz / pmf, 0.0, true);
    }
    let c = 1.0 - u.x * (1.0 - cos_max);
    let s = sqrt(max(1.0 - c * c, 0.0));
    let phi = 2.0 * PI * u.y;
    let wi = to_world(make_frame(params.sun_dir.xyz), vec3<f32>(s * cos(phi), s * sin(phi), c));
    let pdf = pmf / (2.0 * PI * (1.0 - cos_max));
    return LightSample(wi, FAR, params.sun_radiance.xyz, pdf, true);
}

fn sample_light(p: vec3<f32>, u: vec3<f32>) -> LightSample {
    let strategies = params.lights_a.z;
    if (strategies == 0u) {
        return no_light();
    }
    let pick = min(u32(u.x * f32(strategies)), strategies - 1u);
    var k = pick;
    if (params.lights_a.x > 0u) {
        if (k == 0u) {
            let ua = clamp(u.x * f32(strategies) - f32(pick), 0.0, 0.999999);
            return sample_area(p, ua, u.yz);
        }
        k = k - 1u;
    }
    if (k < params.lights_a.y) {
        return sample_point(k, p);
    }
    k = k - params.lights_a.y;
    if (params.lights_b.w > 0.0) {
        if (k == 0u) {
            return sample_sun(u.yz);
        }
        k = k - 1u;
    }
    if (params.env.x == 0u) {
        return no_light();
    }
    let e = env_sample(u.yz);
    if (e.pdf > 0.0) {
        return LightSample(e.wi, FAR, e.radiance, e.pdf * params.lights_b.y, true);
    }
    return no_light();
}

// ---- The environment: a constant, or an equirectangular map (row 0 the zenith, +y up).

fn env_to_map(d: vec3<f32>) -> vec3<f32> {
    let c = params.env_rot.x;
    let s = params.env_rot.y;
    return vec3<f32>(c * d.x - s * d.z, d.y, s * d.x + c * d.z);
}

fn env_to_world(d: vec3<f32>) -> vec3<f32> {
    let c = params.env_rot.x;
    let s = params.env_rot.y;
    return vec3<f32>(c * d.x + s * d.z, d.y, -s * d.x + c * d.z);
}

fn env_texel_of(local: vec3<f32>) -> vec2<u32> {
    let w = params.env.y;
    let h = params.env.z;
    let theta = acos(clamp(local.y, -1.0, 1.0));
    var phi = atan2(local.z, local.x) % (2.0 * PI);
    if (phi < 0.0) {
        phi = phi + 2.0 * PI;
    }
    let x = min(u32(phi / (2.0 * PI) * f32(w)), w - 1u);
    let y = min(u32(theta / PI * f32(h)), h - 1u);
    return vec2<u32>(x, y);
}

fn env_eval(dir: vec3<f32>) -> vec3<f32> {
    if (params.env.x == 1u) {
        return params.env_scale.xyz;
    }
    let t = env_texel_of(env_to_map(dir));
    let k = params.sec_e.z + (t.y * params.env.y + t.x) * 3u;
    return vec3<f32>(texels[k], texels[k + 1u], texels[k + 2u]) * params.env_scale.xyz;
}

// A piecewise-constant distribution at word `b`: integral, n, cdf[n + 1], func[n].
fn dist_pdf(b: u32, i: u32) -> f32 {
    let integral = fword(b);
    if (integral > 0.0) {
        return fword(b + 3u + scene[b + 1u] + i) / integral;
    }
    return 1.0;
}

// A continuous sample in [0, 1) (x) and its bin (y, as bits).
fn dist_sample(b: u32, u: f32) -> vec2<f32> {
    let n = scene[b + 1u];
    let cdf = b + 2u;
    let i = min(max(count_le(cdf, n + 1u, u), 1u) - 1u, n - 1u);
    let width = fword(cdf + i + 1u) - fword(cdf + i);
    var du = 0.5;
    if (width > 0.0) {
        du = (u - fword(cdf + i)) / width;
    }
    let x = min((f32(i) + clamp(du, 0.0, 1.0)) / f32(n), 1.0 - 1.1920929e-7);
    return vec2<f32>(x, bitcast<f32>(i));
}

fn env_row(y: u32) -> u32 {
    return params.sec_e.y + y * (2u * params.env.y + 3u);
}

fn env_pdf(dir: vec3<f32>) -> f32 {
    if (params.env.x == 1u) {
        return 1.0 / (4.0 * PI);
    }
    let local = env_to_map(dir);
    let t = env_texel_of(local);
    let sin_theta = sqrt(max(1.0 - local.y * local.y, 0.0));
    if (sin_theta <= 0.0) {
        return 0.0;
    }
    return dist_pdf(params.sec_e.x, t.y) * dist_pdf(env_row(t.y), t.x) / (2.0 * PI * PI * sin_theta);
}

struct EnvSample {
    wi: vec3<f32>,
    radiance: vec3<f32>,
    pdf: f32,
}

fn env_sample(u: vec2<f32>) -> EnvSample {
    if (params.env.x == 1u) {
        let z = 1.0 - 2.0 * u.x;
        let r = sqrt(max(1.0 - z * z, 0.0));
        let phi = 2.0 * PI * u.y;
        let wi = vec3<f32>(r * cos(phi), z, r * sin(phi));
        return EnvSample(wi, params.env_scale.xyz, 1.0 / (4.0 * PI));
    }
    let v = dist_sample(params.sec_e.x, u.y);
    let row = bitcast<u32>(v.y);
    let uu = dist_sample(env_row(row), u.x);
    let theta = v.x * PI;
    let phi = uu.x * 2.0 * PI;
    let sin_theta = sin(theta);
    if (sin_theta <= 0.0) {
        return EnvSample(vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0), 0.0);
    }
    let local = vec3<f32>(sin_theta * cos(phi), cos(theta), sin_theta * sin(phi));
    let dir = normalize(env_to_world(local));
    return EnvSample(dir, env_eval(dir), env_pdf(dir));
}

// Radiance along an escaping ray from the environment (xyz of the first) and the sun disc
// (the second), each with its light-sampling pdf in w.
struct Escaped {
    env: vec4<f32>,
    sun: vec4<f32>,
}

fn escaped(dir: vec3<f32>) -> Escaped {
    var out = Escaped(vec4<f32>(0.0), vec4<f32>(0.0));
    let pmf = params.lights_b.y;
    if (params.env.x != 0u) {
        out.env = vec4<f32>(env_eval(dir), env_pdf(dir) * pmf);
    }
    let cos_max = params.lights_b.z;
    if (params.lights_b.w > 0.0 && cos_max < 1.0 && dot(dir, params.sun_dir.xyz) >= cos_max) {
        out.sun = vec4<f32>(params.sun_radiance.xyz, pmf / (2.0 * PI * (1.0 - cos_max)));
    }
    return out;
}
