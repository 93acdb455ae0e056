//! Bad scene files are rejected with a message naming the file, the key and the problem.

use std::path::PathBuf;

use gridlight::scene::{self, AssetSearchPath};

const CAMERA: &str = "[camera]\nposition = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 40\n";
const WHITE: &str = "[[materials]]\nname = \"white\"\n";
const CUBE: &str = "[[objects]]\nshape = \"cube\"\nmaterial = \"white\"\n";

/// Loads `text` as `bad.toml` in a fresh directory whose `assets/` holds `files`, and
/// returns the error message; panics if it loads.
fn error_of(text: &str, files: &[(&str, &[u8])]) -> (String, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    for (name, data) in files {
        let file = dir.path().join("assets").join(name);
        std::fs::create_dir_all(file.parent().expect("parent")).expect("mkdir");
        std::fs::write(file, data).expect("write asset");
    }
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, text).expect("write scene");
    let search = AssetSearchPath::new(&[], None, Some(&path));
    match scene::load(&path, &search) {
        Ok(_) => panic!("scene loaded but should not:\n{text}"),
        Err(err) => (err.to_string(), path),
    }
}

/// Asserts that the message names the file, the key and each of `problem`'s fragments.
fn assert_names(text: &str, files: &[(&str, &[u8])], key: &str, problem: &[&str]) {
    let (msg, path) = error_of(text, files);
    assert!(msg.contains(&path.display().to_string()), "file missing in: {msg}");
    assert!(msg.contains(key), "key `{key}` missing in: {msg}");
    for fragment in problem {
        assert!(msg.contains(fragment), "`{fragment}` missing in: {msg}");
    }
}

#[test]
fn the_base_scene_of_these_tests_loads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, format!("{CAMERA}{WHITE}{CUBE}")).expect("write");
    let loaded = scene::load(&path, &AssetSearchPath::from_dirs(vec![])).expect("loads");
    assert_eq!(loaded.state.objects.len(), 1);
}

#[test]
fn toml_syntax_error_names_the_line() {
    let text = format!("{CAMERA}{WHITE}[[objects]\nshape = \"cube\"\n");
    assert_names(&text, &[], "(syntax)", &["TOML syntax error", "line 7"]);
}

#[test]
fn unknown_key_is_rejected() {
    let text = format!("{CAMERA}{WHITE}{CUBE}colour = \"red\"\n");
    assert_names(&text, &[], "objects[0]", &["unknown field `colour`", "line"]);
    let text = format!("{CAMERA}{WHITE}{CUBE}transform = {{ translate = [0, 1, 0] }}\n");
    assert_names(&text, &[], "objects[0].transform", &["unknown field `translate`"]);
}

#[test]
fn missing_mesh_names_the_asset_and_the_search_path() {
    let text = format!("{CAMERA}[[objects]]\nmesh = \"meshes/nope.obj\"\n");
    assert_names(&text, &[], "objects[0].mesh", &["meshes/nope.obj", "not found", "assets"]);
}

#[test]
fn material_with_missing_texture_is_rejected() {
    let text =
        format!("{CAMERA}[[materials]]\nname = \"white\"\ntexture = \"tex/missing.png\"\n{CUBE}");
    assert_names(&text, &[], "materials[0].texture", &["tex/missing.png", "not found"]);
}

#[test]
fn mtl_texture_that_is_missing_names_the_mesh_and_material() {
    let obj = b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl brick\nf 1 2 3\n";
    let mtl = b"newmtl brick\nKd 1 1 1\nmap_Kd brick.png\n";
    let text = format!("{CAMERA}[[objects]]\nmesh = \"m/tri.obj\"\n");
    assert_names(
        &text,
        &[("m/tri.obj", obj), ("m/m.mtl", mtl)],
        "objects[0].mesh",
        &["m/tri.obj:brick", "m/brick.png", "not found"],
    );
}

#[test]
fn nan_and_infinity_in_a_transform_are_rejected() {
    let text = format!("{CAMERA}{WHITE}{CUBE}transform = {{ translation = [0, nan, 0] }}\n");
    assert_names(&text, &[], "objects[0].transform.translation", &["not finite"]);
    let text = format!("{CAMERA}{WHITE}{CUBE}transform = {{ rotation = [0, inf, 0] }}\n");
    assert_names(&text, &[], "objects[0].transform.rotation", &["not finite"]);
    let text = format!("{CAMERA}{WHITE}{CUBE}transform = {{ scale = 0 }}\n");
    assert_names(&text, &[], "objects[0].transform.scale", &["zero"]);
}

#[test]
fn negative_roughness_is_rejected() {
    let text = format!("{CAMERA}[[materials]]\nname = \"white\"\nroughness = -0.5\n{CUBE}");
    assert_names(&text, &[], "materials[0].roughness", &["-0.5", "[0, 1]"]);
}

#[test]
fn field_of_view_out_of_range_is_rejected() {
    let camera = CAMERA.replace("vfov = 40", "vfov = 180");
    assert_names(&format!("{camera}{WHITE}{CUBE}"), &[], "camera.vfov", &["180", "(0, 180)"]);
}

#[test]
fn zero_resolution_is_rejected() {
    let text = format!("{CAMERA}[resolution]\nwidth = 0\n{WHITE}{CUBE}");
    assert_names(&text, &[], "resolution.width", &["0 is not in"]);
}

