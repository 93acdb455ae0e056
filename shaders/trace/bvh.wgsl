// Ray traversal of the tracer's own BVHs (src/render/accel/), uploaded as they are:
// obvhs compressed wide BVH nodes (80 bytes, eight quantised children), triangles in leaf
// order as a vertex and two edges, the flattened world-space BVH of small instances and
// the TLAS over large ones, entered through each BLAS with the ray in object space. The
// node test and the traversal order are obvhs's (`traverse!`, `CwBvhNode::intersect_ray`).

const NODE_WORDS: u32 = 20u;
const INSTANCE_WORDS: u32 = 32u;
// obvhs's lower bound on entry distances.
const BVH_EPSILON: f32 = 0.0001;

struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
    inv: vec3<f32>,
    tmax: f32,
    // Child order by octant, as obvhs's `oct_inv4` (one byte is enough).
    oct: u32,
}

fn safe_inverse(x: f32) -> f32 {
    let eps = 1.1920929e-7;
    if (abs(x) <= eps) {
        return sign_of(x) / eps;
    }
    return 1.0 / x;
}

fn make_ray(o: vec3<f32>, d: vec3<f32>, tmax: f32) -> Ray {
    let inv = vec3<f32>(safe_inverse(d.x), safe_inverse(d.y), safe_inverse(d.z));
    let oct = select(4u, 0u, d.x < 0.0) | select(2u, 0u, d.y < 0.0) | select(1u, 0u, d.z < 0.0);
    return Ray(o, d, inv, tmax, oct);
}

fn byte_of(lo: u32, hi: u32, j: u32) -> u32 {
    let w = select(hi, lo, j < 4u);
    return (w >> ((j & 3u) * 8u)) & 0xffu;
}

// The hit mask of node word offset `n`: child bits shifted to their traversal priority.
fn node_hits(n: u32, ray: Ray) -> u32 {
    let p = vec3_at(n);
    let ew = scene[n + 3u];
    let e = vec3<f32>(
        bitcast<f32>((ew & 0xffu) << 23u),
        bitcast<f32>(((ew >> 8u) & 0xffu) << 23u),
        bitcast<f32>(((ew >> 16u) & 0xffu) << 23u),
    );
    let scale = e * ray.inv;
    let shift = (p - ray.o) * ray.inv;
    let neg = ray.d < vec3<f32>(0.0);
    let meta_lo = scene[n + 6u];
    let meta_hi = scene[n + 7u];
    var mask = 0u;
    for (var j = 0u; j < 8u; j = j + 1u) {
        let cmeta = byte_of(meta_lo, meta_hi, j);
        if (cmeta == 0u) {
            continue; // an empty slot adds no bits
        }
        let lo = vec3<f32>(
            f32(byte_of(scene[n + 8u], scene[n + 9u], j)),
            f32(byte_of(scene[n + 12u], scene[n + 13u], j)),
            f32(byte_of(scene[n + 16u], scene[n + 17u], j)),
        );
        let hi = vec3<f32>(
            f32(byte_of(scene[n + 10u], scene[n + 11u], j)),
            f32(byte_of(scene[n + 14u], scene[n + 15u], j)),
            f32(byte_of(scene[n + 18u], scene[n + 19u], j)),
        );
        let tn = select(lo, hi, neg) * scale + shift;
        let tf = select(hi, lo, neg) * scale + shift;
        let tmin = max(max3(tn), BVH_EPSILON);
        let tmax = min(min(min(tf.x, tf.y), tf.z), ray.tmax);
        if (tmin <= tmax) {
            let inner = select(0u, 0xffu, ((cmeta & (cmeta << 1u)) & 0x10u) != 0u);
            let bit_index = (cmeta ^ (ray.oct & inner)) & 0x1fu;
            mask = mask | (((cmeta >> 5u) & 7u) << bit_index);
        }
    }
    return mask;
}

// The traversal state of obvhs's `traverse!`, stepped one primitive at a time.
struct Trav {
    stack: array<vec2<u32>, 32>,
    sp: u32,
    current: vec2<u32>,
    prims: vec2<u32>,
    root: u32,
}

fn trav_start(root: u32) -> Trav {
    var t: Trav;
    t.sp = 0u;
    t.current = vec2<u32>(0u, 0x80000000u);
    t.prims = vec2<u32>(0u, 0u);
    t.root = root;
    return t;
}

// The next leaf-order primitive whose leaf the ray enters, or NONE when traversal ends.
fn trav_next(t: ptr<function, Trav>, ray: Ray) -> u32 {
    loop {
        if ((*t).prims.y != 0u) {
            let local = firstLeadingBit((*t).prims.y);
            (*t).prims.y = (*t).prims.y & ~(1u << local);
            return (*t).prims.x + local;
        }
        if (((*t).current.y & 0xff000000u) != 0u) {
            let hits = (*t).current.y;
            let offset = firstLeadingBit(hits);
            (*t).current.y = hits & ~(1u << offset);
            if (((*t).current.y & 0xff000000u) != 0u) {
                (*t).stack[(*t).sp] = (*t).current;
                (*t).sp = (*t).sp + 1u;
            }
            let slot = (offset - 24u) ^ ray.oct;
            let relative = countOneBits(hits & ~(0xffffffffu << slot));
            let w = params.sec_a.x + ((*t).root + (*t).current.x + relative) * NODE_WORDS;
            let mask = node_hits(w, ray);
            (*t).current = vec2<u32>(scene[w + 4u], (mask & 0xff000000u) | (scene[w + 3u] >> 24u));
            (*t).prims = vec2<u32>(scene[w + 5u], mask & 0x00ffffffu);
        } else {
            if ((*t).sp == 0u) {
                return NONE;
            }
            (*t).sp = (*t).sp - 1u;
            (*t).current = (*t).stack[(*t).sp];
        }
    }
    return NONE;
}

