// The GPU path tracer's inputs (src/render/gpu/): the uniform `Params` (image, job, camera,
// where each section of the scene buffer starts, light and environment constants), the
// scene as one array of words (`src/render/gpu/pack.rs` writes it), texels, the job's
// pixels with their seeds, and the results. One scene buffer instead of one binding per
// table keeps within every adapter's eight storage buffers per stage.
// Assembled with bvh, material, lights and path (in that order) into one module.

struct Params {
    image: vec4<u32>,        // width, height, spp, max depth
    job: vec4<u32>,          // pixel count, NEE with MIS (1) or BSDF sampling only (0)
    cam_origin: vec4<f32>,   // xyz, aperture
    cam_forward: vec4<f32>,  // xyz, focus distance
    cam_right: vec4<f32>,    // xyz, half width of the image plane at distance one
    cam_up: vec4<f32>,       // xyz, half height
    cam_inv: vec4<f32>,      // 1 / width, 1 / height
    sec_a: vec4<u32>,        // word offsets: nodes, triangles, leaf data, instances
    sec_b: vec4<u32>,        // large instances, flat owners, mesh indices, normals
    sec_c: vec4<u32>,        // uvs, materials, slot materials, area lights
    sec_d: vec4<u32>,        // area cdf, point lights, quad list, Sobol tables
    sec_e: vec4<u32>,        // env marginal, env conditional rows, env texels (texel buffer)
    geo: vec4<u32>,          // flat triangle count, TLAS root node, large instance count
    lights_a: vec4<u32>,     // area count, point count, strategies, quad count
    lights_b: vec4<f32>,     // area power, strategy pmf, sun cos_max, has sun (1)
    sun_dir: vec4<f32>,
    sun_radiance: vec4<f32>,
    env: vec4<u32>,          // kind (0 none, 1 constant, 2 map), map width, height
    env_scale: vec4<f32>,    // map scale, or the constant radiance
    env_rot: vec4<f32>,      // cos and sin of the map's rotation about +y
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> scene: array<u32>;
@group(0) @binding(2) var<storage, read> texels: array<f32>;
// Per pixel: its index (y * width + x) and its sampler seed for the job's frame.
@group(0) @binding(3) var<storage, read> pixels: array<vec2<u32>>;
// Per pixel: reflected radiance and rays cast (bits in w), then directly seen emission.
@group(0) @binding(4) var<storage, read_write> results: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const FRAC_1_PI: f32 = 0.318309886183791;
// Stands for an infinite distance (inf * 0 would make NaNs in the node test).
const FAR: f32 = 3.0e38;
const NONE: u32 = 0xffffffffu;

fn fword(i: u32) -> f32 {
    return bitcast<f32>(scene[i]);
}

fn vec3_at(i: u32) -> vec3<f32> {
    return vec3<f32>(fword(i), fword(i + 1u), fword(i + 2u));
}

fn max3(v: vec3<f32>) -> f32 {
    return max(max(v.x, v.y), v.z);
}

fn is_zero(v: vec3<f32>) -> bool {
    return all(v == vec3<f32>(0.0));
}

// 1.0 with the sign bit of x (Rust's signum/copysign: -0.0 counts as negative).
fn sign_of(x: f32) -> f32 {
    return select(1.0, -1.0, (bitcast<u32>(x) >> 31u) != 0u);
}

fn rem_euclid1(x: f32) -> f32 {
    let r = x % 1.0;
    return select(r, r + 1.0, r < 0.0);
}

// ---- The sampler: src/render/sampler.rs, bit for bit (the pixel seed comes from the CPU,
// whose mix64 needs 64-bit integers that WGSL lacks).

fn laine_karras(x0: u32, seed: u32) -> u32 {
    var x = x0;
    x = x ^ (x * 0x3d20adeau);
    x = x + seed;
    x = x * ((seed >> 16u) | 1u);
    x = x ^ (x * 0x05526c56u);
    x = x ^ (x * 0x53a22864u);
    return x;
}

fn owen_scramble_reversed(reversed: u32, seed: u32) -> u32 {
    return reverseBits(laine_karras(reversed, seed));
}

fn mix32(x0: u32) -> u32 {
    var x = x0;
    x = x ^ (x >> 16u);
    x = x * 0x7feb352du;
    x = x ^ (x >> 15u);
    x = x * 0x846ca68bu;
    return x ^ (x >> 16u);
}

fn to_unit(x: u32) -> f32 {
    return f32(x >> 8u) * (1.0 / 16777216.0);
}

fn sobol_reversed(index: u32, dim: u32) -> u32 {
    let t = params.sec_d.w + dim * 1024u;
    return scene[t + (index & 0xffu)] ^ scene[t + 256u + ((index >> 8u) & 0xffu)]
        ^ scene[t + 512u + ((index >> 16u) & 0xffu)] ^ scene[t + 768u + (index >> 24u)];
}

struct Stream {
    pixel_seed: u32,
    index_reversed: u32,
    draw: u32,
}

fn next4(s: ptr<function, Stream>) -> vec4<f32> {
    let seed = mix32((*s).pixel_seed ^ mix32(((*s).draw * 0x9e3779b9u) ^ 0x68e31da4u));
    (*s).draw = (*s).draw + 1u;
    let i = owen_scramble_reversed((*s).index_reversed, seed);
    return vec4<f32>(
        to_unit(owen_scramble_reversed(i, mix32(seed ^ 0xa511e9b3u))),
        to_unit(owen_scramble_reversed(sobol_reversed(i, 0u), mix32(seed ^ 0x63d83595u))),
        to_unit(owen_scramble_reversed(sobol_reversed(i, 1u), mix32(seed ^ 0x9e1f4a13u))),
        to_unit(owen_scramble_reversed(sobol_reversed(i, 2u), mix32(seed ^ 0x2c1b3c6du))),
    );
}
