//! The acceleration structure as flat arrays for the GPU path tracer (`render::gpu`): the
//! very CWBVH nodes, leaf-order triangles and instances the CPU traverses, so that both
//! tracers agree on what a ray hits. Nodes keep obvhs's 80-byte layout (they are `Pod`);
//! each BVH's node indices stay relative to its own root, which the shader adds.
//!
//! Order: the flattened world-space BVH of small instances first (root node 0, triangles
//! from 0), then the TLAS over large instances, then each distinct BLAS once.

use std::collections::HashMap;
use std::sync::Arc;

use obvhs::cwbvh::CwBvh;

use super::blas::Blas;
use super::tlas::Tlas;
use super::triangle::TriEdges;

/// Words per instance record (`INSTANCE_WORDS` in `shaders/trace/bvh.wgsl`).
pub const INSTANCE_WORDS: usize = 32;
/// Words per CWBVH node (`NODE_WORDS`).
pub const NODE_WORDS: usize = 20;

/// The flattened geometry of one TLAS.
#[derive(Debug, Default)]
pub struct AccelArrays {
    /// CWBVH nodes, [`NODE_WORDS`] each.
    pub nodes: Vec<u32>,
    /// Triangles as vertex and two edges, nine floats each.
    pub tris: Vec<f32>,
    /// Per triangle of a BLAS: mesh triangle, material slot, flat (1) or not.
    pub leaves: Vec<u32>,
    /// [`INSTANCE_WORDS`] per instance: world-to-object rows (12), normal-to-world rows
    /// (12), BLAS root node, BLAS first triangle, first mesh triangle, first vertex,
    /// attribute flags (1 normals, 2 uvs), object, material base, 0.
    pub instances: Vec<u32>,
    /// The TLAS's leaf order of large instances.
    pub large: Vec<u32>,
    /// Per flat triangle: its instance and its triangle in that instance's BLAS.
    pub flat_owner: Vec<u32>,
    /// Vertex indices of every mesh triangle, three per triangle.
    pub mesh_indices: Vec<u32>,
    pub normals: Vec<f32>,
    pub uvs: Vec<f32>,
    /// Triangles of the flat BVH (0: none).
    pub flat_triangles: u32,
    /// Root node of the TLAS.
    pub tlas_root: u32,
}

/// Where one BLAS landed in the arrays.
#[derive(Clone, Copy)]
struct BlasPlace {
    root: u32,
    first_tri: u32,
    first_mesh_tri: u32,
    first_vertex: u32,
    flags: u32,
}

impl AccelArrays {
    fn push_bvh(&mut self, bvh: &CwBvh) -> u32 {
        let root = (self.nodes.len() / NODE_WORDS) as u32;
        self.nodes.extend_from_slice(bytemuck::cast_slice(&bvh.nodes));
        root
    }

    fn push_tris(&mut self, tris: &[TriEdges]) -> u32 {
        let first = (self.tris.len() / 9) as u32;
        for t in tris {
            for v in [t.v0, t.e1, t.e2] {
                self.tris.extend_from_slice(&v.to_array());
            }
        }
        first
    }

    fn push_blas(&mut self, blas: &Blas) -> BlasPlace {
        let root = self.push_bvh(&blas.bvh);
        let first_tri = self.push_tris(&blas.tris);
        for leaf in &blas.leaves {
            self.leaves.extend_from_slice(&[leaf.original, leaf.slot, u32::from(leaf.flat)]);
        }
        let mesh = &blas.mesh;
        let first_mesh_tri = (self.mesh_indices.len() / 3) as u32;
        self.mesh_indices.extend(mesh.indices.iter().flatten());
        let first_vertex = (self.normals.len() / 3) as u32;
        // Attributes are indexed per vertex; absent ones are padded so that the bases agree.
        for i in 0..mesh.positions.len() {
            let n = mesh.normals.get(i).copied().unwrap_or_default();
            self.normals.extend_from_slice(&n.to_array());
            let uv = mesh.uvs.get(i).copied().unwrap_or_default();
            self.uvs.extend_from_slice(&uv.to_array());
        }
        let flags = u32::from(!mesh.normals.is_empty()) | (u32::from(!mesh.uvs.is_empty()) << 1);
        BlasPlace { root, first_tri, first_mesh_tri, first_vertex, flags }
    }
}

