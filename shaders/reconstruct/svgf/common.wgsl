// Shared by the SVGF passes (prefixed to each after the reconstruction's common block): the
// SVGF uniform block, luminance and the edge-stopping weights. The Rust mirror is
// `reconstruct::svgf::gpu::SvgfUniforms`; the CPU references are `svgf::edges` and
// `svgf::reproject`; keep them identical.

struct Svgf {
    // À-trous step of this iteration (pixels).
    step: i32,
    // log2 of the normal exponent.
    normal_squarings: u32,
    // sigma^2 of the plane test.
    plane2: f32,
    // Added to a so that coincident points weigh 1.
    eps2: f32,
    sigma_luminance: f32,
    // Samples the reprojected history counts for at most.
    cap: f32,
    // 1: the previous camera projects (else each pixel maps to itself).
    has_camera: u32,
    // 1: reproject the history; 0: drop it.
    keep: u32,
    // The previous camera: origin | half_w, forward | half_h, right | width, up | height.
    origin: vec4<f32>,
    forward: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    // Tolerance off the plane without a camera (scene units).
    still_plane: f32,
    // 1: this frame's samples rescale the history where the lighting changed (gradient).
    gradient: u32,
    tiles_x: u32,
    tiles_y: u32,
}

@group(0) @binding(1) var<uniform> svgf: Svgf;

fn luminance(c: vec3<f32>) -> f32 {
    return c.x * 0.2126 + c.y * 0.7152 + c.z * 0.0722;
}

// The geometric weight between pixels i and j (0 where j has no surface).
fn geometry(ni: vec3<f32>, pi: vec3<f32>, nj: vec3<f32>, pj: vec3<f32>) -> f32 {
    var wn = max(dot(ni, nj), 0.0);
    for (var k = 0u; k < svgf.normal_squarings; k++) {
        wn = wn * wn;
    }
    if (!(wn > 0.0)) {
        return 0.0;
    }
    let delta = pj - pi;
    let d = dot(ni, delta);
    let a = dot(delta, delta) * svgf.plane2 + svgf.eps2;
    let wp = a / (a + d * d);
    return wn * wp * wp;
}

// The luminance weight of a difference scaled by 1/(sigma_l sigma_i).
fn luminance_weight(dl: f32, inv: f32) -> f32 {
    let t = 1.0 + abs(dl) * inv;
    let t2 = t * t;
    return 1.0 / (t2 * t2);
}

fn inside(p: vec2<i32>) -> bool {
    return p.x >= 0 && p.y >= 0 && p.x < i32(params.width) && p.y < i32(params.height);
}
