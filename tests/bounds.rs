//! Bounded work and time: a huge `--max-depth` costs neither memory nor time, a stage that runs long ends at
//! PATHWAVE_GPU_TIMEOUT_SECS, include cycles are refused before glslang runs, and scenes too big for the host budget
//! are refused before they are built.
mod common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{cornell, insert_into_shade, pathwave_cli as pathwave};

/// Runs `cmd`, killing it after `limit`; the output and how long it ran. A run that had to be killed fails the test.
fn run_within(cmd: &mut Command, limit: Duration) -> (Output, Duration) {
    let start = Instant::now();
    let mut child = cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().unwrap();
            panic!(
                "still running after {limit:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    (child.wait_with_output().unwrap(), start.elapsed())
}

fn render(scene: &Path, out: &Path, extra: &[&str], schedule: &str) -> String {
    let (o, _) = run_within(
        pathwave()
            .env("PATHWAVE_SCHEDULE", schedule)
            .arg("render")
            .arg(scene)
            .arg("-o")
            .arg(out)
            .args(["--size", "16x16", "--spp", "4", "--seed", "2"])
            .args(extra),
        Duration::from_secs(30),
    );
    let log = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{log}");
    log
}

/// Runs `render` of the Cornell box into `out` at `size` and `spp` samples with the shaders in `shaders`, under the
/// environment `env`, killing it after `limit`; the output and how long it ran.
fn render_with_shaders(
    env: &[(&str, &str)],
    out: &Path,
    size: &str,
    spp: &str,
    shaders: &Path,
    limit: Duration,
) -> (Output, Duration) {
    let mut cmd = pathwave();
    cmd.envs(env.iter().copied())
        .arg("render")
        .arg(cornell())
        .arg("-o")
        .arg(out)
        .args(["--size", size, "--spp", spp, "--shader-dir"])
        .arg(shaders);
    run_within(&mut cmd, limit)
}

/// The largest resident set of any child this process has waited for, in bytes.
fn children_max_rss() -> u64 {
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut u) };
    u.ru_maxrss as u64 * 1024
}

/// Before bounces were recorded in batches, --max-depth 4294967295 grew one command buffer without bound (18.5 GB
/// after a minute). Roulette ends every path long before bounce 64, so both caps give the same bytes.
#[test]
fn a_huge_max_depth_costs_nothing_and_changes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    for schedule in ["wavefront", "fused"] {
        let deep = dir.path().join(format!("deep-{schedule}.exr"));
        let capped = dir.path().join(format!("capped-{schedule}.exr"));
        render(&cornell(), &capped, &["--max-depth", "64"], schedule);
        render(&cornell(), &deep, &["--max-depth", "4294967295"], schedule);
        assert_eq!(
            std::fs::read(&deep).unwrap(),
            std::fs::read(&capped).unwrap(),
            "{schedule}: a cap past every path's length changed the image"
        );
    }
    let rss = children_max_rss();
    assert!(rss < 1 << 30, "a render used {} MiB", rss >> 20);
}

/// An #include cycle made glslang expand it until memory ran out; it is refused before glslang runs, named.
#[test]
fn an_include_cycle_in_a_shader_folder_is_refused_fast() {
    let dir = tempfile::tempdir().unwrap();
    pathwave::shaders::export_builtin(dir.path()).unwrap();
    let rng = dir.path().join("include/rng.glsl");
    // path.glsl includes rng.glsl: now rng.glsl includes path.glsl back.
    let text = std::fs::read_to_string(&rng).unwrap();
    std::fs::write(&rng, format!("#include \"path.glsl\"\n{text}")).unwrap();
    let out = dir.path().join("never.exr");
    let (o, took) = render_with_shaders(&[], &out, "8x8", "1", dir.path(), Duration::from_secs(60));
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !log.contains("panicked"), "{log}");
    assert!(
        log.contains("#include cycle") && log.contains("rng.glsl") && log.contains("path.glsl"),
        "{log}"
    );
    assert!(took < Duration::from_secs(30), "took {took:?}");
    assert!(!out.exists(), "a refused render wrote an image");
    let shaders = pathwave::shaders::ShaderDir::open(dir.path()).unwrap();
    let cycle = shaders.include_cycle("shade").expect("shade includes path.glsl");
    assert_eq!(cycle.first(), cycle.last(), "{cycle:?}");
    let fresh = tempfile::tempdir().unwrap();
    pathwave::shaders::export_builtin(fresh.path()).unwrap();
    let builtin = pathwave::shaders::ShaderDir::open(fresh.path()).unwrap();
    for stage in builtin.stages() {
        assert_eq!(builtin.include_cycle(&stage), None, "{stage}");
    }
}

