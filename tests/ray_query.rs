//! Ray-query traversal's ground: the second lavapipe (Mesa >= 24.1 from the backports suite, fetched by
//! ci/lavapipe-rt.sh into the user's cache) exposes VK_KHR_ray_query beside the system's driver, and pathwave tells
//! them apart. Tests that need ray queries run pathwave under that driver's ICD file.
mod common;

use common::gltf_builder::upright;
use std::path::PathBuf;
use std::process::Output;

fn devices(icd: &std::path::Path) -> Output {
    common::pathwave_cli()
        .args(["info", "--devices"])
        .env("VK_DRIVER_FILES", icd)
        .env_remove("VK_ICD_FILENAMES")
        .output()
        .expect("the pathwave binary runs")
}

#[test]
fn the_backports_lavapipe_offers_ray_queries_and_info_says_so() {
    let o = devices(&common::rt::icd());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = text.lines().next().unwrap_or_default();
    assert!(line.contains("llvmpipe") && line.contains("Mesa 2"), "{text}");
    assert!(line.contains("ray queries: yes"), "{text}");
    // The system's lavapipe (Debian 12's Mesa 22.3) has none; a newer system driver may, and says which it is.
    let system = PathBuf::from("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json");
    if system.is_file() {
        let o = devices(&system);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        if text.contains("Mesa 22.") {
            assert!(text.contains("ray queries: no"), "{text}");
        }
    }
}

/// `(extension, shadow)` ray counts from a render's summary line.
fn ray_counts(log: &str) -> (f64, f64) {
    let line = log
        .lines()
        .find(|l| l.contains(" extension + "))
        .unwrap_or_else(|| panic!("no summary in {log}"));
    let before = |word: &str| -> f64 {
        let head = &line[..line.find(word).unwrap_or_else(|| panic!("no {word} in {line}"))];
        let n = head.trim_end().rsplit([' ', '(']).next().unwrap();
        n.parse().unwrap_or_else(|_| panic!("{n} in {line}"))
    };
    (before(" extension"), before(" shadow rays"))
}

/// A project scene rendered with ray queries and with the compute BVH on the backports lavapipe, with different
/// seeds, agrees by the statistical diff (film statistics, family-wise alpha 0.01), and traces as many rays within
/// 5 % plus 200 (the seeds' noise; each render traces thousands): every project scene, then textured.gltf with every
/// mesh instanced (textures, alpha MASK and BLEND, and instances at once) and glass.gltf instanced under the fused
/// schedule. On a cold shader cache the 40 renders take about 3 minutes on 2 cores (6.6 s for layers.gltf's first
/// render with ray queries, 0.9 s once its pipelines are cached). Catches:
/// hits on the wrong triangle or instance (wrong materials and normals), lost alpha coverage, barycentrics off
/// (textures and normals), offsets that let a ray hit its own surface again (shadow acne darkens, ray counts grow),
/// one-sided triangles culled, a stage variant built without ray queries.
#[test]
fn project_scenes_render_alike_with_ray_queries_and_the_compute_bvh() {
    let icd = common::rt::icd();
    let out = tempfile::tempdir().unwrap();
    // (scene, PATHWAVE_INSTANCING, PATHWAVE_SCHEDULE)
    let every = std::fs::read_dir(common::scenes_dir())
        .unwrap()
        .map(|e| e.unwrap().path());
    let every = every.filter(|p| p.extension().is_some_and(|e| e == "gltf"));
    let mut cases: Vec<(String, &str, &str)> = every
        .map(|p| {
            (
                p.file_stem().unwrap().to_string_lossy().into_owned(),
                "auto",
                "wavefront",
            )
        })
        .collect();
    cases.sort();
    assert!(cases.len() >= 18, "the project scenes: {cases:?}");
    cases.push(("textured".into(), "always", "wavefront"));
    cases.push(("glass".into(), "always", "fused"));
    let mut failed = Vec::new();
    for (name, instancing, schedule) in &cases {
        let scene = common::scenes_dir().join(format!("{name}.gltf"));
        let render = |traversal: &str, seed: &str| {
            let exr = out.path().join(format!("{name}.{traversal}.exr"));
            let o = common::pathwave_cli()
                .arg("render")
                .arg(&scene)
                .arg("-o")
                .arg(&exr)
                .args([
                    "--size",
                    "40x30",
                    "--spp",
                    "16",
                    "--film-stats",
                    "--seed",
                    seed,
                    "--traversal",
                    traversal,
                ])
                .env("VK_DRIVER_FILES", &icd)
                .env_remove("VK_ICD_FILENAMES")
                .env("PATHWAVE_INSTANCING", instancing)
                .env("PATHWAVE_SCHEDULE", schedule)
                .output()
                .unwrap();
            let log = String::from_utf8_lossy(&o.stderr).into_owned();
            assert!(o.status.success(), "{name} {traversal}: {log}");
            (exr, log)
        };
        let (rq, rq_log) = render("ray-query", "1");
        assert!(
            rq_log.contains("(ray queries)"),
            "{name} did not trace with ray queries: {rq_log}"
        );
        let (cb, cb_log) = render("compute", "2");
        assert!(!cb_log.contains("(ray queries)"), "{cb_log}");
        let (a, b) = (ray_counts(&rq_log), ray_counts(&cb_log));
        for (what, x, y) in [("extension", a.0, b.0), ("shadow", a.1, b.1)] {
            assert!(
                (x - y).abs() <= 0.05 * y + 200.0,
                "{name}: {x} {what} rays with ray queries, {y} without"
            );
        }
        let o = common::pathwave_cli().arg("diff").arg(&rq).arg(&cb).output().unwrap();
        if o.status.code() != Some(0) {
            failed.push(format!("{name}: {}", String::from_utf8_lossy(&o.stdout)));
        }
    }
    assert!(failed.is_empty(), "{}", failed.join("\n"));
}

