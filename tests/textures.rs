//! Textures on the device: known texels at known pixels through KHR_texture_transform and every wrap mode, bilinear
//! filtering after sRGB decoding, base colour and metallic-roughness maps, normal maps (generated and given
//! tangents), alpha MASK and BLEND for camera and shadow rays, and emissive textures in next-event estimation.
mod common;

use common::gltf_builder::{upright, GltfBuilder, FACING_Z};
use common::screen;
use pathwave::scene::{texture::srgb_to_linear, Environment};
use serde_json::json;

const N: usize = 8; // image side in pixels; the quad fills the view exactly
const NEAREST: u32 = 9728;
const LINEAR: u32 = 9729;
const REPEAT: u32 = 10497;
const CLAMP: u32 = 33071;
const MIRROR: u32 = 33648;

/// Renders `b` at N x N (16 samples per pixel, seed 3, unless `settings` says otherwise) in the uniform environment
/// `env`.
fn render(b: &GltfBuilder, env: Option<[f32; 3]>, settings: impl Fn(&mut pathwave::RenderSettings)) -> pathwave::Film {
    let mut scene = common::load_built(b, "textured.gltf");
    scene.environment = env.map(Environment::constant);
    let mut s = common::settings(N as u32, N as u32, 16, 3);
    settings(&mut s);
    common::render(&mut common::scene_renderer(&scene), &s)
}

/// 4x4 texels, each a different colour (sRGB bytes).
fn texels4() -> Vec<[u8; 4]> {
    (0..16)
        .map(|k| [30 + 50 * (k % 4) as u8, 30 + 50 * (k / 4) as u8, 200, 255])
        .collect()
}

fn decode(t: [u8; 4]) -> [f32; 3] {
    [0, 1, 2].map(|c| srgb_to_linear(t[c] as f32 / 255.0))
}

fn wrap(i: i64, n: i64, mode: u32) -> usize {
    (match mode {
        CLAMP => i.clamp(0, n - 1),
        MIRROR => {
            let m = i.rem_euclid(2 * n);
            if m >= n {
                2 * n - 1 - m
            } else {
                m
            }
        }
        _ => i.rem_euclid(n),
    }) as usize
}

/// KHR_texture_transform as the extension defines it: offset + rotate(scale * uv), the rotation counter-clockwise
/// in uv space (whose v axis points down): (u, v) -> (u cos + v sin, -u sin + v cos).
fn transformed(uv: [f64; 2], offset: [f64; 2], rotation: f64, scale: [f64; 2]) -> [f64; 2] {
    let (s, c) = rotation.sin_cos();
    let (u, v) = (uv[0] * scale[0], uv[1] * scale[1]);
    [offset[0] + c * u + s * v, offset[1] - s * u + c * v]
}

