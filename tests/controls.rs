//! The batch controls a render pipeline needs without editing the file: a camera on the command line, the default
//! view of a file without one, alpha, tone curves for PNG, and 8-bit environment maps. Checked against what the
//! options promise (the file's own camera, analytic coverage, the published curves, an integral of the map).
mod common;

use common::gltf_builder::GltfBuilder;
use pathwave::output::{srgb_decode, srgb_encode, Display, ToneCurve};
use std::path::Path;
use std::process::Output;

fn pathwave(args: &[&str]) -> Output {
    let o = common::pathwave_cli()
        .args(args)
        .output()
        .expect("the pathwave binary runs");
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    o
}

fn exr(path: &Path) -> Vec<[f32; 3]> {
    pathwave::output::read_exr(path).unwrap().2
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The Cornell box's camera (scenes/cornell-box.gltf: a half turn about +y) given on the command line must render the
/// file's bytes: the target is one metre ahead so the view direction is exact, and the degrees are the file's radians
/// printed to 17 digits. A --yfov alone equal to the file's too.
#[test]
fn a_command_line_camera_equal_to_the_files_renders_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = common::cornell();
    let base = ["render", s(&cornell), "--size", "24x24", "--spp", "4"];
    // The file's own camera: it looks down +z, so a target one metre ahead differs from the eye in z alone.
    let file = pathwave::scene::load(&cornell, None).unwrap().camera.unwrap();
    let pathwave::scene::Projection::Perspective { yfov } = file.projection else {
        panic!("the Cornell box's camera is perspective")
    };
    assert_eq!(file.basis().2, glam::Vec3::Z);
    let o = file.origin();
    let yfov = format!("{:.17}", (yfov as f64).to_degrees());
    let eye = format!("{:?},{:?},{:?}", o.x, o.y, o.z);
    let target = format!("{:?},{:?},{:?}", o.x, o.y, o.z + 1.0);
    assert_eq!(o.z + 1.0 - o.z, 1.0, "the view direction is exact");
    let runs: [(&str, Vec<&str>); 3] = [
        ("file", vec![]),
        ("eye", vec!["--eye", &eye, "--target", &target, "--yfov", &yfov]),
        ("yfov", vec!["--yfov", &yfov]),
    ];
    let mut bytes = Vec::new();
    for (name, extra) in &runs {
        let out = dir.path().join(format!("{name}.exr"));
        let mut args = base.to_vec();
        args.extend(["-o", s(&out)]);
        args.extend(extra.iter().copied());
        pathwave(&args);
        bytes.push(std::fs::read(&out).unwrap());
    }
    assert!(
        bytes[1] == bytes[0],
        "--eye/--target/--yfov equal to the file's camera changed the image"
    );
    assert!(bytes[2] == bytes[0], "--yfov equal to the file's changed the image");
    // The test can fail: another field of view changes the bytes.
    let other = dir.path().join("other.exr");
    let mut args = base.to_vec();
    args.extend(["-o", s(&other), "--yfov", "30"]);
    pathwave(&args);
    assert!(std::fs::read(&other).unwrap() != bytes[0]);
}

/// Emission seen directly (max depth 0) of a render through the command line, as the EXR's red channel.
fn direct(scene: &Path, size: u32, spp: u32, extra: &[&str]) -> Vec<f32> {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("direct.exr");
    let size = format!("{size}x{size}");
    let spp = spp.to_string();
    let mut args = vec![
        "render",
        s(scene),
        "-o",
        s(&out),
        "--size",
        &size,
        "--spp",
        &spp,
        "--max-depth",
        "0",
    ];
    args.extend_from_slice(extra);
    pathwave(&args);
    exr(&out).iter().map(|p| p[0]).collect()
}

