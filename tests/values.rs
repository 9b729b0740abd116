//! Values and outputs as a careless user or a hostile file gives them: every bad number and environment word refused
//! naming the option or variable, radiance that could overflow refused, degenerate cameras refused, outputs checked
//! before rendering and written all or nothing, non-finite samples kept out of the film, and an interrupted render
//! saved.
mod common;

use common::gltf_builder::{level, square, GltfBuilder, FACING_DOWN, FACING_UP};
use common::{cornell_arg, render_args};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn command(args: &[&str], env: &[(&str, &str)]) -> Command {
    let mut c = common::pathwave_cli();
    c.args(args);
    for (k, v) in env {
        c.env(k, v);
    }
    c
}

fn run(args: &[&str], env: &[(&str, &str)]) -> Output {
    command(args, env).output().expect("the pathwave binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A run that must fail: non-zero exit, no panic, `needle` in the message, nothing left in `dir`.
fn assert_refused(args: &[&str], env: &[(&str, &str)], dir: &Path, needle: &str) {
    let before: Vec<PathBuf> = listing(dir);
    let o = run(args, env);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} {env:?} succeeded; stderr: {err}");
    assert!(!err.contains("panicked"), "{args:?} {env:?} panicked: {err}");
    assert!(err.contains(needle), "{args:?} {env:?}: expected {needle:?} in: {err}");
    assert_eq!(listing(dir), before, "{args:?} {env:?} left files behind");
}

fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    v.sort();
    v
}

#[test]
fn every_bad_number_is_refused_naming_its_option() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let o = out.to_str().unwrap();
    let cases: &[(&str, &str)] = &[
        ("--env-rotation", "NaN"),
        ("--env-rotation", "inf"),
        ("--env-rotation", "1000"),
        ("--exposure", "NaN"),
        ("--exposure", "100"),
        ("--env-intensity", "NaN"),
        ("--env-intensity", "1e38"),
        ("--env-intensity", "-1"),
        ("--aperture", "NaN"),
        ("--aperture", "-1"),
        ("--aperture", "1e30"),
        ("--focus-distance", "0"),
        ("--focus-distance", "-inf"),
        ("--max-depth", "4294967296"),
        ("--max-depth", "two"),
        ("--max-depth", "-1"),
        ("--spp", "0"),
        ("--spp", "99999999"),
        ("--size", "100000x1"),
        ("--size", "10000x10000"),
        ("--camera", "-1"),
        ("--seed", "-1"),
        ("--seed", "4294967296"),
        ("--env-color", "3e38,1,1"),
        ("--env-color", "NaN,1,1"),
        ("--samples", "8..4"),
        ("--samples", "3..3"),
        ("--samples", "0..99999999"),
        ("--samples", "0..4294967296"),
        ("--samples", "-1..4"),
        ("--part", "4/4"),
        ("--part", "0/0"),
        ("--part", "one/4"),
        ("--part", "-1/4"),
        ("--part", "4"),
    ];
    for (option, value) in cases {
        let args = render_args(cornell_arg(), o, &[option, value]);
        assert_refused(&args, &[], dir.path(), option);
    }
    // In range alone, out of range together.
    let args = render_args(cornell_arg(), o, &["--env-color", "1e9,1,1", "--env-intensity", "100"]);
    assert_refused(&args, &[], dir.path(), "--env-color times --env-intensity");
    let args = render_args(cornell_arg(), o, &["--camera", "3"]);
    assert_refused(&args, &[], dir.path(), "--camera 3");
}