/// An emissive quad with a nearest-filtered 4x4 texture: each pixel's footprint lies inside one texel, so every
/// pixel must be exactly that texel's decoded colour.
#[test]
fn nearest_texels_land_on_known_pixels_through_transforms_and_wrap_modes() {
    // (name, offset, rotation, scale, wrapS, wrapT)
    type Case = (&'static str, [f64; 2], f64, [f64; 2], u32, u32);
    let cases: [Case; 4] = [
        ("identity", [0.0, 0.0], 0.0, [1.0, 1.0], REPEAT, REPEAT),
        (
            "offset, rotation, scale",
            [0.25, 0.5],
            std::f64::consts::FRAC_PI_2,
            [0.5, 0.5],
            REPEAT,
            REPEAT,
        ),
        ("mirrored s, clamped t", [-0.5, -0.25], 0.0, [2.0, 2.0], MIRROR, CLAMP),
        ("clamped s, repeated t", [-0.5, -0.25], 0.0, [2.0, 2.0], CLAMP, REPEAT),
    ];
    let texels = texels4();
    for (name, offset, rotation, scale, wrap_s, wrap_t) in cases {
        let mut b = GltfBuilder::new();
        let m = b.pbr_material("screen", [0.0; 3], 0.0, 1.0, [1.0; 3], false);
        let image = b.png_image(4, 4, &texels);
        let t = b.texture(image, json!({ "magFilter": NEAREST, "wrapS": wrap_s, "wrapT": wrap_t }));
        let mut info = json!({ "index": t });
        if name != "identity" {
            info["extensions"]["KHR_texture_transform"] =
                json!({ "offset": offset, "rotation": rotation, "scale": scale });
            b.use_extension("KHR_texture_transform");
        }
        b.material_json(m)["emissiveTexture"] = info;
        screen::quad(&mut b, m, 0.0);
        screen::view(&mut b);
        let film = render(&b, None, |s| s.max_depth = Some(0));
        let mean = film.mean();
        let mut wrong = Vec::new();
        for j in 0..N {
            for i in 0..N {
                let uv = [(i as f64 + 0.5) / N as f64, (j as f64 + 0.5) / N as f64];
                let st = transformed(uv, offset, rotation, scale);
                let x = wrap((st[0] * 4.0).floor() as i64, 4, wrap_s);
                let y = wrap((st[1] * 4.0).floor() as i64, 4, wrap_t);
                let want = decode(texels[y * 4 + x]);
                let got = mean[j * N + i];
                if (0..3).any(|c| (got[c] - want[c]).abs() > 1e-4) {
                    wrong.push(format!("({i}, {j}): {got:?}, want texel ({x}, {y}) {want:?}"));
                }
            }
        }
        assert!(
            wrong.is_empty(),
            "{name}: {} of {} pixels differ: {:?}",
            wrong.len(),
            N * N,
            &wrong[..wrong.len().min(6)]
        );
    }
}

/// A black and a white texel, bilinearly filtered and clamped: the radiance is linear in u between the texel
/// centres (u = 1/4 and 3/4) because sRGB is decoded before filtering; filtering the encoded values would give
/// srgb_to_linear of the ramp instead (0.12 instead of 0.38 at u = 7/16).
#[test]
fn bilinear_filtering_interpolates_decoded_colour() {
    let mut b = GltfBuilder::new();
    let m = b.pbr_material("screen", [0.0; 3], 0.0, 1.0, [1.0; 3], false);
    let image = b.png_image(2, 1, &[[0, 0, 0, 255], [255, 255, 255, 255]]);
    let t = b.texture(image, json!({ "magFilter": LINEAR, "wrapS": CLAMP, "wrapT": CLAMP }));
    b.material_json(m)["emissiveTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let film = render(&b, None, |s| {
        s.max_depth = Some(0);
        s.spp = 64;
    });
    let mean = film.mean();
    for j in 0..N {
        for i in 0..N {
            let u = (i as f64 + 0.5) / N as f64;
            let want = ((u - 0.25) / 0.5).clamp(0.0, 1.0);
            let got = mean[j * N + i][0] as f64;
            // The jitter's mean over 64 samples is within 1/64 pixel of the centre; the ramp climbs 1/4 per pixel.
            assert!((got - want).abs() < 0.01, "pixel ({i}, {j}): {got}, want {want}");
        }
    }
}

/// A Lambertian quad under a uniform white sky, one bounce, BSDF sampling only: every sample returns the albedo
/// exactly, so each pixel is its texel's decoded base colour times baseColorFactor.
#[test]
fn base_color_texture_is_the_albedo() {
    let texels = texels4();
    let mut b = GltfBuilder::new();
    let m = b.material("quad", [0.5, 1.0, 0.8], [0.0; 3], false);
    let image = b.png_image(4, 4, &texels);
    let t = b.texture(image, json!({ "magFilter": NEAREST }));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let film = render(&b, Some([1.0; 3]), |s| {
        s.max_depth = Some(1);
        s.estimator = pathwave::Estimator::Bsdf;
    });
    let mean = film.mean();
    for j in 0..N {
        for i in 0..N {
            let texel = decode(texels[(j / 2) * 4 + i / 2]);
            let want = [texel[0] * 0.5, texel[1], texel[2] * 0.8];
            let got = mean[j * N + i];
            assert!(
                (0..3).all(|c| (got[c] - want[c]).abs() < 1e-4),
                "({i}, {j}): {got:?}, want {want:?}"
            );
        }
    }
}

