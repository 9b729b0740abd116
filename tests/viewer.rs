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

#[test]
fn viewer_screenshot_is_the_headless_render() {
    if !xvfb_run() {
        eprintln!("note: xvfb-run is not installed; the viewer test is skipped (bash ci/setup.sh installs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("shot.exr");
    let scene = common::scenes_dir().join("cornell-box.gltf");
    let o = pathwave("xvfb-run")
        .args([
            "-a",
            "-s",
            "-screen 0 640x480x24",
            env!("CARGO_BIN_EXE_pathwave"),
            "view",
        ])
        .arg(&scene)
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
    let o = pathwave("xvfb-run")
        .args([
            "-a",
            "-s",
            "-screen 0 640x480x24",
            env!("CARGO_BIN_EXE_pathwave"),
            "view",
        ])
        .arg(&scene)
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
