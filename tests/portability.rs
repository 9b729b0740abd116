//! Subgroup sizes other than lavapipe's default 8: renders through the CLI at LP_NATIVE_VECTOR_WIDTH 128 (subgroups of 4) and 512 (16) must give the default width's bytes and ray counts, for both schedules and both BVH reads.
//!
//! GPUs run subgroups of 16, 32 or 64; lavapipe's width is a process-wide setting read at start-up, so each width
//! needs a process of its own: the renders run the `pathwave` binary with the variable in its environment.
mod common;

use std::path::Path;

/// lavapipe's vector width in bits and the subgroup size it gives.
const WIDTHS: [(u32, u32); 3] = [(256, 8), (128, 4), (512, 16)];

/// What one render gave: the EXR's bytes, the (extension, shadow) ray counts and the device's name.
struct Render {
    bytes: Vec<u8>,
    rays: String,
    device: String,
}

fn render(out: &Path, scene: &str, width: u32, env: &[(&str, &str)], args: &[&str]) -> Render {
    let mut c = common::pathwave_cli();
    let scene = common::scenes_dir().join(scene);
    c.arg("render").arg(&scene).arg("-o").arg(out).args(args);
    c.env("LP_NATIVE_VECTOR_WIDTH", width.to_string())
        .envs(env.iter().copied());
    let o = c.output().expect("the pathwave binary runs");
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        o.status.success(),
        "{} at width {width} {env:?}: {err}",
        scene.display()
    );
    // The summary line: "... on DEVICE: wall ..., 0.07 Mrays/s (13615 extension + 4960 shadow rays), GPU ms ..."
    let summary = err
        .lines()
        .find(|l| l.contains(" extension + "))
        .unwrap_or_else(|| panic!("no summary: {err}"));
    // The part of the summary after `after`, up to `until` (empty when `after` is missing).
    let field = |after: &str, until: char| {
        (summary.split_once(after).map_or("", |(_, r)| r))
            .split(until)
            .next()
            .unwrap_or("")
    };
    let (rays, device) = (field(" Mrays/s (", ')'), field(" on ", ':'));
    Render {
        bytes: std::fs::read(out).unwrap(),
        rays: rays.to_string(),
        device: device.to_string(),
    }
}

/// Renders `scene` at every width with each environment and requires the bytes and ray counts of the default width.
fn assert_same_at_every_width(scene: &str, envs: &[&[(&str, &str)]], args: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    for env in envs {
        let mut reference: Option<Render> = None;
        for (bits, subgroup) in WIDTHS {
            let r = render(&dir.path().join(format!("{bits}.exr")), scene, bits, env, args);
            eprintln!("{scene} {env:?} subgroup {subgroup}: {} ({})", r.rays, r.device);
            if r.device.contains("llvmpipe") {
                assert!(
                    r.device.contains(&format!("{bits} bits")),
                    "LP_NATIVE_VECTOR_WIDTH={bits} did not reach lavapipe: {}",
                    r.device
                );
            }
            let Some(reference) = &reference else {
                reference = Some(r);
                continue;
            };
            assert_eq!(
                r.rays, reference.rays,
                "{scene} {env:?}: ray counts at subgroup size {subgroup}"
            );
            assert!(
                r.bytes == reference.bytes,
                "{scene} {env:?}: the image at subgroup size {subgroup} differs from subgroup size 8"
            );
        }
    }
}

const SCHEDULES: [&[(&str, &str)]; 2] = [&[("PATHWAVE_SCHEDULE", "wavefront")], &[("PATHWAVE_SCHEDULE", "fused")]];

#[test]
fn the_cornell_box_is_the_same_bytes_at_subgroup_sizes_4_8_and_16() {
    assert_same_at_every_width("cornell-box.gltf", &SCHEDULES, &["--size", "48x32", "--spp", "4"]);
}

#[test]
fn the_glass_scene_is_the_same_bytes_at_subgroup_sizes_4_8_and_16() {
    assert_same_at_every_width("glass.gltf", &SCHEDULES, &["--size", "48x32", "--spp", "4"]);
}

/// The material grid's 40k triangles under a sky: most of the work is BVH traversal, through texel views and
/// through storage buffers (tests/bvh.rs holds both to a brute force at the default width).
#[test]
fn bvh_traversal_is_the_same_bytes_at_subgroup_sizes_4_8_and_16() {
    // The default reads texel views where the device holds them (it does here).
    let reads: [&[(&str, &str)]; 2] = [&[], &[("PATHWAVE_BVH_READS", "storage")]];
    let args = ["--size", "48x32", "--spp", "2", "--env-color", "1,1,1"];
    assert_same_at_every_width("material-grid.gltf", &reads, &args);
}
