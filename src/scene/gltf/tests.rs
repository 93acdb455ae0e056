//! glTF loading on fixtures written by [`super::fixture`].

use std::path::Path;

use glam::Vec3;
use gridlight_actors::state::{Geometry, Light, MaterialKind};
use serde_json::json;

use super::fixture::{lit_scene, Bin, Fixture};
use super::*;
use crate::scene::{self, AssetSearchPath, SceneSource};

fn search(dir: &Path) -> AssetSearchPath {
    AssetSearchPath::from_dirs(vec![dir.to_path_buf()])
}

/// `f` written as `dir/x.glb`, then read.
fn read_glb(f: &Fixture) -> Result<GltfData, AssetError> {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("x.glb"), f.glb()).expect("write");
    read_gltf("x.glb", &search(dir.path()))
}

fn error_of(f: &Fixture) -> String {
    read_glb(f).expect_err("malformed file accepted").to_string()
}

fn quad_scene(index_bytes: usize) -> Fixture {
    let mut f = Fixture::new();
    let mesh = f.quad_mesh(None, index_bytes);
    f.node(json!({ "mesh": mesh }), true);
    f
}

#[test]
fn hierarchy_transforms_compose_from_the_root_down() {
    let mut f = Fixture::new();
    let mesh = f.quad_mesh(None, 2);
    // Child: a column-major matrix translating by +1 x; parent: TRS with a 90° turn about
    // z, scale 2 and a translation of +10 y. Vertex (0.5, 0.5, 0) of the quad goes
    // (1.5, 0.5, 0) → scaled (3, 1, 0) → turned (-1, 3, 0) → (-1, 13, 0).
    let child =
        f.node(json!({ "mesh": mesh, "matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 1,0,0,1] }), false);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    f.node(
        json!({ "children": [child], "rotation": [0.0, 0.0, s, s], "scale": [2, 2, 2],
                "translation": [0, 10, 0] }),
        true,
    );
    let data = read_glb(&f).expect("loads");
    let p = data.mesh.positions[2];
    assert!((p - Vec3::new(-1.0, 13.0, 0.0)).length() < 1e-5, "{p}");
    // The +z normal stays +z under a rotation about z.
    assert!((data.mesh.normals[2] - Vec3::Z).length() < 1e-5);
    assert_eq!(data.mesh.uvs[2], glam::Vec2::new(1.0, 1.0), "v flipped to point up");
}

#[test]
fn a_mirroring_node_reverses_the_winding() {
    let mut f = Fixture::new();
    let mesh = f.quad_mesh(None, 2);
    f.node(json!({ "mesh": mesh }), true);
    f.node(json!({ "mesh": mesh, "scale": [-1, 1, 1] }), true);
    let m = read_glb(&f).expect("loads").mesh;
    let normal = |t: usize| {
        let [a, b, c] = m.indices[t].map(|i| m.positions[i as usize]);
        (b - a).cross(c - a).normalize()
    };
    assert!((normal(0) - Vec3::Z).length() < 1e-5);
    assert!((normal(2) - Vec3::Z).length() < 1e-5, "mirrored copy still faces +z");
}

#[test]
fn every_index_width_and_no_indices_give_the_same_mesh() {
    let reference = read_glb(&quad_scene(4)).expect("u32").mesh;
    for bytes in [1, 2] {
        let m = read_glb(&quad_scene(bytes)).expect("narrow indices").mesh;
        assert_eq!(m.indices, reference.indices, "{bytes}-byte indices");
        assert_eq!(m.positions, reference.positions);
    }
    let mut f = Fixture::new();
    let p2 = f.floats(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let mesh = f.mesh(json!({ "POSITION": p2 }), None, None);
    f.node(json!({ "mesh": mesh }), true);
    let m = read_glb(&f).expect("non-indexed").mesh;
    assert_eq!(m.indices, vec![[0, 1, 2]]);
    assert!(m.normals.is_empty(), "no normals anywhere: the geometric normal is used");
}

#[test]
fn primitives_without_normals_get_flat_ones_beside_primitives_with() {
    let mut f = Fixture::new();
    let quad = f.quad_mesh(None, 2);
    let p = f.floats(&[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]);
    let tri = f.mesh(json!({ "POSITION": p }), None, None);
    f.node(json!({ "mesh": quad }), true);
    f.node(json!({ "mesh": tri }), true);
    let m = read_glb(&f).expect("loads").mesh;
    assert_eq!(m.normals.len(), m.positions.len());
    let [a, _, _] = m.indices[2];
    assert!((m.normals[a as usize] - Vec3::NEG_X).length() < 1e-5, "{}", m.normals[a as usize]);
}

#[test]
fn other_primitive_modes_are_skipped_with_a_warning() {
    let mut f = quad_scene(2);
    let p = f.floats(&[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]);
    let lines = f.push(
        "meshes",
        json!({ "primitives": [{ "attributes": { "POSITION": p },
                                                          "mode": 1 }] }),
    );
    f.node(json!({ "mesh": lines }), true);
    let data = read_glb(&f).expect("loads");
    assert_eq!(data.mesh.triangle_count(), 2);
    assert!(data.warnings.as_slice().iter().any(|w| w.contains("Lines")), "{:?}", data.warnings);
}

fn load_scene(dir: &Path, name: &str) -> scene::LoadedScene {
    let source = SceneSource::File(dir.join(name));
    scene::load_source(&source, &source.search_path(&[])).expect("scene loads")
}

#[test]
fn the_first_camera_gives_the_view_and_the_resolution() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut f = quad_scene(2);
    // Camera 1 is placed first but camera 0 is the file's first camera.
    let wide = json!({ "type": "perspective",
                       "perspective": { "yfov": 0.5, "aspectRatio": 2.0, "znear": 0.1 } });
    let c0 = f.push("cameras", wide);
    let c1 = f.push(
        "cameras",
        json!({ "type": "perspective",
                                       "perspective": { "yfov": 1.0, "znear": 0.1 } }),
    );
    f.node(json!({ "camera": c1, "translation": [0, 0, 9] }), true);
    f.node(json!({ "camera": c0, "translation": [0, 1, 5] }), true);
    std::fs::write(dir.path().join("cam.glb"), f.glb()).expect("write");
    let state = load_scene(dir.path(), "cam.glb").state;
    assert!((state.camera.vfov_deg - 0.5f32.to_degrees()).abs() < 1e-4);
    assert_eq!(state.camera.position, Vec3::new(0.0, 1.0, 5.0));
    let forward = (state.camera.look_at - state.camera.position).normalize();
    assert!((forward - Vec3::NEG_Z).length() < 1e-5);
    assert_eq!((state.resolution.width, state.resolution.height), (960, 480));
    let size = |aspect| {
        let r = view::resolution_for(aspect);
        (r.width, r.height)
    };
    assert_eq!(size(Some(4.0 / 3.0)), (640, 480));
    assert_eq!(size(Some(1.0)), (480, 480));
    assert_eq!(size(None), (640, 480));
}

#[test]
fn without_a_camera_the_view_frames_the_scene_under_a_default_sky() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut f = Fixture::new();
    let mesh = f.quad_mesh(None, 2);
    f.node(json!({ "mesh": mesh, "translation": [100, 0, 0], "scale": [10, 10, 10] }), true);
    std::fs::write(dir.path().join("q.glb"), f.glb()).expect("write");
    let state = load_scene(dir.path(), "q.glb").state;
    assert_eq!(state.camera.look_at, Vec3::new(100.0, 0.0, 0.0));
    let distance = (state.camera.position - state.camera.look_at).length();
    let half_diagonal = 50f32.sqrt();
    let half = (state.camera.vfov_deg / 2.0).to_radians();
    assert!(half_diagonal / distance < half.sin(), "the bounding sphere fits");
    assert_eq!((state.resolution.width, state.resolution.height), (640, 480));
    let sky = state.environment.expect("a default sky without lights");
    assert_eq!(sky.color * sky.intensity, Vec3::splat(view::DEFAULT_SKY_RADIANCE));
}

#[test]
fn punctual_lights_become_point_spot_and_sun() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut f = quad_scene(2);
    f.uses("KHR_lights_punctual");
    f.json["extensions"] = json!({ "KHR_lights_punctual": { "lights": [
        { "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 8.0, "range": 10.0 },
        { "type": "spot", "intensity": 2.0,
          "spot": { "innerConeAngle": 0.25, "outerConeAngle": 0.5 } },
        { "type": "directional", "intensity": 3.0 } ] } });
    let light = |i: usize| json!({ "KHR_lights_punctual": { "light": i } });
    f.node(json!({ "translation": [1, 2, 3], "extensions": light(0) }), true);
    // Spot at (0, 4, 0) turned to look down -y (a -90° turn about x).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    f.node(
        json!({ "translation": [0, 4, 0], "rotation": [-s, 0, 0, s], "extensions": light(1) }),
        true,
    );
    f.node(json!({ "rotation": [-s, 0, 0, s], "extensions": light(2) }), true);
    std::fs::write(dir.path().join("l.glb"), f.glb()).expect("write");
    let loaded = load_scene(dir.path(), "l.glb");
    let lights = &loaded.state.lights;
    assert_eq!(lights.len(), 3);
    let Light::Point { position, intensity } = lights[0] else { panic!("{lights:?}") };
    assert_eq!(position, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(intensity, Vec3::new(8.0, 4.0, 2.0), "1 cd → 1 W/sr");
    let Light::Spot { direction, inner_deg, outer_deg, .. } = lights[1] else { panic!() };
    assert!((direction - Vec3::NEG_Y).length() < 1e-5, "{direction}");
    assert!((inner_deg - 0.25f32.to_degrees()).abs() < 1e-3);
    assert!((outer_deg - 0.5f32.to_degrees()).abs() < 1e-3);
    let Light::Sun { direction, radiance, angular_radius_deg } = lights[2] else { panic!() };
    assert!((direction - Vec3::Y).length() < 1e-5, "towards the sun: up");
    let solid = std::f32::consts::TAU * (1.0 - angular_radius_deg.to_radians().cos());
    assert!((radiance.x * solid - 3.0).abs() < 1e-3, "3 lux → irradiance 3");
    assert!(loaded.state.environment.is_none(), "lit files get no sky");
    assert!(loaded.warnings.iter().any(|w| w.contains("range")), "{:?}", loaded.warnings);
}

#[test]
fn materials_map_to_pbr_with_their_factors() {
    let mut f = quad_scene(2);
    for m in [
        json!({ "name": "gold", "pbrMetallicRoughness":
                { "baseColorFactor": [1.0, 0.8, 0.3, 1.0], "metallicFactor": 1.0,
                  "roughnessFactor": 0.2 } }),
        json!({ "name": "plastic", "pbrMetallicRoughness":
                { "metallicFactor": 0.0, "roughnessFactor": 0.4 } }),
        json!({ "name": "chalk", "pbrMetallicRoughness":
                { "metallicFactor": 0.0, "roughnessFactor": 1.0 } }),
        json!({ "name": "glass", "extensions": {
                "KHR_materials_transmission": { "transmissionFactor": 1.0 },
                "KHR_materials_ior": { "ior": 1.33 } } }),
        json!({ "name": "lamp", "emissiveFactor": [1.0, 0.5, 0.0],
                "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 } } }),
    ] {
        f.push("materials", m);
    }
    let data = read_glb(&f).expect("loads");
    assert!(data.materials.iter().all(|m| m.material.kind == MaterialKind::Pbr));
    let m = |i: usize| &data.materials[i].material;
    let factors: Vec<(f32, f32, f32)> =
        (0..5).map(|i| (m(i).metallic, m(i).roughness, m(i).transmission)).collect();
    // glTF's default metallic and roughness factors are 1: the lamp is a (glowing) metal.
    assert_eq!(
        factors,
        [(1.0, 0.2, 0.0), (0.0, 0.4, 0.0), (0.0, 1.0, 0.0), (1.0, 1.0, 1.0), (1.0, 1.0, 0.0)]
    );
    assert_eq!(m(0).base_color, Vec3::new(1.0, 0.8, 0.3));
    assert_eq!(m(3).ior, 1.33);
    assert_eq!((m(4).emission, m(4).emission_strength), (Vec3::new(1.0, 0.5, 0.0), 4.0));
    assert_eq!(data.mesh.slot_count, 6, "five materials plus the no-material slot");
    assert_eq!(data.mesh.slots, [5, 5]);
}

/// A textured quad; the texture is embedded (buffer view or data URI) or external.
fn textured(image: Option<&str>) -> Fixture {
    let mut f = Fixture::new();
    let (img, _) = f.png(2, 1, &[[255, 0, 0], [0, 0, 255]], image);
    let tex = f.texture(img);
    let mat = f.push(
        "materials",
        json!({ "name": "t", "pbrMetallicRoughness":
                                          { "baseColorTexture": { "index": tex } } }),
    );
    let mesh = f.quad_mesh(Some(mat), 2);
    f.node(json!({ "mesh": mesh }), true);
    f
}

#[test]
fn textures_embedded_in_a_glb_or_a_data_uri_or_beside_the_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let resolver = search(dir.path());
    // GLB buffer view.
    std::fs::write(dir.path().join("v.glb"), textured(None).glb()).expect("write");
    let data = read_gltf("v.glb", &resolver).expect("glb");
    let key = data.materials[0].material.base_color_texture.clone().expect("textured");
    assert_eq!(key, "v.glb#image0");
    assert_eq!(embedded_image(&key), Some(("v.glb", 0)));
    let (_, usage, texture) = &data.textures[0];
    assert_eq!(*usage, TextureUse::Color);
    assert_eq!((texture.width, texture.height), (2, 1));
    assert_eq!(texture.texels.get(0), Vec3::X, "red, linearised");
    assert!(data.companions.is_empty());
    // .gltf with its buffer as a data URI: the image is in the buffer too.
    textured(None).write_gltf(dir.path(), "d", Bin::DataUri);
    let data = read_gltf("d.gltf", &resolver).expect("data uri");
    assert_eq!(data.textures[0].0, "d.gltf#image0");
    assert!(data.companions.is_empty());
    // .gltf + .bin + a PNG file, in a subfolder.
    let sub = dir.path().join("m");
    std::fs::create_dir_all(&sub).expect("mkdir");
    let f = textured(Some("tex%20a.png"));
    let (_, png) = Fixture::new().png(2, 1, &[[255, 0, 0], [0, 0, 255]], Some("x"));
    std::fs::write(sub.join("tex a.png"), png).expect("png");
    f.write_gltf(&sub, "e", Bin::File);
    let data = read_gltf("m/e.gltf", &resolver).expect("external files");
    assert_eq!(data.textures[0].0, "m/tex a.png");
    assert_eq!(data.textures[0].2.texels.get(1), Vec3::Z);
    assert_eq!(data.companions, ["m/e.bin", "m/tex a.png"]);
}

#[test]
fn unsupported_features_are_each_warned_about_once() {
    let mut f = Fixture::new();
    let (img, _) = f.png(1, 1, &[[9, 9, 9]], None);
    let tex = f.texture(img);
    for name in ["a", "b"] {
        f.push(
            "materials",
            json!({ "name": name, "alphaMode": "BLEND", "normalTexture": { "index": tex },
                    "pbrMetallicRoughness": { "metallicRoughnessTexture": { "index": tex } } }),
        );
    }
    let m0 = f.quad_mesh(Some(0), 2);
    let m1 = f.quad_mesh(Some(1), 2);
    f.node(json!({ "mesh": m0 }), true);
    f.node(json!({ "mesh": m1 }), true);
    f.uses("KHR_materials_clearcoat");
    f.uses("KHR_materials_sheen");
    f.json["extensionsRequired"] = json!(["KHR_materials_sheen"]);
    let warnings = read_glb(&f).expect("loads").warnings.into_vec();
    for feature in ["KHR_materials_clearcoat", "KHR_materials_sheen", "normal maps"] {
        let n = warnings.iter().filter(|w| w.contains(feature)).count();
        assert_eq!(n, 1, "{feature}: {warnings:#?}");
    }
    // Rendered now: no warning.
    for feature in ["metallicRoughnessTexture", "alphaMode"] {
        assert!(!warnings.iter().any(|w| w.contains(feature)), "{feature}: {warnings:#?}");
    }
}

#[test]
fn malformed_files_are_errors_naming_the_element() {
    // Not glTF at all, and a truncated GLB.
    let mut f = quad_scene(2);
    let err = {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::write(dir.path().join("x.glb"), b"{ nope").expect("write");
        read_gltf("x.glb", &search(dir.path())).expect_err("junk").to_string()
    };
    assert!(err.contains("x.glb") && err.contains("not a valid glTF"), "{err}");
    let glb = f.glb();
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("t.glb"), &glb[..glb.len() / 2]).expect("write");
    let err = read_gltf("t.glb", &search(dir.path())).expect_err("truncated").to_string();
    assert!(err.contains("t.glb"), "{err}");

    // An accessor with more elements than its view holds.
    f.json["accessors"][0]["count"] = json!(400);
    let err = error_of(&f);
    assert!(err.contains("accessors[0]") && err.contains("past its bufferView"), "{err}");

    // An index past the vertices.
    let mut f = Fixture::new();
    let p = f.floats(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let i = f.indices(&[0, 1, 7], 2);
    let mesh = f.mesh(json!({ "POSITION": p }), Some(i), None);
    f.node(json!({ "mesh": mesh }), true);
    let err = error_of(&f);
    assert!(err.contains(&format!("accessors[{i}]")) && err.contains("index 7"), "{err}");

    // POSITION of the wrong type, an index out of range, a cycle, a short buffer.
    let mut f = quad_scene(2);
    f.json["accessors"][0]["componentType"] = json!(5123);
    assert!(error_of(&f).contains("accessors[0]"), "{}", error_of(&f));
    let mut f = quad_scene(2);
    f.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(99);
    let err = error_of(&f);
    assert!(err.contains("meshes[0].primitives[0].attributes.POSITION"), "{err}");
    let mut f = quad_scene(2);
    f.json["nodes"][0]["children"] = json!([1]);
    f.node(json!({ "children": [0] }), false);
    assert!(error_of(&f).contains("cycle"), "{}", error_of(&f));
    let mut f = quad_scene(2);
    f.bin.truncate(10);
    let err = error_of(&f);
    assert!(err.contains("buffers[0]") || err.contains("bufferViews"), "{err}");

    // A missing .bin and an undecodable image name the glTF file and the element.
    let dir = tempfile::tempdir().expect("tempdir");
    quad_scene(2).write_gltf(dir.path(), "q", Bin::File);
    std::fs::remove_file(dir.path().join("q.bin")).expect("rm");
    let err = read_gltf("q.gltf", &search(dir.path())).expect_err("no bin").to_string();
    assert!(err.contains("q.gltf") && err.contains("buffers[0]") && err.contains("q.bin"), "{err}");
    let mut f = textured(None);
    let view = f.json["images"][0]["bufferView"].as_u64().expect("view") as usize;
    let offset = f.json["bufferViews"][view]["byteOffset"].as_u64().expect("offset") as usize;
    f.bin[offset..offset + 8].fill(0);
    let err = error_of(&f);
    assert!(err.contains("images[0]"), "{err}");
}

#[test]
fn a_gltf_mesh_in_a_toml_scene_has_its_transform_and_overrides() {
    let dir = tempfile::tempdir().expect("tempdir");
    let assets = dir.path().join("assets");
    std::fs::create_dir_all(&assets).expect("mkdir");
    let f = lit_scene(json!({ "name": "orange", "pbrMetallicRoughness":
                              { "baseColorFactor": [1.0, 0.4, 0.0, 1.0] } }));
    f.write_gltf(&assets, "lit", Bin::File);
    let toml = r#"
        [camera]
        position = [0, 0, 5]
        look_at = [0, 0, 0]
        vfov = 40
        [[materials]]
        name = "blue"
        base_color = [0, 0, 1]
        [[objects]]
        mesh = "lit.gltf"
        transform = { translation = [0, 3, 0] }
        materials = { orange = "blue" }
    "#;
    std::fs::write(dir.path().join("s.toml"), toml).expect("write");
    let loaded = load_scene(dir.path(), "s.toml");
    let object = &loaded.state.objects[0];
    assert_eq!(object.name, "lit");
    assert_eq!(object.geometry, Geometry::Gltf { path: "lit.gltf".into() });
    assert_eq!(object.transform.translation, Vec3::new(0.0, 3.0, 0.0));
    let names: Vec<&str> = object
        .materials
        .iter()
        .map(|&m| loaded.state.materials[m as usize].name.as_str())
        .collect();
    assert_eq!(names, ["blue", "lit.gltf:grey", "default"]);
    assert!(loaded.state.lights.is_empty(), "a mesh's lights are not the scene's");
    // The manifest lists the file and its buffer; a worker's load gives the same mesh.
    let resolver = SceneSource::File(dir.path().join("s.toml")).search_path(&[]);
    let manifest = scene::manifest(&loaded.state, &resolver).expect("manifest");
    let paths: Vec<&str> = manifest.iter().map(|e| e.path.as_str()).collect();
    assert_eq!(paths, ["lit.gltf", "lit.bin"]);
    let listed = scene::asset_paths(&loaded.state, &loaded.assets).expect("listed");
    assert_eq!(listed, paths);
    let again = scene::load_assets(&loaded.state, &resolver).expect("worker load");
    assert_eq!(again.meshes[&object.geometry], loaded.assets.meshes[&object.geometry]);
}

#[test]
fn an_unknown_material_override_names_the_gltf_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    quad_scene(2).write_gltf(dir.path(), "q", Bin::DataUri);
    let toml = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n\
                [[materials]]\nname = \"b\"\n\
                [[objects]]\nmesh = \"q.gltf\"\nmaterials = { nope = \"b\" }\n";
    let file = scene::parse(Path::new("s.toml"), toml).expect("parses");
    let err = scene::build::build(&file, Path::new("s.toml"), &search(dir.path()))
        .expect_err("no such material")
        .to_string();
    assert!(err.contains("`q.gltf` has no material `nope`"), "{err}");
}

/// The lit scene with its front quad alpha-masked by a 2×1 map, transparent on its left
/// half (u < 0.5) and opaque on its right, loaded as `alpha_mode` says ("OPAQUE" ignores
/// the map's alpha), at 64×48 pixels.
fn masked_scene(alpha_mode: &str) -> scene::LoadedScene {
    let mut f = lit_scene(json!({ "name": "leaf", "alphaMode": alpha_mode, "alphaCutoff": 0.5,
        "pbrMetallicRoughness": { "baseColorFactor": [1.0, 0.4, 0.0, 1.0],
                                  "baseColorTexture": { "index": 0 } } }));
    let image = f.png_rgba(2, 1, &[[255, 255, 255, 0], [255, 255, 255, 255]]);
    assert_eq!(f.texture(image), 0);
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("leaf.glb"), f.glb()).expect("write");
    let mut loaded = load_scene(dir.path(), "leaf.glb");
    loaded.state.resolution = gridlight_actors::state::Resolution { width: 64, height: 48 };
    loaded.state.render.spp = 16;
    loaded
}

