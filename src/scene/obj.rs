//! Wavefront OBJ + MTL loading through an [`AssetResolver`].
//!
//! The OBJ and its material libraries are read through the resolver (not relative to the
//! OBJ's file on disk), so the same code serves the master (search path) and a worker (its
//! hash-keyed cache). Meshes are triangulated by tobj with one index per vertex. Material
//! slots follow the MTL order, plus one last slot for faces that name no material (or a
//! material the MTL lacks), as `gridlight_actors::state::Object::materials` documents.

use std::cell::RefCell;
use std::path::Path;

use glam::{Vec2, Vec3};

use super::error::AssetError;
use super::search::{sibling_asset, AssetBytes, AssetResolver};
use crate::assets::Mesh;

/// What one OBJ file yields.
#[derive(Debug, Clone)]
pub struct ObjData {
    /// All models of the file merged into one mesh, in object space.
    pub mesh: Mesh,
    /// The MTL materials, in slot order (the last slot, "no material", is not listed).
    pub materials: Vec<tobj::Material>,
    /// Asset paths of the material libraries the OBJ names and that were read.
    pub mtl_assets: Vec<String>,
}

fn load_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    }
}

/// Reads the OBJ at asset path `asset` and its MTL files.
pub fn read_obj(asset: &str, resolver: &dyn AssetResolver) -> Result<ObjData, AssetError> {
    let AssetBytes { file, bytes } = resolver.read(asset)?;
    let mtl_assets = RefCell::new(Vec::new());
    // tobj's material loader can only return tobj errors; keep ours on the side.
    let mtl_failure: RefCell<Option<(String, AssetError)>> = RefCell::new(None);
    let load_mtl = |name: &Path| {
        let mtl = sibling_asset(asset, &name.to_string_lossy());
        match read_mtl(&mtl, resolver) {
            Ok(result) => {
                mtl_assets.borrow_mut().push(mtl);
                result
            }
            Err(err) => {
                mtl_failure.borrow_mut().get_or_insert((mtl, err));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    let (models, materials) = tobj::load_obj_buf(&mut &bytes[..], &load_options(), load_mtl)
        .map_err(|source| AssetError::Obj { file: file.clone(), source })?;
    if let Some((mtl, err)) = mtl_failure.into_inner() {
        return Err(AssetError::Mtl { file, mtl, source: Box::new(err) });
    }
    let materials = materials.map_err(|source| AssetError::Mtl {
        file: file.clone(),
        mtl: mtl_assets.borrow().last().cloned().unwrap_or_default(),
        source: Box::new(AssetError::Obj { file: file.clone(), source }),
    })?;
    let mesh = merge_models(&models, materials.len() as u32, &file)?;
    Ok(ObjData { mesh, materials, mtl_assets: mtl_assets.into_inner() })
}

fn read_mtl(asset: &str, resolver: &dyn AssetResolver) -> Result<tobj::MTLLoadResult, AssetError> {
    Ok(tobj::load_mtl_buf(&mut &resolver.read(asset)?.bytes[..]))
}

/// Merges tobj's models into one mesh; `material_count` is the number of MTL materials, so
/// faces without one go to slot `material_count`.
fn merge_models(
    models: &[tobj::Model],
    material_count: u32,
    file: &Path,
) -> Result<Mesh, AssetError> {
    let bad = |reason: String| AssetError::BadMesh { file: file.to_path_buf(), reason };
    let any_normals = models.iter().any(|m| !m.mesh.normals.is_empty());
    let any_uvs = models.iter().any(|m| !m.mesh.texcoords.is_empty());
    let mut mesh = Mesh { slot_count: material_count + 1, ..Mesh::default() };
    for model in models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        let count = m.positions.len() / 3;
        if m.indices.len() % 3 != 0 {
            return Err(bad(format!("model `{}` is not triangulated", model.name)));
        }
        mesh.positions.extend(m.positions.chunks_exact(3).map(|p| Vec3::new(p[0], p[1], p[2])));
        let first_tri = mesh.indices.len();
        for tri in m.indices.chunks_exact(3) {
            if tri.iter().any(|&i| i as usize >= count) {
                return Err(bad(format!("model `{}` has a vertex index out of range", model.name)));
            }
            mesh.indices.push([base + tri[0], base + tri[1], base + tri[2]]);
        }
        let slot = match m.material_id {
            Some(id) if (id as u32) < material_count => id as u32,
            _ => material_count,
        };
        mesh.slots.resize(mesh.indices.len(), slot);
        if any_normals {
            if m.normals.len() == m.positions.len() {
                mesh.normals.extend(
                    m.normals
                        .chunks_exact(3)
                        .map(|n| Vec3::new(n[0], n[1], n[2]).normalize_or_zero()),
                );
            } else {
                // Mixed file: smooth normals for the models that lack them.
                let start = mesh.normals.len();
                mesh.normals.resize(start + count, Vec3::ZERO);
                for &[a, b, c] in &mesh.indices[first_tri..] {
                    let [pa, pb, pc] = [a, b, c].map(|i| mesh.positions[i as usize]);
                    let n = (pb - pa).cross(pc - pa);
                    for i in [a, b, c] {
                        mesh.normals[i as usize] += n;
                    }
                }
                for n in &mut mesh.normals[start..] {
                    *n = n.normalize_or_zero();
                }
            }
        }
        if any_uvs {
            if m.texcoords.len() / 2 == count {
                mesh.uvs.extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
            } else {
                mesh.uvs.resize(mesh.positions.len(), Vec2::ZERO);
            }
        }
    }
    if mesh.indices.is_empty() {
        return Err(AssetError::EmptyMesh { file: file.to_path_buf() });
    }
    if mesh.positions.iter().any(|p| !p.is_finite()) {
        return Err(bad("a vertex position is not finite".to_owned()));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::search::AssetSearchPath;

    fn write(dir: &Path, name: &str, text: &str) {
        let file = dir.join(name);
        std::fs::create_dir_all(file.parent().expect("parent")).expect("mkdir");
        std::fs::write(file, text).expect("write");
    }

    #[test]
    fn slots_follow_mtl_order_with_a_last_slot_for_faces_without_material() {
        let dir = tempfile::tempdir().expect("tempdir");
        write(dir.path(), "m/lib.mtl", "newmtl b\nKd 0 0 1\nnewmtl a\nKd 1 0 0\n");
        // A triangle with no material (none is current yet), a quad with `a`, a triangle
        // naming an unknown one, a triangle with `b`; negative (relative) indices as the
        // McGuire files use.
        let obj = "mtllib lib.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                   o t\nf 1 2 3\n\
                   o q\nusemtl a\nf -4 -3 -2 -1\n\
                   o u\nusemtl nope\nf 1 3 4\n\
                   o w\nusemtl b\nf 2 3 4\n";
        write(dir.path(), "m/x.obj", obj);
        let resolver = AssetSearchPath::from_dirs(vec![dir.path().into()]);
        let data = read_obj("m/x.obj", &resolver).expect("loads");
        assert_eq!(data.mtl_assets, vec!["m/lib.mtl".to_owned()]);
        let names: Vec<&str> = data.materials.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["b", "a"]);
        assert_eq!(data.mesh.slot_count, 3);
        assert_eq!(data.mesh.triangle_count(), 5, "the quad is triangulated");
        assert_eq!(data.mesh.slots, [2, 1, 1, 2, 0]);
        assert!(data.mesh.normals.is_empty() && data.mesh.uvs.is_empty());
    }

    #[test]
    fn missing_mtl_is_an_error_naming_it() {
        let dir = tempfile::tempdir().expect("tempdir");
        write(dir.path(), "x.obj", "mtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let resolver = AssetSearchPath::from_dirs(vec![dir.path().into()]);
        let err = read_obj("x.obj", &resolver).expect_err("mtl missing").to_string();
        assert!(err.contains("gone.mtl") && err.contains("not found"), "{err}");
    }

    #[test]
    fn an_obj_without_faces_is_rejected() {
        let dir = tempfile::tempdir().expect("tempdir");
        write(dir.path(), "x.obj", "v 0 0 0\n");
        let resolver = AssetSearchPath::from_dirs(vec![dir.path().into()]);
        assert!(matches!(read_obj("x.obj", &resolver), Err(AssetError::EmptyMesh { .. })));
    }
}
