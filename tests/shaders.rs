//! User shader folders: exported stages compile back to the built-in pipelines' behaviour, an edited stage replaces
//! its built-in headless (`render --shader-dir`), a broken one is refused with glslang's file:line, and `--watch`
//! rebuilds only what changed, keeps running through a compile error, and keeps the last good image.
mod common;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const CONSTANT: [f32; 3] = [0.25, 0.5, 0.75];

use common::{cornell, pathwave_cli as pathwave};

/// Every built-in stage and variant, sorted as `--shader-dir` reports them.
/// Every built-in stage the test device can build: ray-query variants only where it has ray queries.
fn every_stage() -> Vec<&'static str> {
    let ray_queries = pathwave::vk::list_devices().unwrap()[0].ray_query;
    let usable = |n: &&str| {
        ray_queries
            || !pathwave::render::kernels::Kernel::from_name(n)
                .unwrap()
                .needs_ray_query()
    };
    let mut all: Vec<&str> = pathwave::render::builtin_stage_names().filter(usable).collect();
    all.sort();
    all
}

fn exported() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    pathwave::shaders::export_builtin(dir.path()).unwrap();
    dir
}

/// Makes the shade stage end every path with one radiance, whatever it hit. Only the wavefront runs shade.comp, so
/// the renderer must switch to it for the edit to show.
fn make_shade_constant(dir: &Path) {
    let [r, g, b] = CONSTANT;
    common::insert_into_shade(
        dir,
        &format!("    path_set(PATH_RADIANCE, path, vec4({r}, {g}, {b}, 0.0));\n    return;\n"),
    );
}

/// `render SCENE -o OUT` with `args`, then the shaders in `shaders`.
fn render_with_shaders(scene: &Path, out: &Path, args: &[&str], shaders: &Path) -> Command {
    let mut c = pathwave();
    c.arg("render")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .args(args)
        .arg("--shader-dir")
        .arg(shaders);
    c
}

fn break_shade(dir: &Path) -> usize {
    let path = dir.join("shade.comp");
    let src = std::fs::read_to_string(&path).unwrap();
    let line = src.lines().position(|l| l.contains("void main()")).unwrap() + 2;
    let mut lines: Vec<&str> = src.lines().collect();
    lines.insert(line - 1, "    this is not glsl;");
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    line
}

fn is_constant(exr: &Path) -> bool {
    let (_, _, px) = pathwave::output::read_exr(exr).unwrap();
    px.iter().all(|p| (0..3).all(|c| (p[c] - CONSTANT[c]).abs() < 1e-6))
}

#[test]
fn exported_stages_reproduce_the_builtin_image() {
    let dir = exported();
    let out = tempfile::tempdir().unwrap();
    let (a, b) = (out.path().join("builtin.exr"), out.path().join("exported.exr"));
    let common_args = ["--size", "24x24", "--spp", "4", "--seed", "5"];
    let run = |extra: &[&str], o: &Path| {
        let s = pathwave()
            .arg("render")
            .arg(cornell())
            .arg("-o")
            .arg(o)
            .args(common_args)
            .args(extra)
            .output()
            .unwrap();
        assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
        String::from_utf8_lossy(&s.stderr).into_owned()
    };
    run(&[], &a);
    let log = run(&["--shader-dir", dir.path().to_str().unwrap()], &b);
    assert!(
        log.contains(&format!("using {} from", every_stage().join(", "))),
        "{log}"
    );
    assert_eq!(
        std::fs::read(&a).unwrap(),
        std::fs::read(&b).unwrap(),
        "same sources, same bytes"
    );
}

#[test]
fn an_edited_stage_replaces_the_builtin_and_a_broken_one_is_refused() {
    let dir = exported();
    common::keep_only_shade(dir.path());
    make_shade_constant(dir.path());
    let out = tempfile::tempdir().unwrap();
    let exr = out.path().join("constant.exr");
    let size = ["--size", "16x16", "--spp", "2"];
    let o = render_with_shaders(&cornell(), &exr, &size, dir.path())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && log.contains("using shade, shade_texel, shade_textured, shade_textured_texel from"),
        "{log}"
    );
    assert!(is_constant(&exr), "the edited shade stage was not used");

    let line = break_shade(dir.path());
    let broken = out.path().join("broken.exr");
    let o = render_with_shaders(&cornell(), &broken, &size, dir.path())
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && !log.contains("panicked"), "{log}");
    let want = format!("shade.comp:{line}:");
    assert!(log.contains("ERROR:") && log.contains(&want), "no '{want}' in: {log}");
    assert!(!broken.exists(), "a refused render wrote an image");
}