#[test]
fn unknown_material_name_is_rejected() {
    let text = format!("{CAMERA}{WHITE}[[objects]]\nshape = \"cube\"\nmaterial = \"marble\"\n");
    assert_names(&text, &[], "objects[0].material", &["unknown material `marble`", "white"]);
}

#[test]
fn missing_required_key_and_wrong_type_are_rejected() {
    let text = format!("{WHITE}{CUBE}");
    assert_names(&text, &[], "(top level)", &["missing field `camera`"]);
    let camera = CAMERA.replace("vfov = 40", "vfov = \"wide\"");
    assert_names(&format!("{camera}{WHITE}{CUBE}"), &[], "camera.vfov", &["invalid type"]);
}

#[test]
fn unreadable_scene_file_names_the_file() {
    let missing = PathBuf::from("/nonexistent/scene.toml");
    let err = scene::load(&missing, &AssetSearchPath::from_dirs(vec![])).expect_err("missing");
    assert!(err.to_string().contains("/nonexistent/scene.toml"), "{err}");
}

#[test]
fn pbr_keys_load_and_pbr_only_keys_need_the_pbr_kind() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("assets/mr.png");
    std::fs::create_dir_all(png.parent().expect("parent")).expect("mkdir");
    image::RgbImage::from_pixel(1, 1, image::Rgb([0, 51, 255])).save(&png).expect("png");
    let brass = "[[materials]]\nname = \"white\"\nkind = \"pbr\"\nmetallic = 1.0\n\
                 roughness = 0.5\ntransmission = 0.25\nemission = [1, 1, 1]\n\
                 emission_strength = 3.0\nmetallic_roughness_map = \"mr.png\"\n\
                 emissive_map = \"mr.png\"\n";
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, format!("{CAMERA}{brass}{CUBE}")).expect("write");
    let loaded = scene::load(&path, &AssetSearchPath::new(&[], None, Some(&path))).expect("loads");
    let m = &loaded.state.materials[0];
    assert_eq!(m.kind, gridlight_actors::state::MaterialKind::Pbr);
    assert_eq!((m.metallic, m.roughness, m.transmission), (1.0, 0.5, 0.25));
    assert_eq!(m.emission_strength, 3.0);
    let map = loaded.assets.data_textures.get("mr.png").expect("the map is loaded as data");
    // Linear: G 51 → roughness × 0.2, B 255 → metallic × 1.
    assert!((map.texels.get(0) - glam::Vec3::new(0.0, 0.2, 1.0)).length() < 1e-6);
    // The same file as the emission map is read as sRGB colour, with no warning.
    let emission = loaded.assets.textures.get("mr.png").expect("the emission map is loaded");
    assert_eq!(emission.texels.get(0).z, 1.0);
    assert!((emission.texels.get(0).y - gridlight::assets::srgb_to_linear(51)).abs() < 1e-7);
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);

    let metal_diffuse = "[[materials]]\nname = \"white\"\nmetallic = 1.0\n";
    assert_names(
        &format!("{CAMERA}{metal_diffuse}{CUBE}"),
        &[],
        "materials[0].metallic",
        &["kind = \"pbr\""],
    );
    let too_metallic = "[[materials]]\nname = \"white\"\nkind = \"pbr\"\nmetallic = 1.5\n";
    assert_names(
        &format!("{CAMERA}{too_metallic}{CUBE}"),
        &[],
        "materials[0].metallic",
        &["[0, 1]"],
    );
    let missing = "[[materials]]\nname = \"white\"\nkind = \"pbr\"\nnormal_map = \"n.png\"\n";
    assert_names(
        &format!("{CAMERA}{missing}{CUBE}"),
        &[],
        "materials[0].normal_map",
        &["n.png", "not found"],
    );
}

#[test]
fn alpha_keys_load_without_warnings_and_bad_alpha_values_name_the_key() {
    let dir = tempfile::tempdir().expect("tempdir");
    let png = dir.path().join("assets/leaf.png");
    std::fs::create_dir_all(png.parent().expect("parent")).expect("mkdir");
    let leaf =
        image::RgbaImage::from_fn(2, 1, |x, _| image::Rgba([9, 200, 9, [0, 255][x as usize]]));
    leaf.save(&png).expect("png");
    let masked = "[[materials]]\nname = \"white\"\ntexture = \"leaf.png\"\nalpha = 0.9\n\
                  alpha_mode = \"mask\"\nalpha_cutoff = 0.3\n";
    let path = dir.path().join("ok.toml");
    std::fs::write(&path, format!("{CAMERA}{masked}{CUBE}")).expect("write");
    let loaded = scene::load(&path, &AssetSearchPath::new(&[], None, Some(&path))).expect("loads");
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let m = &loaded.state.materials[0];
    assert_eq!(m.alpha_mode, gridlight_actors::state::AlphaMode::Mask);
    assert_eq!((m.alpha, m.alpha_cutoff), (0.9, 0.3));
    let map = loaded.assets.textures.get("leaf.png").expect("the map is loaded");
    assert_eq!(map.alpha.as_deref(), Some(&[0u8, 255][..]), "its alpha is kept");

    for (key, line, problem) in [
        ("alpha_mode", "alpha_mode = \"cutout\"", "cutout"),
        ("alpha", "alpha = 1.5", "[0, 1]"),
        ("alpha_cutoff", "alpha_cutoff = -0.5", "[0, 1]"),
    ] {
        let bad = format!("[[materials]]\nname = \"white\"\n{line}\n");
        assert_names(&format!("{CAMERA}{bad}{CUBE}"), &[], key, &[problem]);
    }
}
