// The SVGF reprojection (on a new scene state): each pixel's history from the previous
// frame's four pixels around where its hit point was, through the object's and the
// camera's motion; taps on another surface are rejected. CPU reference:
// `reconstruct::svgf::reproject`. Positions carry the object index in w (-1: none).

struct ObjectMotion {
    // Current world to previous world.
    to_prev: mat4x4<f32>,
    // x: the object's index in the previous state, -1 for none.
    prev: vec4<i32>,
}

@group(0) @binding(2) var normals: texture_2d<f32>;
@group(0) @binding(3) var positions: texture_2d<f32>;
@group(0) @binding(4) var prev_normals: texture_2d<f32>;
@group(0) @binding(5) var prev_positions: texture_2d<f32>;
@group(0) @binding(6) var hist_sum: texture_2d<f32>;
@group(0) @binding(7) var hist_lum: texture_2d<f32>;
@group(0) @binding(8) var<storage, read> objects: array<ObjectMotion>;
@group(0) @binding(9) var out_sum: texture_storage_2d<rgba32float, write>;
@group(0) @binding(10) var out_lum: texture_storage_2d<rgba32float, write>;

// Normals closer than this (cosine) count as the same surface.
const SAME_NORMAL: f32 = 0.9;
// Tolerance off the plane in pixel footprints.
const SAME_PLANE_PIXELS: f32 = 2.0;
// Bilinear weight below which a pixel starts empty.
const MIN_WEIGHT: f32 = 1e-3;

fn store(p: vec2<i32>, sum: vec4<f32>, lum: vec2<f32>) {
    textureStore(out_sum, p, sum);
    textureStore(out_lum, p, vec4<f32>(lum, 0.0, 0.0));
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (outside(id)) {
        return;
    }
    let q = vec2<i32>(id.xy);
    let zero = vec4<f32>(0.0);
    let n0 = textureLoad(normals, q, 0).xyz;
    let p0 = textureLoad(positions, q, 0);
    let object = i32(p0.w);
    if (svgf.keep == 0u || !is_surface(n0) || object < 0 || u32(object) >= arrayLength(&objects)) {
        store(q, zero, vec2<f32>(0.0));
        return;
    }
    let motion = objects[object];
    let prev_object = motion.prev.x;
    if (prev_object < 0) {
        store(q, zero, vec2<f32>(0.0));
        return;
    }
    let p = (motion.to_prev * vec4<f32>(p0.xyz, 1.0)).xyz;
    let n = normalize((motion.to_prev * vec4<f32>(n0, 0.0)).xyz);
    var at = vec2<f32>(f32(q.x) + 0.5, f32(q.y) + 0.5);
    var tolerance = svgf.still_plane;
    if (svgf.has_camera == 1u) {
        let v = p - svgf.origin.xyz;
        let depth = dot(v, svgf.forward.xyz);
        if (depth <= 1e-6) {
            store(q, zero, vec2<f32>(0.0));
            return;
        }
        let x = dot(v, svgf.right.xyz) / (depth * svgf.origin.w);
        let y = dot(v, svgf.up.xyz) / (depth * svgf.forward.w);
        at = vec2<f32>((x + 1.0) * 0.5 * svgf.right.w, (1.0 - y) * 0.5 * svgf.up.w);
        let footprint = length(p - svgf.origin.xyz) * 2.0 * svgf.forward.w / svgf.up.w;
        tolerance = SAME_PLANE_PIXELS * footprint;
    }
    let f = at - vec2<f32>(0.5);
    let x0 = floor(f.x);
    let y0 = floor(f.y);
    let fx = f.x - x0;
    let fy = f.y - y0;
    let taps = array<vec3<f32>, 4>(
        vec3<f32>(0.0, 0.0, (1.0 - fx) * (1.0 - fy)),
        vec3<f32>(1.0, 0.0, fx * (1.0 - fy)),
        vec3<f32>(0.0, 1.0, (1.0 - fx) * fy),
        vec3<f32>(1.0, 1.0, fx * fy),
    );
    var sum = vec4<f32>(0.0);
    var lum = vec2<f32>(0.0);
    var wsum = 0.0;
    for (var k = 0; k < 4; k++) {
        let wgt = taps[k].z;
        let t = vec2<i32>(i32(x0 + taps[k].x), i32(y0 + taps[k].y));
        if (wgt <= 0.0 || !inside(t)) {
            continue;
        }
        let pp = textureLoad(prev_positions, t, 0);
        let same = i32(pp.w) == prev_object
            && dot(textureLoad(prev_normals, t, 0).xyz, n) > SAME_NORMAL
            && abs(dot(pp.xyz - p, n)) <= tolerance;
        if (same) {
            sum += textureLoad(hist_sum, t, 0) * wgt;
            lum += textureLoad(hist_lum, t, 0).xy * wgt;
            wsum += wgt;
        }
    }
    if (!(wsum > MIN_WEIGHT)) {
        store(q, zero, vec2<f32>(0.0));
        return;
    }
    sum /= wsum;
    lum /= wsum;
    if (sum.w > svgf.cap) {
        let k = svgf.cap / sum.w;
        sum *= k;
        lum *= k;
    }
    store(q, sum, lum);
}