#[test]
fn every_bad_environment_word_is_refused_naming_its_variable() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let args = render_args(cornell_arg(), out.to_str().unwrap(), &["--size", "8x8", "--spp", "1"]);
    for (var, value) in [
        ("PATHWAVE_VALIDATION", "yes"),
        ("PATHWAVE_VALIDATION", "2"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "0"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "-5"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "ten"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "1e9"),
        ("PATHWAVE_SCHEDULE", "quick"),
        ("PATHWAVE_BVH_READS", "texture"),
    ] {
        assert_refused(&args, &[(var, value)], dir.path(), &format!("{var}={value}"));
    }
    // The allowed words still render.
    let env = [("PATHWAVE_BVH_READS", "texel"), ("PATHWAVE_GPU_TIMEOUT_SECS", "60")];
    let o = run(&args, &env);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A one-quad scene lit by `light`, with a camera.
fn lit_quad(light: impl FnOnce(&mut GltfBuilder)) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let white = b.material("white", [0.8; 3], [0.0; 3], false);
    b.quad("floor", level([-1.0, 1.0], 0.0, [1.0, -1.0]), white, FACING_UP);
    light(&mut b);
    b.camera([0.0, 1.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 40.0);
    b
}

/// Writes `b` as `name` and checks that rendering it is refused naming `needle`; returns the folder and the output
/// the render was given.
fn assert_render_refused(b: &GltfBuilder, name: &str, needle: &str) -> (tempfile::TempDir, PathBuf) {
    let (dir, scene) = common::write_temp(b, name);
    let out = dir.path().join("out.exr");
    let args = render_args(scene.to_str().unwrap(), out.to_str().unwrap(), &[]);
    assert_refused(&args, &[], dir.path(), needle);
    (dir, out)
}

/// An uncompressed Radiance .hdr of 4x2 texels, every one (r, g, b, e) in RGBE.
fn write_hdr(path: &Path, rgbe: [u8; 4]) {
    let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    for _ in 0..8 {
        bytes.extend_from_slice(&rgbe);
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn radiance_that_could_overflow_is_refused_naming_the_item() {
    let emissive = lit_quad(|b| {
        let hot = b.material("sun", [0.0; 3], [3e38, 3e38, 3e38], false);
        b.quad("lamp", square(0.2, 2.0), hot, FACING_DOWN);
    });
    assert_render_refused(&emissive, "hot.gltf", "material 'sun'");

    let punctual = lit_quad(|b| b.point_light([1.0; 3], 3e38, [0.0, 2.0, 0.0]));
    let (dir, out) = assert_render_refused(&punctual, "hot-point.gltf", "light '#0'");
    let o = out.to_str().unwrap();

    // The largest RGBE exponent: finite (about 1.7e38), and Inf in the image before.
    let sky = dir.path().join("sky.hdr");
    write_hdr(&sky, [255, 255, 255, 255]);
    let args = render_args(cornell_arg(), o, &["--env", sky.to_str().unwrap()]);
    assert_refused(&args, &[], dir.path(), "sky.hdr: texel (0, 0)");
    // A bright but physical map still renders, finite.
    write_hdr(&sky, [128, 128, 128, 140]);
    let args = render_args(
        cornell_arg(),
        o,
        &["--env", sky.to_str().unwrap(), "--size", "8x8", "--spp", "2"],
    );
    let run = run(&args, &[]);
    assert!(run.status.success(), "{}", stderr(&run));
    let (_, _, px) = pathwave::output::read_exr(&out).unwrap();
    assert!(px.iter().flatten().all(|c| c.is_finite()));

    // NaN texels in an EXR map were turned black without a word (max(NaN, 0) is 0): refused, counted and placed.
    let nan_sky = dir.path().join("nan-sky.exr");
    exr::prelude::write_rgb_file(&nan_sky, 4, 2, |x, y| {
        let v = if (x, y) == (1, 0) || (x, y) == (2, 1) {
            f32::NAN
        } else {
            1.0
        };
        (v, 1.0f32, 1.0f32)
    })
    .unwrap();
    let args = render_args(cornell_arg(), o, &["--env", nan_sky.to_str().unwrap()]);
    assert_refused(
        &args,
        &[],
        dir.path(),
        "nan-sky.exr: 2 texels of the environment map are NaN (not a number), the first at (1, 0)",
    );
}

#[test]
fn a_camera_of_scale_zero_is_refused() {
    for (name, transform) in [
        ("flat.gltf", json!({ "scale": [0.0, 0.0, 0.0] })),
        ("squashed.gltf", json!({ "scale": [1.0, 0.0, 1.0] })),
    ] {
        let mut b = lit_quad(|b| {
            let lamp = b.material("lamp", [0.0; 3], [5.0; 3], false);
            b.quad("lamp", square(0.2, 2.0), lamp, FACING_DOWN);
        });
        b.transform_last_node(transform);
        let needle = format!("{name}: camera 0: its node's world transform has scale 0");
        assert_render_refused(&b, name, &needle);
    }
}

#[test]
fn outputs_are_checked_before_rendering_and_written_all_or_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.exr");
    let f = first.to_str().unwrap();
    // --spp 16777216 would take hours: refusing in well under that shows nothing was rendered.
    let slow = ["--spp", "16777216"];
    let start = Instant::now();
    // The first output, then `second`: refused naming `needle`.
    let refused = |second: &str, needle: &str| {
        let args = render_args(cornell_arg(), f, &["-o", second, slow[0], slow[1]]);
        assert_refused(&args, &[], dir.path(), needle);
    };
    let missing = dir.path().join("no/such/dir/second.png");
    refused(missing.to_str().unwrap(), "second.png: directory");
    let a_dir = dir.path().join("folder.png");
    std::fs::create_dir(&a_dir).unwrap();
    refused(a_dir.to_str().unwrap(), "folder.png: is a directory");
    refused("second.jpg", "second.jpg: unknown output format");
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "the outputs were not checked first"
    );

    // A failure at writing time (here a folder that vanished) removes what was already encoded.
    let gone = dir.path().join("gone");
    std::fs::create_dir(&gone).unwrap();
    let second = gone.join("second.png");
    std::fs::remove_dir(&gone).unwrap();
    let err = pathwave::output::write_images(&[first.as_path(), second.as_path()], 2, 1, &[[0.5; 3]; 2], 0.0);
    assert!(err.unwrap_err().to_string().contains("second.png"));
    assert_eq!(
        listing(dir.path()),
        vec![a_dir.clone()],
        "the first output was left behind"
    );
    pathwave::output::write_images(
        &[first.as_path(), a_dir.with_extension("exr").as_path()],
        2,
        1,
        &[[0.5; 3]; 2],
        0.0,
    )
    .unwrap();
    assert!(first.exists());
}

