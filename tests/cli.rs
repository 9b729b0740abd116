//! The command line as a user meets it: renders, determinism of the written file, and every kind of bad input.
mod common;

use common::gltf_builder::{square, upright, GltfBuilder, FACING_UP};
use common::{cornell_arg, render_args};
use std::path::{Path, PathBuf};
use std::process::Output;

fn pathwave(args: &[&str]) -> Output {
    common::pathwave_cli()
        .args(args)
        .output()
        .expect("the pathwave binary runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs a render that must fail: non-zero exit, no panic, a message containing `needle`, and no output file.
fn assert_refused(args: &[&str], out: &Path, needle: &str) {
    let o = pathwave(args);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded; stderr: {err}");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: message should mention {needle:?}, got: {err}"
    );
    assert!(!out.exists(), "{args:?} left an output file behind");
    let leftovers: Vec<PathBuf> = match std::fs::read_dir(out.parent().unwrap()) {
        Ok(dir) => dir
            .map(|e| e.unwrap().path())
            .filter(|p| p.to_string_lossy().contains(".pathwave-"))
            .collect(),
        Err(_) => Vec::new(), // the directory itself does not exist
    };
    assert!(leftovers.is_empty(), "temporary files left behind: {leftovers:?}");
}

#[test]
fn renders_the_cornell_box_to_exr_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("cb.exr");
    let more = ["--size", "40x30", "--spp", "8"];
    let o = pathwave(&render_args(cornell_arg(), exr.to_str().unwrap(), &more));
    assert!(o.status.success(), "{}", stderr(&o));
    let summary = stderr(&o);
    for word in ["samples/s", "Mrays/s", "GPU ms", "accumulate"] {
        assert!(summary.contains(word), "the summary line lacks {word}: {summary}");
    }
    // Whichever schedule ran, its stages are timed: the wavefront's three per bounce, or follow.
    let wavefront = ["extend", "shade", "connect"].iter().all(|w| summary.contains(w));
    assert!(
        wavefront || summary.contains("follow"),
        "the summary line lacks the stages: {summary}"
    );
    // Written through a private temporary file, the image still gets a new file's permissions (0666 less the umask).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let fresh = exr.with_file_name("fresh");
        std::fs::write(&fresh, b"").unwrap();
        let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(
            mode(&exr),
            mode(&fresh),
            "the image's permissions are not those of a new file"
        );
    }
    let (w, h, px) = pathwave::output::read_exr(&exr).unwrap();
    assert_eq!((w, h), (40, 30));
    let mean: f64 = px.iter().map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0).sum::<f64>() / px.len() as f64;
    // The box's walls are lit to roughly 0.1-1 W sr^-1 m^-2 and the light itself is ~11: a mean in [0.05, 2] is plausible.
    assert!((0.05..2.0).contains(&mean), "implausible Cornell box mean {mean}");
    assert!(px.iter().all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
    // Row 0 is the top: the light is on the ceiling, so the brightest pixel is in the top fifth.
    let brightest = px
        .iter()
        .enumerate()
        .max_by(|a, b| a.1[0].total_cmp(&b.1[0]))
        .unwrap()
        .0;
    assert!(
        brightest / 40 < 6,
        "brightest pixel is in row {}; the image is upside down?",
        brightest / 40
    );

    let png = dir.path().join("cb.png");
    let more = ["--size", "16x16", "--spp", "2"];
    let o = pathwave(&render_args(cornell_arg(), png.to_str().unwrap(), &more));
    assert!(o.status.success(), "{}", stderr(&o));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let info = decoder.read_info().unwrap().info().clone();
    assert_eq!((info.width, info.height), (16, 16));
}

#[test]
fn same_seed_same_bytes_other_seed_other_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, seed: &str| {
        let p = dir.path().join(name);
        let more = ["--size", "192x144", "--spp", "2", "--seed", seed];
        let o = pathwave(&render_args(cornell_arg(), p.to_str().unwrap(), &more));
        assert!(o.status.success(), "{}", stderr(&o));
        std::fs::read(p).unwrap()
    };
    // Large enough for many EXR chunks: a writer that stores them as they finish compressing differs from run to run.
    let a = run("a.exr", "1");
    let b = run("b.exr", "1");
    let b2 = run("b2.exr", "1");
    let c = run("c.exr", "2");
    assert!(a == b && a == b2, "the same seed gave different bytes");
    assert!(a != c, "a different seed gave the same bytes");
}

