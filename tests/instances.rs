//! Instancing: meshes kept once in object space under a top-level BVH. The two-level traversal (CPU twin and
//! device) against a brute force over the same triangles placed one by one, for rotated, scaled, mirrored and
//! nested instances; instanced images against flattened ones; and a scene of many instances within its memory bound.
mod common;

use common::gltf_builder::{square, GltfBuilder, FACING_DOWN};
use common::stats::{assert_same_within_noise, beyond_noise};
use glam::{Mat4, Quat, Vec3};
use pathwave::bvh::{brute_force, trace_two_level, Ray};
use pathwave::constants::{FEATURE_INSTANCES, FEATURE_MEDIA, FEATURE_MOTION, MOTION_SEGMENTS, NO_HIT, NO_INSTANCE};
use pathwave::render::gpu_scene::try_pack_with;
use pathwave::scene::{load, Instancing, Scene};
use pathwave::{Renderer, RendererOptions};
use serde_json::json;

/// A floor (world space) and a lamp, and one sphere mesh placed five ways: rotated, scaled unevenly, mirrored,
/// nested under a rotated and scaled parent, and plain.
fn placed_spheres() -> (tempfile::TempDir, std::path::PathBuf) {
    common::write_temp(&spheres(), "spheres.gltf")
}

/// `placed_spheres`' builder: nodes 0 floor, 1 lamp, 2 rotated, 3 squashed, 4 mirrored, 5 plain, 6 nested, 7 its
/// parent.
fn spheres() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    // Glass, so that a mirrored instance's front face matters (entering and leaving refract differently).
    let red = b.glass_material("glass", [0.9, 0.5, 0.4], 1.5, 0.0, false, Some(([0.8, 0.5, 0.4], 0.5)));
    let light = b.material("light", [0.8; 3], [6.0; 3], false);
    b.floor_and_lamp(white, light);
    b.uv_sphere("ball", [0.0, 0.0, 0.0], 0.4, red, true);
    b.transform_last_node(
        json!({ "translation": [-1.5, 0.5, 0.0], "rotation": Quat::from_rotation_z(0.6).to_array() }),
    );
    b.place_last_mesh(
        "squashed",
        json!({ "translation": [-0.5, 0.4, 0.8], "scale": [1.5, 0.6, 1.0] }),
    );
    b.place_last_mesh(
        "mirrored",
        json!({ "translation": [0.5, 0.5, -0.5], "scale": [-1.0, 1.0, 1.0] }),
    );
    b.place_last_mesh("plain", json!({ "translation": [1.6, 0.45, 0.6] }));
    let child = b.node("nested", json!({ "mesh": 2, "translation": [0.0, 1.0, 0.0] }));
    let parent = b.node(
        "parent",
        json!({ "translation": [0.4, 0.3, 1.4], "rotation": Quat::from_rotation_y(0.9).to_array(), "scale": [0.5, 0.5, 0.5] }),
    );
    b.add_child(parent, child);
    b.camera([0.0, 2.0, 5.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 45.0);
    b
}

/// `placed_spheres` moving over [0, 1] s: the rotated sphere slides and turns, the mirrored one stretches (staying
/// mirrored), the nested one's parent swings it round; the squashed and plain ones stay still.
fn moving_spheres() -> Scene {
    moving(spheres())
}

/// `spheres()`'s scene moving as `moving_spheres` says, posed over the shutter.
fn moving(mut b: GltfBuilder) -> Scene {
    let turn = |a: f32| Quat::from_rotation_z(0.6) * Quat::from_rotation_x(a);
    let (r0, r1) = (turn(0.0).to_array(), turn(1.2).to_array());
    b.slide("move", 2, [0.0, 1.0], [-1.5, 0.5, 0.0], [-1.1, 0.7, 0.3]);
    b.animate("move", 2, "rotation", "LINEAR", &[0.0, 1.0], &[r0, r1].concat());
    b.animate(
        "move",
        4,
        "scale",
        "LINEAR",
        &[0.0, 1.0],
        &[-1.0, 1.0, 1.0, -1.4, 0.7, 1.2],
    );
    let (p0, p1) = (
        Quat::from_rotation_y(0.9).to_array(),
        Quat::from_rotation_y(1.7).to_array(),
    );
    b.animate("move", 7, "rotation", "LINEAR", &[0.0, 1.0], &[p0, p1].concat());
    let (dir, path) = common::write_temp(&b, "moving-spheres.gltf");
    let mut scene = load(&path, None).unwrap();
    drop(dir);
    scene.pose_shutter(pathwave::scene::PoseTime::default(), 1.0).unwrap();
    assert!(scene.motion.is_some());
    scene
}