/// --orbit without --target looks at the centre of the scene's bounds: a small emitter there, between two dark
/// boxes placed symmetrically about it, lands on the image's centre from every direction tried.
#[test]
fn an_orbit_puts_the_scenes_centre_at_the_image_centre() {
    let centre = [1.0, 2.0, 3.0];
    let mut b = GltfBuilder::new();
    let light = b.material("light", [0.0; 3], [1.0; 3], true);
    let dark = b.material("dark", [0.0; 3], [0.0; 3], false);
    b.sphere("light", centre, 0.25, light);
    b.cube("left", [-2.0, 0.0, 1.0], [-1.5, 1.0, 2.0], dark, false);
    b.cube("right", [3.5, 3.0, 4.0], [4.0, 4.0, 5.0], dark, false);
    b.camera([0.0, 0.0, 20.0], [0.0; 3], [0.0, 1.0, 0.0], 40.0);
    let (_dir, path) = common::write_temp(&b, "orbit.gltf");
    for orbit in ["0,0,8", "-60,20,8", "135,-40,6"] {
        let px = direct(&path, 33, 16, &["--orbit", orbit]);
        let (mut sum, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
        for (i, v) in px.iter().enumerate() {
            sum += *v as f64;
            sx += *v as f64 * ((i % 33) as f64 + 0.5);
            sy += *v as f64 * ((i / 33) as f64 + 0.5);
        }
        assert!(
            px[16 * 33 + 16] > 0.99,
            "--orbit {orbit}: the centre pixel sees {}",
            px[16 * 33 + 16]
        );
        let (cx, cy) = (sx / sum, sy / sum);
        assert!(
            (cx - 16.5).abs() < 0.2 && (cy - 16.5).abs() < 0.2,
            "--orbit {orbit}: the emitter's centroid is at ({cx:.2}, {cy:.2}), not the centre (16.5, 16.5)"
        );
    }
}

/// A --yfov alone keeps the file's camera and changes only its field of view: an emitting square 2 m wide 5 m ahead
/// covers 2 * (1 / 5) / (2 tan(yfov / 2)) of the image's width, measured over the middle rows to a tenth of a pixel
/// (256 samples per pixel: a standard error near 0.01 pixels).
#[test]
fn yfov_changes_the_framing_as_predicted() {
    let mut b = GltfBuilder::new();
    let light = b.material("light", [0.0; 3], [1.0; 3], false);
    let c = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    b.quad("square", c, light, Some([0.0, 0.0, 1.0]));
    b.camera([0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], 90.0);
    let (_dir, path) = common::write_temp(&b, "square.gltf");
    let size = 64u32;
    for yfov in [30.0f64, 50.0] {
        let px = direct(&path, size, 256, &["--yfov", &yfov.to_string()]);
        // The 16 middle rows, all inside the square's height at either field of view.
        let rows = (size / 2 - 8) as usize..(size / 2 + 8) as usize;
        let covered: f64 = (rows.clone())
            .map(|y| {
                px[y * size as usize..(y + 1) * size as usize]
                    .iter()
                    .map(|v| *v as f64)
                    .sum::<f64>()
            })
            .sum::<f64>()
            / rows.len() as f64;
        let predicted = size as f64 * (1.0 / 5.0) / (yfov.to_radians() * 0.5).tan();
        assert!(
            (covered - predicted).abs() < 0.1,
            "--yfov {yfov}: the square covers {covered:.3} pixels of the row, predicted {predicted:.3}"
        );
    }
}

/// The fraction of the image that sees an emitter, rendered through the scene's default view.
fn emitter_coverage(b: &GltfBuilder) -> f64 {
    let (_dir, path) = common::write_temp(b, "uncamera.gltf");
    let mut r = common::renderer(&path);
    let mut settings = common::settings(48, 48, 4, 0);
    settings.max_depth = Some(0);
    let px = common::render(&mut r, &settings).mean();
    px.iter().filter(|p| p[0] > 0.0).count() as f64 / px.len() as f64
}

/// Files without a camera: a flat model in the y = 0 plane (once seen edge-on from the height of its centre: an
/// empty image) and a closed box's contents (once hidden behind the box's outer wall) both fill a good part of
/// the first image.
#[test]
fn the_default_view_shows_flat_models_and_what_closed_boxes_hold() {
    let mut flat = GltfBuilder::new();
    let light = flat.material("light", [0.0; 3], [1.0; 3], false);
    let c = [[-5.0, 0.0, -5.0], [5.0, 0.0, -5.0], [5.0, 0.0, 5.0], [-5.0, 0.0, 5.0]];
    flat.quad("terrain", c, light, Some([0.0, 1.0, 0.0]));
    let seen = emitter_coverage(&flat);
    assert!(seen > 0.12, "the flat model covers {seen:.3} of the image");

    let mut boxed = GltfBuilder::new();
    let wall = boxed.material("wall", [0.5; 3], [0.0; 3], false);
    let light = boxed.material("light", [0.0; 3], [1.0; 3], false);
    boxed.cube("room", [-1.0; 3], [1.0; 3], wall, true);
    boxed.cube("content", [-0.3; 3], [0.3; 3], light, false);
    let seen = emitter_coverage(&boxed);
    assert!(seen > 0.15, "the box's content covers {seen:.3} of the image");
}

/// The area of the unit pixel [x0, x0 + 1] x [y0, y0 + 1] inside the disc of radius r about the origin, by
/// integrating the clipped chord over x (error far below a sample's).
fn pixel_in_disc(x0: f64, y0: f64, r: f64) -> f64 {
    let n = 4000;
    (0..n)
        .map(|k| {
            let x = x0 + (k as f64 + 0.5) / n as f64;
            if x.abs() >= r {
                return 0.0;
            }
            let h = (r * r - x * x).sqrt();
            ((y0 + 1.0).min(h) - y0.max(-h)).max(0.0) / n as f64
        })
        .sum()
}

/// --alpha: a sphere seen by an orthographic camera from above its pole (its silhouette the equator's 64-gon, within
/// 0.002 pixels of the circle) over a hidden environment: alpha 1 inside, 0 outside, and on the edge the pixel's
/// share of the disc (4096 samples: a standard error below 0.008). Glass in front of everything: alpha 1, while
/// its colour shows the environment through it.
#[test]
fn alpha_is_the_share_of_camera_samples_that_hit_the_scene() {
    let (size, radius_px) = (16u32, 5.3f64);
    let half = 8.0f32; // the image plane is 2 * half scene units high: a pixel is one unit
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    b.sphere("ball", [0.0; 3], radius_px as f32, grey);
    b.orthographic_camera([0.0, 20.0, 0.0], [0.0; 3], [0.0, 0.0, -1.0], half, half);
    let (dir, path) = common::write_temp(&b, "ball.gltf");
    let exr_out = dir.path().join("ball.exr");
    let png_out = dir.path().join("ball.png");
    pathwave(&[
        "render",
        s(&path),
        "-o",
        s(&exr_out),
        "-o",
        s(&png_out),
        "--size",
        "16x16",
        "--spp",
        "4096",
        "--env-color",
        "1,1,1",
        "--hide-env",
        "--alpha",
        "--max-depth",
        "1",
    ]);
    let a = read_channel(&exr_out, "A");
    let png = image::open(&png_out).unwrap().into_rgba8();
    let mut edges = 0;
    for y in 0..size {
        for x in 0..size {
            let i = (y * size + x) as usize;
            let expected = pixel_in_disc(x as f64 - 8.0, y as f64 - 8.0, radius_px);
            let tol = if expected == 0.0 || expected == 1.0 { 0.0 } else { 0.035 };
            edges += (tol > 0.0) as usize;
            assert!(
                (a[i] as f64 - expected).abs() <= tol,
                "pixel ({x}, {y}): alpha {} against the disc's share {expected:.4}",
                a[i]
            );
            let png_alpha = png.get_pixel(x, y)[3];
            assert_eq!(
                png_alpha,
                (a[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
                "the PNG's alpha at ({x}, {y})"
            );
        }
    }
    assert!(edges >= 20, "only {edges} edge pixels: the test would not see the edge");

    let mut glass = GltfBuilder::new();
    let g = glass.glass_material("glass", [1.0; 3], 1.5, 0.0, false, None);
    let c = [
        [-20.0, -20.0, 0.0],
        [20.0, -20.0, 0.0],
        [20.0, 20.0, 0.0],
        [-20.0, 20.0, 0.0],
    ];
    glass.quad("pane", c, g, Some([0.0, 0.0, 1.0]));
    glass.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 40.0);
    let (dir, path) = common::write_temp(&glass, "glass.gltf");
    let out = dir.path().join("glass.exr");
    pathwave(&[
        "render",
        s(&path),
        "-o",
        s(&out),
        "--size",
        "8x8",
        "--spp",
        "16",
        "--env-color",
        "1,1,1",
        "--hide-env",
        "--alpha",
    ]);
    assert!(
        read_channel(&out, "A").iter().all(|&v| v == 1.0),
        "glass over a hidden environment has alpha 1"
    );
}

/// One named channel of an EXR, row 0 at the top.
fn read_channel(path: &Path, name: &str) -> Vec<f32> {
    use exr::prelude::*;
    let img = read_all_flat_layers_from_file(path).unwrap();
    let channels = &img.layer_data[0].channel_data.list;
    let c = channels
        .iter()
        .find(|c| c.name.to_string() == name)
        .unwrap_or_else(|| panic!("no channel {name} in {path:?}"));
    c.sample_data.values_as_f32().collect()
}

/// Tone curves as their published formulas give them, written independently of src/output/tone.rs: ACES by
/// Narkowicz's rational fit, PBR Neutral by Khronos's reference steps, AgX by its inset matrix (inverted here in
/// f64), log2 range and sigmoid polynomial. AgX's design anchor: middle grey 0.18 shows near the middle of the
/// display range (sRGB 0.5).
#[test]
fn tone_curves_follow_their_published_formulas() {
    let aces = |x: f64| ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0);
    let neutral = |c: [f64; 3]| {
        let x = c[0].min(c[1]).min(c[2]);
        let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
        let c = c.map(|v| v - offset);
        let peak = c[0].max(c[1]).max(c[2]);
        let start = 0.76;
        if peak < start {
            return c;
        }
        let d = 1.0 - start;
        let new_peak = 1.0 - d * d / (peak + d - start);
        let g = 1.0 - 1.0 / (0.15 * (peak - new_peak) + 1.0);
        c.map(|v| v * new_peak / peak * (1.0 - g) + new_peak * g)
    };
    let inset = [
        [0.842479062253094, 0.0784335999999992, 0.0792237451477643],
        [0.0423282422610123, 0.878468636469772, 0.0791661274605434],
        [0.0423756549057051, 0.0784336, 0.879142973793104],
    ]; // rows
    let agx = |c: [f64; 3]| {
        let m = |a: &[[f64; 3]; 3], v: [f64; 3]| [0, 1, 2].map(|r| a[r][0] * v[0] + a[r][1] * v[1] + a[r][2] * v[2]);
        let (lo, hi) = (-12.47393, 4.026069);
        let x = m(&inset, c).map(|v| ((v.max(1e-12).log2().clamp(lo, hi)) - lo) / (hi - lo));
        let p = x.map(|x| {
            15.5 * x.powi(6) - 40.14 * x.powi(5) + 31.96 * x.powi(4) - 6.868 * x.powi(3) + 0.4298 * x * x + 0.1191 * x
                - 0.00232
        });
        m(&inverse(&inset), p).map(|v| v.max(0.0).powf(2.2).clamp(0.0, 1.0))
    };
    let samples: [[f64; 3]; 8] = [
        [0.0, 0.0, 0.0],
        [0.01, 0.02, 0.005],
        [0.18, 0.18, 0.18],
        [0.5, 0.3, 0.1],
        [0.9, 0.8, 0.85],
        [1.5, 0.7, 0.2],
        [4.0, 4.0, 4.0],
        [30.0, 2.0, 0.5],
    ];
    for c in samples {
        let c32 = c.map(|v| v as f32);
        let want = [
            (ToneCurve::None, c.map(|v| v.clamp(0.0, 1.0))),
            (ToneCurve::Aces, c.map(aces)),
            (ToneCurve::PbrNeutral, neutral(c).map(|v| v.clamp(0.0, 1.0))),
            (ToneCurve::Agx, agx(c)),
        ];
        for (curve, w) in want {
            let got = curve.apply(c32);
            for k in 0..3 {
                assert!(
                    (got[k] as f64 - w[k]).abs() < 2e-5,
                    "{curve:?} of {c:?}: {got:?}, the formula gives {w:?}"
                );
            }
        }
    }
    let grey = srgb_encode(ToneCurve::Agx.apply([0.18; 3])[0]);
    assert!((grey - 0.5).abs() < 0.03, "AgX shows middle grey at sRGB {grey}");
    // PBR Neutral is the identity (less its small offset) below its compression start.
    let low = ToneCurve::PbrNeutral.apply([0.5, 0.4, 0.3]);
    assert!((low[0] - 0.46).abs() < 1e-6 && (low[2] - 0.26).abs() < 1e-6, "{low:?}");
}

fn inverse(a: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    let c = |r0: usize, r1: usize, c0: usize, c1: usize| a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0];
    [
        [c(1, 2, 1, 2) / det, -c(0, 2, 1, 2) / det, c(0, 1, 1, 2) / det],
        [-c(1, 2, 0, 2) / det, c(0, 2, 0, 2) / det, -c(0, 1, 0, 2) / det],
        [c(1, 2, 0, 1) / det, -c(0, 2, 0, 1) / det, c(0, 1, 0, 1) / det],
    ]
}