/// metallicFactor 1 times a texture whose blue (metallic) is 0 in the left half and 1 in the right; green
/// (roughness) is 1 everywhere. The left half is then exactly Lambertian under the sky (albedo 0.25, zero variance),
/// the right half a fully rough grey metal: GGX with alpha 1 reflects about a third of the light in one scattering,
/// so F0 = 0.25 gives about 0.08, plus about 0.03 of multiple scattering, and it is noisy.
#[test]
fn metallic_roughness_texture_reads_blue_and_green() {
    let mut b = GltfBuilder::new();
    let m = b.material("quad", [0.25; 3], [0.0; 3], false);
    b.material_json(m)["pbrMetallicRoughness"]["metallicFactor"] = json!(1.0);
    let texels: Vec<[u8; 4]> = (0..4).map(|x| [0, 255, if x < 2 { 0 } else { 255 }, 255]).collect();
    let image = b.png_image(4, 1, &texels);
    let t = b.texture(image, json!({ "magFilter": NEAREST }));
    b.material_json(m)["pbrMetallicRoughness"]["metallicRoughnessTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let film = render(&b, Some([1.0; 3]), |s| {
        s.max_depth = Some(1);
        s.estimator = pathwave::Estimator::Bsdf;
        s.spp = 64;
    });
    let (mean, var) = (film.mean(), film.sample_variance());
    let mut metal_sum = 0.0;
    let mut metal_var = 0.0;
    for j in 0..N {
        for i in 0..N {
            let (got, v) = (mean[j * N + i][1] as f64, var[j * N + i][1] as f64);
            if i < N / 2 {
                assert!(
                    (got - 0.25).abs() < 1e-4 && v < 1e-8,
                    "diffuse ({i}, {j}): {got} (variance {v})"
                );
            } else {
                metal_sum += got;
                metal_var += v;
            }
        }
    }
    let metal = metal_sum / (N * N / 2) as f64;
    assert!(
        (0.08..0.16).contains(&metal) && metal_var > 0.0,
        "the metallic half gives {metal}, not a rough grey metal's 0.11"
    );
}

/// A white Lambertian quad under a directional light 45 degrees off the normal, towards +x or +y; the normal map
/// tilts the shading normal 30 degrees towards the tangent's +x or +y (glTF: +y is up the image, here world +y).
/// Direct light is albedo / pi * E * cos: cos 15 degrees when the tilt faces the light, cos 75 when it is mirrored.
#[test]
fn normal_maps_tilt_the_shading_normal_the_gltf_way() {
    let tilt = 30f64.to_radians();
    let cases = [
        ("+x", [tilt.sin(), 0.0, tilt.cos()], [1.0, 0.0]),
        ("+y", [0.0, tilt.sin(), tilt.cos()], [0.0, 1.0]),
    ];
    for given_tangents in [false, true] {
        for (name, n, light_xy) in cases {
            let bytes = n.map(|c| ((c + 1.0) * 0.5 * 255.0).round() as u8);
            let decoded = glam::DVec3::from(bytes.map(|b| b as f64 / 255.0 * 2.0 - 1.0)).normalize();
            let mut b = GltfBuilder::new();
            let m = b.material("quad", [1.0; 3], [0.0; 3], false);
            let image = b.png_image(1, 1, &[[bytes[0], bytes[1], bytes[2], 255]]);
            let t = b.texture(image, json!({}));
            b.material_json(m)["normalTexture"] = json!({ "index": t });
            let corners = screen::corners(1.0, 0.0);
            let tangents = [[1.0, 0.0, 0.0, 1.0f32]; 4];
            b.mesh_with_attributes(
                "quad",
                &corners,
                None,
                &screen::UVS,
                given_tangents.then_some(&tangents[..]),
                &[0, 1, 2, 0, 2, 3],
                m,
            );
            // The light travels along -(l): l is 45 degrees from +z towards light_xy.
            let l = glam::DVec3::new(light_xy[0], light_xy[1], 1.0).normalize();
            screen::light_along(&mut b, -l.as_vec3());
            screen::view(&mut b);
            let film = render(&b, None, |s| s.max_depth = Some(1));
            let want = 1.0 / std::f64::consts::PI * 2.0 * decoded.dot(l);
            let label = format!(
                "tilt {name}, {} tangents",
                if given_tangents { "given" } else { "generated" }
            );
            for (k, px) in film.mean().iter().enumerate() {
                let got = px[0] as f64;
                assert!(
                    (got - want).abs() < 1e-4 * want.max(1.0),
                    "{label}: pixel {k} is {got}, want {want}"
                );
            }
        }
    }
}

/// A white emitter behind the view's quad (at z = -1, facing the camera): what alpha lets through shows as 1.
fn emitting_backdrop(b: &mut GltfBuilder) {
    let back = b.pbr_material("emitter", [0.0; 3], 0.0, 1.0, [1.0; 3], false);
    b.quad("emitter", upright([-3.0, 3.0], [-3.0, 3.0], -1.0), back, FACING_Z);
}

