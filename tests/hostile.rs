//! The hostile-input matrix: well over a hundred inputs an attacker or a careless user gives pathwave (bad numbers,
//! bad words, bad files, malformed and extreme scenes, bad outputs), each run as the CLI runs it, within a time
//! bound. Every one must end in `error: ...` naming what is wrong, exit code 1 (no signal, no panic), and no output
//! file; the extreme-but-valid ones must render a finite image. The per-class tests (values, inputs, bounds,
//! mutations) go deeper; this is the one place that runs them all side by side and counts them.
mod common;

use common::gltf_builder::{square, GltfBuilder, FACING_DOWN, FACING_UP};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Stdio;
use std::time::{Duration, Instant};

/// An edit of the scene's JSON.
type Edit = Box<dyn Fn(&mut Value) + Send + Sync>;

/// One input: CLI arguments (SCENE and OUT are replaced by the case's files), environment, the words the error
/// must contain (None: the run must succeed), and an optional scene JSON edit.
struct Case {
    args: Vec<String>,
    env: Vec<(&'static str, String)>,
    needle: Option<&'static str>,
    scene: Option<Edit>,
}

fn case(args: &[&str], needle: &'static str) -> Case {
    Case {
        args: args.iter().map(|s| s.to_string()).collect(),
        env: Vec::new(),
        needle: Some(needle),
        scene: None,
    }
}

fn scene_case(needle: &'static str, edit: impl Fn(&mut Value) + Send + Sync + 'static) -> Case {
    Case {
        scene: Some(Box::new(edit)),
        ..case(&["render", "SCENE", "-o", "OUT", "--size", "8x8", "--spp", "1"], needle)
    }
}

fn base_scene() -> Value {
    serde_json::from_str(&base_builder().to_json()).unwrap()
}

fn base_builder() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let light = b.material("light", [0.8; 3], [4.0; 3], false);
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    b.quad("lamp", square(1.0, 2.0), light, FACING_DOWN);
    b.quad("floor", square(1.0, 0.0), white, FACING_UP);
    b.camera([0.0, 1.0, 3.0], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 50.0);
    b.slide("a", 1, [0.0, 1.0], [0.0, 0.0, 0.0], [0.1, 0.0, 0.0]);
    b
}