fn rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = common::rng::Rng(seed);
    (0..n)
        .map(|_| {
            let origin = Vec3::new(rng.next() * 6.0 - 3.0, rng.next() * 2.0 + 0.2, 4.0);
            let target = Vec3::new(rng.next() * 4.0 - 2.0, rng.next() * 1.6, rng.next() * 3.0 - 1.5);
            common::ray_towards(origin, target)
        })
        .collect()
}

fn renderer(scene: &Scene, instancing: Instancing) -> Renderer {
    let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
    let options = RendererOptions {
        instancing,
        ..Default::default()
    };
    Renderer::with_options(scene, ctx, options).unwrap_or_else(|e| panic!("{e}"))
}

/// `rays` traced at `time` (closest and any hit) by the device and the CPU twin over `packed`, each checked against a
/// brute force over `placed` (the same triangles placed in the world one by one, at that time); returns how many
/// closest hits found an instance. An any hit names the twin's instance too, but under ray queries, which may stop
/// at any.
fn check_against_brute_force(
    packed: &pathwave::render::gpu_scene::PackedScene,
    device: &mut Renderer,
    rays: &[Ray],
    placed: &[pathwave::layout::TriVerts],
    time: f32,
) -> u32 {
    let mut instanced_hits = 0;
    for any_hit in [false, true] {
        let gpu = device.probe_trace_at(rays, any_hit, time).unwrap();
        for (ray, g) in rays.iter().zip(&gpu) {
            let want = brute_force(placed, ray);
            let cpu = trace_two_level(
                &packed.bvh.nodes,
                &packed.tri_verts,
                &packed.instances,
                ray,
                any_hit,
                time,
            );
            for (who, got) in [("cpu twin", cpu), ("device", *g)] {
                assert_eq!(
                    got.tri == NO_HIT,
                    want.tri == NO_HIT,
                    "{who} (time {time}, any hit {any_hit}) on {ray:?}"
                );
                if !any_hit && want.tri != NO_HIT {
                    let tol = 2e-5 * want.t.max(1.0);
                    assert!(
                        (got.t - want.t).abs() < tol,
                        "{who} at {time}: t {} against {}",
                        got.t,
                        want.t
                    );
                }
            }
            if !any_hit || device.traversal() == pathwave::render::Traversal::Compute {
                assert_eq!(cpu.inst, g.inst, "the device and its twin hit different instances");
            }
            instanced_hits += (!any_hit && g.inst != NO_INSTANCE) as u32;
        }
    }
    instanced_hits
}

/// Both schedules give the same bytes on `what`, the scene `inst` renders.
fn assert_schedules_agree(inst: &mut Renderer, what: &str) {
    let s = common::settings(24, 18, 8, 2);
    inst.set_schedule(pathwave::Schedule::Wavefront);
    let w = common::render(inst, &s);
    inst.set_schedule(pathwave::Schedule::Fused);
    let f = common::render(inst, &s);
    assert!(w.sum == f.sum && w.sum_sq == f.sum_sq, "the schedules differ on {what}");
}