fn alpha_material(b: &mut GltfBuilder, mode: &str, alpha: f32, cutoff: Option<f32>) -> usize {
    let m = b.material("occluder", [0.0; 3], [0.0; 3], true);
    let mj = b.material_json(m);
    mj["alphaMode"] = json!(mode);
    mj["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(alpha);
    if let Some(c) = cutoff {
        mj["alphaCutoff"] = json!(c);
    }
    m
}

/// A black quad in front of an emitting one, seen by camera rays: MASK with a checkerboard alpha texture shows the
/// emitter exactly where alpha < cutoff; BLEND with alpha 0.25 lets 3/4 of the samples through.
#[test]
fn alpha_mask_and_blend_hide_surfaces_from_camera_rays() {
    let mut b = GltfBuilder::new();
    let m = alpha_material(&mut b, "MASK", 1.0, Some(0.5));
    let texels: Vec<[u8; 4]> = (0..16)
        .map(|k| [255, 255, 255, if (k % 4 + k / 4) % 2 == 0 { 40 } else { 220 }])
        .collect();
    let image = b.png_image(4, 4, &texels);
    let t = b.texture(image, json!({ "magFilter": NEAREST }));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.5);
    emitting_backdrop(&mut b);
    // The occluder at z = 0.5 fills a wider view than N pixels: frame exactly it.
    let yfov = 2.0 * (1.0f32 / 1.5).atan();
    b.camera([0.0, 0.0, 2.0], [0.0; 3], [0.0, 1.0, 0.0], yfov.to_degrees());
    let film = render(&b, None, |s| s.max_depth = Some(0));
    for (k, px) in film.mean().iter().enumerate() {
        let (i, j) = (k % N, k / N);
        let transparent = ((i / 2) + (j / 2)) % 2 == 0;
        let want = if transparent { 1.0 } else { 0.0 };
        assert!(
            (px[0] - want).abs() < 1e-6,
            "MASK pixel ({i}, {j}) is {}, want {want}",
            px[0]
        );
    }

    let mut b = GltfBuilder::new();
    let m = alpha_material(&mut b, "BLEND", 0.25, None);
    screen::quad(&mut b, m, 0.5);
    emitting_backdrop(&mut b);
    b.camera([0.0, 0.0, 2.0], [0.0; 3], [0.0, 1.0, 0.0], yfov.to_degrees());
    let film = render(&b, None, |s| {
        s.max_depth = Some(0);
        s.spp = 64;
    });
    let (mean, stderr) = common::stats::image_mean_and_stderr(&film);
    assert!(
        (mean - 0.75).abs() < 4.0 * stderr && stderr < 0.01,
        "BLEND 0.25: {mean} +- {stderr}, want 0.75"
    );
}

/// A Lambertian floor lit straight down by a directional light through an alpha-tested sheet the camera (below the
/// sheet) does not see: MASK below the cutoff lets all light through, above it none, BLEND 0.25 three quarters.
#[test]
fn alpha_mask_and_blend_apply_to_shadow_rays() {
    let albedo = 0.5;
    let e = 3.0;
    let lit = albedo / std::f64::consts::PI * e;
    for (mode, alpha, cutoff, want) in [
        ("MASK", 0.3, Some(0.5), lit),
        ("MASK", 0.7, Some(0.5), 0.0),
        ("BLEND", 0.25, None, 0.75 * lit),
    ] {
        let mut b = GltfBuilder::new();
        let floor = b.material("floor", [albedo as f32; 3], [0.0; 3], false);
        b.quad("floor", upright([-5.0, 5.0], [-5.0, 5.0], 0.0), floor, FACING_Z);
        let m = alpha_material(&mut b, mode, alpha, cutoff);
        b.quad("sheet", upright([-5.0, 5.0], [-5.0, 5.0], 2.0), m, FACING_Z);
        b.directional_light([1.0; 3], e as f32, [0.0, 0.0, 4.0], [0.0, 0.0, 0.0, 1.0]);
        b.camera([0.0, 0.0, 1.0], [0.0; 3], [0.0, 1.0, 0.0], 40.0);
        let film = render(&b, None, |s| {
            s.max_depth = Some(1);
            s.spp = 64;
        });
        let (mean, stderr) = common::stats::image_mean_and_stderr(&film);
        let ok = if mode == "BLEND" {
            (mean - want).abs() < 4.0 * stderr && stderr < 0.01 * lit
        } else {
            (mean - want).abs() < 1e-4
        };
        assert!(ok, "{mode} alpha {alpha}: floor {mean} +- {stderr}, want {want}");
    }
}

