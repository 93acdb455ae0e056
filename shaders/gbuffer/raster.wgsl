// standalone: the G-buffer raster pass (src/gbuffer/gpu.rs), not a compute pass.
//
// Rasterises every visible object instance (and every `Light::Quad`) with the camera of the
// tracer's primary rays and writes what `render::primary_hit` returns for the pixel centre.
// WebGPU guarantees only 32 bytes of colour targets per sample, so the values are written in
// two passes over the same geometry: `fs_geometry` (position + object, shading normal + hit
// flag) fills the depth buffer, `fs_material` (albedo, emission) runs with depth test `equal`.
// `@invariant` keeps the depth of both passes bit-identical.

struct View {
    // World to clip: reverse-Z, infinite far plane (CameraRays::raster_view).
    view_proj: mat4x4<f32>,
    // Origin of the primary rays (w unused).
    eye: vec4<f32>,
};

// One draw: an instance's material slot, or the light quads. Mirrors `DrawUniform`.
struct Draw {
    object_to_world: mat4x4<f32>,
    // Inverse transpose of the linear part, as `Instance::normal_to_world`.
    normal_to_world: mat3x3<f32>,
    // Material base colour (rgb) and whether the albedo texture applies (w = 1).
    base_color: vec4<f32>,
    // Emitted radiance (rgb), seen from the front (winding) side only.
    emission: vec4<f32>,
    // x: object index + 1 (0 for light quads); y: 1 for light quads (albedo 1, no clamp).
    info: vec4<u32>,
};

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<uniform> draw: Draw;
// Linear RGB albedo texture (a 1×1 placeholder for untextured materials); rgba32float is
// not filterable everywhere, so the bilinear lookup is done by hand, as `Texture::sample`.
@group(1) @binding(0) var albedo_map: texture_2d<f32>;

// Smallest albedo the tracer divides out (integrator.rs MIN_ALBEDO).
const MIN_ALBEDO: f32 = 1e-3;

struct VertexIn {
    // Object space.
    @location(0) position: vec3<f32>,
    // Object-space shading normal; zero when the mesh has none.
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    // Object-space e1 × e2 of the vertex's triangle (the tracer's geometric normal).
    @location(3) face: vec3<f32>,
};

struct VertexOut {
    @invariant @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) face: vec3<f32>,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let world = draw.object_to_world * vec4<f32>(v.position, 1.0);
    var out: VertexOut;
    out.clip = view.view_proj * world;
    out.world = world.xyz;
    out.normal = v.normal;
    out.uv = v.uv;
    out.face = v.face;
    return out;
}

// The tracer's geometric normal: unit, on the triangle's winding side.
fn geometric_normal(face: vec3<f32>) -> vec3<f32> {
    return normalize(draw.normal_to_world * face);
}

// Interpolated shading normal turned to the geometric normal's side (integrator.rs
// `closest`); the geometric normal where the mesh has none.
fn shading_normal(interpolated: vec3<f32>, ng: vec3<f32>) -> vec3<f32> {
    let n = draw.normal_to_world * interpolated;
    let len2 = dot(n, n);
    var ns = ng;
    if (len2 > 0.0 && len2 < 3.4e38) {
        ns = n * inverseSqrt(len2);
    }
    if (dot(ns, ng) < 0.0) {
        ns = -ns;
    }
    return ns;
}

fn texel(size: vec2<i32>, x: i32, y: i32) -> vec3<f32> {
    let wrapped = ((vec2<i32>(x, y) % size) + size) % size;
    return textureLoad(albedo_map, wrapped, 0).rgb;
}

// `Texture::sample`: bilinear with wrap-around, uv (0, 0) the bottom-left corner.
fn sample_albedo(uv: vec2<f32>) -> vec3<f32> {
    let size = vec2<i32>(textureDimensions(albedo_map));
    let fsize = vec2<f32>(size);
    let wrapped = uv - floor(uv);
    let x = wrapped.x * fsize.x - 0.5;
    let y = (1.0 - wrapped.y) * fsize.y - 0.5;
    let x0 = floor(x);
    let y0 = floor(y);
    let fx = x - x0;
    let fy = y - y0;
    let xi = i32(x0);
    let yi = i32(y0);
    let a = texel(size, xi, yi);
    let top = a + (texel(size, xi + 1, yi) - a) * fx;
    let c = texel(size, xi, yi + 1);
    let bottom = c + (texel(size, xi + 1, yi + 1) - c) * fx;
    return top + (bottom - top) * fy;
}

struct GeometryOut {
    // World position; w = object index + 1 (0: a light quad or nothing).
    @location(0) position: vec4<f32>,
    // World shading normal; w = 1 where something was hit (the clear value is 0).
    @location(1) normal: vec4<f32>,
};

@fragment
fn fs_geometry(in: VertexOut) -> GeometryOut {
    let ng = geometric_normal(in.face);
    var out: GeometryOut;
    out.position = vec4<f32>(in.world, f32(draw.info.x));
    out.normal = vec4<f32>(shading_normal(in.normal, ng), 1.0);
    return out;
}

struct MaterialOut {
    @location(0) albedo: vec4<f32>,
    @location(1) emission: vec4<f32>,
};

@fragment
fn fs_material(in: VertexOut) -> MaterialOut {
    let ng = geometric_normal(in.face);
    var out: MaterialOut;
    var albedo = vec3<f32>(1.0);
    if (draw.info.y == 0u) {
        albedo = draw.base_color.rgb;
        if (draw.base_color.w > 0.5) {
            albedo = sample_albedo(in.uv) * albedo;
        }
        albedo = max(albedo, vec3<f32>(MIN_ALBEDO));
    }
    out.albedo = vec4<f32>(albedo, 1.0);
    // Emission only towards the front side, as the camera ray sees it.
    var emission = vec3<f32>(0.0);
    if (dot(in.world - view.eye.xyz, ng) < 0.0) {
        emission = draw.emission.rgb;
    }
    out.emission = vec4<f32>(emission, 0.0);
    return out;
}
