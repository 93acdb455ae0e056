//! The default scene's node hierarchy flattened into one world-space mesh, with the
//! cameras and lights the nodes place.
//!
//! - Node transforms (TRS or matrix) compose from the roots down; a node under a mirroring
//!   transform (negative determinant) has its triangles' winding reversed, as glTF asks.
//! - Every primitive of every mesh instance is appended; indices may be 8, 16 or 32 bits
//!   wide or absent (non-indexed: consecutive triples). Only `TRIANGLES` are drawn;
//!   other modes are warned about.
//! - Primitives without `NORMAL` get flat normals (glTF's rule): their triangles get
//!   vertices of their own carrying the face normal, unless no primitive of the file has
//!   normals, where the mesh has none and the renderer's geometric normal is the same.
//! - UVs are flipped to gridlight's convention (v up, like OBJ): glTF's v grows downwards.
//! - Every accessor is checked (type, bounds within its buffer view and buffer) before the
//!   crate's readers touch it, so a malformed file is an error, never a panic.

use glam::{Mat3, Mat4, Vec2, Vec3};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

use super::view::{PlacedCamera, PlacedLight};
use super::{view_bytes, GltfError, Warnings};
use crate::assets::Mesh;

/// What the node hierarchy holds.
pub(crate) struct Placed {
    pub mesh: Mesh,
    pub cameras: Vec<PlacedCamera>,
    pub lights: Vec<PlacedLight>,
}

/// One primitive instance in world space.
struct Piece {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    uvs: Option<Vec<Vec2>>,
    triangles: Vec<[u32; 3]>,
    slot: u32,
}