/// A floor lit by a ceiling quad whose emissive texture is one bright texel among dark ones: light sampling (which
/// evaluates the texture at the sampled point, and picks the light by its average) and BSDF sampling (which finds
/// the texture by hitting it) must agree.
#[test]
fn emissive_textures_light_the_scene_the_same_for_both_estimators() {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.8; 3], [0.0; 3], false);
    b.quad("floor", upright([-2.0, 2.0], [-2.0, 2.0], 0.0), floor, FACING_Z);
    let light = b.pbr_material("light", [0.0; 3], 0.0, 1.0, [4.0; 3], false);
    let image = b.png_image(
        2,
        2,
        &[
            [255, 255, 255, 255],
            [20, 20, 20, 255],
            [20, 20, 20, 255],
            [20, 20, 20, 255],
        ],
    );
    let t = b.texture(image, json!({ "magFilter": NEAREST }));
    b.material_json(light)["emissiveTexture"] = json!({ "index": t });
    // Facing down (-z): corners counter-clockwise seen from below.
    b.textured_quad(
        "light",
        [[-1.0, 1.0, 1.0], [1.0, 1.0, 1.0], [1.0, -1.0, 1.0], [-1.0, -1.0, 1.0]],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        light,
    );
    b.camera([0.0, -0.5, 0.6], [0.0, 0.3, 0.0], [0.0, 0.0, 1.0], 70.0);
    let run = |estimator, seed| {
        render(&b, None, |s| {
            s.width = 16;
            s.height = 16;
            s.spp = 256;
            s.max_depth = Some(1);
            s.seed = seed;
            s.estimator = estimator;
        })
    };
    let (light_mean, light_err) = common::stats::image_mean_and_stderr(&run(pathwave::Estimator::Light, 1));
    let (bsdf_mean, bsdf_err) = common::stats::image_mean_and_stderr(&run(pathwave::Estimator::Bsdf, 2));
    let sigma = (light_err * light_err + bsdf_err * bsdf_err).sqrt();
    eprintln!("light sampling {light_mean} +- {light_err}, BSDF sampling {bsdf_mean} +- {bsdf_err}");
    assert!(
        (light_mean - bsdf_mean).abs() < 4.0 * sigma,
        "{light_mean} vs {bsdf_mean} (sigma {sigma})"
    );
    assert!(sigma < 0.02 * light_mean, "too noisy to tell: sigma {sigma}");
}

/// COLOR_0 multiplies the base colour: a grey Lambertian quad with red, green, blue and white corners under a white
/// sky (one bounce, BSDF sampling) shows half the colour interpolated across each of its two triangles.
#[test]
fn vertex_colours_multiply_the_base_colour() {
    let mut b = GltfBuilder::new();
    let m = b.material("quad", [0.5; 3], [0.0; 3], false);
    screen::quad(&mut b, m, 0.0);
    // Corners: top-left, bottom-left, bottom-right, top-right.
    let colors = [
        [1.0, 0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0, 1.0],
        [0.0, 0.0, 1.0, 1.0],
        [1.0, 1.0, 1.0, 1.0],
    ];
    b.add_colors(&colors);
    screen::view(&mut b);
    let film = render(&b, Some([1.0; 3]), |s| {
        s.max_depth = Some(1);
        s.estimator = pathwave::Estimator::Bsdf;
        s.spp = 64;
    });
    let corner = |k: usize| glam::DVec3::new(colors[k][0] as f64, colors[k][1] as f64, colors[k][2] as f64);
    for (k, px) in film.mean().iter().enumerate() {
        let (i, j) = (k % N, k / N);
        let (u, v) = ((i as f64 + 0.5) / N as f64, (j as f64 + 0.5) / N as f64);
        // Triangles (top-left, bottom-left, bottom-right) below the diagonal, (top-left, bottom-right, top-right) above.
        let c = if v >= u {
            corner(0) * (1.0 - v) + corner(1) * (v - u) + corner(2) * u
        } else {
            corner(0) * (1.0 - u) + corner(2) * v + corner(3) * (u - v)
        };
        let want = c * 0.5;
        let got = glam::DVec3::new(px[0] as f64, px[1] as f64, px[2] as f64);
        assert!(
            (got - want).abs().max_element() < 0.03,
            "pixel ({i}, {j}): {got}, want {want}"
        );
    }
}