/// `render --tonemap`: none writes today's PNG (linear, clipped, sRGB), and every curve's PNG holds the curve of
/// the EXR's linear values the same run wrote, after --exposure.
#[test]
fn render_writes_its_png_through_the_tone_curve() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = common::cornell();
    let exr_out = dir.path().join("cb.exr");
    let plain = dir.path().join("plain.png");
    let base = [
        "render",
        s(&cornell),
        "--size",
        "16x16",
        "--spp",
        "4",
        "--exposure",
        "1.5",
    ];
    let mut args = base.to_vec();
    args.extend(["-o", s(&exr_out), "-o", s(&plain)]);
    pathwave(&args);
    let linear = exr(&exr_out);
    let plain_bytes = std::fs::read(&plain).unwrap();
    for curve in ["none", "aces", "agx", "pbr-neutral"] {
        let png = dir.path().join(format!("{curve}.png"));
        let mut args = base.to_vec();
        args.extend(["-o", s(&png), "--tonemap", curve]);
        pathwave(&args);
        if curve == "none" {
            assert!(
                std::fs::read(&png).unwrap() == plain_bytes,
                "--tonemap none changed the PNG"
            );
        }
        let display = Display {
            exposure: 1.5,
            curve: <ToneCurve as clap::ValueEnum>::from_str(curve, false).unwrap(),
        };
        let img = image::open(&png).unwrap().into_rgb8();
        for (i, p) in img.pixels().enumerate() {
            assert_eq!(p.0, display.pixel(linear[i]), "--tonemap {curve}: pixel {i}");
        }
    }
}

