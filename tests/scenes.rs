//! scenes/ holds what tests/common/scenes.rs builds: regenerate with `cargo run --example make_scenes`.
mod common;

#[test]
fn scene_files_match_their_generator() {
    for (name, b) in [
        ("cornell-box.gltf", common::scenes::cornell_box()),
        ("furnace.gltf", common::scenes::furnace(0.5, 0.5)),
        ("two-lights.gltf", common::scenes::two_lights()),
        ("unequal-lights.gltf", common::scenes::unequal_lights()),
    ] {
        let on_disk = std::fs::read_to_string(common::scenes_dir().join(name)).unwrap();
        assert!(
            on_disk == b.to_json(),
            "scenes/{name} is stale: run `cargo run --example make_scenes`"
        );
        let scene = pathwave::scene::load(&common::scenes_dir().join(name), None).unwrap();
        assert!(
            scene.warnings.is_empty(),
            "scenes/{name} loads with warnings: {:?}",
            scene.warnings
        );
        assert!(scene.emissive_triangle_count() > 0);
    }
}

#[test]
fn cornell_box_has_the_classic_layout() {
    let scene =
        pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    let (lo, hi) = scene.bounds();
    // 556 x 548.8 x 559.2 mm.
    assert!(
        (hi - lo - glam::Vec3::new(0.556, 0.5488, 0.5592))
            .abs()
            .max_element()
            < 1e-4,
        "{lo} {hi}"
    );
    assert_eq!(scene.triangles.len(), 32);
    let cam = scene.camera.expect("the Cornell box has its camera");
    assert!((cam.yfov.to_degrees() - 39.3077).abs() < 1e-3);
    let (_, _, forward) = cam.basis();
    assert!(
        (forward - glam::Vec3::Z).length() < 1e-5,
        "the camera looks into the box along +z"
    );
    // The light faces down: its emission must leave its front face towards the floor.
    let light = scene
        .materials
        .iter()
        .position(|m| m.name == "light")
        .unwrap() as u32;
    for (t, _) in scene
        .triangles
        .iter()
        .zip(&scene.material_of)
        .filter(|(_, &m)| m == light)
    {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        assert!(n.y < 0.0, "the light's front face points up");
    }
}