/// A scene that moves over the shutter keeps the compute BVH under --traversal ray-query, and says why in one line.
#[test]
fn a_moving_scene_keeps_the_compute_bvh_and_says_why() {
    let out = tempfile::tempdir().unwrap();
    let exr = out.path().join("moving.exr");
    let o = common::pathwave_cli()
        .arg("render")
        .arg(common::scenes_dir().join("animated.gltf"))
        .arg("-o")
        .arg(&exr)
        .args([
            "--size",
            "16x12",
            "--spp",
            "2",
            "--time",
            "1",
            "--shutter",
            "0.4",
            "--traversal",
            "ray-query",
        ])
        .env("VK_DRIVER_FILES", common::rt::icd())
        .env_remove("VK_ICD_FILENAMES")
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{log}");
    let notices: Vec<&str> = log.lines().filter(|l| l.contains("ray queries asked for")).collect();
    assert_eq!(notices.len(), 1, "{log}");
    assert!(
        notices[0].contains("moves over the shutter") && notices[0].contains("compute BVH"),
        "{log}"
    );
    assert!(!log.contains("(ray queries)"), "{log}");
}

/// PCG4D as Jarzynski and Olano publish it ("Hash Functions for GPU Rendering", JCGT 9(3), 2020, listing 3):
/// written here from the paper, not from rng.glsl.
fn pcg4d(mut v: [u32; 4]) -> [u32; 4] {
    for x in &mut v {
        *x = x.wrapping_mul(1664525).wrapping_add(1013904223);
    }
    let mix = |v: &mut [u32; 4]| {
        v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
        v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
        v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
        v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
    };
    mix(&mut v);
    for x in &mut v {
        *x ^= *x >> 16;
    }
    mix(&mut v);
    v
}

