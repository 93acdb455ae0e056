//! The bottom level: one CWBVH per mesh in object space, built once and shared by every
//! instance of the mesh, with the mesh checks that keep shading in bounds.

use std::sync::Arc;
use std::time::Duration;

use glam::Vec3A;
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::cwbvh::CwBvh;
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

use super::triangle::{LeafTri, TriEdges};
use super::wide::WideBvh;
use crate::assets::Mesh;

/// Bottom-level BVH of one mesh, in object space.
pub struct Blas {
    pub(super) bvh: CwBvh,
    /// The CPU's traversal layout of `bvh` (the GPU's export reads `bvh`).
    pub(super) wide: WideBvh,
    /// Triangles in BVH leaf order.
    pub(super) tris: Vec<TriEdges>,
    /// Shading data of each leaf-order triangle.
    pub(super) leaves: Vec<LeafTri>,
    pub mesh: Arc<Mesh>,
    pub bounds: Aabb,
}

/// Why a mesh cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MeshError {
    #[error("triangle {triangle} refers to vertex {vertex}, but the mesh has {count} vertices")]
    VertexOutOfRange { triangle: usize, vertex: u32, count: usize },
    #[error("triangle {triangle} uses material slot {slot}, but the mesh has {count} slots")]
    SlotOutOfRange { triangle: usize, slot: u32, count: u32 },
    #[error("the mesh has {normals} normals / {uvs} uvs for {positions} positions")]
    AttributeCount { positions: usize, normals: usize, uvs: usize },
    #[error("the mesh has a non-finite vertex position")]
    NonFinite,
}

/// Checks every index of a mesh so that shading never reads out of bounds.
pub fn validate_mesh(mesh: &Mesh) -> Result<(), MeshError> {
    let n = mesh.positions.len();
    let attrs_ok = |len: usize| len == 0 || len == n;
    if !attrs_ok(mesh.normals.len()) || !attrs_ok(mesh.uvs.len()) {
        return Err(MeshError::AttributeCount {
            positions: n,
            normals: mesh.normals.len(),
            uvs: mesh.uvs.len(),
        });
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err(MeshError::NonFinite);
    }
    for (triangle, tri) in mesh.indices.iter().enumerate() {
        if let Some(&vertex) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(MeshError::VertexOutOfRange { triangle, vertex, count: n });
        }
        let slot = mesh.slot(triangle);
        if slot >= mesh.slot_count.max(1) {
            return Err(MeshError::SlotOutOfRange { triangle, slot, count: mesh.slot_count });
        }
    }
    Ok(())
}

/// Vertex normals within this cosine of the face normal count as flat shading
/// (about 0.1°: below what shading could show).
pub(super) const FLAT_COS: f32 = 0.999_998;

pub(super) fn leaf_tri(mesh: &Mesh, original: u32) -> LeafTri {
    let i = original as usize;
    let idx = mesh.indices[i];
    let flat = mesh.normals.is_empty() || {
        let [a, b, c] = idx.map(|v| mesh.positions[v as usize]);
        let face = (b - a).cross(c - a).normalize_or_zero();
        let cos = idx.map(|v| mesh.normals[v as usize].normalize_or_zero().dot(face));
        // Normals facing away are flipped to the geometric side when shading, so
        // all-opposite is as flat as all-aligned; a mix is not.
        face != glam::Vec3::ZERO
            && (cos.iter().all(|&c| c >= FLAT_COS) || cos.iter().all(|&c| c <= -FLAT_COS))
    };
    LeafTri { original, slot: mesh.slot(i), flat }
}

impl Blas {
    /// Builds the BLAS of a validated mesh.
    pub fn build(mesh: Arc<Mesh>) -> Result<Self, MeshError> {
        validate_mesh(&mesh)?;
        let tris: Vec<Triangle> = mesh
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vec3A::from(mesh.positions[i as usize]));
                Triangle { v0: a, v1: b, v2: c }
            })
            .collect();
        let mut bounds = Aabb::empty();
        for t in &tris {
            bounds = bounds.union(&t.aabb());
        }
        let (bvh, original) = build_tri_bvh(&tris, BvhBuildParams::medium_build());
        let leaves = original.iter().map(|&i| leaf_tri(&mesh, i)).collect();
        let tris = original
            .iter()
            .map(|&i| {
                let t = &tris[i as usize];
                TriEdges::new(t.v0, t.v1, t.v2)
            })
            .collect::<Vec<_>>();
        let wide = WideBvh::build(&bvh, &tris);
        Ok(Self { bvh, wide, tris, leaves, mesh, bounds })
    }

    /// Shading data of leaf-order triangle `prim`.
    #[inline]
    pub fn leaf(&self, prim: u32) -> &LeafTri {
        &self.leaves[prim as usize]
    }

    /// Leaf-order triangle `prim`.
    #[inline]
    pub fn tri(&self, prim: u32) -> &TriEdges {
        &self.tris[prim as usize]
    }

    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }
}

/// Builds a CWBVH over triangles, returning it with the leaf order (a triangle
/// may appear more than once when `params` pre-split).
pub(super) fn build_tri_bvh(tris: &[Triangle], params: BvhBuildParams) -> (CwBvh, Vec<u32>) {
    if tris.is_empty() {
        return (CwBvh::default(), Vec::new());
    }
    let bvh = build_cwbvh_from_tris(tris, params, &mut Duration::default());
    let order = bvh.primitive_indices.clone();
    (bvh, order)
}