/// COLOR_0's alpha multiplies the material's: a black quad whose vertex alpha runs from 0 on its left edge to 1 on
/// its right, in front of an emitter. MASK (cutoff 0.5) hides its left half from camera rays, BLEND lets 1 - alpha
/// of each column's samples through (alpha is linear in x across both triangles), and OPAQUE ignores alpha, as glTF
/// says. Would catch vertex alpha dropped (it was: every mode rendered the quad opaque), or applied under OPAQUE.
#[test]
fn vertex_alpha_is_coverage_under_mask_and_blend() {
    let yfov = 2.0 * (1.0f32 / 1.5).atan();
    for mode in ["MASK", "BLEND", "OPAQUE"] {
        let mut b = GltfBuilder::new();
        let m = alpha_material(&mut b, mode, 1.0, None);
        screen::quad(&mut b, m, 0.5);
        // Corners: top-left, bottom-left, bottom-right, top-right.
        b.add_colors(&[
            [1.0, 1.0, 1.0, 0.0],
            [1.0, 1.0, 1.0, 0.0],
            [1.0, 1.0, 1.0, 1.0],
            [1.0, 1.0, 1.0, 1.0],
        ]);
        emitting_backdrop(&mut b);
        b.camera([0.0, 0.0, 2.0], [0.0; 3], [0.0, 1.0, 0.0], yfov.to_degrees());
        let film = render(&b, None, |s| {
            s.max_depth = Some(0);
            s.spp = 256;
        });
        let (mean, var) = (film.mean(), film.sample_variance());
        for i in 0..N {
            let column: f64 = (0..N).map(|j| mean[j * N + i][0] as f64).sum::<f64>() / N as f64;
            let stderr = ((0..N).map(|j| var[j * N + i][0] as f64).sum::<f64>() / film.spp as f64).sqrt() / N as f64;
            let u = (i as f64 + 0.5) / N as f64;
            let want = match mode {
                "MASK" => f64::from(u < 0.5),
                "BLEND" => 1.0 - u,
                _ => 0.0,
            };
            eprintln!("{mode} column {i}: {column:.4} +- {stderr:.4}, want {want:.4}");
            assert!(
                (column - want).abs() < 4.0 * stderr + 1e-6,
                "{mode}: column {i} lets {column} through, want {want}"
            );
        }
    }
}

/// A texture whose image file is missing is left out with a warning naming the image, and its material renders
/// with its factors (as Blender and three.js do); `strict` (--strict) refuses the scene instead. Would catch the
/// whole scene refused for one missing file (it was), the warning lost, or the texture's slot left pointing at
/// nothing.
#[test]
fn a_missing_image_file_leaves_its_texture_out_with_a_warning() {
    let mut b = GltfBuilder::new();
    let m = b.material("grey", [0.5; 3], [0.0; 3], false);
    let image = b.png_image(1, 1, &[[255, 0, 0, 255]]);
    let t = b.texture(image, json!({}));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let mut doc: serde_json::Value = serde_json::from_str(&b.to_json()).unwrap();
    doc["images"][0] = json!({ "uri": "gone.png", "name": "brick" });
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();

    let strict = pathwave::scene::LoadOptions {
        strict: true,
        ..Default::default()
    };
    let e = pathwave::scene::load_with(&path, &strict)
        .map(|_| ())
        .expect_err("--strict refuses")
        .to_string();
    assert!(e.contains("image 0 'brick'") && e.contains("file not found"), "{e}");

    let mut scene = pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let w = &scene.warnings[0];
    assert!(
        w.contains("image 0 'brick' (gone.png): file not found") && w.contains("--strict"),
        "{w}"
    );
    assert!(scene.materials[0].base_color_texture.is_none());
    // Its factor, 0.5 grey, under a white sky, one bounce by BSDF sampling: exactly 0.5.
    scene.environment = Some(Environment::constant([1.0; 3]));
    let mut r = common::scene_renderer(&scene);
    let mut s = common::settings(N as u32, N as u32, 4, 3);
    s.max_depth = Some(1);
    s.estimator = pathwave::Estimator::Bsdf;
    for px in common::render(&mut r, &s).mean() {
        assert!(px.iter().all(|c| (c - 0.5).abs() < 1e-4), "{px:?}");
    }
}