/// A floor, a MASK quad kept (alpha 0.7, cutoff 0.5) and one cut (alpha 0.3), a BLEND sphere (alpha 0.4) placed
/// three ways (plain, turned, mirrored) so it is instanced, and in front of them all two degenerate triangles: a
/// sliver (three points on a line) and one with two corners at one point.
fn alpha_scene() -> (tempfile::TempDir, PathBuf) {
    use glam::Quat;
    use serde_json::json;
    let mut b = common::gltf_builder::GltfBuilder::new();
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    let light = b.material("light", [0.8; 3], [5.0; 3], false);
    let kept = b.material("kept", [0.2, 0.8, 0.2], [0.0; 3], true);
    let cut = b.material("cut", [0.8, 0.2, 0.2], [0.0; 3], true);
    let blend = b.material("blend", [0.2, 0.2, 0.8], [0.0; 3], true);
    for (m, alpha, mode) in [(kept, 0.7, "MASK"), (cut, 0.3, "MASK"), (blend, 0.4, "BLEND")] {
        let j = b.material_json(m);
        j["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(alpha);
        j["alphaMode"] = json!(mode);
        if mode == "MASK" {
            j["alphaCutoff"] = json!(0.5);
        }
    }
    b.floor_and_lamp(white, light);
    b.quad("kept", upright([-2.0, -0.5], [0.2, 1.6], 0.5), kept, None);
    b.quad("cut", upright([0.5, 2.0], [0.2, 1.6], 0.8), cut, None);
    b.uv_sphere("ball", [0.0, 0.0, 0.0], 0.45, blend, true);
    b.transform_last_node(json!({ "translation": [0.0, 0.6, 0.0] }));
    b.place_last_mesh(
        "turned",
        json!({ "translation": [-1.2, 0.7, -0.6], "rotation": Quat::from_rotation_z(0.7).to_array() }),
    );
    b.place_last_mesh(
        "mirrored",
        json!({ "translation": [1.3, 0.5, -0.4], "scale": [-1.0, 1.2, 1.0] }),
    );
    // Three points on a line (in floats, a sliver of area about 1e-8), and a triangle with two corners at one
    // point (no area at all).
    b.mesh(
        "degenerate",
        &[[-2.5, 0.3, 2.0], [0.0, 0.9, 2.0], [2.5, 1.5, 2.0], [2.5, 1.5, 2.0]],
        &[0, 1, 2, 0, 2, 3],
        white,
    );
    b.camera([0.0, 2.0, 5.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 45.0);
    common::write_temp(&b, "alpha.gltf")
}

/// Catches, under both traversals: alpha-tested candidates committed untested (the cut quad and the BLEND sphere
/// would stop every ray), MASK's cutoff read the wrong way, BLEND's coin not the ray's key and triangle hashed as
/// alpha_stops says (ray queries testing instanced triangles by their BLAS-local index instead of the mesh's first
/// triangle plus it, or twice per candidate), a degenerate triangle reaching traversal, sliver triangles hit where
/// the brute force misses them or missed where it hits, any hit stopping at a triangle the ray passes through. The reference (the scene flattened): every triangle intersected one by one, the nearest
/// that stops the ray by its coverage (MASK: alpha against the cutoff; BLEND: PCG4D of (key, triangle, 0x2545F491,
/// seed 0) below alpha). With instances, where the triangles' indices are the instanced packing's, ray queries
/// against the compute BVH, ray by ray.
#[test]
fn alpha_tested_triangles_stop_rays_where_brute_force_says_under_both_traversals() {
    if !common::rt::on_ray_query_driver("alpha_tested_triangles_stop_rays_where_brute_force_says_under_both_traversals")
    {
        return;
    }
    use glam::Vec3;
    use pathwave::bvh::{brute_force, Ray};
    use pathwave::constants::{ALPHA_BLEND, ALPHA_MASK, ALPHA_OPAQUE, NO_HIT};
    use pathwave::render::gpu_scene::try_pack_with;
    use pathwave::render::Traversal;
    use pathwave::scene::Instancing;
    let (_dir, path) = alpha_scene();
    let scene = pathwave::scene::load(&path, None).unwrap();
    let mut rng = common::rng::Rng(11);
    let rays: Vec<Ray> = (0..4000)
        .map(|_| {
            let origin = Vec3::new(rng.next() * 6.0 - 3.0, rng.next() * 2.0 + 0.2, 4.0);
            let target = Vec3::new(rng.next() * 4.4 - 2.2, rng.next() * 1.6, rng.next() * 2.0 - 1.2);
            common::ray_towards(origin, target)
        })
        .collect();
    let trace = |instancing, traversal, any_hit| {
        let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
        let options = pathwave::RendererOptions {
            instancing,
            traversal,
            ..Default::default()
        };
        let mut r = pathwave::Renderer::with_options(&scene, ctx, options).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.traversal(), traversal, "{:?}", r.warnings);
        r.probe_trace_alpha(&rays, any_hit).unwrap()
    };

    // The flattened scene against the brute force.
    let flat = try_pack_with(&scene, Instancing::Never).unwrap();
    let coverage = |tri: usize| {
        let m = &flat.materials[flat.tri_verts[tri].v0[3].to_bits() as usize];
        let alpha = m.base_color[3];
        match m.alpha[0].to_bits() {
            ALPHA_OPAQUE => 1.0,
            ALPHA_MASK => (alpha >= m.alpha[1]) as u32 as f32,
            ALPHA_BLEND => alpha,
            other => panic!("alpha mode {other}"),
        }
    };
    let stops = |tri: usize, key: u32| {
        let c = coverage(tri);
        c >= 1.0 || (c > 0.0 && (pcg4d([key, tri as u32, 0x2545F491, 0])[0] >> 8) as f32 / 16777216.0 < c)
    };
    // The triangle without area is dropped when the scene is packed; the line-shaped sliver and those at the
    // spheres' poles stay, and are checked with every other triangle.
    assert_eq!(
        flat.tri_verts.iter().filter(|t| t.v0[2] == 2.0).count(),
        1,
        "the sliver should reach traversal, the triangle without area not"
    );
    let slivers = (flat.tri_verts.iter())
        .filter(|t| {
            Vec3::from_slice(&t.e1[..3])
                .cross(Vec3::from_slice(&t.e2[..3]))
                .length()
                < 1e-9
        })
        .count();
    assert!(slivers > 0, "the spheres' poles should have sliver triangles");
    // Per ray: the nearest stopping triangle, and whether the ray met a BLEND triangle that let it through.
    let mut passed_blend = 0;
    let mut stopped_blend = 0;
    let reference: Vec<(u32, f32)> = rays
        .iter()
        .enumerate()
        .map(|(key, ray)| {
            let mut best = (NO_HIT, f32::INFINITY);
            let mut met = Vec::new();
            for i in 0..flat.tri_verts.len() {
                let h = brute_force(&flat.tri_verts[i..=i], ray);
                if h.tri == NO_HIT {
                    continue;
                }
                met.push((h.t, i));
                if h.t < best.1 && stops(i, key as u32) {
                    best = (i as u32, h.t);
                }
            }
            for (t, i) in met {
                if coverage(i) > 0.0 && coverage(i) < 1.0 && t <= best.1 {
                    if stops(i, key as u32) {
                        stopped_blend += 1;
                    } else {
                        passed_blend += 1;
                    }
                }
            }
            best
        })
        .collect();
    assert!(
        passed_blend > 300 && stopped_blend > 300,
        "the rays should meet the BLEND sphere often: {passed_blend} passed, {stopped_blend} stopped"
    );
    for traversal in [Traversal::Compute, Traversal::RayQuery] {
        let closest = trace(Instancing::Never, traversal, false);
        let any = trace(Instancing::Never, traversal, true);
        let mut other_tri = 0;
        for (k, ((want, c), a)) in reference.iter().zip(&closest).zip(&any).enumerate() {
            let (tri, t) = *want;
            assert_eq!(
                c.tri == NO_HIT,
                tri == NO_HIT,
                "{traversal:?}, closest hit of ray {k}: {c:?} against {want:?}"
            );
            assert_eq!(
                a.tri == NO_HIT,
                tri == NO_HIT,
                "{traversal:?}, any hit of ray {k}: {a:?} against {want:?}"
            );
            if tri != NO_HIT {
                assert!(
                    (c.t - t).abs() < 2e-5 * t.max(1.0),
                    "{traversal:?}, ray {k}: t {} against {t}",
                    c.t
                );
                other_tri += (c.tri != tri) as usize;
            }
        }
        // Rays through an edge shared by two triangles may take either.
        assert!(
            other_tri * 500 <= rays.len(),
            "{traversal:?}: {other_tri} rays hit another triangle"
        );
    }

    // Instanced: ray queries against the compute BVH, ray by ray (the same keys and triangle indices).
    for any_hit in [false, true] {
        let compute = trace(Instancing::Always, Traversal::Compute, any_hit);
        let rq = trace(Instancing::Always, Traversal::RayQuery, any_hit);
        let mut differ = 0;
        let mut instanced = 0;
        for (k, (c, q)) in compute.iter().zip(&rq).enumerate() {
            assert_eq!(
                c.tri == NO_HIT,
                q.tri == NO_HIT,
                "instanced, any hit {any_hit}, ray {k}: {c:?} against {q:?}"
            );
            if !any_hit && c.tri != NO_HIT {
                assert!(
                    (c.t - q.t).abs() < 2e-5 * c.t.max(1.0),
                    "instanced, ray {k}: t {} against {}",
                    q.t,
                    c.t
                );
                differ += (c.tri != q.tri || c.inst != q.inst) as usize;
                instanced += (c.inst != pathwave::constants::NO_INSTANCE) as usize;
            }
        }
        assert!(
            differ * 500 <= rays.len(),
            "instanced: {differ} rays hit another triangle"
        );
        if !any_hit {
            assert!(instanced > 300, "only {instanced} rays hit an instance");
        }
    }
}

/// Catches a missing barrier around ray-query traversal: the structures' builds before the first trace (a build's
/// writes not made visible to the compute stages that read the top level), and every queue the wavefront and the
/// fused loop hand between stages, on the driver that runs ray queries, for both traversals and both schedules, in
/// a scene with instances and alpha-tested triangles (their candidates leave the query for the shader). The AOV
/// survey and adaptive sampling's plan run too. Every validation message fails the render.
#[test]
fn ray_query_renders_pass_synchronization_validation() {
    if !common::validation_layer_installed() {
        eprintln!("skipped: VK_LAYER_KHRONOS_validation is not installed");
        return;
    }
    if !common::rt::on_ray_query_driver("ray_query_renders_pass_synchronization_validation") {
        return;
    }
    use pathwave::render::Traversal;
    let (_dir, path) = alpha_scene();
    let scene = pathwave::scene::load(&path, None).unwrap();
    for traversal in [Traversal::Compute, Traversal::RayQuery] {
        let ctx = pathwave::vk::Context::new(&Default::default(), pathwave::vk::Validation::Sync).unwrap();
        let options = pathwave::RendererOptions {
            instancing: pathwave::scene::Instancing::Always,
            traversal,
            ..Default::default()
        };
        let mut r = pathwave::Renderer::with_options(&scene, ctx, options).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(r.traversal(), traversal, "{:?}", r.warnings);
        for schedule in [pathwave::Schedule::Wavefront, pathwave::Schedule::Fused] {
            r.set_schedule(schedule);
            let (film, _) = r
                .render(&common::settings(16, 16, 3, 0), &mut |_| {})
                .unwrap_or_else(|e| panic!("{traversal:?}, {schedule:?}: {e}"));
            assert!(film.mean().iter().any(|p| p[0] > 0.0));
            let s = pathwave::RenderSettings {
                aovs: true,
                adaptive: Some(pathwave::Adaptive {
                    threshold: 0.05,
                    pilot: 2,
                }),
                first_sample: 1,
                ..common::settings(16, 16, 6, 0)
            };
            r.render(&s, &mut |_| {})
                .unwrap_or_else(|e| panic!("{traversal:?}, {schedule:?}, AOVs and adaptive: {e}"));
        }
        assert!(r.context().validation_errors().is_empty());
    }
}

/// Catches a ray-query build that overruns the device budget (allocating until the driver fails, or crashing)
/// instead of refusing before it starts: a 180,000-triangle terrain whose buffers fit 24 MiB but whose
/// structures, with their build's scratch and vertices, do not is refused with the sizes named; the compute BVH
/// renders it in the same budget.
#[test]
fn ray_query_structures_past_the_device_budget_are_refused_by_name() {
    if !common::rt::on_ray_query_driver("ray_query_structures_past_the_device_budget_are_refused_by_name") {
        return;
    }
    use pathwave::render::Traversal;
    let scene = pathwave::bench::terrain(300);
    let renderer = |traversal| {
        let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
        let options = pathwave::RendererOptions {
            traversal,
            max_device_memory: Some(24 << 20),
            ..Default::default()
        };
        pathwave::Renderer::with_options(&scene, ctx, options)
    };
    let mut compute = renderer(Traversal::Compute).unwrap_or_else(|e| panic!("the compute BVH should fit: {e}"));
    common::render(&mut compute, &common::settings(8, 8, 1, 0));
    let e = renderer(Traversal::RayQuery)
        .err()
        .expect("the structures should not fit 24 MiB");
    let text = e.to_string();
    assert!(
        text.contains("acceleration structures need") && text.contains("MiB"),
        "{text}"
    );
}