/// Catches: rays not moved into the instance's space (or moved by the wrong matrix), distances measured in object
/// space, TLAS boxes not holding their instances, BLAS indices not offset to where their nodes and triangles live,
/// any hit stopping on a miss.
#[test]
fn two_level_traversal_finds_what_brute_force_over_the_placed_triangles_finds() {
    let (_dir, path) = placed_spheres();
    let scene = load(&path, None).unwrap();
    let packed = try_pack_with(&scene, Instancing::Always).unwrap();
    assert_ne!(
        packed.features() & FEATURE_INSTANCES,
        0,
        "the sphere should be instanced"
    );
    assert_eq!(packed.instances.len(), 1 + 5, "the header and five instances");
    // The reference: every triangle placed in the world one by one.
    let flat = try_pack_with(&scene, Instancing::Never).unwrap();
    assert_eq!(flat.features() & FEATURE_INSTANCES, 0);
    let rays = rays(3000, 5);
    let mut device = renderer(&scene, Instancing::Always);
    let instanced_hits = check_against_brute_force(&packed, &mut device, &rays, &flat.tri_verts, 0.0);
    assert!(instanced_hits > 300, "only {instanced_hits} rays hit an instance");
}

/// Ray-query traversal (Mesa 25's lavapipe) against the same brute force, on the same instances and on the scene
/// flattened. Catches: a top-level instance whose index is not its instance record's, a custom index that is not
/// the mesh's first triangle (hits naming another mesh's triangles), transforms not the records' rows, mirrored
/// instances culled, the world's triangles lost when instances exist, any hit not stopping, and a scene traced by the
/// compute BVH while claiming ray queries (renderer.traversal()).
#[test]
fn ray_queries_find_what_brute_force_over_the_placed_triangles_finds() {
    if !common::rt::on_ray_query_driver("ray_queries_find_what_brute_force_over_the_placed_triangles_finds") {
        return;
    }
    let (_dir, path) = placed_spheres();
    let scene = load(&path, None).unwrap();
    let flat = try_pack_with(&scene, Instancing::Never).unwrap();
    let rays = rays(3000, 5);
    for instancing in [Instancing::Always, Instancing::Never] {
        let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
        let options = RendererOptions {
            instancing,
            traversal: pathwave::render::Traversal::RayQuery,
            ..Default::default()
        };
        let mut device = Renderer::with_options(&scene, ctx, options).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            device.traversal(),
            pathwave::render::Traversal::RayQuery,
            "{:?}",
            device.warnings
        );
        let packed = try_pack_with(&scene, instancing).unwrap();
        let instanced_hits = check_against_brute_force(&packed, &mut device, &rays, &flat.tri_verts, 0.0);
        if instancing == Instancing::Always {
            assert!(instanced_hits > 300, "only {instanced_hits} rays hit an instance");
        }
        // The same triangle as the CPU twin's, and barycentrics that place the hit where t does (rays through a
        // shared edge may take either triangle).
        let gpu = device.probe_trace(&rays, false).unwrap();
        let mut differ = 0;
        for (ray, g) in rays.iter().zip(&gpu) {
            let cpu = trace_two_level(&packed.bvh.nodes, &packed.tri_verts, &packed.instances, ray, false, 0.0);
            differ += (g.tri != cpu.tri) as usize;
            if g.tri != NO_HIT && g.inst == NO_INSTANCE {
                let t = packed.tri_verts[g.tri as usize];
                let (v0, e1, e2) = (
                    Vec3::from_slice(&t.v0[..3]),
                    Vec3::from_slice(&t.e1[..3]),
                    Vec3::from_slice(&t.e2[..3]),
                );
                let at = v0 + e1 * g.uv.x + e2 * g.uv.y;
                let want = ray.origin + ray.dir * g.t;
                assert!(
                    (at - want).length() < 1e-4,
                    "barycentrics {:?} place the hit at {at}, t at {want}",
                    g.uv
                );
            }
        }
        assert!(
            differ * 200 <= rays.len(),
            "{differ} of {} rays hit another triangle",
            rays.len()
        );
    }
}