// Möller–Trumbore against triangle `k` (TriEdges::intersect): (t, u, v, 1) or zero.
fn tri_test(k: u32, o: vec3<f32>, d: vec3<f32>, tmax: f32) -> vec4<f32> {
    let b = params.sec_a.y + k * 9u;
    let v0 = vec3_at(b);
    let e1 = vec3_at(b + 3u);
    let e2 = vec3_at(b + 6u);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if (abs(det) < 1e-12) {
        return vec4<f32>(0.0);
    }
    let inv = 1.0 / det;
    let s = o - v0;
    let u = dot(s, p) * inv;
    if (!(u >= 0.0 && u <= 1.0)) {
        return vec4<f32>(0.0);
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if (v < 0.0 || u + v > 1.0) {
        return vec4<f32>(0.0);
    }
    let t = dot(e2, q) * inv;
    if (t > 0.0 && t < tmax) {
        return vec4<f32>(t, u, v, 1.0);
    }
    return vec4<f32>(0.0);
}

struct Hit {
    t: f32,
    instance: u32,
    // Leaf-order triangle within the instance's BLAS.
    prim: u32,
    u: f32,
    v: f32,
}

fn row_transform(base: u32, p: vec3<f32>, w: f32) -> vec3<f32> {
    let r0 = vec4<f32>(vec3_at(base), fword(base + 3u));
    let r1 = vec4<f32>(vec3_at(base + 4u), fword(base + 7u));
    let r2 = vec4<f32>(vec3_at(base + 8u), fword(base + 11u));
    let q = vec4<f32>(p, w);
    return vec3<f32>(dot(r0, q), dot(r1, q), dot(r2, q));
}

// Closest (or any) hit of the world ray in large instance `index` beyond `best`.
fn enter_instance(index: u32, o: vec3<f32>, d: vec3<f32>, best: Hit, any_hit: bool) -> Hit {
    let ib = params.sec_a.w + index * INSTANCE_WORDS;
    let lo = row_transform(ib, o, 1.0);
    let ld = row_transform(ib, d, 0.0);
    var ray = make_ray(lo, ld, best.t);
    var tr = trav_start(scene[ib + 24u]);
    let tri_base = scene[ib + 25u];
    var out = best;
    loop {
        let p = trav_next(&tr, ray);
        if (p == NONE) {
            break;
        }
        let h = tri_test(tri_base + p, lo, ld, ray.tmax);
        if (h.w > 0.0) {
            ray.tmax = h.x;
            out = Hit(h.x, index, p, h.y, h.z);
            if (any_hit) {
                return out;
            }
        }
    }
    return out;
}

// Tlas::intersect (any_hit false) and Tlas::occluded (true: the hit is any blocker).
fn trace_geometry(o: vec3<f32>, d: vec3<f32>, tmax: f32, any_hit: bool) -> Hit {
    var best = Hit(tmax, NONE, 0u, 0.0, 0.0);
    if (params.geo.x > 0u) {
        var ray = make_ray(o, d, tmax);
        var tr = trav_start(0u);
        loop {
            let p = trav_next(&tr, ray);
            if (p == NONE) {
                break;
            }
            let h = tri_test(p, o, d, ray.tmax);
            if (h.w > 0.0) {
                let owner = params.sec_b.y + p * 2u;
                best = Hit(h.x, scene[owner], scene[owner + 1u], h.y, h.z);
                if (any_hit) {
                    return best;
                }
                if (!any_hit) {
                    ray.tmax = h.x;
                }
            }
        }
    }
    let large = params.geo.z;
    if (large == 0u) {
        return best;
    }
    // Occlusion keeps testing against the full segment, as on the CPU.
    let limit = select(best.t, tmax, any_hit);
    if (large == 1u) {
        var seed = best;
        seed.t = limit;
        let h = enter_instance(scene[params.sec_b.x], o, d, seed, any_hit);
        if (h.instance != NONE) {
            return h;
        }
        return best;
    }
    var world = make_ray(o, d, limit);
    var tr = trav_start(params.geo.y);
    loop {
        let p = trav_next(&tr, world);
        if (p == NONE) {
            break;
        }
        var seed = best;
        if (any_hit) {
            seed.t = tmax;
        }
        let h = enter_instance(scene[params.sec_b.x + p], o, d, seed, any_hit);
        if (h.instance != NONE) {
            best = h;
            if (any_hit) {
                return best;
            }
            world.tmax = best.t;
        }
    }
    return best;
}

fn occluded(o: vec3<f32>, d: vec3<f32>, tmax: f32) -> bool {
    return trace_geometry(o, d, tmax, true).instance != NONE;
}