/// A render that took every sample non-finite for even pixels (an edited path.glsl) keeps them out of the film:
/// dropped, counted in the summary, the same bytes from both schedules, and the image finite.
#[test]
fn non_finite_samples_are_dropped_counted_and_the_schedules_agree() {
    let dir = tempfile::tempdir().unwrap();
    let exported = dir.path().join("exported");
    let o = run(&["export-shaders", exported.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let path_glsl = std::fs::read_to_string(exported.join("include/path.glsl")).unwrap();
    let anchor = "    shadow.radiance = Spectrum(0.0);\n";
    assert!(path_glsl.contains(anchor), "path.glsl changed; update this test's edit");
    let poisoned = path_glsl.replacen(
        anchor,
        &format!("{anchor}    if ((pixel & 1u) == 0u) {{ v.radiance = Spectrum(uintBitsToFloat(0x7f800000u)); return false; }}\n"),
        1,
    );
    let mut images = Vec::new();
    for stage in ["shade", "follow"] {
        let folder = dir.path().join(stage);
        std::fs::create_dir_all(folder.join("include")).unwrap();
        std::fs::write(folder.join("include/path.glsl"), &poisoned).unwrap();
        std::fs::copy(
            exported.join(format!("{stage}.comp")),
            folder.join(format!("{stage}.comp")),
        )
        .unwrap();
        let out = dir.path().join(format!("{stage}.exr"));
        let more = ["--size", "16x8", "--spp", "4", "--shader-dir", folder.to_str().unwrap()];
        let o = run(&render_args(cornell_arg(), out.to_str().unwrap(), &more), &[]);
        let err = stderr(&o);
        assert!(o.status.success(), "{err}");
        // Half of 128 pixels, 4 samples each.
        assert!(err.contains("256 non-finite samples dropped"), "{stage}: {err}");
        let (_, _, px) = pathwave::output::read_exr(&out).unwrap();
        assert!(
            px.iter().flatten().all(|c| c.is_finite()),
            "{stage}: the film holds non-finite values"
        );
        assert!(
            px.iter().step_by(2).all(|p| *p == [0.0; 3]),
            "{stage}: a dropped sample is not a zero"
        );
        images.push(std::fs::read(&out).unwrap());
    }
    assert!(images[0] == images[1], "the two schedules differ");
}

/// No project scene yields a single non-finite sample, with either schedule.
#[test]
fn project_scenes_have_no_non_finite_samples() {
    let mut scenes: Vec<PathBuf> = listing(&common::scenes_dir())
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "gltf"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 8);
    let settings = common::settings(24, 16, 4, 1);
    for path in scenes {
        let mut r = common::renderer(&path);
        let (_, stats) = r.render(&settings, &mut |_| {}).unwrap();
        assert_eq!(stats.nonfinite, 0, "{}: {}", path.display(), stats.summary());
    }
}

/// SIGTERM during a long render: the samples done so far are written as a valid EXR, with a message saying how many,
/// and the exit is non-zero.
#[test]
fn sigterm_writes_the_samples_done_so_far() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("partial.exr");
    let args = render_args(
        cornell_arg(),
        out.to_str().unwrap(),
        &["--size", "32x32", "--spp", "1000000"],
    );
    // A signal before the render begins (loading, compiling) ends the process without an image, as it should; so
    // wait longer on a slow machine rather than fail.
    for wait in [3u64, 8, 20] {
        let mut child = command(&args, &[]).stderr(Stdio::piped()).spawn().unwrap();
        std::thread::sleep(Duration::from_secs(wait));
        let kill = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let start = Instant::now();
        while child.try_wait().unwrap().is_none() {
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "the render did not stop after SIGTERM"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert!(!o.status.success(), "an interrupted render exited 0: {err}");
        assert!(!err.contains("panicked"), "{err}");
        if !out.exists() {
            assert!(err.contains("interrupted"), "{err}");
            continue;
        }
        assert!(err.contains("of 1000000 samples per pixel"), "{err}");
        let (w, h, px) = pathwave::output::read_exr(&out).unwrap();
        assert_eq!((w, h), (32, 32));
        assert!(px.iter().flatten().all(|c| c.is_finite()));
        assert!(px.iter().flatten().any(|c| *c > 0.0), "the partial image is black");
        return;
    }
    panic!("the render never got past loading within 20 s");
}

/// The library refuses what the CLI would: an environment built by a caller with a NaN rotation or radiance past
/// the limit.
#[test]
fn the_renderer_refuses_an_environment_it_cannot_render() {
    let mut scene = pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    let mut nan_rotation = pathwave::scene::Environment::constant([1.0; 3]);
    nan_rotation.rotation = f32::NAN;
    for (env, needle) in [
        (nan_rotation, "rotation NaN"),
        (pathwave::scene::Environment::constant([3e38, 1.0, 1.0]), "radiance"),
        (pathwave::scene::Environment::constant([f32::INFINITY; 3]), "radiance"),
    ] {
        scene.environment = Some(env);
        let r = pathwave::Renderer::with_validation(&scene, &pathwave::vk::DeviceChoice::Best, common::validation());
        let err = r.err().expect("the renderer took the environment").to_string();
        assert!(err.contains("the environment: ") && err.contains(needle), "{err}");
    }
}
