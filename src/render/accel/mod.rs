//! Two-level ray acceleration: one bottom-level BVH per mesh, a top-level BVH over
//! the placed instances.
//!
//! Both levels are built by obvhs as compressed wide BVHs (CWBVH, eight children per
//! node), which the GPU tracer traverses as they are. The CPU traverses meshes and the
//! flattened small instances through `wide/`'s layout of the same trees (full-precision
//! child boxes, one SIMD lane per child, four-triangle leaf packets); the top level, over
//! a few instances, keeps the CWBVH traversal. A mesh's BLAS is built once and shared by every instance of
//! it; a new scene state only rebuilds the small TLAS, so moving an object never
//! touches its triangles. Triangles are stored in BVH leaf order as a base vertex
//! and two edges (Möller–Trumbore needs nothing else), which keeps the hot loop on
//! contiguous memory; shading data is fetched once per closest hit.
//!
//! Instances of small meshes (at most [`FLAT_MAX_TRIANGLES`], such as the walls
//! and boxes of a Cornell box) are not traversed through their own BLAS: per
//! scene state their triangles are copied to world space into one shared BVH.
//! Entering an instance costs a ray transform, a traversal set-up and a root node
//! test, far more than testing a handful of triangles, and rebuilding a few
//! hundred world-space triangles per state costs about as little as the TLAS
//! itself. Large meshes keep the two-level path, so moving them stays cheap.
//!
//! Files: `triangle.rs` (the triangle test), `blas.rs` (per mesh), `tlas.rs` (per scene
//! state), `wide/` (the CPU's layout and traversal of meshes and flattened instances), `traverse.rs`
//! (the CWBVH node test and traversal restart of the top level), `export.rs` (both levels
//! as flat arrays for the GPU path tracer).

mod blas;
pub mod export;
mod tlas;
mod traverse;
mod triangle;
mod wide;

