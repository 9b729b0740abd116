//! The exact film and film files: the device's fixed-point sums against a host twin, parts of a render merged into
//! the bits of one render in any order, and parts that do not belong refused with nothing written.
mod common;

use common::{cornell, pathwave_cli, render, scene_renderer, settings};
use pathwave::render::Schedule;
use pathwave::{Film, RenderSettings};
use std::path::{Path, PathBuf};

/// The host twin of film.glsl's conversion, by another road: f64 arithmetic (x and x^2 of an f32 are exact in f64)
/// rounded to nearest, ties up. Units 2^-64 for the sum, 2^-48 for the square.
fn quanta(x: f32) -> (i128, u128) {
    let x = x as f64;
    let sum = (x.abs() * 2f64.powi(64) + 0.5).floor() as i128;
    let square = (x * x * 2f64.powi(48) + 0.5).floor() as u128;
    (if x < 0.0 { -sum } else { sum }, square)
}

fn exact(r: &mut pathwave::Renderer, s: &RenderSettings, schedule: Schedule) -> Film {
    r.set_schedule(schedule);
    render(
        r,
        &RenderSettings {
            exact_film: true,
            ..s.clone()
        },
    )
}

/// Catches a conversion that shifts, rounds, carries or signs wrongly on the device, or a film that stores the
/// texels out of place: one sample per pixel, so each pixel's exact sums are that sample's quanta, and the float
/// film (0 + x) holds the same sample exactly. A glossy, textured, lit scene gives samples over many exponents.
#[test]
fn one_sample_s_exact_sums_are_its_fixed_point_quanta_on_both_schedules() {
    for name in ["cornell-box.gltf", "textured.gltf", "glass.gltf"] {
        let mut r = scene_renderer(&pathwave::scene::load(&common::scenes_dir().join(name), None).unwrap());
        let s = settings(40, 30, 1, 7);
        r.set_schedule(Schedule::Wavefront);
        let float = render(&mut r, &s);
        let mut exponents = std::collections::BTreeSet::new();
        for schedule in [Schedule::Wavefront, Schedule::Fused] {
            let film = exact(&mut r, &s, schedule);
            let e = film.exact.as_ref().expect("an exact film");
            assert_eq!(e.samples, vec![0..1]);
            for p in 0..e.pixels() {
                assert_eq!(e.count[p], 1, "{name}: pixel {p}");
                for c in 0..3 {
                    let x = float.sum[p][c];
                    let (sum, square) = quanta(x);
                    assert_eq!(
                        e.sum[p][c], sum,
                        "{name} {schedule:?}: pixel {p} channel {c}, sample {x:e}"
                    );
                    assert_eq!(e.sum_sq[p][c].lo, square, "{name} {schedule:?}: square of {x:e}");
                    assert_eq!(e.sum_sq[p][c].hi, 0);
                    if x > 0.0 {
                        exponents.insert(x.log2().floor() as i32);
                    }
                }
            }
            // The mean of one sample is the sample: no bit lost above the units.
            for (m, f) in film.mean().iter().zip(&float.sum) {
                for (&m, &x) in m.iter().zip(f) {
                    assert!((m - x).abs() <= x * 1e-7, "{name}: mean {m} of {x}");
                }
            }
        }
        eprintln!(
            "{name}: samples over {} binary exponents ({exponents:?})",
            exponents.len()
        );
        assert!(
            exponents.len() >= 4,
            "{name}: the samples should span several exponents"
        );
    }
}

/// Catches sums whose bits depend on how the samples were grouped: passes of different sizes (one sample a pass
/// against many), the two schedules, and the float film's mean against the exact film's within rounding; on the
/// Cornell box and on scattering media (subsurface.gltf: long paths carrying a medium stack).
#[test]
fn exact_sums_do_not_depend_on_passes_or_schedules() {
    for scene in [cornell(), common::scenes_dir().join("subsurface.gltf")] {
        exact_sums_agree(&scene);
    }
}

fn exact_sums_agree(scene: &Path) {
    let name = scene.file_name().unwrap().to_string_lossy();
    let mut r = scene_renderer(&pathwave::scene::load(scene, None).unwrap());
    let s = settings(32, 24, 24, 3);
    let wavefront = exact(&mut r, &s, Schedule::Wavefront);
    let fused = exact(&mut r, &s, Schedule::Fused);
    assert_eq!(
        wavefront.exact, fused.exact,
        "{name}: the schedules' exact films differ"
    );
    // One sample at a time, through the progressive API.
    r.set_schedule(Schedule::Wavefront);
    let s1 = RenderSettings {
        exact_film: true,
        ..s.clone()
    };
    let mut session = r.begin(&s1).unwrap();
    while session.done < s.spp {
        r.advance(&mut session, 1).unwrap();
    }
    let stepped = r.film(&session).unwrap();
    assert_eq!(
        stepped.exact, wavefront.exact,
        "{name}: one sample a pass gives other bits"
    );
    // Sample ranges added on the host give the render of their union.
    let mut part = |a: u32, b: u32| {
        let s = RenderSettings {
            first_sample: a,
            spp: b - a,
            ..s1.clone()
        };
        render(&mut r, &s).exact.unwrap()
    };
    let mut sum = part(16, 24);
    sum.add(&part(0, 5)).unwrap();
    sum.add(&part(5, 16)).unwrap();
    assert_eq!(
        Some(&sum),
        wavefront.exact.as_ref(),
        "{name}: parts 0..5, 5..16, 16..24 do not add up to 0..24"
    );
    assert!(
        sum.add(&part(4, 6)).is_err(),
        "{name}: overlapping ranges must be refused"
    );
    // The float film's mean agrees to rounding.
    r.set_schedule(Schedule::Wavefront);
    let float = render(&mut r, &s).mean();
    for (p, (a, b)) in float.iter().zip(wavefront.mean()).enumerate() {
        for c in 0..3 {
            assert!(
                (a[c] - b[c]).abs() <= 1e-5 * b[c].abs().max(1e-3),
                "{name}: pixel {p}: {} against {}",
                a[c],
                b[c]
            );
        }
    }
}