/// Catches: moving instances placed at the wrong time or by the wrong map (their transforms not interpolated
/// between the keys on either side, the inverse not that map's), TLAS boxes not holding an instance over the whole
/// shutter, key records read for still instances, instanced triangles taken through world triangles' motion keys,
/// turns interpolated other than at a constant rate about one axis. The reference is the animation posed at each
/// time itself (the instances' parents do not move, so translation, slerp and scale between keys are exact).
#[test]
fn moving_instances_are_found_where_brute_force_finds_them_at_every_time() {
    let scene = moving_spheres();
    let packed = try_pack_with(&scene, Instancing::Always).unwrap();
    let features = packed.features();
    assert_ne!(features & FEATURE_INSTANCES, 0, "the sphere should be instanced");
    assert_ne!(features & FEATURE_MOTION, 0);
    let segments = MOTION_SEGMENTS as usize;
    assert_eq!(
        packed.instances.len(),
        1 + 5 + 3 * (segments + 1),
        "the header, five instances, and the keys of the three that move"
    );
    let rays = rays(3000, 8);
    let mut device = renderer(&scene, Instancing::Always);
    let mut instanced_hits = 0;
    for time in [0.0, 0.15, 0.4, 0.62, 0.999] {
        let placed = common::exact_tri_verts(&scene, time);
        instanced_hits += check_against_brute_force(&packed, &mut device, &rays, &placed, time);
    }
    assert!(instanced_hits > 1500, "only {instanced_hits} rays hit an instance");
}

/// Catches: a moving instance shaded at another time than it was hit (normals, hit points), or its mirror flag lost
/// while it moves: the image would differ from the flattened moving scene's beyond noise. Also: a mesh whose
/// instance turns inside out over the shutter (a scale through 0) is flattened, not instanced.
#[test]
fn a_moving_instanced_scene_renders_like_its_triangles_moved_one_by_one() {
    let scene = moving_spheres();
    let s = common::settings(48, 36, 256, 4);
    let flat = common::render(&mut renderer(&scene, Instancing::Never), &s);
    let mut inst = renderer(&scene, Instancing::Always);
    let a = common::render(&mut inst, &s);
    let bad = beyond_noise(&a, &flat, 1e-3);
    assert!(bad <= 3, "{bad} pixel channels differ beyond noise");
    let sum = |m: &[[f32; 3]]| m.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>();
    let (ma, mb) = (sum(&a.mean()), sum(&flat.mean()));
    assert!((ma / mb - 1.0).abs() < 0.01, "{ma} against {mb}");
    assert_schedules_agree(&mut inst, "a moving instanced scene");

    let mut b = spheres();
    b.animate(
        "flip",
        4,
        "scale",
        "LINEAR",
        &[0.0, 1.0],
        &[-1.0, 1.0, 1.0, 1.0, 1.0, 1.0],
    );
    let (_dir, path) = common::write_temp(&b, "flipping.gltf");
    let mut flipping = load(&path, None).unwrap();
    flipping
        .pose_shutter(pathwave::scene::PoseTime::default(), 1.0)
        .unwrap();
    let ball = flipping.meshes.iter().position(|m| m.name == "ball").unwrap();
    assert!(
        !flipping.instanced_meshes(Instancing::Always)[ball],
        "a mesh turning inside out is flattened"
    );
    assert!(scene.instanced_meshes(Instancing::Always)[ball]);
}

