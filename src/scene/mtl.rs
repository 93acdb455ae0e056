//! MTL materials → gridlight [`Material`]s, by the usual heuristics.
//!
//! - `Kd` → base colour, `map_Kd` → albedo texture (an asset beside the OBJ), `Ke` → emission.
//! - `illum` 4, 6, 7 or 9, or `d` < 1 → dielectric with IOR `Ni` (1.5 where `Ni` ≤ 1, which
//!   exporters write for "unset") and `Tf` as tint.
//! - `illum` 3 or 5 with a non-black `Ks` → conductor (mirror-like) with reflectance `Ks`.
//! - any other non-black `Ks` → glossy (diffuse `Kd` under a clear coat).
//! - otherwise diffuse.
//! - Roughness from the Phong exponent `Ns`: Beckmann-equivalent α = √(2/(Ns+2)), and the
//!   state stores perceptual roughness √α.
//! - `Tr` is ignored (the Dabrovic Sponza writes `Tr 0` next to `d 1`: opaque), and so are
//!   `bump`/`map_bump`: in these files they are height maps, not tangent-space normal maps.

use glam::Vec3;
use gridlight_actors::state::{Material, MaterialKind};

use super::search::sibling_asset;

/// `Ks` components below this count as black.
const SPECULAR_EPSILON: f32 = 0.01;
/// IOR used where the MTL gives none (or a meaningless ≤ 1).
const DEFAULT_IOR: f32 = 1.5;

/// Converts one MTL material of the OBJ at asset path `obj_asset`; `name` is what the scene
/// state calls it.
pub fn convert(mtl: &tobj::Material, obj_asset: &str, name: String) -> Material {
    let kd = mtl.diffuse.map(Vec3::from).unwrap_or(Vec3::splat(0.8));
    let ks = mtl.specular.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let emission = mtl.emissive.map(Vec3::from).unwrap_or(Vec3::ZERO);
    let illum = mtl.illumination_model.unwrap_or(2);
    let dissolve = mtl.dissolve.unwrap_or(1.0);
    let roughness = mtl.shininess.map(roughness_from_phong).unwrap_or(0.5);
    let ior = mtl.optical_density.filter(|&n| n > 1.0 && n.is_finite()).unwrap_or(DEFAULT_IOR);
    let texture =
        mtl.diffuse_texture.as_deref().and_then(texture_file).map(|t| sibling_asset(obj_asset, t));
    let clean = |v: Vec3| if v.is_finite() { v.max(Vec3::ZERO) } else { Vec3::ZERO };

    let (kind, base_color) = if matches!(illum, 4 | 6 | 7 | 9) || dissolve < 1.0 {
        let tint = mtl.unknown_param.get("Tf").and_then(|s| parse_vec3(s)).unwrap_or(Vec3::ONE);
        (MaterialKind::Dielectric, tint)
    } else if matches!(illum, 3 | 5) && ks.max_element() > SPECULAR_EPSILON {
        (MaterialKind::Conductor, ks)
    } else if ks.max_element() > SPECULAR_EPSILON {
        (MaterialKind::Glossy, kd)
    } else {
        (MaterialKind::Diffuse, kd)
    };
    Material {
        name,
        kind,
        base_color: clean(base_color).min(Vec3::ONE),
        base_color_texture: if kind == MaterialKind::Dielectric { None } else { texture },
        roughness,
        ior,
        emission: clean(emission),
        ..Material::diffuse("", Vec3::ZERO)
    }
}

/// Perceptual GGX roughness matching a Phong exponent.
pub fn roughness_from_phong(ns: f32) -> f32 {
    if !ns.is_finite() || ns < 0.0 {
        return 1.0;
    }
    (2.0 / (ns + 2.0)).sqrt().sqrt().clamp(0.0, 1.0)
}

/// The file name of a texture statement, without options such as `-bm 1`.
fn texture_file(statement: &str) -> Option<&str> {
    let statement = statement.trim();
    if statement.is_empty() {
        return None;
    }
    if statement.starts_with('-') {
        statement.split_whitespace().last()
    } else {
        Some(statement)
    }
}

fn parse_vec3(s: &str) -> Option<Vec3> {
    let v: Vec<f32> = s.split_whitespace().map(str::parse).collect::<Result<_, _>>().ok()?;
    match v.as_slice() {
        [x] => Some(Vec3::splat(*x)),
        [x, y, z] => Some(Vec3::new(*x, *y, *z)),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mtl(f: impl FnOnce(&mut tobj::Material)) -> Material {
        let mut m = tobj::Material::default();
        f(&mut m);
        convert(&m, "dir/x.obj", "m".into())
    }

    #[test]
    fn diffuse_with_texture_beside_the_obj() {
        let m = mtl(|m| {
            m.diffuse = Some([0.5, 0.25, 0.125]);
            m.diffuse_texture = Some("tex/a.jpg".into());
        });
        assert_eq!(m.kind, MaterialKind::Diffuse);
        assert_eq!(m.base_color, Vec3::new(0.5, 0.25, 0.125));
        assert_eq!(m.base_color_texture.as_deref(), Some("dir/tex/a.jpg"));
    }

    #[test]
    fn emission_glossy_mirror_and_glass() {
        let light = mtl(|m| m.emissive = Some([17.0, 12.0, 4.0]));
        assert_eq!(light.emission, Vec3::new(17.0, 12.0, 4.0));
        let glossy = mtl(|m| {
            m.specular = Some([0.5; 3]);
            m.shininess = Some(100.0);
        });
        assert_eq!(glossy.kind, MaterialKind::Glossy);
        assert!(glossy.roughness > 0.0 && glossy.roughness < 0.5);
        let mirror = mtl(|m| {
            m.specular = Some([0.9; 3]);
            m.illumination_model = Some(3);
        });
        assert_eq!(mirror.kind, MaterialKind::Conductor);
        assert_eq!(mirror.base_color, Vec3::splat(0.9));
        let glass = mtl(|m| {
            m.illumination_model = Some(4);
            m.optical_density = Some(1.0);
        });
        assert_eq!(glass.kind, MaterialKind::Dielectric);
        assert_eq!(glass.ior, DEFAULT_IOR);
    }

    #[test]
    fn sharper_highlights_mean_lower_roughness() {
        assert!(roughness_from_phong(1000.0) < roughness_from_phong(10.0));
        assert_eq!(roughness_from_phong(0.0), 1.0);
    }
}