#[test]
fn bad_inputs_are_refused_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.exr");
    let o = out.to_str().unwrap();
    // `render SCENE -o out.exr MORE` must be refused naming `needle`.
    let refused = |scene: &Path, more: &[&str], needle: &str| {
        assert_refused(&render_args(scene.to_str().unwrap(), o, more), &out, needle)
    };

    refused(&d.join("missing.gltf"), &[], "missing.gltf: file not found");

    let not_gltf = d.join("notes.gltf");
    std::fs::write(&not_gltf, "these are not the droids").unwrap();
    refused(&not_gltf, &[], "notes.gltf: not a valid glTF");

    let truncated = d.join("truncated.gltf");
    let text = std::fs::read_to_string(common::cornell()).unwrap();
    std::fs::write(&truncated, &text[..text.len() / 2]).unwrap();
    refused(&truncated, &[], "truncated.gltf: not a valid glTF");

    let no_bin = d.join("no-bin.gltf");
    let start = text.find("data:application/octet-stream;base64,").unwrap();
    let end = start + text[start..].find('"').unwrap();
    std::fs::write(&no_bin, format!("{}missing.bin{}", &text[..start], &text[end..])).unwrap();
    let needle = "no-bin.gltf: buffer 0 (missing.bin): cannot load buffer data";
    refused(&no_bin, &[], needle);

    let no_tris = d.join("no-triangles.gltf");
    std::fs::write(
        &no_tris,
        r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"name":"empty"}]}"#,
    )
    .unwrap();
    refused(&no_tris, &[], "no-triangles.gltf: the scene has no triangles");

    let cornell = common::cornell();
    refused(&cornell, &["--size", "0x0"], "--size");
    refused(&cornell, &["--spp", "-1"], "--spp");
    refused(&cornell, &["--size", "big"], "WIDTHxHEIGHT");
    let txt = d.join("out.txt");
    let args = render_args(cornell_arg(), txt.to_str().unwrap(), &[]);
    assert_refused(&args, &txt, ".exr or .png");
    let nodir = d.join("no/such/dir/out.exr");
    let args = render_args(cornell_arg(), nodir.to_str().unwrap(), &["--size", "8x8", "--spp", "1"]);
    assert_refused(&args, &nodir, "does not exist");
    refused(&cornell, &["--device", "no-such-gpu"], "no device matches");
    let sky = d.join("sky.hdr");
    refused(&cornell, &["--env", sky.to_str().unwrap()], "sky.hdr: cannot read");
    let txt_env = d.join("sky.txt");
    std::fs::write(&txt_env, "not an image").unwrap();
    let needle = "must be .hdr, .exr, .png, .jpg or .jpeg";
    refused(&cornell, &["--env", txt_env.to_str().unwrap()], needle);
    refused(&cornell, &["--env-color", "1,2"], "R,G,B");
    let more = ["--env-color", "1,1,1", "--env-intensity", "-2"];
    refused(&cornell, &more, "intensity");
}

#[test]
fn a_scene_without_lights_renders_black_with_a_warning() {
    let mut b = GltfBuilder::new();
    let m = b.material("grey", [0.5; 3], [0.0; 3], false);
    b.quad("floor", square(1.0, 0.0), m, FACING_UP);
    let (dir, path) = common::write_temp(&b, "dark.gltf");
    let out = dir.path().join("dark.exr");
    let more = ["--size", "8x8", "--spp", "2"];
    let o = pathwave(&render_args(path.to_str().unwrap(), out.to_str().unwrap(), &more));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("no emissive surface"),
        "missing the no-light warning: {err}"
    );
    assert!(
        err.contains("the file has no camera"),
        "missing the no-camera warning: {err}"
    );
    let (_, _, px) = pathwave::output::read_exr(&out).unwrap();
    assert!(px.iter().all(|p| *p == [0.0; 3]));
}