/// KHR_materials_pbrSpecularGlossiness as its metal-rough equivalent (the extension's own reading: diffuse is the
/// colour under a dielectric whose F0 is the specular colour, glossiness = 1 - roughness): a dielectric specular of
/// exactly the default F0 0.04, glossiness 0.625 and a diffuse texture, and then a specular-glossiness texture whose
/// alpha varies per texel, must render as the metallic-roughness material with the same base colour texture,
/// roughness 0.375 or a metallicRoughnessTexture of green 255 - alpha. Property names as the extension's README
/// table gives them (its schema file is not among the copies in tests/data).
#[test]
fn specular_glossiness_renders_as_its_metal_rough_equivalent() {
    let f0 = (0.5f32 / 2.5).powi(2); // IOR 1.5's F0, as the loader computes it
    let gloss_texels: Vec<[u8; 4]> = (0..16).map(|k| [255, 255, 255, (k * 17) as u8]).collect();
    for textured in [false, true] {
        let scene = |spec_gloss: bool, glossiness: f32| {
            let mut b = GltfBuilder::new();
            let m = b.pbr_material("m", [1.0; 3], 0.0, 0.375, [0.0; 3], false);
            let image = b.png_image(4, 4, &texels4());
            let base = b.texture(image, json!({ "magFilter": NEAREST }));
            let rough_texels: Vec<[u8; 4]> = gloss_texels.iter().map(|t| [0, 255 - t[3], 0, 255]).collect();
            let gloss = if spec_gloss { &gloss_texels } else { &rough_texels };
            let image = b.png_image(4, 4, gloss);
            let second = b.texture(image, json!({ "magFilter": NEAREST }));
            if spec_gloss {
                let mut ext = json!({
                    "diffuseFactor": [1.0, 1.0, 1.0, 1.0],
                    "diffuseTexture": { "index": base },
                    "specularFactor": [f0, f0, f0],
                    "glossinessFactor": glossiness,
                });
                if textured {
                    ext["glossinessFactor"] = json!(1.0);
                    ext["specularGlossinessTexture"] = json!({ "index": second });
                }
                *b.material_json(m) =
                    json!({ "name": "m", "extensions": { "KHR_materials_pbrSpecularGlossiness": ext } });
                b.use_extension("KHR_materials_pbrSpecularGlossiness");
            } else {
                b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": base });
                if textured {
                    b.material_json(m)["pbrMetallicRoughness"]["roughnessFactor"] = json!(1.0);
                    b.material_json(m)["pbrMetallicRoughness"]["metallicRoughnessTexture"] = json!({ "index": second });
                }
            }
            screen::quad(&mut b, m, 0.0);
            screen::view(&mut b);
            b
        };
        let settings = |s: &mut pathwave::RenderSettings| s.spp = 64;
        let sg = render(&scene(true, 0.625), Some([1.0; 3]), settings).mean();
        let mr = render(&scene(false, 0.625), Some([1.0; 3]), settings).mean();
        for (i, (a, b)) in sg.iter().zip(&mr).enumerate() {
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 1e-3 * b[c].max(a[c]) + 1e-6,
                    "textured {textured}, pixel {i}: specular-glossiness {a:?}, metallic-roughness {b:?}"
                );
            }
        }
        if !textured {
            // The test can fail: another glossiness is another image here.
            let other = render(&scene(true, 0.95), Some([1.0; 3]), settings).mean();
            let moved = other
                .iter()
                .zip(&mr)
                .filter(|(a, b)| (a[0] - b[0]).abs() > 1e-2 * b[0])
                .count();
            assert!(moved > 0, "glossiness 0.95 rendered like 0.625");
        }
    }
}

