//! Ray-query traversal's ground: the second lavapipe (Mesa >= 24.1 from the backports suite, fetched by
//! ci/lavapipe-rt.sh into the user's cache) exposes VK_KHR_ray_query beside the system's driver, and pathwave tells
//! them apart. Tests that need ray queries run pathwave under that driver's ICD file.
mod common;

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
/// 5 % plus 200 (the seeds' noise; each render traces thousands). The case CI runs, textured.gltf with every mesh
/// instanced, has textures, alpha (MASK and BLEND) and instances at once; each render there compiles its pipelines
/// afresh (about 30 s on 2 cores), so the sweep of every project scene, plus glass.gltf instanced under the fused
/// schedule, runs under PATHWAVE_TEST_EVERY_SCENE=1 (18 of 18 and the fused case agreed on 2026-12-06). Catches:
/// hits on the wrong triangle or instance (wrong materials and normals), lost alpha coverage, barycentrics off
/// (textures and normals), offsets that let a ray hit its own surface again (shadow acne darkens, ray counts grow),
/// one-sided triangles culled, a stage variant built without ray queries.
#[test]
fn project_scenes_render_alike_with_ray_queries_and_the_compute_bvh() {
    let icd = common::rt::icd();
    let out = tempfile::tempdir().unwrap();
    // (scene, PATHWAVE_INSTANCING, PATHWAVE_SCHEDULE)
    let mut cases: Vec<(String, &str, &str)> = vec![("textured".into(), "always", "wavefront")];
    if std::env::var_os("PATHWAVE_TEST_EVERY_SCENE").is_some() {
        let every = std::fs::read_dir(common::scenes_dir())
            .unwrap()
            .map(|e| e.unwrap().path());
        let every = every.filter(|p| p.extension().is_some_and(|e| e == "gltf"));
        cases = every
            .map(|p| {
                (
                    p.file_stem().unwrap().to_string_lossy().into_owned(),
                    "auto",
                    "wavefront",
                )
            })
            .collect();
        cases.sort();
        cases.push(("glass".into(), "always", "fused"));
    }
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
