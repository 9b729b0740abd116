//! The viewer under a headless X server (xvfb-run) on lavapipe: it opens a window, renders frames, presents them,
//! and its screenshot after N frames is the headless render of the same samples per pixel, byte for byte.
mod common;

use std::path::Path;
use std::process::Command;

fn xvfb_run() -> bool {
    let found = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found && std::env::var("CI").is_ok() {
        panic!("xvfb-run is missing; bash ci/setup.sh installs it");
    }
    found
}

fn pathwave(program: &str) -> Command {
    let mut c = Command::new(program);
    if common::validation() == pathwave::vk::Validation::On {
        c.env("PATHWAVE_VALIDATION", "1");
    }
    c
}

/// The viewer on `scene` in a headless X server, for the options that follow.
fn headless_viewer(scene: &Path) -> Command {
    let mut c = pathwave("xvfb-run");
    let args = [
        "-a",
        "-s",
        "-screen 0 640x480x24",
        env!("CARGO_BIN_EXE_pathwave"),
        "view",
    ];
    c.args(args).arg(scene);
    c
}

#[test]
fn viewer_screenshot_is_the_headless_render() {
    if !xvfb_run() {
        eprintln!("note: xvfb-run is not installed; the viewer test is skipped (bash ci/setup.sh installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot.exr");
    let scene = common::scenes_dir().join("cornell-box.gltf");
    let o = headless_viewer(&scene)
        .args(["--size", "64x48", "--frames", "5", "--screenshot"])
        .arg(&shot)
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "the viewer failed: {log}");
    // "5 frames in 1.23 s (4.1 frames/s) at 64x48: 37 spp, ..."
    let spp: u32 = log
        .lines()
        .find_map(|l| {
            l.split(" spp")
                .next()
                .filter(|_| l.contains(" frames in "))?
                .rsplit(' ')
                .next()?
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("no frame summary in: {log}"));
    assert!(spp >= 5, "{spp} spp after 5 frames: {log}");
    let reference = dir.path().join("reference.exr");
    let r = pathwave(env!("CARGO_BIN_EXE_pathwave"))
        .arg("render")
        .arg(&scene)
        .args(["--size", "64x48", "--spp", &spp.to_string(), "-o"])
        .arg(&reference)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let read = |p: &Path| pathwave::output::read_exr(p).unwrap();
    let (view, headless) = (read(&shot), read(&reference));
    assert_eq!((view.0, view.1), (64, 48));
    let mean = |px: &[[f32; 3]]| px.iter().map(|p| (p[0] + p[1] + p[2]) as f64).sum::<f64>() / (3 * px.len()) as f64;
    assert!(mean(&view.2) > 0.01, "the screenshot is black");
    assert!(
        view.2 == headless.2,
        "the viewer's {spp}-spp image differs from the headless render: means {} vs {}",
        mean(&view.2),
        mean(&headless.2)
    );
}

/// Catches: --play not advancing the animation, or a new pose per frame failing (set_scene between frames).
#[test]
fn the_viewer_plays_an_animation() {
    if !xvfb_run() {
        eprintln!("note: xvfb-run is not installed; the viewer test is skipped (bash ci/setup.sh installs it)");
        return;
    }
    let scene = common::scenes_dir().join("animated.gltf");
    let o = headless_viewer(&scene)
        .args(["--size", "64x48", "--frames", "8", "--play", "--shutter", "0.05"])
        .output()
        .unwrap();
    let log = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "the viewer failed: {log}");
    // "8 frames in 0.52 s (...) at 64x48: 1 spp, 0.40 M samples/s, t 0.43 s"
    let t: f32 = log
        .lines()
        .find_map(|l| l.split(", t ").nth(1)?.split(' ').next()?.parse().ok())
        .unwrap_or_else(|| panic!("no time in the viewer's summary: {log}"));
    assert!(t > 0.0, "the animation did not advance: {log}");
}

/// Catches: a view or the denoised image never made or never shown (the screenshot would be the noisy running mean),
/// a view's image that is not the AOV (the shading-normal view of the box must hold its walls' normals), and device
/// objects outliving the device at exit (a crash after the screenshot).
#[test]
fn the_viewer_shows_a_debug_view_and_the_denoised_image() {
    if !xvfb_run() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scenes_dir().join("cornell-box.gltf");
    let run = |mode: &[&str], shot: &Path| {
        let o = headless_viewer(&scene)
            .args(["--size", "64x48", "--screenshot"])
            .arg(shot)
            .args(if mode.contains(&"--frames") {
                &[][..]
            } else {
                &["--frames", "8"][..]
            })
            .args(mode)
            .output()
            .unwrap();
        let log = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{mode:?}: the viewer failed: {log}");
        pathwave::output::read_exr(shot).unwrap().2
    };
    let normals = run(&["--show", "shading-normal"], &dir.path().join("normal.exr"));
    // The screenshot holds the view's picture (n / 2 + 1/2 in 8-bit sRGB) decoded to linear: encoded again, every
    // pixel is a unit normal (or zero: nothing hit) but where a pixel's samples straddle an edge.
    let encode = pathwave::output::srgb_encode;
    let decoded: Vec<[f32; 3]> = normals.iter().map(|p| p.map(|c| encode(c) * 2.0 - 1.0)).collect();
    let length = |n: &[f32; 3]| n.iter().map(|c| c * c).sum::<f32>().sqrt();
    let unit = decoded.iter().filter(|n| (length(n) - 1.0).abs() < 0.05).count();
    let zero = decoded.iter().filter(|n| length(n) < 0.05).count();
    assert!(
        unit > decoded.len() / 2,
        "only {unit} of {} shown normals are unit",
        decoded.len()
    );
    // At 64x48 the box's dozen edges cross about 13 % of the pixels (87 % unit or zero when written).
    assert!(
        (unit + zero) * 5 > decoded.len() * 4,
        "{unit} unit and {zero} zero normals of {}",
        decoded.len()
    );
    let Ok(_) = pathwave::denoise::Denoiser::from_env() else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI must have Open Image Denoise"
        );
        return;
    };
    // Two frames: few samples, so noise the denoiser removes rather than edges dominates the roughness.
    let noisy = run(&["--frames", "2"], &dir.path().join("noisy.exr"));
    let denoised = run(&["--frames", "2", "--denoise"], &dir.path().join("denoised.exr"));
    let roughness = |v: &[[f32; 3]]| {
        (v.windows(2))
            .map(|p| (p[1][0].clamp(0.0, 1.0) - p[0][0].clamp(0.0, 1.0)).abs() as f64)
            .sum::<f64>()
    };
    eprintln!(
        "roughness: running mean {}, denoised {}",
        roughness(&noisy),
        roughness(&denoised)
    );
    assert!(
        roughness(&denoised) * 2.0 < roughness(&noisy),
        "the denoised view is no smoother than the running mean"
    );
}