/// A MASK quad in front of a lit wall: the G-buffer and the rendered pixels see the wall
/// through the cut-out half and the quad's orange on the kept half; drawn opaque, both
/// halves are orange.
#[test]
fn an_alpha_masked_quad_shows_the_wall_through_its_cut_out_half_only() {
    use crate::render::{primary_hit, render_pixels, RenderScene};
    let render = |loaded: scene::LoadedScene| {
        assert!(loaded.warnings.iter().all(|w| !w.contains("alpha")), "{:?}", loaded.warnings);
        RenderScene::new(std::sync::Arc::new(loaded.assets), &loaded.state).expect("renders")
    };
    let (opaque, masked) = (render(masked_scene("OPAQUE")), render(masked_scene("MASK")));
    // The pixels that see the middle of each half of the quad when it is opaque.
    let nearest = |target: Vec3| {
        (0..64 * 48)
            .min_by(|&a, &b| {
                let d = |p| (primary_hit(&opaque, p).position - target).length();
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    };
    let (cut, kept) = (nearest(Vec3::new(-0.25, 0.0, 0.0)), nearest(Vec3::new(0.25, 0.0, 0.0)));
    // Green over red: 0.4 for the orange quad, 1 for the grey wall (indirect light off the
    // quad's back tints the wall a little, noise moves both a little).
    let orange = |v: Vec3| v.x > 0.0 && (v.y / v.x - 0.4).abs() < 0.1;
    let grey = |v: Vec3| v.x > 0.0 && (v.y / v.x - 1.0).abs() < 0.15;
    for (scene, cut_seen) in [(&opaque, "quad"), (&masked, "wall")] {
        let (a, b) = (primary_hit(scene, cut), primary_hit(scene, kept));
        // The G-buffer: position and albedo of what the pixel's centre sees.
        assert!(b.position.z.abs() < 1e-3 && orange(b.albedo), "kept half: {b:?}");
        let on_wall = (a.position.z + 1.0).abs() < 1e-3;
        assert_eq!(on_wall, cut_seen == "wall", "cut half: {a:?}");
        assert_eq!(grey(a.albedo), on_wall, "cut half's albedo: {a:?}");
        // The rendered colour.
        let mut out = Vec::new();
        render_pixels(scene, 0, &[cut, kept], &mut out);
        let colour = |s: &crate::render::PixelSample| s.reflected + s.emission;
        assert!(orange(colour(&out[1])), "kept half renders {:?}", colour(&out[1]));
        let c = colour(&out[0]);
        assert!(if on_wall { grey(c) } else { orange(c) }, "cut half renders {c:?}");
    }
    // The CPU G-buffer the master composes with sees through the cut-out too.
    let g = crate::gbuffer::GBuffer::from_scene(&masked, 1.0);
    assert!((g.position[cut as usize].z + 1.0).abs() < 1e-3);
    assert!(g.position[kept as usize].z.abs() < 1e-3);
}

/// `emissiveFactor` × `emissiveTexture` (sRGB) × `KHR_materials_emissive_strength`: the lit
/// scene's quad emits red on its left half and blue on its right, twice the map's codes;
/// the G-buffer's emission plane and the rendered pixels see it, and no warning is given.
#[test]
fn an_emission_map_colours_the_emitter_in_the_gbuffer_and_the_render() {
    use crate::render::{primary_hit, render_pixels, RenderScene};
    let mut f = lit_scene(json!({ "name": "sign", "emissiveFactor": [1.0, 1.0, 0.5],
        "emissiveTexture": { "index": 0 },
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 2.0 } },
        "pbrMetallicRoughness": { "baseColorFactor": [0.0, 0.0, 0.0, 1.0] } }));
    let (image, _) = f.png(2, 1, &[[255, 0, 0], [0, 0, 255]], None);
    assert_eq!(f.texture(image), 0);
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("sign.glb"), f.glb()).expect("write");
    let mut loaded = load_scene(dir.path(), "sign.glb");
    assert!(loaded.warnings.iter().all(|w| !w.contains("emissive")), "{:?}", loaded.warnings);
    loaded.state.resolution = gridlight_actors::state::Resolution { width: 64, height: 48 };
    loaded.state.render.spp = 4;
    let scene = RenderScene::new(std::sync::Arc::new(loaded.assets), &loaded.state).unwrap();
    let nearest = |target: Vec3| {
        (0..64 * 48)
            .min_by(|&a, &b| {
                let d = |p| (primary_hit(&scene, p).position - target).length();
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    };
    let (left, right) = (nearest(Vec3::new(-0.25, 0.0, 0.0)), nearest(Vec3::new(0.25, 0.0, 0.0)));
    let close = |a: Vec3, b: Vec3| (a - b).abs().max_element() < 0.25;
    let g = crate::gbuffer::GBuffer::from_scene(&scene, 1.0);
    let (red, blue) = (Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
    assert!(close(g.emission[left as usize], red), "{}", g.emission[left as usize]);
    assert!(close(g.emission[right as usize], blue), "{}", g.emission[right as usize]);
    let mut out = Vec::new();
    render_pixels(&scene, 0, &[left, right], &mut out);
    assert!(close(out[0].emission, red) && close(out[1].emission, blue), "{out:?}");
}

/// Sampler wrap modes and `KHR_texture_transform` reach each map's lookup, with no warning;
/// a transform's `texCoord` override to set 1 is warned about.
#[test]
fn wrap_modes_and_texture_transforms_reach_each_maps_lookup() {
    use gridlight_actors::state::{MapLookup, Wrap};
    let mut f = Fixture::new();
    let (img, _) = f.png(1, 1, &[[9, 9, 9]], None);
    // 33071 CLAMP_TO_EDGE, 33648 MIRRORED_REPEAT.
    let sampler = f.push("samplers", json!({ "wrapS": 33071, "wrapT": 33648 }));
    let clamped = f.push("textures", json!({ "source": img, "sampler": sampler }));
    let plain = f.texture(img);
    let transform = json!({ "KHR_texture_transform":
        { "offset": [0.5, 0.25], "rotation": 0.3, "scale": [2.0, 3.0] } });
    f.push(
        "materials",
        json!({ "name": "m",
                "normalTexture": { "index": plain, "extensions": transform },
                "emissiveTexture": { "index": plain,
                    "extensions": { "KHR_texture_transform": { "texCoord": 1 } } },
                "pbrMetallicRoughness": { "baseColorTexture": { "index": clamped } } }),
    );
    let mesh = f.quad_mesh(Some(0), 2);
    f.node(json!({ "mesh": mesh }), true);
    f.uses("KHR_texture_transform");
    let data = read_glb(&f).expect("loads");
    let l = data.materials[0].material.lookups;
    assert_eq!(l.base_color.wrap, [Wrap::ClampToEdge, Wrap::MirroredRepeat]);
    assert!(l.base_color.offset == glam::Vec2::ZERO && l.metallic_roughness.is_plain());
    let expected = MapLookup {
        wrap: [Wrap::Repeat; 2],
        offset: glam::Vec2::new(0.5, 0.25),
        rotation: 0.3,
        scale: glam::Vec2::new(2.0, 3.0),
    };
    assert_eq!(l.normal, expected);
    let warnings = data.warnings.into_vec();
    assert!(!warnings.iter().any(|w| w.contains("wrap") || w.contains("KHR_texture_transform")));
    assert_eq!(warnings.iter().filter(|w| w.contains("TEXCOORD_1")).count(), 1, "{warnings:?}");
}
