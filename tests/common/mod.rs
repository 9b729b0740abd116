//! Helpers shared by the integration tests.
#![allow(dead_code)]
pub mod gltf_builder;
pub mod mutate;
pub mod rng;
pub mod rt;
pub mod scenes;
pub mod screen;
pub mod stats;

use std::path::PathBuf;

/// Tests run with the validation layer when it is installed (a render then fails on any of its errors);
/// PATHWAVE_VALIDATION=0 turns it off, =sync adds synchronization checks.
pub fn validation() -> pathwave::vk::Validation {
    use pathwave::vk::Validation;
    match std::env::var("PATHWAVE_VALIDATION").as_deref() {
        Ok("0") | Ok("off") => Validation::Off,
        Ok("sync") => Validation::Sync,
        _ if validation_layer_installed() => Validation::On,
        _ => {
            eprintln!("note: VK_LAYER_KHRONOS_validation is not installed; running without validation");
            Validation::Off
        }
    }
}

/// A renderer for a scene file on the best device, with the tests' validation setting.
pub fn renderer(path: &std::path::Path) -> pathwave::Renderer {
    scene_renderer(&pathwave::scene::load(path, None).unwrap_or_else(|e| panic!("{e}")))
}

/// A renderer for a scene on the best device, with the tests' validation setting.
pub fn scene_renderer(scene: &pathwave::scene::Scene) -> pathwave::Renderer {
    pathwave::Renderer::with_validation(scene, &pathwave::vk::DeviceChoice::Best, validation())
        .unwrap_or_else(|e| panic!("{e}"))
}

/// A Lambertian: the default material with neither metal nor a specular layer.
pub fn lambert() -> pathwave::scene::Material {
    pathwave::scene::Material {
        metallic: 0.0,
        specular: 0.0,
        ..Default::default()
    }
}

/// A faceted (or smooth) unit sphere of `material` filling a 30° view from distance 3, in a uniform environment of
/// `env`: the white furnace's scene (tests/environment.rs, tests/spectral.rs).
pub fn sphere_in_environment(
    material: pathwave::scene::Material,
    env: [f32; 3],
    smooth: bool,
) -> pathwave::scene::Scene {
    let mut b = gltf_builder::GltfBuilder::new();
    let m = b.material("placeholder", [1.0; 3], [0.0; 3], false);
    b.uv_sphere("sphere", [0.0; 3], 1.0, m, smooth);
    b.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 30.0);
    let (_dir, path) = write_temp(&b, "sphere.gltf");
    let mut scene = pathwave::scene::load(&path, None).unwrap();
    scene.materials[0] = material;
    scene.environment = Some(pathwave::scene::Environment::constant(env));
    scene
}

pub fn settings(width: u32, height: u32, spp: u32, seed: u32) -> pathwave::RenderSettings {
    pathwave::RenderSettings {
        width,
        height,
        spp,
        seed,
        ..Default::default()
    }
}

pub fn render(r: &mut pathwave::Renderer, s: &pathwave::RenderSettings) -> pathwave::Film {
    let (film, stats) = r.render(s, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{}x{} {} spp: {}", s.width, s.height, s.spp, stats.summary());
    film
}

pub fn validation_layer_installed() -> bool {
    [
        "/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json",
        "/etc/vulkan/explicit_layer.d/VkLayer_khronos_validation.json",
    ]
    .iter()
    .any(|p| std::path::Path::new(p).exists())
}

/// The pathwave binary, with the validation layer on when the tests run with it.
pub fn pathwave_cli() -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_pathwave"));
    if validation() == pathwave::vk::Validation::On {
        c.env("PATHWAVE_VALIDATION", "1");
    }
    c
}

/// The project's Cornell box.
pub fn cornell() -> PathBuf {
    scenes_dir().join("cornell-box.gltf")
}

/// Loads the scene `b` builds (written as `name` in a temporary folder), which must load without warnings.
pub fn load_built(b: &gltf_builder::GltfBuilder, name: &str) -> pathwave::scene::Scene {
    let (_dir, path) = write_temp(b, name);
    let scene = pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    scene
}

/// The Cornell box's path as a command-line argument.
pub fn cornell_arg() -> &'static str {
    static ARG: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    ARG.get_or_init(|| cornell().display().to_string())
}