/// Flattens `tlas` (every instance's BLAS once, however many instances share it).
pub fn export(tlas: &Tlas) -> AccelArrays {
    let mut out = AccelArrays::default();
    if !tlas.flat.tris.is_empty() {
        out.push_bvh(&tlas.flat.bvh);
        out.push_tris(&tlas.flat.tris);
        // Flat triangles have no leaf data of their own: the owner's BLAS has it.
        out.leaves.resize(tlas.flat.tris.len() * 3, 0);
        out.flat_owner = tlas.flat.owner.iter().flat_map(|&(i, p)| [i, p]).collect();
        out.flat_triangles = tlas.flat.tris.len() as u32;
    }
    out.tlas_root = out.push_bvh(&tlas.bvh);
    out.large = tlas.large.clone();
    let mut places: HashMap<*const Blas, BlasPlace> = HashMap::new();
    for inst in &tlas.instances {
        let place =
            *places.entry(Arc::as_ptr(&inst.blas)).or_insert_with(|| out.push_blas(&inst.blas));
        let w2o = &inst.world_to_object;
        let n2w = &inst.normal_to_world;
        let mut words = Vec::with_capacity(INSTANCE_WORDS);
        for row in 0..3 {
            let m = &w2o.matrix3;
            let r = [m.x_axis[row], m.y_axis[row], m.z_axis[row], w2o.translation[row]];
            words.extend(r.map(f32::to_bits));
        }
        for row in 0..3 {
            let r = [n2w.x_axis[row], n2w.y_axis[row], n2w.z_axis[row], 0.0];
            words.extend(r.map(f32::to_bits));
        }
        words.extend_from_slice(&[
            place.root,
            place.first_tri,
            place.first_mesh_tri,
            place.first_vertex,
            place.flags,
            inst.object,
            inst.material_base,
            0,
        ]);
        debug_assert_eq!(words.len(), INSTANCE_WORDS);
        out.instances.extend(words);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes;
    use glam::Affine3A;

    #[test]
    fn nodes_keep_obvhs_layout_and_blases_are_shared() {
        assert_eq!(std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>(), NODE_WORDS * 4);
        let sphere = Arc::new(Blas::build(Arc::new(shapes::sphere(3))).unwrap());
        let cube = Arc::new(Blas::build(Arc::new(shapes::cube())).unwrap());
        let at = |x: f32| Affine3A::from_translation(glam::Vec3::new(x, 0.0, 0.0));
        let instances = vec![
            super::super::Instance::new(sphere.clone(), at(0.0), 0, 0),
            super::super::Instance::new(sphere.clone(), at(3.0), 1, 1),
            super::super::Instance::new(cube.clone(), at(-3.0), 2, 2),
        ];
        let tlas = Tlas::build(instances);
        let a = export(&tlas);
        assert_eq!(a.flat_triangles as usize, cube.triangle_count());
        // One copy of the sphere's BLAS and of the cube's (the cube's also flattened).
        let tris = cube.triangle_count() * 2 + sphere.triangle_count();
        assert_eq!(a.tris.len(), tris * 9);
        assert_eq!(a.instances.len(), 3 * INSTANCE_WORDS);
        assert_eq!(a.large.len(), 2);
        assert_eq!(a.flat_owner.len(), 2 * cube.triangle_count());
        // Both sphere instances point at the same BLAS root.
        let root = |i: usize| a.instances[i * INSTANCE_WORDS + 24];
        let sphere_instances: Vec<usize> =
            (0..3).filter(|&i| Arc::ptr_eq(&tlas.instances[i].blas, &sphere)).collect();
        assert_eq!(root(sphere_instances[0]), root(sphere_instances[1]));
    }
}