fn cases() -> Vec<Case> {
    let render = |extra: &[&str], needle| {
        let mut a = vec!["render", "SCENE", "-o", "OUT", "--size", "8x8", "--spp", "1"];
        a.extend_from_slice(extra);
        case(&a, needle)
    };
    let mut v = Vec::new();
    // Numbers: every numeric option, not finite, negative, out of range, not a number.
    for (opt, bads) in [
        ("--spp", &["0", "-1", "16777217", "NaN", "1e3", "x"][..]),
        ("--size", &["0x0", "8", "-8x8", "70000x1", "65536x65536", "NaNxNaN"]),
        ("--max-depth", &["-1", "4294967296", "NaN"]),
        ("--exposure", &["NaN", "inf", "65", "-65"]),
        ("--env-rotation", &["NaN", "361", "-inf"]),
        ("--env-intensity", &["NaN", "-1", "1e11"]),
        ("--aperture", &["NaN", "-0.1", "1e19"]),
        ("--focus-distance", &["0", "-1", "NaN"]),
        ("--seed", &["-1", "4294967296", "one"]),
        ("--camera", &["7", "-1"]),
        ("--time", &["NaN", "inf", "1e30"]),
        ("--shutter", &["-1", "NaN", "4000"]),
        ("--max-memory", &["0", "-1G", "1.5G", "99999999999T"]),
        ("--max-texture-pixels", &["0", "-5"]),
        ("--yfov", &["0", "180", "-10", "NaN", "inf"]),
        (
            "--orbit",
            &["0,90,1", "0,-90,1", "361,0,1", "0,0,0", "0,0,-1", "NaN,0,1", "1,2"],
        ),
        ("--up", &["0,0,0", "1,inf,0", "1,1"]),
        ("--tonemap", &["filmic", ""]),
    ] {
        for bad in bads {
            let needle = if opt == "--camera" && *bad == "7" {
                "--camera 7"
            } else {
                opt
            };
            v.push(render(&[opt, bad], needle));
        }
    }
    for bad in ["NaN,1,1", "1,1", "-1,0,0", "3e38,1,1", "a,b,c"] {
        v.push(render(&["--env-color", bad], "--env-color"));
    }
    // A command-line camera: points, their pairing and a view that has no image direction.
    for (args, needle) in [
        (&["--eye", "NaN,0,0", "--target", "0,0,0"][..], "--eye"),
        (&["--eye", "0,0,1e19", "--target", "0,0,0"], "--eye"),
        (&["--eye", "0,0,1"], "--target"),
        (&["--eye", "0,0,1", "--target", "0,0,0", "--orbit", "0,0,1"], "--orbit"),
        (&["--eye", "1,2,3", "--target", "1,2,3"], "one point"),
        (&["--eye", "0,5,0", "--target", "0,0,0"], "parallel"),
        (&["--eye", "0,0,5", "--target", "0,0,0", "--up", "0,0,1"], "parallel"),
    ] {
        v.push(render(args, needle));
    }
    for (args, needle) in [
        (&["--frames", "3..1"][..], "--frames"),
        (&["--frames", "0..3"], "run of #"),
        (&["--frames", "0..2000000"], "--frames"),
        (&["--frames", "0..2", "--fps", "0"], "--fps"),
        (&["--frames", "0..2", "--fps", "NaN"], "--fps"),
        (&["--fps", "30"], "--frames"),
        (&["--resume"], "--frames"),
        (&["--animation", "nope"], "--animation nope"),
        (&["--animation", "9"], "--animation 9"),
        (&["--watch"], "--shader-dir"),
    ] {
        v.push(render(args, needle));
    }
    // Words: every environment variable's wrong word.
    for (var, bad) in [
        ("PATHWAVE_SCHEDULE", "fast"),
        ("PATHWAVE_BVH_READS", "mmap"),
        ("PATHWAVE_INSTANCING", "sometimes"),
        ("PATHWAVE_VALIDATION", "maybe"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "0"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "-5"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "ten"),
        ("PATHWAVE_GPU_TIMEOUT_SECS", "99999999999"),
    ] {
        let mut c = render(&[], var);
        c.env.push((var, bad.to_string()));
        v.push(c);
    }
    // Files: what the scene or map path may name.
    for (path, needle) in [
        ("/dev/zero", "regular file"),
        ("/tmp", "regular file"),
        ("/nonexistent/scene.gltf", "scene.gltf"),
        ("FIFO", "regular file"),
        ("EMPTY", "not a valid glTF"),
        ("JUNK", "not a valid glTF"),
        ("TRUNCATED_GLB", "GLB"),
    ] {
        v.push(case(
            &["render", path, "-o", "OUT", "--size", "8x8", "--spp", "1"],
            needle,
        ));
    }
    for (map, needle) in [
        ("/dev/zero", "/dev/zero"),
        ("FIFO_HDR", "regular file"),
        ("JUNK_HDR", "junk.hdr"),
        ("/nonexistent.hdr", "nonexistent.hdr"),
        ("JUNK", "must be .hdr, .exr, .png, .jpg or .jpeg"),
    ] {
        v.push(render(&["--env", map], needle));
    }
    // Outputs.
    for (out, needle) in [
        ("/nonexistent/dir/x.png", "nonexistent"),
        ("OUTDIR/x.tiff", "unknown output format"),
        ("OUTDIR/noext", "unknown output format"),
        ("/proc/x.png", "/proc"),
    ] {
        v.push(case(
            &["render", "SCENE", "-o", out, "--size", "8x8", "--spp", "1"],
            needle,
        ));
    }
    v.push(case(
        &[
            "render",
            "SCENE",
            "-o",
            "OUT",
            "-o",
            "/nonexistent/y.exr",
            "--size",
            "8x8",
            "--spp",
            "1",
        ],
        "nonexistent",
    ));
    // Scenes: malformed or hostile JSON.
    let set = |path: &'static str, value: Value| {
        move |doc: &mut Value| {
            let mut at = &mut *doc;
            for key in path.split('/') {
                at = match key.parse::<usize>() {
                    Ok(i) => &mut at[i],
                    Err(_) => &mut at[key],
                };
            }
            *at = value.clone();
        }
    };
    let scene_edits: Vec<(&'static str, Edit)> = vec![
        ("appears twice", Box::new(set("nodes/0/children", json!([0])))),
        (
            "appears twice",
            Box::new(|d: &mut Value| {
                d["nodes"][0]["children"] = json!([1]);
                d["nodes"][1]["children"] = json!([0]);
            }),
        ),
        ("not a valid glTF", Box::new(set("nodes/0/mesh", json!(99)))),
        ("not a valid glTF", Box::new(set("accessors/0/bufferView", json!(99)))),
        ("not a valid glTF", Box::new(set("accessors/0/count", json!(-1)))),
        ("runs past the end", Box::new(set("accessors/0/count", json!(100000)))),
        (
            "runs past the end",
            Box::new(set("accessors/0/byteOffset", json!(1000000))),
        ),
        ("byteStride", Box::new(set("bufferViews/0/byteStride", json!(4)))),
        ("not a valid glTF", Box::new(set("buffers/0/byteLength", json!("big")))),
        ("buffer", Box::new(set("buffers/0/byteLength", json!(1u64 << 40)))),
        ("/etc/passwd", Box::new(set("buffers/0/uri", json!("/etc/passwd")))),
        (
            "outside",
            Box::new(set("buffers/0/uri", json!("../../../../etc/passwd"))),
        ),
        ("file:", Box::new(set("buffers/0/uri", json!("file:///etc/passwd")))),
        (
            "outside",
            Box::new(set("buffers/0/uri", json!("%2e%2e/%2e%2e/etc/passwd"))),
        ),
        (
            "/proc/self/environ",
            Box::new(set("buffers/0/uri", json!("/proc/self/environ"))),
        ),
        (
            "data: URI",
            Box::new(set("buffers/0/uri", json!("http://example.com/x.bin"))),
        ),
        ("reaches", Box::new(set("nodes/0/scale", json!([1e38, 1e38, 1e38])))),
        (
            "non-finite transform",
            Box::new(|d: &mut Value| {
                d["nodes"][0]["scale"] = json!([1e30, 1e30, 1e30]);
                d["nodes"][1]["scale"] = json!([1e30, 1e30, 1e30]);
                d["nodes"][0]["children"] = json!([1]);
                d["scenes"][0]["nodes"] = json!([0, 2]);
            }),
        ),
        ("no view", Box::new(set("nodes/2/scale", json!([0.0, 0.0, 0.0])))),
        (
            "not a valid glTF",
            Box::new(set("nodes/2/rotation", json!([0, 0, 0, "x"]))),
        ),
        (
            "emission",
            Box::new(set("materials/0/emissiveFactor", json!([3e38, 1, 1]))),
        ),
        (
            "radiance limit",
            Box::new(|d: &mut Value| {
                d["materials"][0]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = json!(1e12);
            }),
        ),
        (
            "requires extension",
            Box::new(set("extensionsRequired", json!(["EXT_no_such_extension"]))),
        ),
        (
            "POSITION",
            Box::new(set("meshes/0/primitives/0/attributes/POSITION", json!(1))),
        ),
        ("out of range", Box::new(set("accessors/0/count", json!(2)))),
        (
            "no triangles",
            Box::new(|d: &mut Value| {
                d["scenes"][0]["nodes"] = json!([]);
            }),
        ),
        ("reaches", Box::new(set("nodes/0/translation", json!([5e9, 0, 0])))),
        (
            "inverseBindMatrices",
            Box::new(|d: &mut Value| {
                d["skins"] = json!([{ "joints": [0, 1] , "inverseBindMatrices": 0 }]);
                d["nodes"][1]["skin"] = json!(0);
            }),
        ),
        (
            "accessor 99",
            Box::new(|d: &mut Value| {
                d["nodes"][1]["extensions"] =
                    json!({ "EXT_mesh_gpu_instancing": { "attributes": { "TRANSLATION": 99 } } });
            }),
        ),
        (
            "sparse",
            Box::new(|d: &mut Value| {
                d["accessors"][0]["sparse"] = json!({ "count": 9, "indices": { "bufferView": 0, "componentType": 5125 }, "values": { "bufferView": 0 } });
            }),
        ),
        (
            "morph",
            Box::new(|d: &mut Value| {
                d["meshes"][1]["primitives"][0]["targets"] = json!([{ "POSITION": 1 }]);
            }),
        ),
        (
            "EXT_mesh_gpu_instancing",
            Box::new(|d: &mut Value| {
                d["nodes"][1]["extensions"] = json!({ "EXT_mesh_gpu_instancing": { "attributes": {} } });
            }),
        ),
        (
            "--camera",
            Box::new(|d: &mut Value| {
                d["nodes"][2].as_object_mut().unwrap().remove("camera");
            }),
        ),
    ];
    for (needle, edit) in scene_edits {
        let mut c = scene_case(needle, edit);
        if needle == "--camera" {
            c.args.extend(["--camera", "0"].map(String::from));
        }
        v.push(c);
    }
    // Outputs that are inputs: the scene itself (a glTF named .exr), and a film file merged onto itself.
    v.push(case(
        &["render", "SCENE_EXR", "-o", "SCENE_EXR", "--size", "8x8", "--spp", "1"],
        "also the scene",
    ));
    v.push(case(
        &["merge", "OUTDIR/part.exr", "-o", "OUTDIR/part.exr"],
        "also the film file",
    ));
    // A GLB with bytes past the length its header declares.
    v.push(case(
        &["render", "LONG_GLB", "-o", "OUT", "--size", "8x8", "--spp", "1"],
        "declares a length of",
    ));
    // Integer positions without KHR_mesh_quantization.
    v.push(scene_case("need KHR_mesh_quantization", |d: &mut Value| {
        let a = d["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
            .as_u64()
            .unwrap() as usize;
        d["accessors"][a]["componentType"] = json!(5121);
        d["accessors"][a]["min"] = json!([0, 0, 0]);
        d["accessors"][a]["max"] = json!([255, 255, 255]);
    }));
    // Hostile but handled: a channel whose keys do not increase is dropped with a warning, and the scene renders.
    let mut c = scene_case("", |d: &mut Value| {
        let s = d["animations"][0]["samplers"][0]["input"].as_u64().unwrap() as usize;
        d["accessors"][s]["count"] = json!(1);
        d["accessors"][s]["max"] = json!([0.0]);
    });
    c.needle = None;
    v.push(c);
    // Extreme but valid: these must render, with a finite image.
    for extra in [
        &["--max-depth", "4294967295"][..],
        &["--exposure", "64"],
        &["--env-color", "1e10,0,0"],
        &["--aperture", "1e17", "--focus-distance", "1e17"],
        &["--time", "-3e7"],
        &["--time", "3e7", "--shutter", "3600"],
        &["--seed", "4294967295"],
        &["--seed", "7"],
        &["--orbit", "-360,89.9,1e17", "--yfov", "179.9"],
        &[
            "--eye",
            "-1e17,1e17,-1e17",
            "--target",
            "1e17,-1e17,1e17",
            "--up",
            "1e-30,1,0",
        ],
        &["--tonemap", "agx", "--alpha", "--env-color", "1,1,1", "--hide-env"],
    ] {
        let mut c = render(extra, "");
        c.needle = None;
        v.push(c);
    }
    v
}

