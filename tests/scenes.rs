//! scenes/ holds what tests/common/scenes.rs builds: regenerate with `cargo run --example make_scenes`.
mod common;

#[test]
fn scene_files_match_their_generator() {
    for (name, b) in common::scenes::all() {
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
        assert!(
            scene.emissive_triangle_count() + scene.punctual.len() > 0,
            "scenes/{name} has no light"
        );
    }
}

#[test]
fn cornell_box_has_the_classic_layout() {
    let scene = pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    let (lo, hi) = scene.bounds();
    // 556 x 548.8 x 559.2 mm.
    assert!(
        (hi - lo - glam::Vec3::new(0.556, 0.5488, 0.5592)).abs().max_element() < 1e-4,
        "{lo} {hi}"
    );
    let soup = scene.flatten();
    assert_eq!(soup.len(), 32);
    let cam = scene.camera.expect("the Cornell box has its camera");
    assert!((cam.projection.half_height().atan().to_degrees() * 2.0 - 39.3077).abs() < 1e-3);
    let (_, _, forward) = cam.basis();
    assert!(
        (forward - glam::Vec3::Z).length() < 1e-5,
        "the camera looks into the box along +z"
    );
    // The light faces down: its emission must leave its front face towards the floor.
    let light = scene.materials.iter().position(|m| m.name == "light").unwrap() as u32;
    for (t, _) in soup
        .positions()
        .iter()
        .zip(soup.material())
        .filter(|(_, &m)| m == light)
    {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        assert!(n.y < 0.0, "the light's front face points up");
    }
}

#[test]
fn gltf_with_external_bin_and_glb_load_the_same_scene() {
    let b = common::scenes::cornell_box();
    let dir = tempfile::tempdir().unwrap();
    let (json, bin) = b.to_json_and_bin("cornell.bin");
    std::fs::write(dir.path().join("cornell.gltf"), json).unwrap();
    std::fs::write(dir.path().join("cornell.bin"), bin).unwrap();
    std::fs::write(dir.path().join("cornell.glb"), b.to_glb()).unwrap();
    let embedded = pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    for name in ["cornell.gltf", "cornell.glb"] {
        let s = pathwave::scene::load(&dir.path().join(name), None).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(s.flatten(), embedded.flatten(), "{name}");
        assert_eq!(s.materials, embedded.materials, "{name}");
        assert_eq!(s.camera, embedded.camera, "{name}");
    }
}

#[test]
fn node_transforms_compose_and_mirroring_keeps_front_faces() {
    // A triangle under a parent (translate) and a child (mirror in x, scale 2): world = parent * child.
    let json = r#"{"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],
      "nodes":[{"translation":[1,0,0],"children":[1]},{"scale":[-2,2,2],"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
      "bufferViews":[{"buffer":0,"byteLength":36}],
      "buffers":[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]}"#;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mirror.gltf");
    std::fs::write(&path, json).unwrap();
    let s = pathwave::scene::load(&path, None).unwrap();
    let t = s.flatten().positions()[0];
    let mut xs: Vec<f32> = t.iter().map(|v| v.x).collect();
    xs.sort_by(f32::total_cmp);
    assert_eq!(
        xs,
        vec![-1.0, 1.0, 1.0],
        "vertices (0,0,0),(1,0,0),(0,1,0) under x -> 1 - 2x"
    );
    assert!(t.iter().any(|v| v.y == 2.0), "scale 2 applies to y");
    // The file's triangle faces +z (counter-clockwise seen from +z); a mirror must not turn it around.
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    assert!(n.z > 0.0, "mirroring flipped the front face: {n}");
}

/// A mesh two nodes place is stored once, with an instance per node, and flattens to exactly the triangles of two
/// meshes with the same data, one on each node: normals, colours and generated tangents included.
#[test]
fn a_mesh_placed_by_two_nodes_is_stored_once() {
    use common::gltf_builder::GltfBuilder;
    use serde_json::json;
    // The second node mirrors (scale -1 in x), which swaps the winding, and turns the normals and tangents.
    let moved = json!({ "translation": [0.5, 1.0, -2.0], "rotation": [0.0, 0.3826834, 0.0, 0.9238795], "scale": [-1.0, 2.0, 1.0] });
    let build = |shared: bool| {
        let mut b = GltfBuilder::new();
        let m = b.material("bumpy", [0.5; 3], [1.0, 1.0, 1.0], false);
        let image = b.png_image(
            2,
            2,
            &[
                [128, 128, 255, 255],
                [200, 128, 230, 255],
                [128, 60, 230, 255],
                [128, 128, 255, 255],
            ],
        );
        let t = b.texture(image, json!({}));
        b.material_json(m)["normalTexture"] = json!({ "index": t });
        let positions = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [1.0, 1.0, 0.0], [0.0, 1.0, 0.2]];
        let normals = [[0.0, 0.0, 1.0], [0.1, 0.0, 1.0], [0.0, 0.2, 1.0], [0.0, 0.0, 1.0]];
        let uvs = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        let colors = [
            [1.0, 0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0, 1.0],
            [1.0, 1.0, 0.0, 1.0],
        ];
        let indices = [0, 1, 2, 0, 2, 3];
        b.mesh_with_attributes("quad", &positions, Some(&normals), &uvs, None, &indices, m);
        b.add_colors(&colors);
        if shared {
            b.place_last_mesh("quad again", moved.clone());
        } else {
            b.mesh_with_attributes("quad copy", &positions, Some(&normals), &uvs, None, &indices, m);
            b.add_colors(&colors);
            b.transform_last_node(moved.clone());
        }
        b
    };
    let (_d1, shared_path) = common::write_temp(&build(true), "shared.gltf");
    let (_d2, copied_path) = common::write_temp(&build(false), "copied.gltf");
    let shared = pathwave::scene::load(&shared_path, None).unwrap();
    let copied = pathwave::scene::load(&copied_path, None).unwrap();
    assert_eq!(shared.meshes.len(), 1, "one mesh for both nodes");
    assert_eq!(shared.instances.len(), 2);
    assert!(shared.instances.iter().all(|i| i.mesh == 0));
    assert_ne!(
        shared.instances[0].world_from_object,
        shared.instances[1].world_from_object
    );
    assert_eq!(shared.meshes[0].triangle_count(), 2);
    assert_eq!(copied.meshes.len(), 2);
    let soup = shared.flatten();
    assert_eq!(soup.len(), 4, "each node places both triangles");
    assert_eq!(soup, copied.flatten(), "sharing a mesh changes no world-space triangle");
    assert_eq!(shared.bounds(), copied.bounds());
    assert_eq!(shared.bounds(), soup.bounds());
    assert_eq!(shared.triangle_count(), 4);
    assert_eq!(shared.emissive_triangle_count(), 4);
    // The second instance's vertices are the first's object-space ones under its node's transform.
    let world = shared.instances[1].world_from_object;
    let object = &shared.meshes[0].primitives[0].positions;
    for tri in &soup.positions()[2..] {
        for v in tri {
            assert!(
                object.iter().any(|p| world.transform_point3(*p) == *v),
                "{v} is not a placed vertex"
            );
        }
    }
}
