//! Built-in shapes: the meshes of `Geometry::{Quad, Cube, Sphere}`.
//!
//! Scenes that must work on a fresh machine (the demo's Cornell box) are made from
//! these, so they need no asset files. All shapes have one material slot and are
//! centred at the origin with unit size; objects place them with their transform.

use glam::{Vec2, Vec3};
use gridlight_actors::state::Geometry;

use crate::assets::Mesh;

/// Largest sphere subdivision accepted (20 · 4^6 ≈ 82k triangles).
pub const MAX_SPHERE_SUBDIVISIONS: u32 = 6;

/// The mesh of a built-in shape, or `None` for file-backed geometry.
pub fn mesh(geometry: &Geometry) -> Option<Mesh> {
    match geometry {
        Geometry::Quad => Some(quad()),
        Geometry::Cube => Some(cube()),
        Geometry::Sphere { subdivisions } => {
            Some(sphere((*subdivisions).min(MAX_SPHERE_SUBDIVISIONS)))
        }
        Geometry::Obj { .. } | Geometry::Gltf { .. } => None,
    }
}

/// Unit square in the xz-plane, normal +y.
pub fn quad() -> Mesh {
    let mut mesh = Mesh::default();
    push_face(&mut mesh, Vec3::Y, Vec3::X, Vec3::NEG_Z, 0.0);
    mesh
}

/// Axis-aligned unit cube with outward normals (flat shaded: 24 vertices).
pub fn cube() -> Mesh {
    let mut mesh = Mesh::default();
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    for (normal, u, v) in faces {
        push_face(&mut mesh, normal, u, v, 0.5);
    }
    mesh
}

/// Icosphere of radius 1 with smooth normals.
pub fn sphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut indices: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = ((positions[a as usize] + positions[b as usize]) * 0.5).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(indices.len() * 4);
        for [a, b, c] in indices {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            next.extend_from_slice(&[[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        indices = next;
    }
    let uvs = positions
        .iter()
        .map(|p| {
            let u = 0.5 + p.z.atan2(p.x) / std::f32::consts::TAU;
            let v = 0.5 + p.y.asin() / std::f32::consts::PI;
            Vec2::new(u, v)
        })
        .collect();
    let slots = vec![0; indices.len()];
    Mesh { normals: positions.clone(), positions, uvs, indices, slots, slot_count: 1 }
}

/// Appends a unit square with the given outward `normal`, spanned by `u` × `v`
/// (counter-clockwise seen from the front), moved `offset` along the normal.
fn push_face(mesh: &mut Mesh, normal: Vec3, u: Vec3, v: Vec3, offset: f32) {
    let base = mesh.positions.len() as u32;
    let centre = normal * offset;
    for (su, sv) in [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
        mesh.positions.push(centre + u * su + v * sv);
        mesh.normals.push(normal);
        mesh.uvs.push(Vec2::new(su + 0.5, sv + 0.5));
    }
    mesh.indices.push([base, base + 1, base + 2]);
    mesh.indices.push([base, base + 2, base + 3]);
    mesh.slots.extend_from_slice(&[0, 0]);
    mesh.slot_count = 1;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Winding must agree with the stored normal, or back-face logic breaks.
    fn assert_winding_matches_normals(mesh: &Mesh) {
        for tri in &mesh.indices {
            let [a, b, c] = tri.map(|i| mesh.positions[i as usize]);
            let geometric = (b - a).cross(c - a).normalize();
            let shading = mesh.normals[tri[0] as usize];
            assert!(geometric.dot(shading) > 0.5, "triangle {tri:?} winds against its normal");
        }
    }

    #[test]
    fn quad_faces_up_and_spans_unit_square() {
        let q = quad();
        assert_eq!(q.triangle_count(), 2);
        assert_winding_matches_normals(&q);
        for p in &q.positions {
            assert_eq!(p.y, 0.0);
            assert_eq!(p.x.abs(), 0.5);
            assert_eq!(p.z.abs(), 0.5);
        }
    }

    #[test]
    fn cube_is_closed_unit_box_with_outward_normals() {
        let c = cube();
        assert_eq!(c.triangle_count(), 12);
        assert_winding_matches_normals(&c);
        for (p, n) in c.positions.iter().zip(&c.normals) {
            assert!((p.abs().max_element() - 0.5).abs() < 1e-6);
            assert!(p.dot(*n) > 0.0, "normal {n} points inwards at {p}");
        }
    }

    #[test]
    fn sphere_subdivides_onto_unit_sphere() {
        let s = sphere(2);
        assert_eq!(s.triangle_count(), 20 * 16);
        assert_winding_matches_normals(&s);
        for p in &s.positions {
            assert!((p.length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn obj_geometry_is_not_a_builtin_shape() {
        assert!(mesh(&Geometry::Obj { path: "x.obj".into() }).is_none());
        assert!(mesh(&Geometry::Sphere { subdivisions: 99 }).is_some());
    }
}