fn run(args: &[&str], dir: &Path) -> std::process::Output {
    let out = pathwave_cli()
        .args(args)
        .current_dir(dir)
        .output()
        .expect("pathwave runs");
    eprintln!(
        "pathwave {}: {}\n{}",
        args.join(" "),
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn render_cli(dir: &Path, out: &str, extra: &[&str]) {
    let scene = cornell();
    let mut args = vec!["render", scene.to_str().unwrap(), "-o", out];
    for (option, default) in [("--size", "40x30"), ("--seed", "5")] {
        if !extra.contains(&option) {
            args.extend([option, default]);
        }
    }
    args.extend_from_slice(extra);
    assert!(run(&args, dir).status.success(), "render {out} failed");
}

fn bytes(dir: &Path, name: &str) -> Vec<u8> {
    std::fs::read(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Catches a merge that is not exact or depends on the order of its parts, and a film file that does not carry
/// what it says: `--samples` parts merged in both orders and three parts equal `--spp --film-stats` byte for byte,
/// `--part I/N` gives the same parts, and the file reads back as the render's exact film.
#[test]
fn merged_parts_are_the_bytes_of_one_render_in_any_order() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_cli(d, "single.exr", &["--spp", "24", "--film-stats"]);
    render_cli(d, "a.exr", &["--samples", "0..10"]);
    render_cli(d, "b.exr", &["--samples", "10..24"]);
    render_cli(d, "p0.exr", &["--spp", "24", "--part", "0/3"]);
    render_cli(d, "p1.exr", &["--spp", "24", "--part", "1/3"]);
    render_cli(d, "p2.exr", &["--spp", "24", "--part", "2/3"]);
    let single = bytes(d, "single.exr");
    for (parts, out) in [
        (vec!["a.exr", "b.exr"], "ab.exr"),
        (vec!["b.exr", "a.exr"], "ba.exr"),
        (vec!["p2.exr", "p0.exr", "p1.exr"], "p.exr"),
    ] {
        let mut args = vec!["merge"];
        args.extend(parts.iter().copied());
        args.extend(["-o", out]);
        assert!(run(&args, d).status.success(), "merge {parts:?}");
        assert!(
            bytes(d, out) == single,
            "{parts:?} merged differ from the single render"
        );
    }
    let file = pathwave::output::read_film(&d.join("single.exr")).unwrap();
    let (film, meta) = file.stats.expect("film statistics");
    assert_eq!(meta.samples, vec![0..24]);
    assert_eq!(film.count, vec![24; 40 * 30]);
    assert_eq!(file.mean, film.mean());
    let p1 = pathwave::output::read_film(&d.join("p1.exr")).unwrap().stats.unwrap().1;
    assert_eq!(p1.samples, vec![8..16], "part 1 of 3 of 24 samples");
}

/// Catches light selection through the light tree that depends on anything but the point, its normal and the
/// sample's random numbers (a pass's or a part's place, state left from another pass): the lamp grid, where the tree
/// runs, rendered in two `--samples` parts merges to the bytes of one render; a part whose lights were picked by
/// power is refused, naming the light sampler.
#[test]
fn lamp_grid_parts_through_the_light_tree_merge_to_one_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let grid = common::scenes_dir().join("lamp-grid.gltf");
    let lamps = |out: &str, extra: &[&str]| {
        let mut args = vec![
            "render",
            grid.to_str().unwrap(),
            "--size",
            "48x32",
            "--seed",
            "3",
            "-o",
            out,
        ];
        args.extend_from_slice(extra);
        let r = run(&args, d);
        assert!(r.status.success(), "render {out} failed");
        r
    };
    let single = lamps("single.exr", &["--spp", "12", "--film-stats"]);
    assert!(
        String::from_utf8_lossy(&single.stderr).contains("lights by bvh"),
        "the lamp grid's render did not run the light tree"
    );
    lamps("a.exr", &["--samples", "0..5"]);
    lamps("b.exr", &["--samples", "5..12"]);
    lamps("power.exr", &["--samples", "5..12", "--light-sampler", "power"]);
    assert!(run(&["merge", "b.exr", "a.exr", "-o", "ab.exr"], d).status.success());
    assert!(
        bytes(d, "ab.exr") == bytes(d, "single.exr"),
        "the lamp grid's parts merged differ from one render"
    );
    let out = run(&["merge", "a.exr", "power.exr", "-o", "mixed.exr"], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("power.exr") && err.contains("light-sampler"), "{err}");
    assert!(!d.join("mixed.exr").exists());
}

/// Catches a merge that writes something it should have refused: overlapping ranges, another seed, scene, option
/// or size, and a plain EXR; each is an error naming the part, and no output appears.
#[test]
fn parts_that_do_not_belong_are_refused_naming_them_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_cli(d, "a.exr", &["--samples", "0..8"]);
    render_cli(d, "overlap.exr", &["--samples", "6..12"]);
    render_cli(d, "seed.exr", &["--samples", "8..16", "--seed", "6"]);
    render_cli(d, "depth.exr", &["--samples", "8..16", "--max-depth", "3"]);
    render_cli(d, "plain.exr", &["--spp", "8"]);
    let glass = common::scenes_dir().join("glass.gltf");
    let scene = run(
        &[
            "render",
            glass.to_str().unwrap(),
            "--size",
            "40x30",
            "--seed",
            "5",
            "--samples",
            "8..16",
            "-o",
            "scene.exr",
        ],
        d,
    );
    assert!(scene.status.success());
    render_cli(d, "small.exr", &["--samples", "8..16", "--size", "20x30"]);
    for (part, why) in [
        ("overlap.exr", "overlap"),
        ("seed.exr", "seed"),
        ("depth.exr", "max-depth"),
        ("scene.exr", "scene"),
        ("small.exr", "size"),
        ("plain.exr", "no film statistics"),
    ] {
        let out = run(&["merge", "a.exr", part, "-o", "merged.exr", "-o", "merged.png"], d);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{part}: {err}");
        assert!(err.contains(part), "{part}: the error should name the part: {err}");
        assert!(err.contains(why), "{part}: the error should say '{why}': {err}");
        assert!(
            !d.join("merged.exr").exists() && !d.join("merged.png").exists(),
            "{part}: something was written"
        );
    }
    // A part of another --spp.
    render_cli(d, "q1.exr", &["--spp", "30", "--part", "1/3"]);
    render_cli(d, "q0.exr", &["--spp", "24", "--part", "0/3"]);
    let out = run(&["merge", "q0.exr", "q1.exr", "-o", "merged.exr"], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("q1.exr") && err.contains("--spp 30"), "{err}");
    assert!(!d.join("merged.exr").exists());
    // A farm task that never ran: its part is named.
    render_cli(d, "p0.exr", &["--spp", "24", "--part", "0/3"]);
    render_cli(d, "p2.exr", &["--spp", "24", "--part", "2/3"]);
    let out = run(&["merge", "p0.exr", "p2.exr", "-o", "merged.exr"], d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("missing part 1/3"), "{err}");
    assert!(!d.join("merged.exr").exists());
    let leftovers: Vec<PathBuf> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(".pathwave-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// Catches an interrupted film render that cannot be finished later: SIGTERM a long `--film-stats` render, then
/// render the samples it did not reach (as its message says) and merge: the result is the bytes of one render of
/// them all, so no sample was lost, doubled or half-added when the signal came.
#[test]
fn an_interrupted_film_render_is_finished_by_rendering_the_rest_and_merging() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = cornell();
    let args = [
        "render",
        scene.to_str().unwrap(),
        "-o",
        "partial.exr",
        "--size",
        "24x16",
        "--spp",
        "1000000",
        "--film-stats",
    ];
    // A signal while the scene still loads ends the process without an image: wait longer on a slow machine.
    for wait in [3u64, 8, 20] {
        let child = pathwave_cli()
            .args(args)
            .current_dir(d)
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_secs(wait));
        let kill = std::process::Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "an interrupted render exited 0: {err}");
        if !d.join("partial.exr").exists() {
            continue;
        }
        let (_, meta) = pathwave::output::read_film(&d.join("partial.exr"))
            .unwrap()
            .stats
            .expect("film statistics");
        assert_eq!(meta.samples.len(), 1);
        let done = meta.samples[0].end;
        assert_eq!(meta.samples[0].start, 0);
        let rest = format!("{done}..{}", done + 5);
        assert!(
            err.contains(&format!("render --samples {done}..1000000")),
            "the message should say how to go on: {err}"
        );
        render_cli(d, "rest.exr", &["--size", "24x16", "--seed", "0", "--samples", &rest]);
        let whole = (done + 5).to_string();
        render_cli(
            d,
            "whole.exr",
            &["--size", "24x16", "--seed", "0", "--spp", &whole, "--film-stats"],
        );
        assert!(run(&["merge", "rest.exr", "partial.exr", "-o", "merged.exr"], d)
            .status
            .success());
        assert!(
            bytes(d, "merged.exr") == bytes(d, "whole.exr"),
            "{done} interrupted + 5 samples differ from one render"
        );
        return;
    }
    panic!("the render never got past loading within 20 s");
}