/// Flattens the default scene (else the first, else every root node); `material_count`
/// glTF materials give `material_count + 1` slots.
pub(crate) fn flatten(
    doc: &gltf::Document,
    buffers: &[Vec<u8>],
    warnings: &mut Warnings,
    material_count: u32,
) -> Result<Placed, GltfError> {
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let children: Vec<usize> =
                doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    let mut pieces = Vec::new();
    let mut cameras = Vec::new();
    let mut lights = Vec::new();
    let node_count = doc.nodes().len();
    let mut stack: Vec<(gltf::Node, Mat4, usize)> =
        roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        let element = format!("nodes[{}]", node.index());
        if depth > node_count {
            return Err(GltfError::invalid(element, "the node hierarchy has a cycle"));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err(GltfError::invalid(element, "its transform is not finite"));
        }
        if let Some(mesh) = node.mesh() {
            for primitive in mesh.primitives() {
                let piece = primitive_piece(
                    buffers,
                    warnings,
                    mesh.index(),
                    &primitive,
                    world,
                    material_count,
                )?;
                if let Some(piece) = piece {
                    pieces.push(piece);
                }
            }
        }
        if let Some(camera) = node.camera() {
            cameras.push(PlacedCamera::new(&camera, world));
        }
        if let Some(light) = node.light() {
            lights.push(PlacedLight::new(&light, world));
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    Ok(Placed { mesh: merge(pieces, material_count)?, cameras, lights })
}

/// One primitive transformed by `world`, `None` (with a warning) for non-triangle modes.
fn primitive_piece(
    buffers: &[Vec<u8>],
    warnings: &mut Warnings,
    mesh: usize,
    primitive: &gltf::Primitive,
    world: Mat4,
    material_count: u32,
) -> Result<Option<Piece>, GltfError> {
    if primitive.mode() != Mode::Triangles {
        warnings
            .push(format!("primitive mode {:?}: not drawn (only triangles are)", primitive.mode()));
        return Ok(None);
    }
    let element = format!("meshes[{mesh}].primitives[{}]", primitive.index());
    if primitive.get(&gltf::Semantic::Colors(0)).is_some() {
        warnings.push("vertex colours (COLOR_0): not rendered");
    }
    if primitive.morph_targets().len() > 0 {
        warnings.push("morph targets: not applied (the base shape is drawn)");
    }
    let position = primitive
        .get(&gltf::Semantic::Positions)
        .ok_or_else(|| GltfError::invalid(&element, "has no POSITION attribute"))?;
    check_accessor(buffers, &position, &[DataType::F32], Dimensions::Vec3)?;
    let normal = primitive.get(&gltf::Semantic::Normals);
    if let Some(a) = &normal {
        check_accessor(buffers, a, &[DataType::F32], Dimensions::Vec3)?;
        same_count(a, &position)?;
    }
    let uv = primitive.get(&gltf::Semantic::TexCoords(0));
    if let Some(a) = &uv {
        check_accessor(
            buffers,
            a,
            &[DataType::F32, DataType::U8, DataType::U16],
            Dimensions::Vec2,
        )?;
        same_count(a, &position)?;
    }
    let indices = primitive.indices();
    if let Some(a) = &indices {
        check_accessor(
            buffers,
            a,
            &[DataType::U8, DataType::U16, DataType::U32],
            Dimensions::Scalar,
        )?;
    }
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let unreadable = |a: &gltf::Accessor| {
        GltfError::invalid(format!("accessors[{}]", a.index()), "cannot be read")
    };
    let positions: Vec<Vec3> = reader
        .read_positions()
        .ok_or_else(|| unreadable(&position))?
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    if positions.iter().any(|p| !p.is_finite()) {
        let a = format!("accessors[{}]", position.index());
        return Err(GltfError::invalid(a, "a POSITION is not finite"));
    }
    let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
    let normals = match &normal {
        Some(a) => Some(
            reader
                .read_normals()
                .ok_or_else(|| unreadable(a))?
                .map(|n| (normal_matrix * Vec3::from(n)).normalize_or_zero())
                .collect(),
        ),
        None => None,
    };
    let uvs = match &uv {
        Some(a) => Some(
            reader
                .read_tex_coords(0)
                .ok_or_else(|| unreadable(a))?
                .into_f32()
                .map(|[u, v]| Vec2::new(u, 1.0 - v))
                .collect(),
        ),
        None => None,
    };
    let flat: Vec<u32> = match &indices {
        Some(a) => reader.read_indices().ok_or_else(|| unreadable(a))?.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    if !flat.len().is_multiple_of(3) {
        return Err(GltfError::invalid(
            element,
            format!("{} indices are not whole triangles", flat.len()),
        ));
    }
    if let Some(bad) = flat.iter().find(|&&i| i as usize >= positions.len()) {
        let a = indices.as_ref().map_or(element, |a| format!("accessors[{}]", a.index()));
        return Err(GltfError::invalid(
            a,
            format!("index {bad} is past the {} vertices", positions.len()),
        ));
    }
    let mirrored = world.determinant() < 0.0;
    let triangles = flat
        .chunks_exact(3)
        .map(|t| if mirrored { [t[0], t[2], t[1]] } else { [t[0], t[1], t[2]] })
        .collect();
    let slot = primitive.material().index().map_or(material_count, |i| i as u32);
    Ok(Some(Piece { positions, normals, uvs, triangles, slot }))
}

/// Checks that `a` has one of `types`, the dimensions `dims`, a view, and that all of its
/// `count` elements lie inside the view and the view inside its buffer's bytes.
fn check_accessor(
    buffers: &[Vec<u8>],
    a: &gltf::Accessor,
    types: &[DataType],
    dims: Dimensions,
) -> Result<(), GltfError> {
    let element = format!("accessors[{}]", a.index());
    let bad = |reason: String| GltfError::invalid(&element, reason);
    if !types.contains(&a.data_type()) || a.dimensions() != dims {
        return Err(bad(format!(
            "is {:?} {:?}, expected {dims:?} of {types:?}",
            a.dimensions(),
            a.data_type()
        )));
    }
    if a.sparse().is_some() {
        return Err(bad("sparse accessors are not supported".to_owned()));
    }
    let view = a.view().ok_or_else(|| bad("has no bufferView (compressed data?)".to_owned()))?;
    if a.count() == 0 {
        return Err(bad("has no elements".to_owned()));
    }
    let size = a.size();
    let stride = view.stride().unwrap_or(size);
    if stride < size {
        return Err(bad(format!("byteStride {stride} is below the element size {size}")));
    }
    let end = (a.count() - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(size))
        .and_then(|n| n.checked_add(a.offset()));
    if end.is_none_or(|end| end > view.length()) {
        return Err(bad(format!("{} elements run past its bufferView", a.count())));
    }
    if view_bytes(&view, buffers).is_none() {
        return Err(GltfError::invalid(
            format!("bufferViews[{}]", view.index()),
            "runs past the end of its buffer",
        ));
    }
    Ok(())
}

fn same_count(a: &gltf::Accessor, position: &gltf::Accessor) -> Result<(), GltfError> {
    if a.count() == position.count() {
        return Ok(());
    }
    Err(GltfError::invalid(
        format!("accessors[{}]", a.index()),
        format!("has {} elements, POSITION has {}", a.count(), position.count()),
    ))
}

/// Merges the pieces into one mesh (see the module doc for normals).
fn merge(pieces: Vec<Piece>, material_count: u32) -> Result<Mesh, GltfError> {
    let any_normals = pieces.iter().any(|p| p.normals.is_some());
    let any_uvs = pieces.iter().any(|p| p.uvs.is_some());
    let mut mesh = Mesh { slot_count: material_count + 1, ..Mesh::default() };
    for mut piece in pieces {
        if any_normals && piece.normals.is_none() {
            unshare_with_face_normals(&mut piece);
        }
        let base = mesh.positions.len() as u32;
        let count = piece.positions.len();
        mesh.positions.extend(&piece.positions);
        mesh.indices.extend(piece.triangles.iter().map(|t| t.map(|i| base + i)));
        mesh.slots.resize(mesh.indices.len(), piece.slot);
        if any_normals {
            mesh.normals.extend(piece.normals.expect("set above"));
        }
        if any_uvs {
            match piece.uvs {
                Some(uvs) => mesh.uvs.extend(uvs),
                None => mesh.uvs.resize(mesh.uvs.len() + count, Vec2::ZERO),
            }
        }
    }
    if mesh.indices.is_empty() {
        return Err(GltfError::NoTriangles);
    }
    Ok(mesh)
}

/// Gives every triangle of `piece` three vertices of its own carrying its face normal.
fn unshare_with_face_normals(piece: &mut Piece) {
    let mut positions = Vec::with_capacity(piece.triangles.len() * 3);
    let mut normals = Vec::with_capacity(positions.capacity());
    let mut uvs = piece.uvs.as_ref().map(|_| Vec::with_capacity(positions.capacity()));
    for (t, tri) in piece.triangles.iter_mut().enumerate() {
        let [a, b, c] = tri.map(|i| piece.positions[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for (k, i) in tri.iter_mut().enumerate() {
            positions.push(piece.positions[*i as usize]);
            normals.push(n);
            if let (Some(out), Some(src)) = (uvs.as_mut(), piece.uvs.as_ref()) {
                out.push(src[*i as usize]);
            }
            *i = (3 * t + k) as u32;
        }
    }
    piece.positions = positions;
    piece.normals = Some(normals);
    piece.uvs = uvs;
}