#[test]
fn includes_decide_which_stages_are_stale() {
    let dir = exported();
    let shaders = pathwave::shaders::ShaderDir::open(dir.path()).unwrap();
    let root = shaders.root().to_path_buf();
    let bsdf = shaders.affected(&[root.join("include/bsdf.glsl")]);
    assert_eq!(
        bsdf,
        [
            "aniso_table",
            "energy_tables",
            "follow",
            "follow_alpha",
            "follow_alpha_rq",
            "follow_alpha_texel",
            "follow_rq",
            "follow_texel",
            "follow_textured",
            "follow_textured_rq",
            "follow_textured_texel",
            "probe_bsdf",
            "shade",
            "shade_texel",
            "shade_textured",
            "shade_textured_texel",
            "sheen_table",
            "survey",
            "survey_alpha",
            "survey_alpha_texel",
            "survey_texel",
            "survey_textured",
            "survey_textured_texel"
        ]
    );
    let traverse = shaders.affected(&[root.join("include/traverse.glsl")]);
    let want = ["connect", "extend", "follow", "probe_trace", "survey"];
    let twins = |s: &&String| want.iter().any(|w| s.as_str() == *w || s.starts_with(&format!("{w}_")));
    assert!(
        traverse.len() == 33 && traverse.iter().all(|s| twins(&s)),
        "{traverse:?}"
    );
    assert_eq!(shaders.affected(&[root.join("generate.comp")]), ["generate"]);
    assert!(shaders.affected(&[root.join("notes.txt")]).is_empty());
}

/// The headless hot-reload session: `render --watch` re-renders when shade.comp changes, and survives a broken edit.
#[test]
fn watch_rebuilds_on_change_and_survives_a_compile_error() {
    let dir = exported();
    let out = tempfile::tempdir().unwrap();
    let exr = out.path().join("watched.exr");
    let watch = ["--size", "16x16", "--spp", "2", "--watch"];
    let mut child = render_with_shaders(&cornell(), &exr, &watch, dir.path())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (tx, lines) = mpsc::channel::<String>();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut log = Vec::new();
    let wait_for = |needle: &str, log: &mut Vec<String>| {
        let deadline = Instant::now() + Duration::from_secs(120);
        while Instant::now() < deadline {
            if let Ok(l) = lines.recv_timeout(Duration::from_millis(200)) {
                log.push(l.clone());
                if l.contains(needle) {
                    return true;
                }
            }
        }
        false
    };
    let result = (|| -> Result<(), String> {
        if !wait_for("watching", &mut log) {
            return Err("never started watching".into());
        }
        if is_constant(&exr) {
            return Err("the first image is already constant".into());
        }
        make_shade_constant(dir.path());
        if !wait_for("rebuilt shade", &mut log) || !wait_for("watched.exr", &mut log) {
            return Err("the change was not picked up".into());
        }
        if !is_constant(&exr) {
            return Err("the rebuilt stage's image is not constant".into());
        }
        let line = break_shade(dir.path());
        let want = format!("shade.comp:{line}:");
        if !wait_for(&want, &mut log) {
            return Err(format!("no compile error naming {want}"));
        }
        std::thread::sleep(Duration::from_millis(300));
        if child.try_wait().unwrap().is_some() {
            return Err("the process stopped on a compile error".into());
        }
        if !is_constant(&exr) {
            return Err("the last good image was not kept".into());
        }
        Ok(())
    })();
    let _ = child.kill();
    let _ = child.wait();
    if let Err(e) = result {
        panic!("{e}; stderr so far:\n{}", log.join("\n"));
    }
}

/// examples/shaders/bvh-cost holds only extend.comp and shade.comp (its includes are the built-in ones): a false
/// colour of the child boxes each camera ray tested: rays over the open floor test few (blue), rays grazing the
/// spheres' silhouettes many (red).
#[test]
fn the_bvh_cost_example_renders_a_false_colour_image() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/shaders/bvh-cost");
    let out = tempfile::tempdir().unwrap();
    let exr = out.path().join("cost.exr");
    let grid = common::scenes_dir().join("material-grid.gltf");
    let o = render_with_shaders(&grid, &exr, &["--size", "32x24", "--spp", "1"], &dir)
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success()
            && log.contains(
                "using extend, extend_alpha, extend_alpha_texel, extend_texel, shade, shade_texel, shade_textured, \
                 shade_textured_texel from"
            ),
        "{log}"
    );
    let (_, _, px) = pathwave::output::read_exr(&exr).unwrap();
    // Under 32 boxes: blue to half green, no red. Over 64: some red.
    let cheap = px.iter().filter(|p| p[0] == 0.0 && p[1] < 0.5).count();
    let costly = px.iter().filter(|p| p[0] > 0.0).count();
    assert!(
        cheap > px.len() / 10 && costly > px.len() / 100,
        "{cheap} cheap and {costly} costly pixels of {}",
        px.len()
    );
}