/// The tone-map stage the viewer shows through gives the host's curves (within one 8-bit step: the device's pow and
/// log2 are not the host's to the last bit).
#[test]
fn the_viewers_tone_map_stage_matches_the_host_curves() {
    use ash::vk;
    use pathwave::vk::Buffer;
    let r = common::renderer(&common::cornell());
    let ctx = r.context();
    let n = 64usize;
    let values: Vec<[f32; 3]> = (0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32;
            [20f32.powf(t * 2.0 - 1.0) * t, (t * 7.0).sin().abs() * 3.0, 0.02 + t * t]
        })
        .collect();
    let texels: Vec<[f32; 4]> = values.iter().map(|v| [v[0], v[1], v[2], 1.0]).collect();
    let image = Buffer::with_data(ctx, "tonemap test image", &texels).unwrap();
    let out = Buffer::new(
        ctx,
        "tonemap test pixels",
        (n * 4) as u64,
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        gpu_allocator::MemoryLocation::GpuToCpu,
    )
    .unwrap();
    let size = [n as u32, 1];
    for curve in [ToneCurve::None, ToneCurve::Aces, ToneCurve::Agx, ToneCurve::PbrNeutral] {
        let exposure = 0.5f32;
        ctx.submit_and_wait(|cmd| {
            r.record_tonemap_image(cmd, &image, size, &out, size, curve.code(), 2f32.powf(exposure))
        })
        .unwrap();
        let words: Vec<u32> = out.download(ctx).unwrap();
        let host = Display { exposure, curve };
        for (i, w) in words.iter().enumerate() {
            let device = w.to_le_bytes();
            let want = host.pixel(values[i]);
            for k in 0..3 {
                assert!(
                    (device[k] as i32 - want[k] as i32).abs() <= 1,
                    "{curve:?} of {:?}: the device shows {:?}, the host {want:?}",
                    values[i],
                    &device[..3]
                );
            }
        }
    }
}

