//! glTF animation as the loader reads it and `Scene::pose` places it: channels on nodes and cameras, morph
//! weights, a two-bone skin, against values worked out by hand; and the CLI's --time, --animation and --frames.
mod common;

use common::gltf_builder::{square, GltfBuilder, FACING_DOWN, FACING_UP};
use common::render_args;
use glam::{Quat, Vec3};
use pathwave::scene::{load, PoseTime, Scene};
use serde_json::json;
use std::path::Path;

fn posed(path: &Path, time: f32, animation: Option<usize>) -> Scene {
    let mut scene = load(path, None).unwrap_or_else(|e| panic!("{e}"));
    scene
        .pose(PoseTime { time, animation })
        .unwrap_or_else(|e| panic!("{e}"));
    scene
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

/// A lit quad at the origin on node 1 (node 0 is the lamp), for channels to move.
fn lit_quad() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let light = b.material("light", [0.8; 3], [5.0; 3], false);
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    b.quad("lamp", square(1.0, 3.0), light, FACING_DOWN);
    b.quad("quad", square(0.5, 0.0), white, FACING_UP);
    b
}

fn translation_of(scene: &Scene, instance: usize) -> Vec3 {
    scene.instances[instance].world_from_object.transform_point3(Vec3::ZERO)
}

/// Catches: keys read from the wrong place, times not clamped, STEP or LINEAR mixed up, CUBICSPLINE's triplets
/// read as plain keys, tangents not scaled by the segment's length.
#[test]
fn translation_channels_place_the_node_at_and_between_keys_for_each_interpolation() {
    /// Interpolation, key times, output values, and (time, expected x) pairs.
    type Case = (&'static str, Vec<f32>, Vec<f32>, Vec<(f32, f32)>);
    let cases: [Case; 3] = [
        (
            "STEP",
            vec![1.0, 2.0],
            vec![3.0, 0.0, 0.0, 5.0, 0.0, 0.0],
            vec![(0.0, 3.0), (1.5, 3.0), (2.0, 5.0), (9.0, 5.0)],
        ),
        (
            "LINEAR",
            vec![1.0, 3.0],
            vec![2.0, 0.0, 0.0, 6.0, 0.0, 0.0],
            vec![(0.0, 2.0), (1.5, 3.0), (2.0, 4.0), (3.0, 6.0), (4.0, 6.0)],
        ),
        // Keys at 1 and 3: value 0 with out-tangent 1, value 4 with in-tangent -1 (worked out in the sampler's
        // unit test): 2.5 at t = 2 and 1.0 at t = 1.5.
        (
            "CUBICSPLINE",
            vec![1.0, 3.0],
            vec![
                9.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 4.0, 0.0, 0.0, 9.0, 0.0, 0.0,
            ],
            vec![(1.0, 0.0), (1.5, 1.0), (2.0, 2.5), (3.0, 4.0)],
        ),
    ];
    for (interpolation, times, values, expect) in cases {
        let mut b = lit_quad();
        b.animate("a", 1, "translation", interpolation, &times, &values);
        let (_dir, path) = common::write_temp(&b, "moving.gltf");
        for (t, x) in expect {
            let scene = posed(&path, t, None);
            let got = translation_of(&scene, 1);
            assert!(
                close(got, Vec3::new(x, 0.0, 0.0)),
                "{interpolation} at t = {t}: {got}, expected x = {x}"
            );
        }
    }
}

/// Catches: rotations lerped instead of slerped, the long way round when keys flip sign, and scale or rotation
/// replacing the node's other TRS parts.
#[test]
fn rotation_and_scale_channels_compose_with_the_nodes_own_translation() {
    let mut b = lit_quad();
    b.transform_last_node(json!({ "translation": [0.0, 1.0, 0.0] }));
    let end = -Quat::from_rotation_y(std::f32::consts::FRAC_PI_2); // the same rotation as +q, sign flipped
    let mut rotations = Quat::IDENTITY.to_array().to_vec();
    rotations.extend(end.to_array());
    b.animate("a", 1, "rotation", "LINEAR", &[0.0, 1.0], &rotations);
    b.animate("a", 1, "scale", "LINEAR", &[0.0, 1.0], &[1.0, 1.0, 1.0, 3.0, 3.0, 3.0]);
    let (_dir, path) = common::write_temp(&b, "turning.gltf");
    let scene = posed(&path, 0.25, None);
    let m = scene.instances[1].world_from_object;
    // At u = 0.25: 22.5 degrees about +y (a lerp would give 26.6), scale 1.5, translation kept.
    let x = m.transform_vector3(Vec3::X);
    let want = Quat::from_rotation_y(22.5f32.to_radians()) * Vec3::X * 1.5;
    assert!(close(x, want), "x axis {x}, expected {want}");
    assert!(close(translation_of(&scene, 1), Vec3::Y));
}

/// Catches: a camera node's animation ignored, or the camera taken from the rest pose.
#[test]
fn an_animated_camera_moves_with_its_node() {
    let mut b = lit_quad();
    b.camera([0.0, 1.0, 5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0);
    let cam = b.last_node();
    b.slide("dolly", cam, [0.0, 2.0], [0.0, 1.0, 5.0], [0.0, 1.0, 1.0]);
    let (_dir, path) = common::write_temp(&b, "dolly.gltf");
    let scene = posed(&path, 1.0, None);
    let origin = scene.camera.unwrap().origin();
    assert!(close(origin, Vec3::new(0.0, 1.0, 3.0)), "{origin}");
}

fn vertices(scene: &Scene) -> Vec<Vec3> {
    scene.flatten().positions().iter().flatten().copied().collect()
}

/// Asserts that a vertex of `scene` is at `at`.
fn assert_vertex_at(scene: &Scene, at: Vec3) {
    let all = vertices(scene);
    assert!(all.iter().any(|v| close(*v, at)), "{all:?}");
}

/// Catches: morph weights not read, not animated, or applied without the weight.
#[test]
fn morph_target_weights_displace_vertices_by_their_weight() {
    let mut b = lit_quad();
    b.add_morph_target(&[[0.0; 3], [0.0; 3], [0.0, 2.0, 0.0], [0.0; 3]], &[0.25]);
    let (_dir, still) = common::write_temp(&b, "still.gltf");
    // Without animation the mesh's default weight holds: the corner (0.5, 0, 0.5) is up by 0.25 * 2.
    assert_vertex_at(&posed(&still, 0.0, None), Vec3::new(0.5, 0.5, 0.5));
    b.animate("m", 1, "weights", "LINEAR", &[0.0, 1.0], &[0.0, 1.0]);
    let (_dir2, moving) = common::write_temp(&b, "morph.gltf");
    assert_vertex_at(&posed(&moving, 0.75, None), Vec3::new(0.5, 1.5, 0.5));
    let scene = posed(&moving, 0.0, None);
    // Weight 0 at t = 0: every vertex is the quad's (y = 0) or the lamp's (y = 3).
    assert!(
        vertices(&scene).iter().all(|v| v.y == 0.0 || v.y == 3.0),
        "{:?}",
        vertices(&scene)
    );
}

/// Every item of `items` twice in a row.
fn doubled<T: Copy>(items: &[T]) -> Vec<T> {
    items.iter().flat_map(|&v| [v, v]).collect()
}

/// A two-bone bar: vertices at y = 0 (bone 0), y = 1 (half each) and y = 2 (bone 1, jointed at y = 1), its upper
/// bone turned 90 degrees about +z at t = 1.
fn two_bone_bar() -> GltfBuilder {
    let mut b = lit_quad();
    let yellow = b.material("yellow", [0.8, 0.6, 0.1], [0.0; 3], false);
    let positions = [
        [0.1, 0.0, 0.0],
        [-0.1, 0.0, 0.0],
        [0.1, 1.0, 0.0],
        [-0.1, 1.0, 0.0],
        [0.1, 2.0, 0.0],
        [-0.1, 2.0, 0.0],
    ];
    b.mesh("bar", &positions, &[0, 2, 1, 1, 2, 3, 2, 4, 3, 3, 4, 5], yellow);
    // The skinned node's own transform must be ignored (glTF): move it far away to catch it being applied.
    b.transform_last_node(json!({ "translation": [100.0, 0.0, 0.0] }));
    let root = b.node("bone 0", json!({}));
    let upper = b.node("bone 1", json!({ "translation": [0.0, 1.0, 0.0] }));
    b.add_child(root, upper);
    // Both vertices of a level (y = 0, 1, 2) have the same joints and weights.
    let joints: Vec<[u16; 4]> = doubled(&[[0, 0, 0, 0], [0, 1, 0, 0], [1, 0, 0, 0]]);
    let weights: Vec<[f32; 4]> = doubled(&[[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]]);
    let ibm = [
        glam::Mat4::IDENTITY.to_cols_array(),
        glam::Mat4::from_translation(-Vec3::Y).to_cols_array(),
    ];
    b.skin_last_mesh(&[root, upper], &ibm, &joints, &weights);
    let mut keys = Quat::IDENTITY.to_array().to_vec();
    keys.extend(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2).to_array());
    b.animate("bend", upper, "rotation", "LINEAR", &[0.0, 1.0], &keys);
    b
}

/// Catches: joints' world transforms or inverse bind matrices left out, weights not blended, the skinned node's
/// transform applied, the skin read from JOINTS as weights or the other way round.
#[test]
fn a_two_bone_skin_moves_vertices_by_their_blended_joints() {
    let (_dir, path) = common::write_temp(&two_bone_bar(), "skin.gltf");
    let at_rest = vertices(&posed(&path, 0.0, None));
    for v in [[0.1, 0.0, 0.0], [-0.1, 1.0, 0.0], [0.1, 2.0, 0.0]] {
        assert!(
            at_rest.iter().any(|p| close(*p, Vec3::from(v))),
            "{v:?} missing at rest: {at_rest:?}"
        );
    }
    // At t = 1, bone 1 is T(0, 1, 0) Rz(90): its vertices, taken back by the inverse bind T(0, -1, 0), turn about
    // (0, 1, 0). (0.1, 2, 0) -> (0.1, 1, 0) -> (-1, 0.1, 0) -> (-1, 1.1, 0). The middle vertex (0.1, 1, 0) goes to
    // (0.1, 1, 0) under bone 0 and to (0, 1.1, 0) under bone 1: half of each is (0.05, 1.05, 0).
    let bent = vertices(&posed(&path, 1.0, None));
    for v in [
        [0.1, 0.0, 0.0],
        [-1.0, 1.1, 0.0],
        [-1.0, 0.9, 0.0],
        [0.05, 1.05, 0.0],
        [-0.05, 0.95, 0.0],
    ] {
        assert!(
            bent.iter().any(|p| close(*p, Vec3::from(v))),
            "{v:?} missing when bent: {bent:?}"
        );
    }
}

/// Catches: --animation picking the wrong one, or playing the others' channels too.
#[test]
fn one_animation_plays_alone_when_picked() {
    let mut b = lit_quad();
    b.slide("right", 1, [0.0, 1.0], [0.0; 3], [1.0, 0.0, 0.0]);
    b.slide("up", 0, [0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0]);
    let (_dir, path) = common::write_temp(&b, "two.gltf");
    let both = posed(&path, 1.0, None);
    assert!(close(translation_of(&both, 1), Vec3::X) && close(translation_of(&both, 0), Vec3::Y));
    let up = load(&path, None).unwrap().rig.find_animation("up").unwrap();
    let only_up = posed(&path, 1.0, Some(up));
    assert!(close(translation_of(&only_up, 1), Vec3::ZERO) && close(translation_of(&only_up, 0), Vec3::Y));
    let scene = load(&path, None).unwrap();
    assert_eq!(scene.rig.find_animation("0"), Ok(0));
    let err = scene.rig.find_animation("sideways").unwrap_err();
    assert!(err.contains("0 'right', 1 'up'"), "{err}");
}

/// Catches: a malformed channel refusing the whole scene, or a bad one played anyway.
#[test]
fn a_channel_that_cannot_play_is_dropped_with_a_warning() {
    let mut b = lit_quad();
    b.slide("bad", 1, [1.0, 1.0], [0.0; 3], [1.0, 0.0, 0.0]);
    let (_dir, path) = common::write_temp(&b, "bad.gltf");
    let scene = load(&path, None).unwrap();
    assert!(
        scene.warnings.iter().any(|w| w.contains("strictly increasing")),
        "{:?}",
        scene.warnings
    );
    assert!(scene.rig.animations[0].channels.is_empty());
}

fn pathwave(args: &[&str]) -> std::process::Output {
    common::pathwave_cli()
        .args(args)
        .output()
        .expect("the pathwave binary runs")
}

fn ok(args: &[&str]) -> String {
    let o = pathwave(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?} failed: {err}");
    err
}

/// Catches: --time not reaching the render, or placing the node anywhere but where a static file at that pose
/// puts it (byte for byte, so nothing else of the file changes with time).
#[test]
fn a_render_at_a_time_is_the_static_scene_at_that_pose() {
    let mut moving = lit_quad();
    moving.camera([0.0, 2.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 50.0);
    // The baked file: the same scene, the quad's node where the animation has it at t = 0.5.
    let mut baked: serde_json::Value = serde_json::from_str(&moving.to_json()).unwrap();
    baked["nodes"][1]["translation"] = json!([0.25, 0.0, -0.125]);
    moving.slide("a", 1, [0.0, 1.0], [0.0; 3], [0.5, 0.0, -0.25]);
    let (dir, moving_path) = common::write_temp(&moving, "moving.gltf");
    let baked_path = dir.path().join("baked.gltf");
    std::fs::write(&baked_path, baked.to_string()).unwrap();
    // Renders `scene` to `name` with `time` (--time T or nothing) and the common options.
    let render = |scene: &Path, name: &str, time: &[&str]| {
        let out = dir.path().join(name).display().to_string();
        let more = [time, &["--size", "32x24", "--spp", "4"]].concat();
        ok(&render_args(scene.to_str().unwrap(), &out, &more));
    };
    render(&moving_path, "t.exr", &["--time", "0.5"]);
    render(&baked_path, "b.exr", &[]);
    render(&moving_path, "t0.exr", &[]);
    let read = |n: &str| std::fs::read(dir.path().join(n)).unwrap();
    assert_eq!(
        read("t.exr"),
        read("b.exr"),
        "--time 0.5 differs from the scene baked at t = 0.5"
    );
    assert_ne!(read("t.exr"), read("t0.exr"), "the quad did not move");
}

/// Catches: frame k rendered at any time but k / fps, frames sharing state that changes their bytes (the
/// renderer is reused between frames), names numbered wrongly, --resume re-rendering finished frames or skipping
/// missing ones.
#[test]
fn frames_are_single_renders_at_k_over_fps_and_resume_renders_only_missing_ones() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scenes_dir().join("animated.gltf");
    let scene = scene.to_str().unwrap();
    let out = |n: &str| dir.path().join(n).display().to_string();
    let size = ["--size", "40x30", "--spp", "4"];
    // Frames 1 to 3 at 4 per second as EXR and PNG, with `resume` (--resume or nothing).
    let render_frames = |resume: &[&str]| {
        let (exr, png) = (out("f.###.exr"), out("f.###.png"));
        let outputs = ["-o", exr.as_str(), "-o", png.as_str()];
        let frames = ["render", scene, "--frames", "1..3", "--fps", "4"];
        let args = [&frames[..], resume, &outputs, &size].concat();
        ok(&args)
    };
    render_frames(&[]);
    for (k, t) in [(1, "0.25"), (2, "0.5"), (3, "0.75")] {
        ok(&[
            &["render", scene, "--time", t, "-o", &out(&format!("single{k}.exr"))][..],
            &size,
        ]
        .concat());
        let frame = std::fs::read(dir.path().join(format!("f.{k:03}.exr"))).unwrap();
        let single = std::fs::read(dir.path().join(format!("single{k}.exr"))).unwrap();
        assert!(frame == single, "frame {k} differs from a render at --time {t}");
        assert!(dir.path().join(format!("f.{k:03}.png")).exists());
    }
    let frames: Vec<Vec<u8>> = (1..=3)
        .map(|k| std::fs::read(dir.path().join(format!("f.{k:03}.exr"))).unwrap())
        .collect();
    assert!(
        frames[0] != frames[1] && frames[1] != frames[2],
        "the animation did not move between frames"
    );
    std::fs::remove_file(dir.path().join("f.002.png")).unwrap();
    let log = render_frames(&["--resume"]);
    assert!(log.contains("1 rendered, 2 already there"), "{log}");
    assert_eq!(std::fs::read(dir.path().join("f.002.exr")).unwrap(), frames[1]);
}

#[test]
fn bad_animation_options_are_refused_with_the_option_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scenes_dir().join("animated.gltf");
    let scene = scene.to_str().unwrap();
    let out = dir.path().join("x.png").display().to_string();
    for (args, needle) in [
        (vec!["--animation", "nope"], "'blink', 1 'move'"),
        (vec!["--time", "NaN"], "--time"),
        (vec!["--time", "1e30"], "--time"),
        (vec!["--frames", "0..3"], "run of #"),
        (vec!["--frames", "3..1"], "--frames"),
        (vec!["--frames", "0..2", "--fps", "0"], "--fps"),
        (vec!["--frames", "0..2", "--time", "1"], "--time"),
        (vec!["--fps", "30"], "--frames"),
    ] {
        let o = pathwave(&[&["render", scene, "-o", &out, "--size", "8x8", "--spp", "1"][..], &args].concat());
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(needle) && !err.contains("panicked"),
            "{args:?}: {err}"
        );
        assert!(!Path::new(&out).exists());
    }
}