/// A floor, a grey ball, and one glowing sphere mesh (single-sided: it emits outwards) placed four ways: rotated,
/// stretched, mirrored and plain. Its instances are the only lights.
/// Catches, for each estimator: instanced emitters picked with probabilities other than those the device divides by
/// (light sampling: the instance's pick times its triangle's within the mesh, over the triangle's area in the world),
/// emission hits weighted against another density than light sampling's (MIS weights would not add to 1), a
/// mirrored emitter's front turned (it emits outwards only), a stretched one's area taken in its mesh's space; and
/// the same for emitters moving over the shutter. Each image must match the one whose emitters are placed triangle
/// by triangle in the world.
/// The moving spheres' glass filled with a scattering medium (KHR_materials_scatter): the medium stack and the free
/// flights through instanced, mirrored and moving meshes. Catches a medium entered or left by the wrong face of a
/// mirrored or moving instance (its stack then holds the wrong volume), or a scattering point placed in the wrong
/// space: the instanced image would differ from the flattened one beyond noise.
#[test]
fn moving_instanced_scattering_media_render_like_their_triangles_moved_one_by_one() {
    let mut b = spheres();
    b.material_json(1)["extensions"]["KHR_materials_scatter"] =
        json!({ "scatterStrengthFactor": 1.0, "multiscatterColorFactor": [0.8, 0.6, 0.5], "scatterAnisotropy": 0.3 });
    b.use_extension("KHR_materials_scatter");
    let scene = moving(b);
    let features = try_pack_with(&scene, Instancing::Always).unwrap().features();
    assert_ne!(
        features & FEATURE_MEDIA,
        0,
        "the spheres should hold a scattering medium"
    );
    assert_ne!(features & FEATURE_INSTANCES, 0);
    let s = common::settings(48, 36, 256, 6);
    let flat = common::render(&mut renderer(&scene, Instancing::Never), &s);
    let mut inst = renderer(&scene, Instancing::Always);
    let a = common::render(&mut inst, &s);
    let bad = beyond_noise(&a, &flat, 1e-3);
    assert!(bad <= 3, "{bad} pixel channels differ beyond noise");
    assert_schedules_agree(&mut inst, "moving scattering spheres");
}

#[test]
fn instanced_emitters_light_the_scene_as_placed_ones_do() {
    use pathwave::{Estimator, RenderSettings};
    let (dir, path) = common::write_temp(&common::scenes::lamps(), "lamps.gltf");
    let still = load(&path, None).unwrap();
    let bulb = still.meshes.iter().position(|m| m.name == "bulb").unwrap();
    assert!(still.instanced_meshes(Instancing::Always)[bulb]);
    let packed = try_pack_with(&still, Instancing::Always).unwrap();
    assert_eq!(packed.light_count, 4, "one light per instance");
    let mut b = common::scenes::lamps();
    b.slide("move", 2, [0.0, 1.0], [-1.4, 1.2, 0.3], [-0.8, 1.5, 0.6]);
    b.animate(
        "move",
        3,
        "scale",
        "LINEAR",
        &[0.0, 1.0],
        &[1.8, 0.5, 1.0, 1.0, 1.2, 0.8],
    );
    let moving_path = dir.path().join("moving-lamps.gltf");
    b.write(&moving_path);
    let mut moving = load(&moving_path, None).unwrap();
    moving.pose_shutter(pathwave::scene::PoseTime::default(), 1.0).unwrap();
    let cases = [
        ("mis", &still, Estimator::Mis),
        ("light", &still, Estimator::Light),
        ("bsdf", &still, Estimator::Bsdf),
        ("moving mis", &moving, Estimator::Mis),
    ];
    for (what, scene, estimator) in cases {
        let s = RenderSettings {
            estimator,
            ..common::settings(40, 30, 256, 6)
        };
        let flat = common::render(&mut renderer(scene, Instancing::Never), &s);
        let inst = common::render(&mut renderer(scene, Instancing::Always), &s);
        assert_same_within_noise(what, &inst, &flat);
    }
}

/// Catches: normals not taken to world space by the inverse transpose, a mirrored instance's front face turned (the
/// spheres are glass with absorption, so which side is inside shows), hit points left in object space: the image
/// would differ from the flattened scene's beyond noise.
#[test]
fn an_instanced_scene_renders_like_its_triangles_placed_one_by_one() {
    let (_dir, path) = placed_spheres();
    let scene = load(&path, None).unwrap();
    let s = common::settings(48, 36, 256, 9);
    let flat = common::render(&mut renderer(&scene, Instancing::Never), &s);
    let mut inst = renderer(&scene, Instancing::Always);
    let a = common::render(&mut inst, &s);
    // Per pixel within five standard errors of the difference of two independent means, and the same overall
    // brightness within 1 %.
    let (ma, mb) = (a.mean(), flat.mean());
    let bad = beyond_noise(&a, &flat, 1e-3);
    assert!(bad <= 3, "{bad} pixel channels differ beyond noise");
    let sum = |m: &[[f32; 3]]| m.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>();
    assert!(
        (sum(&ma) / sum(&mb) - 1.0).abs() < 0.01,
        "{} against {}",
        sum(&ma),
        sum(&mb)
    );
    assert_schedules_agree(&mut inst, "an instanced scene");
}