pub use blas::{validate_mesh, Blas, MeshError};
pub use tlas::{Hit, Instance, Tlas, FLAT_MAX_TRIANGLES};
pub use triangle::{LeafTri, TriEdges};
pub use wide::LaneFill;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;
    use std::sync::Arc;

    use glam::{Affine3A, Quat, Vec3};

    /// Tiny deterministic generator for test inputs only (not used for rendering).
    fn lcg(state: &mut u64) -> f32 {
        *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*state >> 40) as f32 / (1u64 << 24) as f32
    }

    fn brute_force(instances: &[Instance], o: Vec3, d: Vec3) -> Option<(f32, u32)> {
        let mut best: Option<(f32, u32)> = None;
        for inst in instances {
            let lo = inst.world_to_object.transform_point3a(o.into());
            let ld = inst.world_to_object.transform_vector3a(d.into());
            for (i, t) in inst.blas.tris.iter().enumerate() {
                let tmax = best.map_or(f32::INFINITY, |b| b.0);
                if let Some((t, ..)) = t.intersect(lo, ld, 0.0, tmax) {
                    best = Some((t, inst.object * 1_000_000 + inst.blas.leaf(i as u32).original));
                }
            }
        }
        best
    }

    /// Random rays through the scene must find what brute force finds.
    fn check_against_brute_force(instances: Vec<Instance>, rng: &mut u64) {
        let tlas = Tlas::build(instances.clone());
        let mut hits = 0;
        for _ in 0..2000 {
            let o = Vec3::new(lcg(rng) - 0.5, lcg(rng) - 0.5, lcg(rng) - 0.5) * 12.0;
            let target = (Vec3::new(lcg(rng), lcg(rng), lcg(rng)) - 0.5) * 6.0;
            let d = (target - o).normalize();
            let expected = brute_force(&instances, o, d);
            let got = tlas.intersect(o, d, f32::INFINITY).map(|h| {
                let inst = &tlas.instances[h.instance as usize];
                (h.t, inst.object * 1_000_000 + inst.blas.leaf(h.prim).original)
            });
            match (expected, got) {
                (None, None) => {}
                (Some(e), Some(g)) => {
                    hits += 1;
                    assert!((e.0 - g.0).abs() < 1e-4 * e.0.max(1.0), "t {} vs {}", e.0, g.0);
                    assert!(tlas.occluded(o, d, e.0 * 1.001));
                    assert!(!tlas.occluded(o, d, e.0 * 0.999));
                }
                other => panic!("brute force and BVH disagree: {other:?}"),
            }
        }
        assert!(hits > 300, "too few hits ({hits}) to test anything");
    }

    /// A bounce ray and a shadow ray traced together give what each gives alone, bit
    /// for bit, with the top level flat only, with one large instance and with several.
    #[test]
    fn interleaved_closest_and_shadow_rays_match_separate_ones() {
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        let mut rng = 777u64;
        for large in [0, 1, 3] {
            let mut instances = Vec::new();
            for object in 0..6u32 {
                let blas = if object < large { sphere.clone() } else { cube.clone() };
                instances.push(Instance::new(blas, random_transform(&mut rng), object, 0));
            }
            let tlas = Tlas::build(instances);
            let ray = |rng: &mut u64| {
                let o = Vec3::new(lcg(rng) - 0.5, lcg(rng) - 0.5, lcg(rng) - 0.5) * 12.0;
                let d = ((Vec3::new(lcg(rng), lcg(rng), lcg(rng)) - 0.5) * 6.0 - o).normalize();
                (o, d, if lcg(rng) < 0.3 { f32::INFINITY } else { lcg(rng) * 15.0 })
            };
            let (mut hits, mut blocked) = (0, 0);
            for _ in 0..1500 {
                let (a, b) = (ray(&mut rng), ray(&mut rng));
                let both =
                    tlas.intersect_and_occluded_with(crate::render::isa::Cpu::BASELINE, a, b);
                let alone = (tlas.intersect(a.0, a.1, a.2), tlas.occluded(b.0, b.1, b.2));
                assert_eq!(both, alone);
                hits += usize::from(alone.0.is_some());
                blocked += usize::from(alone.1);
            }
            assert!(hits > 100 && blocked > 100, "too few hits ({hits}, {blocked})");
        }
    }

    /// Sixteen coherent rays traced together (`Tlas::intersect_lanes_with`) hit what each
    /// hits alone, bit for bit, over flattened cubes and two large spheres, with lanes
    /// left empty; and the walk in lanes answers nearly every lane itself.
    #[test]
    fn coherent_rays_in_lanes_hit_what_each_ray_hits_alone() {
        use crate::render::isa::Cpu;
        use crate::render::lanes::{Vec3s, WIDTH};
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        let mut rng = 4242u64;
        let instances = (0..10u32)
            .map(|object| {
                let blas = if object < 2 { sphere.clone() } else { cube.clone() };
                Instance::new(blas, random_transform(&mut rng), object, 0)
            })
            .collect();
        let tlas = Tlas::build(instances);
        let bits = |h: Option<Hit>| {
            h.map(|h| (h.t.to_bits(), h.instance, h.prim, h.u.to_bits(), h.v.to_bits()))
        };
        let (mut hits, mut sure, mut lanes) = (0, 0, 0);
        for round in 0..400 {
            let o = Vec3::new(lcg(&mut rng) - 0.5, lcg(&mut rng) - 0.5, lcg(&mut rng) - 0.5) * 12.0;
            let target = (Vec3::new(lcg(&mut rng), lcg(&mut rng), lcg(&mut rng)) - 0.5) * 6.0;
            let centre = (target - o).normalize();
            let (mut os, mut ds) = (Vec3s::default(), Vec3s::default());
            for l in 0..WIDTH {
                let jitter = Vec3::new(lcg(&mut rng), lcg(&mut rng), lcg(&mut rng)) - 0.5;
                os.set_lane(l, o);
                ds.set_lane(l, (centre + jitter * 0.02).normalize());
            }
            let active = if round % 4 == 0 { 0x0f0f } else { (1 << WIDTH) - 1 };
            let got = tlas.intersect_lanes_with(Cpu::BASELINE, &os, &ds, active);
            for (l, &got) in got.iter().enumerate() {
                let want = (active & (1 << l) != 0)
                    .then(|| tlas.intersect(o, ds.lane(l), f32::INFINITY))
                    .flatten();
                assert_eq!(bits(got), bits(want), "round {round}, lane {l}");
                hits += usize::from(want.is_some());
            }
            if let Some(rays) = wide::RayLanes::new(&os, &ds, active) {
                sure += tlas.flat.wide.intersect_lanes(&rays).sure.count_ones();
                lanes += active.count_ones();
            }
        }
        assert!(hits > 1000, "too few hits ({hits}) to test anything");
        assert!(sure as f64 > 0.98 * lanes as f64, "{sure} of {lanes} lanes sure");
    }

    /// Geometric normals are the normal matrix times the edges' cross product, normalised,
    /// bit for bit, whether the budget stored them or not (here it holds the first two
    /// instances only).
    #[test]
    fn stored_geometric_normals_are_the_computed_ones() {
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let mut rng = 99u64;
        let instances: Vec<Instance> = (0..4u32)
            .map(|object| Instance::new(sphere.clone(), random_transform(&mut rng), object, 0))
            .collect();
        let budget = 2 * sphere.triangle_count() + 1;
        let all = Tlas::build(instances.clone());
        let some = Tlas::build_with_normal_budget(instances, budget);
        assert!(all.normals.base.iter().all(|&b| b != tlas::NOT_STORED));
        assert_eq!(some.normals.base[2..], [tlas::NOT_STORED; 2]);
        assert!(some.normals.base[..2].iter().all(|&b| b != tlas::NOT_STORED));
        for tlas in [all, some] {
            for (index, inst) in tlas.instances.iter().enumerate() {
                for prim in 0..inst.blas.triangle_count() as u32 {
                    let tri = inst.blas.tri(prim);
                    let expected =
                        Vec3::from(inst.normal_to_world * tri.e1.cross(tri.e2)).normalize();
                    let hit = Hit { t: 1.0, instance: index as u32, prim, u: 0.0, v: 0.0 };
                    let n = tlas.geometric_normal(&hit);
                    assert_eq!(
                        n.to_array().map(f32::to_bits),
                        expected.to_array().map(f32::to_bits)
                    );
                }
            }
        }
    }

    fn random_transform(rng: &mut u64) -> Affine3A {
        let t = Vec3::new(lcg(rng) * 6.0 - 3.0, lcg(rng) * 6.0 - 3.0, lcg(rng) * 6.0 - 3.0);
        let r = Quat::from_euler(glam::EulerRot::XYZ, lcg(rng) * 3.0, lcg(rng), 0.5);
        let s = Vec3::new(0.3 + lcg(rng), 0.3 + lcg(rng), 0.3 + lcg(rng));
        Affine3A::from_scale_rotation_translation(s, r, t)
    }

    #[test]
    fn bvh_hits_match_brute_force() {
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        // Spheres go through their own BLAS, cubes into the flattened world-space BVH.
        assert!(sphere.triangle_count() > FLAT_MAX_TRIANGLES);
        assert!(cube.triangle_count() <= FLAT_MAX_TRIANGLES);
        let mut rng = 12345u64;
        let mut instances = Vec::new();
        for object in 0..12u32 {
            let blas = if object % 3 == 0 { cube.clone() } else { sphere.clone() };
            instances.push(Instance::new(blas, random_transform(&mut rng), object, 0));
        }
        check_against_brute_force(instances, &mut rng);
        // A single large instance skips the top level; a lone small one is flat only.
        for blas in [sphere, cube] {
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::new(2.5, 2.0, 3.0),
                Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, 0.2),
                Vec3::new(0.2, -0.1, 0.3),
            );
            check_against_brute_force(vec![Instance::new(blas, m, 0, 0)], &mut rng);
        }
    }

    #[test]
    fn flat_shading_is_detected_per_triangle() {
        let cube = Blas::build(Arc::new(shapes::cube())).unwrap();
        assert!((0..cube.triangle_count() as u32).all(|p| cube.leaf(p).flat));
        let sphere = Blas::build(Arc::new(shapes::sphere(2))).unwrap();
        assert!((0..sphere.triangle_count() as u32).all(|p| !sphere.leaf(p).flat));
        // Normals all facing away are flat too (shading flips them); a mix is not.
        let mut mesh = shapes::quad();
        mesh.normals.iter_mut().for_each(|n| *n = -*n);
        let flipped = Blas::build(Arc::new(mesh.clone())).unwrap();
        assert!((0..2).all(|p| flipped.leaf(p).flat));
        mesh.normals[mesh.indices[0][1] as usize] *= -1.0;
        let mixed = Blas::build(Arc::new(mesh)).unwrap();
        assert!((0..2).any(|p| !mixed.leaf(p).flat));
        // Without vertex normals every triangle is flat.
        let mut bare = shapes::quad();
        bare.normals.clear();
        let bare = Blas::build(Arc::new(bare)).unwrap();
        assert!((0..2).all(|p| bare.leaf(p).flat));
    }

    #[test]
    fn single_instance_single_triangle_scene_works() {
        let mut mesh = shapes::quad();
        mesh.indices.truncate(1);
        mesh.slots.truncate(1);
        let blas = Arc::new(Blas::build(Arc::new(mesh)).unwrap());
        let tlas = Tlas::build(vec![Instance::new(blas, Affine3A::IDENTITY, 0, 0)]);
        let hit = tlas.intersect(Vec3::new(0.1, 1.0, 0.1), Vec3::NEG_Y, f32::INFINITY);
        let miss = tlas.intersect(Vec3::new(-0.1, 1.0, -0.1), Vec3::NEG_Y, f32::INFINITY);
        // The first triangle of the quad covers one half of the square.
        assert!(hit.is_some() != miss.is_some());
    }

    #[test]
    fn bad_meshes_are_rejected() {
        let mut mesh = shapes::quad();
        mesh.indices[1][2] = 99;
        assert!(matches!(
            validate_mesh(&mesh),
            Err(MeshError::VertexOutOfRange { vertex: 99, .. })
        ));
        let mut mesh = shapes::quad();
        mesh.slots[0] = 3;
        assert!(matches!(validate_mesh(&mesh), Err(MeshError::SlotOutOfRange { slot: 3, .. })));
    }
}