#[test]
fn info_describes_animations_skins_and_morph_targets() {
    let o = pathwave(&["info", common::scenes_dir().join("animated.gltf").to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(
        text.contains("1 skins, 1 skinned meshes, 1 meshes with morph targets"),
        "{text}"
    );
    assert!(
        text.contains("animation   1 'move': 6 channels, keys from 0 s to 2 s"),
        "{text}"
    );
}

/// The lit quad's node (1) placing its mesh three times through EXT_mesh_gpu_instancing.
fn gpu_instanced(translations: &[[f32; 3]], rotations: Option<&[[f32; 4]]>, scales: &[[f32; 3]]) -> serde_json::Value {
    let mut b = lit_quad();
    b.camera([0.0, 3.0, 4.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 50.0);
    let (t, r, s) = (
        b.raw_accessor(translations),
        rotations.map(|r| b.raw_accessor(r)),
        b.raw_accessor(scales),
    );
    let mut doc: serde_json::Value = serde_json::from_str(&b.to_json()).unwrap();
    let mut attributes = json!({ "TRANSLATION": t, "SCALE": s });
    if let Some(r) = r {
        attributes["ROTATION"] = json!(r);
    }
    doc["nodes"][1]["extensions"] = json!({ "EXT_mesh_gpu_instancing": { "attributes": attributes } });
    doc["extensionsUsed"] = json!(["EXT_mesh_gpu_instancing"]);
    doc
}

/// Catches: EXT_mesh_gpu_instancing ignored (one quad), its transforms applied before instead of after the node's,
/// or its rotations misread.
#[test]
fn gpu_instancing_places_the_mesh_once_per_instance_after_the_nodes_transform() {
    let translations = [[-1.0, 0.0, 0.0], [0.0, 0.0, 0.5], [1.0, 0.0, 0.0]];
    let scales = [[1.0, 1.0, 1.0], [0.5, 1.0, 0.5], [2.0, 1.0, 1.0]];
    let mut doc = gpu_instanced(&translations, None, &scales);
    doc["nodes"][1]["translation"] = json!([0.0, 0.25, 0.0]);
    let dir = tempfile::tempdir().unwrap();
    let instanced = dir.path().join("instanced.gltf");
    std::fs::write(&instanced, doc.to_string()).unwrap();
    let scene = load(&instanced, None).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let quads: Vec<Vec3> = (1..4).map(|i| translation_of(&scene, i)).collect();
    assert_eq!(scene.instances.len(), 4, "the lamp and three quads");
    for (q, t) in quads.iter().zip(translations) {
        assert!(close(*q, Vec3::from(t) + Vec3::new(0.0, 0.25, 0.0)), "{q} for {t:?}");
    }
    // The same quads as three nodes of their own render the same bytes.
    let mut nodes = doc.clone();
    nodes["nodes"][1]["extensions"] = json!({});
    nodes["extensionsUsed"] = json!([]);
    let quad = nodes["nodes"][1].clone();
    let mut placed = Vec::new();
    for (t, s) in translations.iter().zip(scales) {
        let mut n = quad.clone();
        n["translation"] = json!([t[0], t[1] + 0.25, t[2]]);
        n["scale"] = json!(s);
        placed.push(n);
    }
    let first = nodes["nodes"].as_array().unwrap().len();
    nodes["nodes"].as_array_mut().unwrap().extend(placed);
    nodes["nodes"][1].as_object_mut().unwrap().remove("mesh");
    let roots = nodes["scenes"][0]["nodes"].as_array_mut().unwrap();
    roots.extend((first..first + 3).map(|i| json!(i)));
    let separate = dir.path().join("separate.gltf");
    std::fs::write(&separate, nodes.to_string()).unwrap();
    let out = |n: &str| dir.path().join(n).display().to_string();
    let size = ["--size", "32x24", "--spp", "4"];
    ok(&render_args(instanced.to_str().unwrap(), &out("a.exr"), &size));
    ok(&render_args(separate.to_str().unwrap(), &out("b.exr"), &size));
    assert_eq!(
        std::fs::read(dir.path().join("a.exr")).unwrap(),
        std::fs::read(dir.path().join("b.exr")).unwrap()
    );

    let q = Quat::from_rotation_y(0.7);
    let doc = gpu_instanced(&translations, Some(&[q.to_array(); 3]), &scales);
    std::fs::write(&instanced, doc.to_string()).unwrap();
    let scene = load(&instanced, None).unwrap();
    let x = scene.instances[3].world_from_object.transform_vector3(Vec3::X);
    assert!(close(x, q * Vec3::X * 2.0), "{x}");
}

/// Catches: sparse accessors refused (morph targets in the sample models use them), their base taken as data when
/// it has no bufferView, or a malformed one read instead of refused.
#[test]
fn a_sparse_morph_target_displaces_only_the_vertices_it_lists() {
    let mut b = lit_quad();
    b.add_morph_target(&[[0.0; 3]; 4], &[0.5]);
    // Vertex 2 displaced by (0, 2, 0), stored sparse: one index (u32 2) and one value, no base.
    let index = b.raw_accessor(&[[f32::from_bits(2)]]);
    let value = b.raw_accessor(&[[0.0, 2.0, 0.0]]);
    let mut doc: serde_json::Value = serde_json::from_str(&b.to_json()).unwrap();
    let view = |doc: &serde_json::Value, acc: usize| doc["accessors"][acc]["bufferView"].clone();
    let target = doc["meshes"][1]["primitives"][0]["targets"][0]["POSITION"]
        .as_u64()
        .unwrap() as usize;
    let (iv, vv) = (view(&doc, index), view(&doc, value));
    doc["accessors"][target] = json!({
        "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.0, 2.0, 0.0],
        "sparse": { "count": 1, "indices": { "bufferView": iv, "componentType": 5125 }, "values": { "bufferView": vv } }
    });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sparse.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let scene = load(&path, None).unwrap_or_else(|e| panic!("{e}"));
    let v = vertices(&scene);
    // Weight 0.5 of (0, 2, 0) on the quad's corner (0.5, 0, 0.5); every other corner stays on y = 0.
    assert!(v.iter().any(|p| close(*p, Vec3::new(0.5, 1.0, 0.5))), "{v:?}");
    assert_eq!(
        v.iter().filter(|p| p.y > 0.0 && p.y < 3.0).count(),
        2,
        "the one corner, in both its triangles: {v:?}"
    );
    // An index past the accessor's count is refused, naming the accessor.
    let bad = dir.path().join("bad.gltf");
    let mut broken = doc.clone();
    broken["accessors"][target]["count"] = json!(2);
    broken["accessors"][target]["sparse"]["count"] = json!(1);
    std::fs::write(&bad, broken.to_string()).unwrap();
    match load(&bad, None) {
        Ok(_) => panic!("a sparse index beyond the count loaded"),
        Err(e) => assert!(e.to_string().contains("sparse index 2"), "{e}"),
    }
}

/// KHR_animation_pointer against values worked out by hand at and between keys, one channel per kind of target:
/// a material's base colour (LINEAR, vec4 blended per component, alpha included) and emission (its factor by STEP
/// and KHR_materials_emissive_strength by LINEAR, multiplied), a node's translation through the pointer, a spot
/// light's intensity and outer cone, a camera's yfov, a texture transform's offset (its rotation kept) and
/// KHR_node_visibility's `visible` as unsigned bytes.
/// Catches: pointers read under other spellings or not at all (the values would stay the file's), the emission's
/// parts not kept apart, visibility not hiding the node's mesh or not coming back, an unsupported pointer dropped
/// without naming it, and a shutter over a visibility key placing keys with different instances.
#[test]
fn pointer_channels_drive_materials_lights_cameras_and_visibility() {
    let mut b = lit_quad();
    b.punctual(
        json!({ "type": "spot", "spot": { "innerConeAngle": 0.1, "outerConeAngle": 0.5 } }),
        [1.0, 0.5, 0.25],
        10.0,
        [0.0, 2.0, 0.0],
        Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2).to_array(),
    );
    b.camera([0.0, 1.0, 4.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0);
    let ptr = |b: &mut GltfBuilder, pointer: &str, interp: &str, times: &[f32], values: &[f32], width: usize| {
        b.animate_pointer("a", pointer, interp, times, values, width, false)
    };
    let base = [0.2, 0.4, 0.6, 1.0, 0.6, 0.2, 0.0, 0.5];
    ptr(
        &mut b,
        "/materials/1/pbrMetallicRoughness/baseColorFactor",
        "LINEAR",
        &[0.0, 2.0],
        &base,
        4,
    );
    ptr(
        &mut b,
        "/materials/0/emissiveFactor",
        "STEP",
        &[0.0, 1.0],
        &[1.0, 1.0, 1.0, 0.5, 0.25, 0.0],
        3,
    );
    let strength = "/materials/0/extensions/KHR_materials_emissive_strength/emissiveStrength";
    ptr(&mut b, strength, "LINEAR", &[0.0, 2.0], &[2.0, 4.0], 1);
    ptr(
        &mut b,
        "/nodes/1/translation",
        "LINEAR",
        &[0.0, 2.0],
        &[0.0, 0.0, 0.0, 2.0, 0.0, 0.0],
        3,
    );
    ptr(
        &mut b,
        "/extensions/KHR_lights_punctual/lights/0/intensity",
        "LINEAR",
        &[0.0, 2.0],
        &[10.0, 30.0],
        1,
    );
    let outer = "/extensions/KHR_lights_punctual/lights/0/spot/outerConeAngle";
    ptr(&mut b, outer, "LINEAR", &[0.0, 2.0], &[0.5, 0.9], 1);
    ptr(
        &mut b,
        "/cameras/0/perspective/yfov",
        "LINEAR",
        &[0.0, 2.0],
        &[0.5, 1.0],
        1,
    );
    ptr(
        &mut b,
        "/materials/1/occlusionTexture/strength",
        "LINEAR",
        &[0.0, 2.0],
        &[0.0, 1.0],
        1,
    );
    // A texture transform's offset moves while its rotation stays the file's.
    let image = b.png_image(2, 1, &[[255, 0, 0, 255], [0, 255, 0, 255]]);
    let texture = b.texture(image, json!({}));
    b.material_json(1)["pbrMetallicRoughness"]["baseColorTexture"] =
        json!({ "index": texture, "extensions": { "KHR_texture_transform": { "rotation": 0.3 } } });
    b.use_extension("KHR_texture_transform");
    let offset = "/materials/1/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform/offset";
    ptr(&mut b, offset, "LINEAR", &[0.0, 2.0], &[0.0, 0.0, 1.0, 0.5], 2);
    let visible = "/nodes/1/extensions/KHR_node_visibility/visible";
    b.animate_pointer("a", visible, "STEP", &[0.0, 1.0], &[1.0, 0.0], 1, true);
    b.use_extension("KHR_materials_emissive_strength");
    b.use_extension("KHR_node_visibility");
    let (_dir, path) = common::write_temp(&b, "pointer.gltf");

    let scene = posed(&path, 0.5, None);
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.contains("/materials/1/occlusionTexture/strength")),
        "{:?}",
        scene.warnings
    );
    assert_eq!(
        scene.rig.animations[0].channels.len(),
        9,
        "every supported pointer is read: {:?}",
        scene.warnings
    );
    let transform = scene.materials[1]
        .base_color_texture
        .expect("the quad's texture")
        .transform;
    let (s, c) = 0.3f32.sin_cos();
    let want = [[c, s, 0.25], [-s, c, 0.125]];
    assert!(
        transform
            .iter()
            .flatten()
            .zip(want.iter().flatten())
            .all(|(a, b)| (a - b).abs() < 1e-6),
        "{transform:?}"
    );
    let white = &scene.materials[1];
    assert!(
        close(white.base_color, Vec3::new(0.3, 0.35, 0.45)),
        "{}",
        white.base_color
    );
    assert!((white.alpha - 0.875).abs() < 1e-6, "{}", white.alpha);
    assert!(
        close(scene.materials[0].emission, Vec3::splat(2.5)),
        "{}",
        scene.materials[0].emission
    );
    assert!(close(translation_of(&scene, 1), Vec3::new(0.5, 0.0, 0.0)));
    let light = scene.punctual[0];
    assert!(
        close(light.intensity, Vec3::new(1.0, 0.5, 0.25) * 15.0),
        "{}",
        light.intensity
    );
    match light.kind {
        pathwave::scene::PunctualKind::Spot { inner, outer } => {
            assert!(
                (inner - 0.1).abs() < 1e-6 && (outer - 0.6).abs() < 1e-6,
                "{inner} {outer}"
            )
        }
        k => panic!("{k:?}"),
    }
    match scene.camera.unwrap().projection {
        pathwave::scene::Projection::Perspective { yfov } => assert!((yfov - 0.625).abs() < 1e-6, "{yfov}"),
        p => panic!("{p:?}"),
    }
    assert_eq!(scene.instances.len(), 2, "the quad is shown before its visibility key");

    let scene = posed(&path, 1.5, None);
    assert!(
        close(scene.materials[0].emission, Vec3::new(0.5, 0.25, 0.0) * 3.5),
        "{}",
        scene.materials[0].emission
    );
    assert_eq!(scene.instances.len(), 1, "the quad is hidden after it");
    let scene = posed(&path, 3.0, None);
    assert!(close(scene.materials[1].base_color, Vec3::new(0.6, 0.2, 0.0)));
    assert!((scene.materials[1].alpha - 0.5).abs() < 1e-6);

    // A shutter over the visibility key: the frame's time decides, and every key places the same instances.
    let mut scene = load(&path, None).unwrap();
    scene
        .pose_shutter(
            PoseTime {
                time: 0.9,
                animation: None,
            },
            0.2,
        )
        .unwrap();
    let motion = scene.motion.as_ref().expect("the quad moves over the shutter");
    assert_eq!(scene.instances.len(), 2);
    assert!(motion.keys.iter().all(|k| k.instances.len() == 2));
}

/// The pointer channels as Khronos' sample models write them (a census of AnimatedColorsCube, AnimationPointerUVs,
/// PotOfCoalsAnimationPointer, CubeVisibility, LightVisibility and MarblesForever): a texture transform animated
/// on a slot that has no KHR_texture_transform object (AnimationPointerUVs) starts from the identity, an empty one
/// (`{}`) too; a target animated by two channels (AnimationPointerUVs repeats four in one animation,
/// MarblesForever one across two animations) takes the later channel's value when every channel plays, and its own
/// animation's when one is chosen. Catches: a missing transform object dropping the channel or leaving the
/// texture untransformed, an empty one read as zero scale, the first of two channels winning in one pose and not
/// another.
#[test]
fn pointer_channels_read_as_the_sample_models_write_them() {
    let mut b = lit_quad();
    let image = b.png_image(2, 1, &[[255, 0, 0, 255], [0, 255, 0, 255]]);
    let texture = b.texture(image, json!({}));
    b.material_json(1)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": texture });
    b.material_json(1)["emissiveTexture"] = json!({ "index": texture, "extensions": { "KHR_texture_transform": {} } });
    b.material_json(1)["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    b.use_extension("KHR_texture_transform");
    let slot = |name: &str, part: &str| format!("/materials/1/{name}/extensions/KHR_texture_transform/{part}");
    let base = "pbrMetallicRoughness/baseColorTexture";
    b.animate_pointer(
        "a",
        &slot(base, "rotation"),
        "LINEAR",
        &[0.0, 2.0],
        &[0.0, 1.0],
        1,
        false,
    );
    b.animate_pointer(
        "a",
        &slot("emissiveTexture", "offset"),
        "LINEAR",
        &[0.0, 2.0],
        &[0.0, 0.0, 0.5, 1.0],
        2,
        false,
    );
    // The same target twice in one animation, then again in a second one.
    let color = "/materials/1/pbrMetallicRoughness/baseColorFactor";
    b.animate_pointer("a", color, "STEP", &[0.0], &[0.1, 0.1, 0.1, 1.0], 4, false);
    b.animate_pointer("a", color, "STEP", &[0.0], &[0.2, 0.2, 0.2, 1.0], 4, false);
    b.animate_pointer("b", color, "STEP", &[0.0], &[0.3, 0.3, 0.3, 1.0], 4, false);
    let (_dir, path) = common::write_temp(&b, "sample-pointers.gltf");

    let scene = posed(&path, 1.0, Some(0));
    let m = &scene.materials[1];
    let rotation = m.base_color_texture.expect("the quad's texture").transform;
    let (s, c) = 0.5f32.sin_cos();
    let want = [[c, s, 0.0], [-s, c, 0.0]];
    let near = |a: [[f32; 3]; 2], b: [[f32; 3]; 2]| {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() < 1e-6)
    };
    assert!(near(rotation, want), "{rotation:?}");
    let offset = m.emissive_texture.expect("the emissive texture").transform;
    assert!(near(offset, [[1.0, 0.0, 0.25], [0.0, 1.0, 0.5]]), "{offset:?}");
    assert!(
        close(m.base_color, Vec3::splat(0.2)),
        "one animation: its later channel, {}",
        m.base_color
    );
    let scene = posed(&path, 1.0, Some(1));
    assert!(
        close(scene.materials[1].base_color, Vec3::splat(0.3)),
        "{}",
        scene.materials[1].base_color
    );
    let scene = posed(&path, 1.0, None);
    assert!(
        close(scene.materials[1].base_color, Vec3::splat(0.3)),
        "every channel: the last, {}",
        scene.materials[1].base_color
    );
}