/// Catches: instances copied into the device buffers (memory growing with placed triangles), or the host memory
/// check refusing a scene that instancing keeps small. 4,000 instances of a 2,048-triangle mesh place 8.2 M
/// triangles; stored once they take the mesh's bytes plus 128 per instance.
#[test]
fn many_instances_of_one_mesh_take_the_mesh_once_plus_a_record_each() {
    let mut scene = Scene::default();
    let mesh = pathwave::bench::terrain(32).meshes.remove(0);
    let tris = mesh.triangle_count();
    scene.meshes.push(mesh);
    scene.materials.push(pathwave::scene::Material::default());
    for i in 0..4000 {
        let (x, z) = ((i % 64) as f32 * 3.0, (i / 64) as f32 * 3.0);
        scene.instances.push(pathwave::scene::Instance {
            mesh: 0,
            world_from_object: Mat4::from_rotation_translation(Quat::from_rotation_y(i as f32), Vec3::new(x, 0.0, z)),
        });
    }
    scene.environment = Some(pathwave::scene::Environment::constant([1.0; 3]));
    assert!(scene.flattened_triangle_bound() > 8_000_000);
    scene
        .check_host_memory(256 << 20, Instancing::Auto)
        .expect("instancing keeps the scene within 256 MiB");
    let packed = try_pack_with(&scene, Instancing::Auto).unwrap();
    assert_eq!(packed.instances.len(), 4001);
    assert_eq!(packed.tri_verts.len(), tris, "the mesh is stored once");
    let bytes = std::mem::size_of_val(&packed.tri_verts[..])
        + std::mem::size_of_val(&packed.tri_shading[..])
        + std::mem::size_of_val(&packed.bvh.nodes[..])
        + std::mem::size_of_val(&packed.instances[..]);
    let bound = tris * (48 + 48 + 48) + 4001 * (128 + 2 * 48);
    assert!(bytes <= bound, "{bytes} device bytes, more than the bound {bound}");
    let mut r = renderer(&scene, Instancing::Auto);
    let film = common::render(&mut r, &common::settings(16, 16, 2, 1));
    assert!(film.mean().iter().all(|p| p.iter().all(|c| c.is_finite())));
}

