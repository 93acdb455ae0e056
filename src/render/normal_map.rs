//! Tangent-space normal maps (glTF's `normalTexture`): the shading normal of a hit bent by
//! the map's texel, in the frame of the triangle's texture directions.
//!
//! The tangent and bitangent are the triangle's ∂P/∂u and ∂P/∂v (v up, as gridlight's
//! texture coordinates are: glTF's are flipped on load), made orthonormal to the
//! interpolated normal. That is MikkTSpace on flat triangles; on a curved mesh it differs
//! from the per-vertex tangents a baker used by the tangents' variation across each
//! triangle, so the file's `TANGENT` attribute and generated MikkTSpace tangents are
//! the next step (the loader warns meanwhile).

use glam::{Affine3A, Vec2, Vec3};

use crate::assets::{Lookup, Texture};

/// The triangle `positions`/`uvs` (object space) seen through `to_world`: its world-space
/// ∂P/∂u and ∂P/∂v, `None` where its texture coordinates are degenerate.
#[inline]
pub fn triangle_tangents(
    positions: [Vec3; 3],
    uvs: [Vec2; 3],
    to_world: &Affine3A,
) -> Option<(Vec3, Vec3)> {
    let (e1, e2) = (positions[1] - positions[0], positions[2] - positions[0]);
    let (d1, d2) = (uvs[1] - uvs[0], uvs[2] - uvs[0]);
    let det = d1.x * d2.y - d1.y * d2.x;
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let r = 1.0 / det;
    let dpdu = (e1 * d2.y - e2 * d1.y) * r;
    let dpdv = (e2 * d1.x - e1 * d2.x) * r;
    Some((to_world.transform_vector3(dpdu), to_world.transform_vector3(dpdv)))
}

/// The shading normal `ns` bent by `map`'s texel at `uv` (looked up as `lookup` says; xy
/// scaled by `scale`), in the
/// frame of `dpdu`, `dpdv`; `ns` itself where that frame or the result is degenerate or
/// the bent normal would face away from the geometric normal `ng`.
#[inline]
pub fn bend(
    map: &Texture,
    lookup: Option<&Lookup>,
    scale: f32,
    uv: Vec2,
    ns: Vec3,
    ng: Vec3,
    (dpdu, dpdv): (Vec3, Vec3),
) -> Vec3 {
    let t = (dpdu - ns * ns.dot(dpdu)).normalize_or_zero();
    if t == Vec3::ZERO {
        return ns;
    }
    // The bitangent's side follows ∂P/∂v, so that mirrored texture coordinates keep
    // their handedness.
    let b = ns.cross(t);
    let b = if b.dot(dpdv) < 0.0 { -b } else { b };
    let texel = map.sample_with(uv, lookup) * 2.0 - Vec3::ONE;
    let n = (t * (texel.x * scale) + b * (texel.y * scale) + ns * texel.z).normalize_or_zero();
    if n.dot(ng) <= 0.0 {
        return ns;
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flat_map_keeps_the_normal_and_a_tilted_one_tilts_towards_the_tangent() {
        let positions = [Vec3::ZERO, Vec3::X, Vec3::NEG_Z];
        let uvs = [Vec2::ZERO, Vec2::X, Vec2::Y];
        let frame = triangle_tangents(positions, uvs, &Affine3A::IDENTITY).unwrap();
        assert_eq!(frame, (Vec3::X, Vec3::NEG_Z));
        let flat = Texture::linear(1, 1, vec![Vec3::new(0.5, 0.5, 1.0)]);
        assert_eq!(bend(&flat, None, 1.0, Vec2::ZERO, Vec3::Y, Vec3::Y, frame), Vec3::Y);
        // 30° towards +u, then towards +v, in texel encoding (n + 1) / 2.
        let (s, c) = (0.5f32, 0.75f32.sqrt());
        let towards_u = Texture::linear(1, 1, vec![Vec3::new(s + 1.0, 1.0, c + 1.0) * 0.5]);
        let n = bend(&towards_u, None, 1.0, Vec2::ZERO, Vec3::Y, Vec3::Y, frame);
        assert!((n - Vec3::new(s, c, 0.0)).length() < 1e-5, "{n}");
        let towards_v = Texture::linear(1, 1, vec![Vec3::new(1.0, s + 1.0, c + 1.0) * 0.5]);
        let n = bend(&towards_v, None, 1.0, Vec2::ZERO, Vec3::Y, Vec3::Y, frame);
        assert!((n - Vec3::new(0.0, c, -s)).length() < 1e-5, "{n}");
        // A scale of 0 flattens the map; degenerate uvs leave the normal alone.
        assert_eq!(bend(&towards_u, None, 0.0, Vec2::ZERO, Vec3::Y, Vec3::Y, frame), Vec3::Y);
        assert!(triangle_tangents(positions, [Vec2::ZERO; 3], &Affine3A::IDENTITY).is_none());
    }

    /// Through the kernel: a glTF material's normal map bends the primary hit's normal
    /// (what the G-buffer records), in the placed object's frame.
    #[test]
    fn a_pbr_material_s_normal_map_bends_the_hit_normal() {
        use gridlight_actors::state::{
            Camera, Geometry, Material, Object, Resolution, SceneState, Transform,
        };
        use std::sync::Arc;
        let camera = Camera::pinhole(Vec3::new(0.0, 3.0, 0.5), Vec3::ZERO, 20.0);
        let mut material = Material::pbr("bumpy", Vec3::ONE, 0.0, 0.5);
        material.normal_texture = Some("n.png".into());
        let mut quad = Object::new("quad", Geometry::Quad);
        // Turned a quarter about +y: the map's +u now points along -z.
        quad.transform = Transform {
            rotation: glam::Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            ..Transform::default()
        };
        let state = SceneState::empty(Resolution { width: 9, height: 9 }, camera)
            .with_object(quad, material);
        let (s, c) = (0.5f32, 0.75f32.sqrt());
        let mut assets = crate::assets::Assets::default();
        let map = Texture::linear(1, 1, vec![Vec3::new(s + 1.0, 1.0, c + 1.0) * 0.5]);
        assets.data_textures.insert("n.png".into(), Arc::new(map));
        let scene = crate::render::RenderScene::new(Arc::new(assets), &state).unwrap();
        let hit = crate::render::primary_hit(&scene, 4 * 9 + 4);
        assert_eq!(hit.object, 0);
        assert!((hit.normal - Vec3::new(0.0, c, -s)).length() < 1e-4, "{}", hit.normal);
        // Without the map, the quad's own normal.
        let mut flat = state.clone();
        flat.materials[0].normal_texture = None;
        let scene = crate::render::RenderScene::new(Arc::new(Default::default()), &flat).unwrap();
        assert!((crate::render::primary_hit(&scene, 40).normal - Vec3::Y).length() < 1e-6);
    }
}
