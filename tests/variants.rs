//! KHR_materials_variants: each variant renders its mapping (and no variant the primitives' own materials), from the
//! library and the CLI; unknown names and broken mappings are refused naming them.
mod common;

use common::gltf_builder::{GltfBuilder, FACING_Z};
use common::screen;
use serde_json::json;

/// Two unlit quads side by side (exact colours to the camera): the left one blue, the right one white, and variants
/// 'red' (left red), 'green' (both green) and 'plain' (mapping nothing).
fn variants_scene() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let blue = b.unlit_material("blue", [0.0, 0.0, 1.0]);
    let white = b.unlit_material("white", [1.0; 3]);
    let red = b.unlit_material("red", [1.0, 0.0, 0.0]);
    let green = b.unlit_material("green", [0.0, 1.0, 0.0]);
    b.use_extension("KHR_materials_variants");
    b.quad(
        "left",
        [[-1.0, 1.0, 0.0], [-1.0, -1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
        blue,
        FACING_Z,
    );
    b.quad(
        "right",
        [[0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0]],
        white,
        FACING_Z,
    );
    screen::view(&mut b);
    b.set_root_extension(
        "KHR_materials_variants",
        json!({ "variants": [{ "name": "red" }, { "name": "green" }, { "name": "plain" }] }),
    );
    b.set_primitive_extension(
        0,
        "KHR_materials_variants",
        json!({ "mappings": [{ "material": red, "variants": [0] }, { "material": green, "variants": [1] }] }),
    );
    b.set_primitive_extension(
        1,
        "KHR_materials_variants",
        json!({ "mappings": [{ "material": green, "variants": [1] }] }),
    );
    b
}

fn halves(film: &pathwave::Film) -> [[f32; 3]; 2] {
    let mean = film.mean();
    let (w, h) = (8usize, 8usize);
    let at = |i: usize, j: usize| mean[j * w + i];
    for j in 0..h {
        for i in 0..w {
            let side = if i < w / 2 { at(0, 0) } else { at(w - 1, 0) };
            assert_eq!(at(i, j), side, "each half is one flat unlit colour");
        }
    }
    [at(0, 0), at(w - 1, 0)]
}

// Would catch a mapping ignored, applied to the wrong primitive or variant, or a variant leaking into the default.
#[test]
fn each_variant_renders_its_mapping() {
    let (_dir, path) = common::write_temp(&variants_scene(), "variants.gltf");
    let cases = [
        (None, [[0.0, 0.0, 1.0], [1.0; 3]]),
        (Some("red"), [[1.0, 0.0, 0.0], [1.0; 3]]),
        (Some("green"), [[0.0, 1.0, 0.0], [0.0, 1.0, 0.0]]),
        (Some("plain"), [[0.0, 0.0, 1.0], [1.0; 3]]),
    ];
    for (variant, want) in cases {
        let options = pathwave::scene::LoadOptions {
            variant: variant.map(str::to_string),
            ..Default::default()
        };
        let scene = pathwave::scene::load_with(&path, &options).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
        assert_eq!(scene.variants, ["red", "green", "plain"]);
        let mut r = common::scene_renderer(&scene);
        let got = halves(&common::render(&mut r, &common::settings(8, 8, 2, 1)));
        assert_eq!(got, want, "variant {variant:?}");
    }
}

#[test]
fn unknown_variants_and_broken_mappings_are_refused() {
    let (_dir, path) = common::write_temp(&variants_scene(), "variants.gltf");
    let options = pathwave::scene::LoadOptions {
        variant: Some("blue".into()),
        ..Default::default()
    };
    let e = pathwave::scene::load_with(&path, &options)
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(e.contains("'blue'") && e.contains("'red', 'green', 'plain'"), "{e}");

    // The error loading the scene with the right quad's mappings replaced by `mappings`.
    let refusal = |mappings: serde_json::Value| {
        let mut b = variants_scene();
        b.set_primitive_extension(1, "KHR_materials_variants", json!({ "mappings": mappings }));
        let (_dir, path) = common::write_temp(&b, "variants.gltf");
        pathwave::scene::load(&path, None).map(|_| ()).unwrap_err().to_string()
    };
    let e = refusal(json!([{ "material": 0, "variants": [7] }]));
    assert!(e.contains("variant 7") && e.contains("mesh 'right'"), "{e}");

    let e = refusal(json!([{ "material": 99, "variants": [0] }]));
    assert!(e.contains("material") && e.contains("mesh 'right'"), "{e}");
}

#[test]
fn the_cli_lists_and_renders_variants() {
    let (dir, path) = common::write_temp(&variants_scene(), "variants.gltf");
    let bin = env!("CARGO_BIN_EXE_pathwave");
    let info = std::process::Command::new(bin).arg("info").arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success() && text.contains("variants    3 (--variant NAME): 'red', 'green', 'plain'"),
        "{text}"
    );
    assert!(text.contains("KHR_materials_variants: supported"), "{text}");
    let out = dir.path().join("green.exr");
    let run = std::process::Command::new(bin)
        .args([
            "render",
            path.to_str().unwrap(),
            "--size",
            "8x8",
            "--spp",
            "1",
            "--variant",
            "green",
            "-o",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let bad = std::process::Command::new(bin)
        .args([
            "render",
            path.to_str().unwrap(),
            "--size",
            "8x8",
            "--variant",
            "purple",
            "-o",
        ])
        .arg(dir.path().join("purple.exr"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("'purple'") && err.contains("variants.gltf"),
        "{err}"
    );
    assert!(
        !dir.path().join("purple.exr").exists(),
        "a refused render writes nothing"
    );
}