/// An 8-bit map (PNG or JPEG) is sRGB-decoded: an upward-facing white Lambertian floor seen from above under it
/// shows (1 / pi) times the cosine-weighted integral of the decoded map over the upper hemisphere, computed here
/// texel by texel (the lookup is nearest, so the integral is exact). Taken as linear, the same map would give a
/// value many standard errors away.
#[test]
fn eight_bit_environment_maps_are_srgb_decoded() {
    let (w, h) = (64u32, 32u32);
    let rgb = image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([(x * 4) as u8, (255 - y * 6) as u8, (40 + (x * 7 + y * 13) % 180) as u8])
    });
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("sky.png");
    let jpg = dir.path().join("sky.jpg");
    rgb.save(&png).unwrap();
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
        .encode_image(&rgb)
        .unwrap();
    std::fs::write(&jpg, jpeg).unwrap();

    let mut b = GltfBuilder::new();
    let white = b.material("white", [1.0; 3], [0.0; 3], false);
    let c = [
        [-50.0, 0.0, -50.0],
        [50.0, 0.0, -50.0],
        [50.0, 0.0, 50.0],
        [-50.0, 0.0, 50.0],
    ];
    b.quad("floor", c, white, Some([0.0, 1.0, 0.0]));
    b.orthographic_camera([0.0, 5.0, 0.0], [0.0; 3], [0.0, 0.0, -1.0], 1.0, 1.0);
    let (_d, scene_path) = common::write_temp(&b, "floor.gltf");
    for map in [&png, &jpg] {
        let decoded = image::open(map).unwrap().into_rgb8();
        let integral = |decode: &dyn Fn(u8) -> f64| -> [f64; 3] {
            let mut sum = [0.0; 3];
            for y in 0..h / 2 {
                let (t0, t1) = (
                    std::f64::consts::PI * y as f64 / h as f64,
                    std::f64::consts::PI * (y + 1) as f64 / h as f64,
                );
                // (1 / pi) * dphi * integral of cos sin dtheta over the row
                let weight = (2.0 / w as f64) * 0.5 * (t1.sin().powi(2) - t0.sin().powi(2));
                for x in 0..w {
                    let p = decoded.get_pixel(x, y).0;
                    for k in 0..3 {
                        sum[k] += weight * decode(p[k]);
                    }
                }
            }
            sum
        };
        let expected = integral(&|v| srgb_decode(v as f32 / 255.0) as f64);
        let as_linear = integral(&|v| v as f64 / 255.0);
        let mut scene = pathwave::scene::load(&scene_path, None).unwrap();
        scene.environment = Some(pathwave::scene::Environment::load(map, 1.0).unwrap());
        let mut r = common::scene_renderer(&scene);
        let film = common::render(&mut r, &common::settings(16, 16, 256, 5));
        let (mean, var) = (film.mean(), film.sample_variance());
        let n = mean.len() as f64;
        for k in 0..3 {
            let m = mean.iter().map(|p| p[k] as f64).sum::<f64>() / n;
            let se = (var.iter().map(|v| v[k] as f64).sum::<f64>() / n / (n * 256.0)).sqrt();
            assert!(
                (m - expected[k]).abs() < 4.0 * se + 1e-4,
                "{map:?} channel {k}: the floor shows {m:.5} +- {se:.5}, the decoded map's integral is {:.5}",
                expected[k]
            );
            assert!(
                (as_linear[k] - expected[k]).abs() > 10.0 * se,
                "channel {k}: the test cannot tell decoded from linear"
            );
        }
    }
}

