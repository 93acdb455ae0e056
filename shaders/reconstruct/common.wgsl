// Shared by every reconstruction pass (prefixed to each pass's source): the uniform block
// and the discontinuity function D. The Rust mirror is `reconstruct::pass::Uniforms` and
// the CPU reference is `reconstruct::discontinuity`; keep all three identical.

struct Params {
    width: u32,
    height: u32,
    radius: i32,
    gauss_radius: i32,
    alpha: f32,
    // 1 / (1 - alpha).
    inv_one_minus_alpha: f32,
    // 1 / beta^2, beta in scene units.
    inv_beta2: f32,
    // Exposure multiplier (2^stops).
    exposure: f32,
    // 1: the scene state changed, restart the running average.
    reset: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    // w = 1/(F_i - F_j) per history layer; 0 = unused layer.
    history_weight: vec4<f32>,
    // exp(-d^2 / 2 sigma^2) for d = 0..7.
    gauss: array<vec4<f32>, 2>,
}

@group(0) @binding(0) var<uniform> params: Params;

// Intended meaning of the paper's D (docs/design.md): positive only when the normals agree and
// the positions are close, 1 for a pixel against itself, 0 for pixels with no surface.
fn discontinuity(ni: vec3<f32>, nj: vec3<f32>, zi: vec3<f32>, zj: vec3<f32>) -> f32 {
    let orientation = max((dot(ni, nj) - params.alpha) * params.inv_one_minus_alpha, 0.0);
    let d = zi - zj;
    let position = max(1.0 - dot(d, d) * params.inv_beta2, 0.0);
    return orientation * position;
}

fn is_surface(n: vec3<f32>) -> bool {
    return dot(n, n) > 0.25;
}

fn gauss_weight(d: i32) -> f32 {
    let k = u32(abs(d));
    return params.gauss[k / 4u][k % 4u];
}

fn outside(id: vec3<u32>) -> bool {
    return id.x >= params.width || id.y >= params.height;
}
