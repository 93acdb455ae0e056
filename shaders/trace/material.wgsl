// The four material kinds in a local shading frame (src/render/bsdf.rs and microfacet.rs,
// ported line by line): values are f · |cos θi| with the solid-angle pdf.

const DIFFUSE: u32 = 0u;
const CONDUCTOR: u32 = 1u;
const GLOSSY: u32 = 2u;
const DIELECTRIC: u32 = 3u;
const SMOOTH: f32 = 1e-3;

struct Frame {
    s: vec3<f32>,
    t: vec3<f32>,
    n: vec3<f32>,
}

fn make_frame(n: vec3<f32>) -> Frame {
    let sign = sign_of(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let s = vec3<f32>(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let t = vec3<f32>(b, sign + n.y * n.y * a, -n.y);
    return Frame(s, t, n);
}

fn to_local(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(v, f.s), dot(v, f.t), dot(v, f.n));
}

fn to_world(f: Frame, v: vec3<f32>) -> vec3<f32> {
    return f.s * v.x + f.t * v.y + f.n * v.z;
}

fn ggx_d(alpha: f32, m: vec3<f32>) -> f32 {
    if (m.z <= 0.0) {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let k = m.z * m.z * (a2 - 1.0) + 1.0;
    return a2 / (PI * k * k);
}

fn ggx_lambda(alpha: f32, w: vec3<f32>) -> f32 {
    let cos2 = w.z * w.z;
    if (cos2 >= 1.0) {
        return 0.0;
    }
    let tan2 = max(1.0 - cos2, 0.0) / cos2;
    return (sqrt(1.0 + alpha * alpha * tan2) - 1.0) * 0.5;
}

fn ggx_g1(alpha: f32, w: vec3<f32>) -> f32 {
    return 1.0 / (1.0 + ggx_lambda(alpha, w));
}

fn ggx_g2(alpha: f32, wo: vec3<f32>, wi: vec3<f32>) -> f32 {
    return 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
}

fn ggx_pdf_visible(alpha: f32, w: vec3<f32>, m: vec3<f32>) -> f32 {
    let c = abs(w.z);
    if (c == 0.0) {
        return 0.0;
    }
    return ggx_g1(alpha, w) * abs(dot(w, m)) * ggx_d(alpha, m) / c;
}

fn ggx_sample_visible(alpha: f32, w_in: vec3<f32>, u: vec2<f32>) -> vec3<f32> {
    let w = select(w_in, -w_in, w_in.z < 0.0);
    let vh = normalize(vec3<f32>(alpha * w.x, alpha * w.y, w.z));
    let len2 = vh.x * vh.x + vh.y * vh.y;
    var t1 = vec3<f32>(1.0, 0.0, 0.0);
    if (len2 > 0.0) {
        t1 = vec3<f32>(-vh.y, vh.x, 0.0) * (1.0 / sqrt(len2));
    }
    let t2 = cross(vh, t1);
    let r = sqrt(u.x);
    let phi = 2.0 * PI * u.y;
    let p1 = r * cos(phi);
    var p2 = r * sin(phi);
    let s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * p2;
    let nh = t1 * p1 + t2 * p2 + vh * sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
    return normalize(vec3<f32>(alpha * nh.x, alpha * nh.y, max(nh.z, 1e-6)));
}

fn fresnel_dielectric(cos_in: f32, eta_in: f32) -> f32 {
    var c = cos_in;
    var eta = eta_in;
    if (c < 0.0) {
        c = -c;
        eta = 1.0 / eta;
    }
    let sin2_t = max(1.0 - c * c, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let r_parl = (eta * c - cos_t) / (eta * c + cos_t);
    let r_perp = (c - eta * cos_t) / (c + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

fn fresnel_schlick(f0: vec3<f32>, c: f32) -> vec3<f32> {
    let x = 1.0 - clamp(c, 0.0, 1.0);
    let m = x * x * x * x * x;
    return f0 + (vec3<f32>(1.0) - f0) * m;
}

fn reflect_about(w: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    return 2.0 * dot(w, n) * n - w;
}

// Refraction (microfacet::refract): the direction and the index ratio crossed in w,
// or w = 0 on total internal reflection.
fn refract_through(w: vec3<f32>, n_in: vec3<f32>, eta_in: f32) -> vec4<f32> {
    var c = dot(n_in, w);
    var n = n_in;
    var eta = eta_in;
    if (c < 0.0) {
        eta = 1.0 / eta;
        c = -c;
        n = -n;
    }
    let sin2_t = max(1.0 - c * c, 0.0) / (eta * eta);
    if (sin2_t >= 1.0) {
        return vec4<f32>(0.0);
    }
    let cos_t = sqrt(1.0 - sin2_t);
    return vec4<f32>(-w / eta + (c / eta - cos_t) * n, eta);
}

fn cosine_hemisphere(u: vec2<f32>) -> vec3<f32> {
    let a = 2.0 * u - vec2<f32>(1.0);
    if (a.x == 0.0 && a.y == 0.0) {
        return vec3<f32>(0.0, 0.0, 1.0);
    }
    var r: f32;
    var phi: f32;
    if (abs(a.x) > abs(a.y)) {
        r = a.x;
        phi = PI / 4.0 * (a.y / a.x);
    } else {
        r = a.y;
        phi = PI / 2.0 - PI / 4.0 * (a.x / a.y);
    }
    let x = r * cos(phi);
    let y = r * sin(phi);
    return vec3<f32>(x, y, sqrt(max(1.0 - x * x - y * y, 0.0)));
}

struct Bsdf {
    kind: u32,
    color: vec3<f32>,
    alpha: f32,
    eta: f32,
}

fn is_delta(b: Bsdf) -> bool {
    return (b.kind == CONDUCTOR || b.kind == DIELECTRIC) && b.alpha < SMOOTH;
}

fn two_sided(b: Bsdf) -> bool {
    return b.kind != DIELECTRIC;
}

// f · |cos θi| in xyz and the pdf in w.
fn bsdf_eval(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    if (is_delta(b)) {
        return vec4<f32>(0.0);
    }
    switch b.kind {
        case 0u: {
            if (wi.z <= 0.0 || wo.z <= 0.0) {
                return vec4<f32>(0.0);
            }
            return vec4<f32>(b.color * (wi.z * FRAC_1_PI), wi.z * FRAC_1_PI);
        }
        case 1u: {
            return eval_conductor(b, wo, wi);
        }
        case 2u: {
            return eval_glossy(b, wo, wi);
        }
        default: {
            return eval_dielectric(b, wo, wi);
        }
    }
}

fn eval_conductor(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    if (wi.z <= 0.0 || wo.z <= 0.0) {
        return vec4<f32>(0.0);
    }
    let m = normalize(wo + wi);
    let d = ggx_d(b.alpha, m);
    let f = fresnel_schlick(b.color, dot(wo, m));
    let value = f * (d * ggx_g2(b.alpha, wo, wi) / (4.0 * wo.z));
    return vec4<f32>(value, ggx_g1(b.alpha, wo) * d / (4.0 * wo.z));
}

fn coat_probability(b: Bsdf, wo: vec3<f32>) -> f32 {
    let f = fresnel_dielectric(wo.z, b.eta);
    let base = (1.0 - f) * max3(b.color);
    return clamp(f / max(f + base, 1e-6), 0.0, 1.0);
}

fn eval_glossy(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    if (wi.z <= 0.0 || wo.z <= 0.0) {
        return vec4<f32>(0.0);
    }
    let m = normalize(wo + wi);
    let d = ggx_d(b.alpha, m);
    let f_o = fresnel_dielectric(wo.z, b.eta);
    let spec = f_o * d * ggx_g2(b.alpha, wo, wi) / (4.0 * wo.z);
    let transmit = (1.0 - f_o) * (1.0 - fresnel_dielectric(wi.z, b.eta));
    let diffuse = b.color * (transmit * wi.z * FRAC_1_PI);
    let p = coat_probability(b, wo);
    let pdf_spec = ggx_g1(b.alpha, wo) * d / (4.0 * wo.z);
    let pdf = p * pdf_spec + (1.0 - p) * wi.z * FRAC_1_PI;
    return vec4<f32>(vec3<f32>(spec) + diffuse, pdf);
}

fn eval_dielectric(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> vec4<f32> {
    let cos_o = wo.z;
    let cos_i = wi.z;
    if (cos_o == 0.0 || cos_i == 0.0) {
        return vec4<f32>(0.0);
    }
    let reflected = cos_i * cos_o > 0.0;
    var etap = 1.0;
    if (!reflected) {
        etap = select(1.0 / b.eta, b.eta, cos_o > 0.0);
    }
    let wm0 = wi * etap + wo;
    if (dot(wm0, wm0) == 0.0) {
        return vec4<f32>(0.0);
    }
    var wm = normalize(wm0);
    if (wm.z < 0.0) {
        wm = -wm;
    }
    if (dot(wm, wi) * cos_i < 0.0 || dot(wm, wo) * cos_o < 0.0) {
        return vec4<f32>(0.0);
    }
    let fr = fresnel_dielectric(dot(wo, wm), b.eta);
    let d = ggx_d(b.alpha, wm);
    let g = ggx_g2(b.alpha, wo, wi);
    let pdf_m = ggx_pdf_visible(b.alpha, wo, wm);
    if (reflected) {
        let f = d * g * fr / abs(4.0 * cos_i * cos_o);
        let pdf = pdf_m / (4.0 * abs(dot(wo, wm))) * fr;
        return vec4<f32>(vec3<f32>(f * abs(cos_i)), pdf);
    }
    let x = dot(wi, wm) + dot(wo, wm) / etap;
    let denom = x * x;
    let t = 1.0 - fr;
    var f = t * d * g * abs(dot(wi, wm) * dot(wo, wm) / (cos_i * cos_o * denom));
    f = f / (etap * etap);
    let pdf = pdf_m * abs(dot(wi, wm)) / denom * t;
    return vec4<f32>(b.color * (f * abs(cos_i)), pdf);
}

struct BsdfSample {
    wi: vec3<f32>,
    weight: vec3<f32>,
    pdf: f32,
    delta: bool,
    ok: bool,
}

fn no_sample() -> BsdfSample {
    return BsdfSample(vec3<f32>(0.0), vec3<f32>(0.0), 0.0, false, false);
}

fn weighted(b: Bsdf, wo: vec3<f32>, wi: vec3<f32>) -> BsdfSample {
    let e = bsdf_eval(b, wo, wi);
    if (e.w > 0.0) {
        return BsdfSample(wi, e.xyz / e.w, e.w, false, true);
    }
    return no_sample();
}

fn bsdf_sample(b: Bsdf, wo: vec3<f32>, u: vec3<f32>) -> BsdfSample {
    let u2 = u.yz;
    switch b.kind {
        case 0u: {
            if (wo.z <= 0.0) {
                return no_sample();
            }
            let wi = cosine_hemisphere(u2);
            return BsdfSample(wi, b.color, wi.z * FRAC_1_PI, false, true);
        }
        case 1u: {
            if (wo.z <= 0.0) {
                return no_sample();
            }
            if (is_delta(b)) {
                let wi = vec3<f32>(-wo.x, -wo.y, wo.z);
                return BsdfSample(wi, fresnel_schlick(b.color, wo.z), 1.0, true, true);
            }
            let m = ggx_sample_visible(b.alpha, wo, u2);
            let wi = reflect_about(wo, m);
            if (wi.z <= 0.0) {
                return no_sample();
            }
            let f = fresnel_schlick(b.color, dot(wo, m));
            let weight = f * (ggx_g2(b.alpha, wo, wi) / ggx_g1(b.alpha, wo));
            let pdf = ggx_g1(b.alpha, wo) * ggx_d(b.alpha, m) / (4.0 * wo.z);
            return BsdfSample(wi, weight, pdf, false, true);
        }
        case 2u: {
            if (wo.z <= 0.0) {
                return no_sample();
            }
            var wi: vec3<f32>;
            if (u.x < coat_probability(b, wo)) {
                wi = reflect_about(wo, ggx_sample_visible(b.alpha, wo, u2));
            } else {
                wi = cosine_hemisphere(u2);
            }
            return weighted(b, wo, wi);
        }
        default: {
            return sample_dielectric(b, wo, u);
        }
    }
}

fn sample_dielectric(b: Bsdf, wo: vec3<f32>, u: vec3<f32>) -> BsdfSample {
    if (wo.z == 0.0) {
        return no_sample();
    }
    if (is_delta(b)) {
        let fr = fresnel_dielectric(wo.z, b.eta);
        if (u.x < fr) {
            let wi = vec3<f32>(-wo.x, -wo.y, wo.z);
            return BsdfSample(wi, vec3<f32>(1.0), 1.0, true, true);
        }
        let r = refract_through(wo, vec3<f32>(0.0, 0.0, 1.0), b.eta);
        if (r.w == 0.0) {
            return no_sample();
        }
        return BsdfSample(r.xyz, b.color / (r.w * r.w), 1.0, true, true);
    }
    let wm = ggx_sample_visible(b.alpha, wo, u.yz);
    let fr = fresnel_dielectric(dot(wo, wm), b.eta);
    var wi: vec3<f32>;
    if (u.x < fr) {
        wi = reflect_about(wo, wm);
        if (wi.z * wo.z <= 0.0) {
            return no_sample();
        }
    } else {
        let r = refract_through(wo, wm, b.eta);
        if (r.w == 0.0) {
            return no_sample();
        }
        wi = r.xyz;
        if (wi.z * wo.z >= 0.0) {
            return no_sample();
        }
    }
    return weighted(b, wo, wi);
}