#[test]
fn info_describes_scene_and_devices() {
    let o = pathwave(&["info", cornell_arg()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(text.contains("triangles   32"), "{text}");
    assert!(text.contains("lights      2 emissive triangles"), "{text}");
    assert!(text.contains("SAH cost"), "{text}");
    let o = pathwave(&["info", "--devices"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("0: "), "no device listed");
}

#[test]
fn environment_lights_the_scene_and_hide_env_keeps_it_from_the_camera() {
    // A floor seen from above with the sky behind it: the top rows see only the environment.
    let mut b = GltfBuilder::new();
    let m = b.material("grey", [0.5; 3], [0.0; 3], false);
    b.quad("floor", square(10.0, 0.0), m, FACING_UP);
    b.camera([0.0, 0.5, 3.0], [0.0, 0.3, 0.0], [0.0, 1.0, 0.0], 40.0);
    let (dir, path) = common::write_temp(&b, "floor.gltf");
    let run = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = render_args(
            path.to_str().unwrap(),
            out.to_str().unwrap(),
            &["--size", "16x16", "--spp", "8"],
        );
        args.extend_from_slice(extra);
        let o = pathwave(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(!stderr(&o).contains("nothing lights it"), "the environment is a light");
        pathwave::output::read_exr(&out).unwrap().2
    };
    let seen = run("seen.exr", &["--env-color", "0.2,0.4,0.8"]);
    let hidden = run("hidden.exr", &["--env-color", "0.2,0.4,0.8", "--hide-env"]);
    let sky = [0.2, 0.4, 0.8];
    assert!(
        (0..3).all(|c| (seen[0][c] - sky[c]).abs() < 1e-6),
        "the top-left pixel sees the sky: {:?}",
        seen[0]
    );
    assert_eq!(hidden[0], [0.0; 3], "--hide-env keeps the sky out of camera rays");
    let floor = 15 * 16 + 8;
    assert!(
        hidden[floor][2] > 0.0 && hidden[floor] == seen[floor],
        "the floor is lit the same either way"
    );
}

/// `pathwave bench --quick` runs every case and writes JSON with a positive figure for each measurement.
#[test]
fn bench_compare_names_a_missing_python() {
    let o = pathwave(&[
        "bench",
        "--compare",
        "embree",
        "--only-compare",
        "--quick",
        "--python",
        "/nonexistent/python3",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("cannot run /nonexistent/python3"), "{e}");
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn bench_reports_every_case() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("bench.json");
    let o = pathwave(&["bench", "--quick", "--json", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(&json).unwrap()).unwrap();
    assert!(v["startup_s"].as_f64().unwrap() > 0.0);
    let cases = v["cases"].as_array().unwrap();
    let names: Vec<&str> = cases.iter().map(|c| c["name"].as_str().unwrap()).collect();
    assert_eq!(
        names[..],
        [
            "cornell-box",
            "cornell-storage",
            "cornell-fused",
            "cornell-wavefront",
            "cornell-spectral",
            "glass",
            "textured-props",
            "textured-props-bilinear",
            "terrain-32k",
            "terrain-storage",
            "instances-400x3k"
        ],
        "{names:?}"
    );
    for c in cases {
        for key in [
            "render_s",
            "samples_per_s",
            "extension_rays_per_s",
            "bvh_build_s",
            "bytes_per_triangle",
            "image_mean",
        ] {
            assert!(c[key].as_f64().unwrap() > 0.0, "{}: {key} is {}", c["name"], c[key]);
        }
        assert!(table.contains(c["name"].as_str().unwrap()), "{table}");
    }
    assert!(cases[8]["triangles"].as_u64().unwrap() > 30_000);
    let stages = |k: usize| {
        cases[k]["stage_ms"]
            .as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect::<Vec<_>>()
    };
    assert_eq!(cases[2]["schedule"], "fused");
    assert!(stages(2).contains(&"follow".to_string()), "{:?}", stages(2));
    assert_eq!(cases[3]["schedule"], "wavefront");
    for s in ["generate", "extend", "shade", "connect", "accumulate"] {
        assert!(stages(3).contains(&s.to_string()), "{:?}", stages(3));
    }
}

#[test]
fn dispersion_renders_spectrally_unless_rgb_is_asked_for() {
    let dir = tempfile::tempdir().unwrap();
    let prism = common::scenes_dir().join("prism.gltf").display().to_string();
    let out = |name: &str| dir.path().join(name).display().to_string();
    let run = |extra: &[&str], name: &str| {
        let o = out(name);
        let mut args = vec![
            "render",
            prism.as_str(),
            "--size",
            "24x16",
            "--spp",
            "2",
            "-o",
            o.as_str(),
        ];
        args.extend_from_slice(extra);
        let r = pathwave(&args);
        assert!(r.status.success(), "{args:?}: {}", stderr(&r));
        (stderr(&r), std::fs::read(&o).unwrap())
    };
    let (said, spectral) = run(&[], "default.png");
    assert!(
        said.contains("rendering spectrally"),
        "a dispersive scene should say it renders spectrally: {said}"
    );
    let (said, rgb) = run(&["--rgb"], "rgb.png");
    assert!(
        said.contains("warning") && said.contains("dispersion"),
        "--rgb should warn: {said}"
    );
    let (_, forced) = run(&["--spectral"], "spectral.png");
    assert_eq!(spectral, forced, "--spectral on a dispersive scene is its default");
    assert_ne!(spectral, rgb, "--rgb changed nothing");
    let (said, _) = run(&["--spectral"], "quiet.png");
    assert!(!said.contains("warning"), "--spectral needs no warning: {said}");
    let o = out("both.png");
    assert_refused(
        &["render", prism.as_str(), "--spectral", "--rgb", "-o", o.as_str()],
        Path::new(&o),
        "cannot be used with",
    );
}

/// `info FOLDER` takes a census: every .gltf and .glb under it loads or is refused on a line of its own (a bad file
/// does not end the census), then the extensions and a summary line.
#[test]
fn info_takes_a_census_of_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let nested = dir.path().join("nested");
    std::fs::create_dir(&nested).unwrap();
    let mut b = GltfBuilder::new();
    let m = b.material("m", [0.5; 3], [1.0; 3], false);
    b.quad("q", upright([0.0, 1.0], [0.0, 1.0], 0.0), m, None);
    b.write(&dir.path().join("quad.gltf"));
    std::fs::write(nested.join("quad.glb"), b.to_glb()).unwrap();
    std::fs::write(nested.join("junk.gltf"), "not json").unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not a scene").unwrap();
    let o = pathwave(&["info", dir.path().to_str().unwrap()]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(text.contains("loads    quad.gltf: 2 triangles"), "{text}");
    assert!(text.contains("loads    nested/quad.glb: 2 triangles"), "{text}");
    assert!(text.contains("refused  nested/junk.gltf: "), "{text}");
    assert!(
        text.contains("extension   KHR_materials_specular: 2 of the files that load, supported"),
        "{text}"
    );
    assert!(text.contains("census: 2 of 3 files load"), "{text}");
}