/// Makes shade.comp spend a long time per path: iterations stay under lavapipe's loop budget, each one heavy.
fn make_shade_slow(dir: &Path) {
    let slow = "#define S x = sin(x) * 0.999 + cos(x * 1.001);\n\
                #define S8 S S S S S S S S\n\
                float x = float(path);\n\
                for (uint i = 0u; i < frame.width * 900u; i++) { S8 S8 S8 S8 S8 S8 S8 S8 }\n\
                if (x == 12345.0) path_set(PATH_RADIANCE, path, vec4(x));\n";
    insert_into_shade(dir, slow);
}

/// The timeout used to be reported only once the device went idle (94 s with a 20 s limit), and never on a hung
/// device: now the process ends within a few seconds of the limit.
#[test]
fn a_stage_that_runs_long_ends_at_the_gpu_timeout() {
    let dir = tempfile::tempdir().unwrap();
    pathwave::shaders::export_builtin(dir.path()).unwrap();
    common::keep_only_shade(dir.path());
    make_shade_slow(dir.path());
    let out = dir.path().join("never.exr");
    let env = [("PATHWAVE_GPU_TIMEOUT_SECS", "2"), ("PATHWAVE_SCHEDULE", "wavefront")];
    let (o, took) = render_with_shaders(&env, &out, "64x64", "4", dir.path(), Duration::from_secs(60));
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !log.contains("panicked"), "{log}");
    assert!(log.contains("did not finish within 2 s"), "{log}");
    // Compiling the four shade variants takes a few seconds of its own.
    assert!(took < Duration::from_secs(20), "took {took:?}: {log}");
    assert!(!out.exists(), "a timed-out render wrote an image");
}

/// `nodes` nodes sharing one 200x200-vertex grid of 79,202 emissive triangles.
fn shared_grid(nodes: u32) -> common::gltf_builder::GltfBuilder {
    let n = 200u32;
    let positions: Vec<[f32; 3]> = (0..n * n)
        .map(|i| [(i % n) as f32 / n as f32, (i / n) as f32 / n as f32, 0.0])
        .collect();
    let mut indices = Vec::new();
    for y in 0..n - 1 {
        for x in 0..n - 1 {
            let a = y * n + x;
            indices.extend([a, a + 1, a + n, a + 1, a + n + 1, a + n]);
        }
    }
    let mut b = common::gltf_builder::GltfBuilder::new();
    let light = b.material("light", [0.0; 3], [1.0; 3], true);
    b.mesh("grid", &positions, &indices, light);
    for i in 1..nodes {
        b.place_last_mesh("copy", serde_json::json!({ "translation": [i as f32 * 1.5, 0.0, 0.0] }));
    }
    b
}