/// The arguments of `pathwave render SCENE -o OUT` followed by `more`.
pub fn render_args<'a>(scene: &'a str, out: &'a str, more: &[&'a str]) -> Vec<&'a str> {
    [&["render", scene, "-o", out][..], more].concat()
}

/// Puts `glsl` into shade.comp in the exported shader folder `dir`, just before the path's vertex is declared.
pub fn insert_into_shade(dir: &std::path::Path, glsl: &str) {
    let path = dir.join("shade.comp");
    let src = std::fs::read_to_string(&path).unwrap();
    let anchor = "    PathVertex v;";
    assert!(src.contains(anchor), "shade.comp changed; update this test's anchor");
    std::fs::write(&path, src.replacen(anchor, &format!("{glsl}{anchor}"), 1)).unwrap();
}

/// Removes every stage but shade.comp from the exported shader folder `dir`: only the stage under test is
/// overridden.
pub fn keep_only_shade(dir: &std::path::Path) {
    for f in std::fs::read_dir(dir).unwrap() {
        let p = f.unwrap().path();
        if p.extension().is_some_and(|e| e == "comp") && !p.ends_with("shade.comp") {
            std::fs::remove_file(p).unwrap();
        }
    }
}

/// The Khronos glTF-Validator's test files, in shared/ beside the repository (absent: the tests that read it skip).
pub const CORPUS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/gltf-validator-corpus");

/// Every .gltf and .glb under `dir`, in sorted order, depth first.
pub fn corpus_files(dir: &std::path::Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            corpus_files(&p, out);
        } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
            out.push(p);
        }
    }
}

pub fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// Writes a built scene into a fresh temporary directory and returns (dir guard, path).
pub fn write_temp(b: &gltf_builder::GltfBuilder, name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    b.write(&path);
    (dir, path)
}

/// A ray from `origin` through `target`, unbounded.
pub fn ray_towards(origin: glam::Vec3, target: glam::Vec3) -> pathwave::bvh::Ray {
    pathwave::bvh::Ray {
        origin,
        dir: (target - origin).normalize(),
        tmin: 0.0,
        tmax: f32::INFINITY,
    }
}

/// The scene's triangles where its animation places them at `time` (a fraction of its shutter), posed at that very
/// time: the exact placement, independent of how the renderer interpolates between the shutter's keys.
pub fn exact_tri_verts(scene: &pathwave::scene::Scene, time: f32) -> Vec<pathwave::layout::TriVerts> {
    let shutter = scene.motion.as_ref().expect("the scene moves").shutter;
    let opening = scene.rig.posed;
    let mut at = scene.clone();
    at.pose(pathwave::scene::PoseTime {
        time: opening.time + time * shutter,
        ..opening
    })
    .unwrap();
    let (soup, _) = at.try_flatten_motion().unwrap();
    (soup.positions().iter())
        .map(|t| pathwave::layout::TriVerts {
            v0: t[0].extend(0.0).to_array(),
            e1: (t[1] - t[0]).extend(0.0).to_array(),
            e2: (t[2] - t[0]).extend(0.0).to_array(),
        })
        .collect()
}

/// Every triangle of a moving scene, flattened, at shutter position `x` (in segments) as the device should place it:
/// its keys on either side, linearly between (the reference moving traversals are checked against by brute force).
pub fn posed_tri_verts(scene: &pathwave::scene::Scene, x: f32) -> Vec<pathwave::layout::TriVerts> {
    let (soup, keys) = scene.try_flatten_motion().unwrap();
    let keys = keys.expect("the scene moves");
    let k = (x as usize).min(keys.len() - 1);
    let f = x - k as f32;
    let key = |k: usize, i: usize| {
        if k == 0 {
            soup.positions()[i]
        } else {
            keys[k - 1][i].positions
        }
    };
    (0..soup.len())
        .map(|i| {
            let (a, b) = (key(k, i), key(k + 1, i));
            let t = [0, 1, 2].map(|v| a[v] + (b[v] - a[v]) * f);
            pathwave::layout::TriVerts {
                v0: t[0].extend(0.0).to_array(),
                e1: (t[1] - t[0]).extend(0.0).to_array(),
                e2: (t[2] - t[0]).extend(0.0).to_array(),
            }
        })
        .collect()
}