/// Runs `c` in `dir` within 60 s; returns a failure description, if any.
fn run(c: &Case, dir: &Path) -> Option<String> {
    let scene = dir.join("scene.gltf");
    let mut doc = base_scene();
    if let Some(edit) = &c.scene {
        edit(&mut doc);
    }
    std::fs::write(&scene, doc.to_string()).unwrap();
    let fifo = dir.join("fifo");
    if !fifo.exists() {
        let _ = std::process::Command::new("mkfifo").arg(&fifo).status();
    }
    std::fs::write(dir.join("empty.gltf"), b"").unwrap();
    std::fs::write(dir.join("junk.gltf"), b"{\"asset\": [[[[ \x00\xff").unwrap();
    std::fs::write(dir.join("truncated.glb"), b"glTF\x02\x00\x00\x00\x08\x00\x00\x00").unwrap();
    std::fs::write(dir.join("scene.exr"), doc.to_string()).unwrap();
    std::fs::write(dir.join("part.exr"), b"not a film").unwrap();
    let mut long = base_builder().to_glb();
    long.extend_from_slice(&[0; 16]);
    std::fs::write(dir.join("long.glb"), long).unwrap();
    let out = dir.join("out.png");
    let _ = std::fs::remove_file(&out);
    std::fs::write(dir.join("junk.hdr"), b"#?RADIANCE\nnot an image").unwrap();
    let fifo_hdr = dir.join("fifo.hdr");
    if !fifo_hdr.exists() {
        let _ = std::process::Command::new("mkfifo").arg(&fifo_hdr).status();
    }
    let map = |a: &str| -> String {
        match a {
            "SCENE" => scene.display().to_string(),
            "OUT" => out.display().to_string(),
            "FIFO" => fifo.display().to_string(),
            "FIFO_HDR" => fifo_hdr.display().to_string(),
            "JUNK_HDR" => dir.join("junk.hdr").display().to_string(),
            "EMPTY" => dir.join("empty.gltf").display().to_string(),
            "JUNK" => dir.join("junk.gltf").display().to_string(),
            "TRUNCATED_GLB" => dir.join("truncated.glb").display().to_string(),
            "LONG_GLB" => dir.join("long.glb").display().to_string(),
            "SCENE_EXR" => dir.join("scene.exr").display().to_string(),
            a if a.starts_with("OUTDIR/") => dir.join(&a[7..]).display().to_string(),
            a => a.to_string(),
        }
    };
    let args: Vec<String> = c.args.iter().map(|a| map(a)).collect();
    let mut cmd = common::pathwave_cli();
    cmd.args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    for (k, v) in &c.env {
        cmd.env(k, v);
    }
    let start = Instant::now();
    let child = cmd.spawn().unwrap();
    let pid = child.id();
    let watchdog = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_secs(60));
        let _ = std::process::Command::new("kill")
            .args(["-9", &pid.to_string()])
            .status();
    });
    let o = child.wait_with_output().unwrap();
    drop(watchdog);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let took = start.elapsed();
    let what = format!("{args:?} {:?} (expecting {:?})", c.env, c.needle);
    if took > Duration::from_secs(55) {
        return Some(format!("{what}: hung ({took:?})"));
    }
    if err.contains("panicked") {
        return Some(format!("{what}: panicked: {err}"));
    }
    match c.needle {
        None => {
            if !o.status.success() || !out.exists() {
                return Some(format!("{what}: should render, got {:?}: {err}", o.status));
            }
            std::fs::remove_file(&out).unwrap();
        }
        Some(needle) => {
            if o.status.code() != Some(1) && !(o.status.code() == Some(2) && err.contains("error:")) {
                return Some(format!("{what}: exit {:?} (not a clean error): {err}", o.status));
            }
            if !err.contains(needle) {
                return Some(format!("{what}: the message does not mention {needle:?}: {err}"));
            }
            if out.exists() {
                return Some(format!("{what}: left an output file"));
            }
            let leftovers = std::fs::read_dir(dir)
                .unwrap()
                .filter(|e| e.as_ref().unwrap().file_name().to_string_lossy().contains(".pathwave-"))
                .count();
            if leftovers > 0 {
                return Some(format!("{what}: left temporary files"));
            }
        }
    }
    None
}

/// Catches: any hostile input that panics, aborts, hangs, exits 0, leaves an output behind, or gives an error that
/// does not say what is wrong; and any extreme-but-valid one that does not render.
#[test]
fn the_hostile_input_matrix_is_refused_clearly_and_bounded() {
    let cases = cases();
    assert!(cases.len() >= 100, "only {} cases", cases.len());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let failures = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| {
                let dir = tempfile::tempdir().unwrap();
                loop {
                    let i = next.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                    let Some(c) = cases.get(i) else { break };
                    if let Some(f) = run(c, dir.path()) {
                        failures.lock().unwrap().push(format!("case {i}: {f}"));
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    eprintln!("{} hostile inputs, {} failures", cases.len(), failures.len());
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}