/// A Lambertian quad textured with a 256x256 black and white checkerboard of single texels, under a white sky with
/// BSDF sampling only (each sample returns the albedo it finds): 32 texels across each of the 8x8 pixels. Mip
/// levels prefilter it, so one sample per pixel already shows its average, 0.5 in linear light (the analytic answer,
/// independent of pathwave's filtering), in every pixel and for every seed (no shimmer); read from level 0
/// (bilinear, or a sampler whose minFilter LINEAR asks for no mipmaps) each sample lands on black, white or between
/// and the pixels scatter widely about the same average. Catches levels averaged in sRGB (0.21), a level chosen
/// too fine (shimmer returns), the footprint ignored, or a sampler's "no mipmaps" ignored.
#[test]
fn a_minified_checkerboard_is_its_average_at_one_sample_without_shimmer() {
    let side = 256;
    let texels: Vec<[u8; 4]> = (0..side * side)
        .map(|k| {
            let v = if (k % side + k / side) % 2 == 0 { 255 } else { 0 };
            [v, v, v, 255]
        })
        .collect();
    let built = |sampler: serde_json::Value| {
        let mut b = GltfBuilder::new();
        let m = b.material("quad", [1.0; 3], [0.0; 3], false);
        let image = b.png_image(side as u32, side as u32, &texels);
        let t = b.texture(image, sampler);
        b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
        screen::quad(&mut b, m, 0.0);
        screen::view(&mut b);
        b
    };
    let mipmapped = built(json!({}));
    let no_mipmaps = built(json!({ "minFilter": LINEAR }));
    let one_sample = |b: &GltfBuilder, seed: u32, filter: pathwave::TextureFilter| {
        let film = render(b, Some([1.0; 3]), |s| {
            s.max_depth = Some(1);
            s.estimator = pathwave::Estimator::Bsdf;
            s.spp = 1;
            s.seed = seed;
            s.texture_filter = filter;
        });
        film.mean().iter().map(|p| p[1]).collect::<Vec<f32>>()
    };
    let (mut spread_lod, mut spread_flat, mut sum_flat, mut n) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for seed in 1..=4 {
        let lod = one_sample(&mipmapped, seed, pathwave::TextureFilter::Trilinear);
        let flat = one_sample(&mipmapped, seed, pathwave::TextureFilter::Bilinear);
        assert_eq!(
            one_sample(&no_mipmaps, seed, pathwave::TextureFilter::Trilinear),
            flat,
            "minFilter LINEAR (no mipmaps) reads level 0 as --texture-filter bilinear does"
        );
        for (&a, &b) in lod.iter().zip(&flat) {
            assert!(
                (a - 0.5).abs() < 0.01,
                "seed {seed}: a pixel of the mip-mapped checkerboard is {a}, not 0.5"
            );
            spread_lod += ((a - 0.5) as f64).powi(2);
            spread_flat += ((b - 0.5) as f64).powi(2);
            sum_flat += b as f64;
            n += 1.0;
        }
    }
    let (rms_lod, rms_flat) = ((spread_lod / n).sqrt(), (spread_flat / n).sqrt());
    // Level 0 at one sample: each pixel one bilinear lookup of the checkerboard at a uniform point of a texel square,
    // (1 - x)(1 - y) + xy, whose standard deviation is sqrt(1/36) = 0.17; 256 of them average to 0.5 within 0.01
    // (one standard deviation), so 0.05 is five.
    assert!(rms_flat > 0.1, "level 0 should shimmer: rms {rms_flat}");
    assert!(rms_lod < 0.01, "the mip-mapped checkerboard shimmers: rms {rms_lod}");
    assert!(
        (sum_flat / n - 0.5).abs() < 0.05,
        "level 0's mean {} is not the checkerboard's 0.5",
        sum_flat / n
    );
}

/// Magnified textures keep their detail: where a pixel spans less than a texel, the mip-mapped lookup is level 0's
/// bilinear one, to the bit (the 4x4 texture over 8x8 pixels of base_color_texture_is_the_albedo, bilinear, at 16
/// samples, whose later samples' footprints shrink further).
#[test]
fn magnified_textures_read_level_zero_to_the_bit() {
    let mut b = GltfBuilder::new();
    let m = b.material("quad", [0.5, 1.0, 0.8], [0.0; 3], false);
    let image = b.png_image(4, 4, &texels4());
    let t = b.texture(image, json!({}));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let with = |filter| {
        render(&b, Some([1.0; 3]), |s| {
            s.max_depth = Some(1);
            s.estimator = pathwave::Estimator::Bsdf;
            s.texture_filter = filter;
        })
        .mean()
    };
    assert_eq!(
        with(pathwave::TextureFilter::Trilinear),
        with(pathwave::TextureFilter::Bilinear)
    );
}
