//! Every scene in `scenes/` loads. Scenes that use the public assets are skipped, with the
//! reason printed, when no asset directory is configured (`GRIDLIGHT_ASSETS`, which
//! `.ci/run` sets when the public assets are beside the clone).

use std::path::{Path, PathBuf};

use gridlight::scene::{self, AssetError, AssetSearchPath, LoadedScene, Problem, ResolveError};
use gridlight_actors::state::{Geometry, MaterialKind};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The shared assets, when this machine has them.
fn shared_assets() -> Option<PathBuf> {
    std::env::var_os("GRIDLIGHT_ASSETS").map(PathBuf::from)
}

fn search_path(scene: &Path) -> AssetSearchPath {
    let extra: Vec<PathBuf> = shared_assets().into_iter().collect();
    AssetSearchPath::from_env(&extra, Some(scene))
}

/// Loads a scene, or `None` (printed) when it needs assets this machine does not have.
fn load(name: &str) -> Option<LoadedScene> {
    let path = repo().join("scenes").join(name);
    match scene::load(&path, &search_path(&path)) {
        Ok(loaded) => Some(loaded),
        Err(err)
            if shared_assets().is_none()
                && matches!(
                    *err.problem,
                    Problem::Asset(AssetError::Resolve(ResolveError::NotFound { .. }))
                ) =>
        {
            gridlight::testing::skip(name, gridlight::testing::Missing::Assets, err);
            None
        }
        Err(err) => panic!("{err}"),
    }
}

#[test]
fn every_scene_file_loads() {
    let mut names: Vec<String> = std::fs::read_dir(repo().join("scenes"))
        .expect("scenes/ exists")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 5, "expected the built-in and asset scenes, found {names:?}");
    for name in &names {
        if let Some(loaded) = load(name) {
            let state = &loaded.state;
            assert!(!state.objects.is_empty(), "{name}: no objects");
            for object in &state.objects {
                let mesh = loaded.assets.meshes.get(&object.geometry).expect("mesh loaded");
                assert_eq!(
                    object.materials.len(),
                    mesh.slot_count as usize,
                    "{name}: {}",
                    object.name
                );
                assert!(object.materials.iter().all(|&m| (m as usize) < state.materials.len()));
            }
            for material in &state.materials {
                if let Some(t) = &material.base_color_texture {
                    assert!(
                        loaded.assets.textures.contains_key(t),
                        "{name}: texture {t} not loaded"
                    );
                }
            }
        }
    }
}

#[test]
fn cornell_box_matches_mitsubas_dictionary() {
    let loaded = load("cornell-box.toml").expect("built-in scene needs no assets");
    let state = &loaded.state;
    assert_eq!((state.resolution.width, state.resolution.height), (640, 480));
    assert_eq!(state.camera.position, glam::Vec3::new(0.0, 0.0, 3.9));
    assert!((state.camera.vfov_deg - 39.3077).abs() < 1e-4);
    let object = |name: &str| state.objects.iter().find(|o| o.name == name).expect(name);
    let material = |name: &str| &state.materials[object(name).materials[0] as usize];
    // Red on the left (−x) as seen from the camera on +z looking down −z, green on the right.
    assert!(object("red-wall").transform.translation.x < 0.0);
    assert!(object("green-wall").transform.translation.x > 0.0);
    assert!(material("red-wall").base_color.x > material("red-wall").base_color.y);
    assert!(material("green-wall").base_color.y > material("green-wall").base_color.x);
    // Every wall faces into the room: its +y normal, transformed, points at the origin.
    for wall in ["floor", "ceiling", "back", "red-wall", "green-wall", "light"] {
        let t = object(wall).transform;
        let normal = t.rotation * glam::Vec3::Y;
        assert!(normal.dot(-t.translation) > 0.9 * t.translation.length(), "{wall} faces {normal}");
    }
    let light = object("light");
    assert_eq!(light.geometry, Geometry::Quad);
    assert_eq!(material("light").emission, glam::Vec3::new(18.387, 13.9873, 6.75357));
    // The light is 0.46 × 0.38 (Mitsuba: rectangle [-1,1]² scaled 0.23 × 0.19).
    let corners = [glam::Vec3::new(0.5, 0.0, 0.5), glam::Vec3::new(-0.5, 0.0, -0.5)]
        .map(|c| light.transform.matrix().transform_point3(c));
    let size = (corners[0] - corners[1]).abs();
    assert!((size.x - 0.46).abs() < 1e-5 && (size.z - 0.38).abs() < 1e-5, "light size {size}");
    assert!(corners.iter().all(|c| (c.y - 0.99).abs() < 1e-6));
}

#[test]
fn glossy_glass_scene_has_glass_and_gloss() {
    let loaded = load("glossy-glass.toml").expect("built-in scene needs no assets");
    let kinds: Vec<MaterialKind> = loaded.state.materials.iter().map(|m| m.kind).collect();
    for kind in [MaterialKind::Dielectric, MaterialKind::Glossy, MaterialKind::Conductor] {
        assert!(kinds.contains(&kind), "no {kind:?} material");
    }
}

#[test]
fn sponza_gets_mtl_materials_with_linear_textures() {
    let Some(loaded) = load("sponza.toml") else { return };
    let sponza = &loaded.state.objects[0];
    let mesh = &loaded.assets.meshes[&sponza.geometry];
    assert_eq!(mesh.triangle_count(), 66_450);
    assert_eq!(mesh.slot_count, 21, "20 MTL materials plus the no-material slot");
    assert!(mesh.normals.is_empty(), "sponza has no normals: geometric ones are used");
    assert_eq!(mesh.uvs.len(), mesh.positions.len());
    assert!(loaded.assets.textures.len() >= 10);
    for texture in loaded.assets.textures.values() {
        assert!(texture.texels.iter().all(|t| t.is_finite() && t.max_element() <= 1.0));
    }
}

#[test]
fn manifest_lists_obj_mtl_textures_and_envmap_with_hashes() {
    let Some(loaded) = load("sponza.toml") else { return };
    let path = repo().join("scenes/sponza.toml");
    let manifest = scene::manifest(&loaded.state, &search_path(&path)).expect("manifest");
    let names: Vec<&str> = manifest.iter().map(|e| e.path.as_str()).collect();
    assert_eq!(names[0], "dabrovic_sponza/sponza.obj");
    assert_eq!(names[1], "dabrovic_sponza/sponza.mtl");
    assert!(names.iter().filter(|n| n.ends_with(".jpg")).count() >= 10);
    let obj = &manifest[0];
    assert_eq!(obj.len, 5_610_593);
    assert_eq!(
        hex::encode(obj.hash),
        "f109270c87e563790153e557890c1029eea4fda4ce360b4164fa8682627bd90d"
    );
    // The master lists the same paths from what it loaded, without reading the OBJ again.
    let listed = scene::asset_paths(&loaded.state, &loaded.assets).expect("asset paths");
    assert_eq!(listed, names, "the master's asset list differs from the manifest");
    // A worker's view: assets from the state alone give the same data.
    let again = scene::load_assets(&loaded.state, &search_path(&path)).expect("load from state");
    assert_eq!(again.meshes.len(), loaded.assets.meshes.len());
    assert_eq!(again.textures.len(), loaded.assets.textures.len());
    assert_eq!(again.mesh_companions, loaded.assets.mesh_companions);

    let Some(car) = load("envmap-object.toml") else { return };
    let manifest = scene::manifest(&car.state, &search_path(&path)).expect("manifest");
    assert_eq!(manifest.last().map(|e| e.path.as_str()), Some("envmaps/venice_sunset_1k.hdr"));
}