/// 25,600 nodes sharing one 79,202-triangle mesh, with instancing off (PATHWAVE_INSTANCING=never), flatten to 2
/// billion triangles (hundreds of GiB): refused from the instance count before anything is placed, where it used to
/// run for a minute and die out of memory. With instancing (the default) such a file renders (tests/instances.rs).
#[test]
fn a_scene_whose_flattening_exceeds_the_budget_is_refused_fast() {
    let (dir, path) = common::write_temp(&shared_grid(25_600), "many.gltf");
    let out = dir.path().join("never.exr");
    for (args, limit) in [(&[][..], "GiB"), (&["--max-memory", "512M"][..], "512.0 MiB")] {
        let (o, took) = run_within(
            pathwave()
                .env("PATHWAVE_INSTANCING", "never")
                .arg("render")
                .arg(&path)
                .arg("-o")
                .arg(&out)
                .args(["--size", "8x8", "--spp", "1"])
                .args(args),
            Duration::from_secs(30),
        );
        let log = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !log.contains("panicked"), "{log}");
        assert!(
            log.contains("many.gltf")
                && log.contains("2027571200 triangles")
                && log.contains(limit)
                && log.contains("--max-memory"),
            "{log}"
        );
        assert!(took < Duration::from_secs(10), "took {took:?}");
        assert!(!out.exists());
    }
}

/// Past the budget check (a generous --max-memory) a host that cannot give the memory (here a 1.5 GB address-space
/// limit; 15.8 M placed triangles, instancing off, need about 5 GB) is an error naming the scene, where the
/// allocator used to abort.
#[test]
fn running_out_of_host_memory_is_an_error_not_an_abort() {
    use std::os::unix::process::{CommandExt, ExitStatusExt};
    let (_dir, path) = common::write_temp(&shared_grid(200), "grids.gltf");
    let mut cmd = pathwave();
    cmd.env("PATHWAVE_INSTANCING", "never")
        .arg("info")
        .arg(&path)
        .args(["--max-memory", "100G"]);
    // SAFETY: only setrlimit runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: 1_500_000_000,
                rlim_max: 1_500_000_000,
            };
            libc::setrlimit(libc::RLIMIT_AS, &limit);
            Ok(())
        });
    }
    let (o, _) = run_within(&mut cmd, Duration::from_secs(60));
    let log = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.signal(), None, "{log}");
    assert!(
        !o.status.success() && log.contains("grids.gltf") && log.contains("out of host memory"),
        "{log}"
    );
}

/// Reading a file is held to the budget too, from its JSON before its buffers are read: a 79k-triangle grid's 3.8
/// MiB of buffers and decoded accessors do not fit in 1 MiB.
#[test]
fn a_file_too_big_to_read_within_the_budget_is_refused_before_reading() {
    let (_dir, path) = common::write_temp(&shared_grid(1), "grid.gltf");
    let (o, _) = run_within(
        pathwave().arg("info").arg(&path).args(["--max-memory", "1M"]),
        Duration::from_secs(30),
    );
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && log.contains("grid.gltf: reading it would need about") && log.contains("1.0 MiB"),
        "{log}"
    );
    let (o, _) = run_within(
        pathwave().arg("info").arg(&path).args(["--max-memory", "64M"]),
        Duration::from_secs(30),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A user's shade.comp whose loop never ends: lavapipe cuts every loop of the invocation once 65,535 iterations are
/// spent, silently, which used to give a wrong image with exit 0. The stage's own budget check now makes it an error.
#[test]
fn a_stage_that_spends_the_loop_budget_is_an_error_not_a_wrong_image() {
    let dir = tempfile::tempdir().unwrap();
    pathwave::shaders::export_builtin(dir.path()).unwrap();
    // Endless as far as the compiler can tell: the bound depends on the frame, and x never reaches it.
    let endless = "float x = float(path);\n\
                   for (uint i = 0u; i < frame.width + 1u; i += 0u) { x = x * 0.5 + 1.0; }\n\
                   if (x == 12345.0) path_set(PATH_RADIANCE, path, vec4(x));\n";
    insert_into_shade(dir.path(), endless);
    let out = dir.path().join("never.exr");
    let env = [("PATHWAVE_SCHEDULE", "wavefront")];
    let (o, took) = render_with_shaders(&env, &out, "16x16", "1", dir.path(), Duration::from_secs(120));
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !log.contains("panicked"), "{log}");
    assert!(log.contains("loop budget"), "{log}");
    assert!(took < Duration::from_secs(100), "took {took:?}");
    assert!(!out.exists(), "a cut render wrote an image");
}