/// --env-rotation -90 shows a map as three.js and Blender do (docs/guide/rendering.md, "Environment map"): the map's centre straight
/// ahead of a camera looking down +x, and a quarter turn later (u = 0.75) down +z.
#[test]
fn env_rotation_minus_90_matches_three_js_and_blender() {
    let (w, h) = (64u32, 32u32);
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("spots.png");
    image::RgbImage::from_fn(w, h, |x, y| {
        let spot = (15..17).contains(&y);
        match x {
            31..=32 if spot => image::Rgb([255, 0, 0]),
            47..=48 if spot => image::Rgb([0, 255, 0]),
            _ => image::Rgb([0, 0, 0]),
        }
    })
    .save(&map)
    .unwrap();
    for (target, channel) in [([1.0, 0.0, 0.0], 0usize), ([0.0, 0.0, 1.0], 1)] {
        // A speck far below, out of view: a scene needs a triangle.
        let mut b = GltfBuilder::new();
        let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
        b.cube("speck", [-0.01, -50.0, -0.01], [0.01, -49.98, 0.01], grey, false);
        b.camera([0.0; 3], target, [0.0, 1.0, 0.0], 4.0);
        let (_d, path) = common::write_temp(&b, "spots.gltf");
        let mut scene = pathwave::scene::load(&path, None).unwrap();
        let mut env = pathwave::scene::Environment::load(&map, 1.0).unwrap();
        env.rotation = (-90f32).to_radians();
        scene.environment = Some(env);
        let mut r = common::scene_renderer(&scene);
        let px = common::render(&mut r, &common::settings(3, 3, 16, 0)).mean();
        assert!(
            px[4][channel] > 0.9,
            "looking at {target:?}: the centre shows {:?}",
            px[4]
        );
    }
}