/// The file: 25,600 nodes sharing one 80,000-triangle mesh (2 billion placed triangles). Before instancing,
/// loading it tried to allocate tens of gigabytes and aborted; now it renders within a 400 MiB host budget, still
/// and with every instance moving over the shutter.
#[test]
fn a_file_of_25600_nodes_sharing_one_80k_triangle_mesh_renders_within_a_small_budget() {
    let n = 200u32;
    let mut positions = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
            positions.push([x * 0.9, 0.05 * (x * 20.0).sin() * (z * 17.0).cos(), z * 0.9]);
        }
    }
    let mut indices = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            indices.extend([a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2]);
        }
    }
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    b.mesh("grid", &positions, &indices, grey);
    for k in 1..25_600 {
        let (x, z) = ((k % 160) as f32 - 80.0, (k / 160) as f32 - 80.0);
        b.place_last_mesh("grid", json!({ "translation": [x, 0.0, z] }));
    }
    // Every grid hangs from one node the wind sways, so with the shutter open all 25,600 instances move.
    let wind = b.node("wind", json!({}));
    for k in 0..25_600 {
        b.add_child(wind, k);
    }
    b.slide("sway", wind, [0.0, 1.0], [0.0, 0.0, 0.0], [0.3, 0.0, 0.1]);
    b.camera([0.0, 40.0, 120.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 45.0);
    let (dir, path) = common::write_temp(&b, "forest.gltf");
    let out = dir.path().join("forest.png");
    // Still, then moving: the moving instances keep the mesh once (their keys cost 512 bytes each), where flattening
    // them would need keys for 2 billion triangles.
    for shutter in ["0", "0.5"] {
        let o = common::pathwave_cli()
            .arg("render")
            .arg(&path)
            .args([
                "--env-color",
                "1,1,1",
                "--size",
                "32x18",
                "--spp",
                "2",
                "--shutter",
                shutter,
                "--max-memory",
                "400M",
                "-o",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let log = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "shutter {shutter}: {log}");
        assert!(out.exists());
        std::fs::remove_file(&out).unwrap();
    }
    let info = common::pathwave_cli().arg("info").arg(&path).output().unwrap();
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(text.contains("80000 stored, 2048000000 placed"), "{text}");
    assert!(text.contains("placed by 25600 instances"), "{text}");
}

/// Catches: an instanced normal map's tangents left in object space, or a mirroring instance's bitangent not
/// flipped: the bumps would light differently from the same quads placed one by one.
#[test]
fn instanced_normal_maps_shade_like_placed_ones() {
    let mut b = GltfBuilder::new();
    let light = b.material("light", [0.8; 3], [5.0; 3], false);
    b.quad("lamp", square(2.0, 3.0), light, FACING_DOWN);
    // Ridges: normals tilted along u in alternate columns and along v in all, so the map's effect depends on both the
    // tangent's direction and the bitangent's sign.
    let size = 16;
    let texels: Vec<[u8; 4]> = (0..size * size)
        .map(|k| {
            let n = if (k % size) / 2 % 2 == 0 {
                Vec3::new(0.5, 0.6, 0.6)
            } else {
                Vec3::new(-0.5, 0.6, 0.6)
            }
            .normalize();
            let e = |c: f32| ((c + 1.0) * 0.5 * 255.0).round() as u8;
            [e(n.x), e(n.y), e(n.z), 255]
        })
        .collect();
    let bumpy = b.pbr_material("bumpy", [0.8; 3], 0.0, 0.5, [0.0; 3], false);
    let image = b.png_image(size as u32, size as u32, &texels);
    let tex = b.texture(image, json!({ "magFilter": 9728, "minFilter": 9728 }));
    b.material_json(bumpy)["normalTexture"] = json!({ "index": tex });
    b.textured_quad(
        "tile",
        [[-0.5, 0.0, -0.5], [-0.5, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 0.0, -0.5]],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        bumpy,
    );
    b.transform_last_node(
        json!({ "translation": [-1.2, 0.0, 0.0], "rotation": Quat::from_rotation_y(0.5).to_array() }),
    );
    b.place_last_mesh(
        "mirrored",
        json!({ "translation": [0.0, 0.0, 0.0], "scale": [-1.0, 1.0, 1.0] }),
    );
    // Apart from the others (coplanar overlaps would z-fight, each traversal picking its own winner).
    b.place_last_mesh("stretched", json!({ "translation": [1.5, 0.0, 0.2], "scale": [0.6, 1.0, 1.4], "rotation": Quat::from_rotation_y(1.2).to_array() }));
    b.camera([0.0, 2.5, 2.5], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 50.0);
    let (_dir, path) = common::write_temp(&b, "tiles.gltf");
    let scene = load(&path, None).unwrap();
    assert_ne!(
        try_pack_with(&scene, Instancing::Always).unwrap().features() & FEATURE_INSTANCES,
        0
    );
    let s = common::settings(48, 36, 256, 4);
    let a = common::render(&mut renderer(&scene, Instancing::Always), &s);
    let flat = common::render(&mut renderer(&scene, Instancing::Never), &s);
    let bad = beyond_noise(&a, &flat, 2e-3);
    assert!(bad <= 3, "{bad} pixel channels differ beyond noise");
}
