//! Spectral transport (FEATURE_SPECTRAL) end to end on the device: white furnaces stay white, colours upsampled to
//! spectra and integrated back by the film keep their values, and a neutral scene renders the same in RGB and
//! spectral mode. Each compares per-channel means against their standard errors (fixed seeds).
mod common;

use common::gltf_builder::{upright, FACING_Z};
use pathwave::scene::{Material, Scene};
use pathwave::{Film, RenderSettings, Renderer};

/// A faceted sphere filling the view in a uniform environment (the white-furnace scene of tests/environment.rs).
fn sphere(material: Material, env: [f32; 3]) -> Scene {
    common::sphere_in_environment(material, env, false)
}

fn spectral(width: u32, height: u32, spp: u32, seed: u32) -> RenderSettings {
    RenderSettings {
        spectral: true,
        ..common::settings(width, height, spp, seed)
    }
}

/// Per channel, the mean over the central 8x8 pixels of a 16x16 film (all on the sphere) and its standard error.
fn centre_means(film: &Film) -> [(f64, f64); 3] {
    let (mean, var) = (film.mean(), film.sample_variance());
    std::array::from_fn(|c| {
        let (mut sum, mut v, mut n) = (0.0, 0.0, 0.0);
        for y in 4..12 {
            for x in 4..12 {
                let i = y * film.width as usize + x;
                sum += mean[i][c] as f64;
                v += var[i][c] as f64 / film.spp as f64;
                n += 1.0;
            }
        }
        (sum / n, (v / (n * n)).sqrt())
    })
}

/// `got` within z standard errors plus `tolerance` of `want`, per channel.
fn assert_channels(what: &str, got: [(f64, f64); 3], want: [f64; 3], tolerance: f64) {
    for c in 0..3 {
        let (m, se) = got[c];
        eprintln!("{what}: channel {c}: {m:.5} ± {se:.5}, expected {:.5}", want[c]);
        assert!(
            se > 0.0,
            "{what}: no noise in channel {c}: the wavelengths are not being sampled"
        );
        assert!(
            (m - want[c]).abs() < 4.0 * se + tolerance,
            "{what}: channel {c} is {m} ± {se}, expected {} (±{tolerance} for the upsampling's round trip)",
            want[c]
        );
    }
}

/// In a white environment (D65 in spectral mode), materials that keep all energy return exactly what arrives, which
/// the film turns back into white: a Lambertian, a smooth and a rough white dielectric (refraction and reflection
/// at one IOR for every wavelength). Catches a film weight that forgets the wavelengths' density, D65 or the
/// observer normalised wrongly (every channel off by the same factor), or an XYZ matrix off (the channels apart).
#[test]
fn white_furnaces_stay_white_in_spectral_mode() {
    let glass = |thin_walled: bool| Material {
        metallic: 0.0,
        roughness: 0.0,
        transmission: 1.0,
        thin_walled,
        ..Material::default()
    };
    // (A rough dielectric loses what its microfacets scatter more than once, in RGB as well: 1.4 % at roughness 0.3.)
    let cases = [
        ("lambert", common::lambert()),
        ("glass sphere", glass(false)),
        ("thin glass shell", glass(true)),
        // Every wavelength bent its own way, each path keeping its hero alone past the first hit.
        (
            "dispersive glass sphere",
            Material {
                dispersion: 1.0,
                ..glass(false)
            },
        ),
    ];
    for (name, m) in cases {
        let mut r = common::scene_renderer(&sphere(m, [1.0; 3]));
        let film = common::render(&mut r, &spectral(16, 16, 1024, 3));
        assert_channels(name, centre_means(&film), [1.0; 3], 0.0);
    }
}

/// A closed room of grey emission 0.5 and albedo 0.5 converges to 0.5 / (1 - 0.5) = 1 in every channel, spectral:
/// many bounces, so a throughput that drifts between wavelengths (one of the four lanes not carried along) shows.
#[test]
fn the_closed_furnace_stays_white_in_spectral_mode() {
    let (_dir, path) = common::write_temp(&common::scenes::furnace(0.5, 0.5), "furnace.gltf");
    let mut r = common::renderer(&path);
    let film = common::render(&mut r, &spectral(16, 16, 256, 7));
    assert_channels("furnace", centre_means(&film), [1.0; 3], 0.0);
}

/// A closed room of coloured emission and coloured albedo: every wavelength converges to its own E / (1 - a), which
/// the film integrates over the observer. The expected colour is that integral at 1 nm steps with the host's spectra
/// (tests/spectrum.rs holds them to the CIE data and the round trip); it is not E / (1 - a) per channel, which the
/// spectra's overlap moves by up to 0.05 here. Nothing in this room needs the RGB-to-spectrum table on the device (the
/// Cornell box's kind of scene: untextured colours, emitters, no environment), so it checks what the scene's
/// precomputed coefficients give: a base colour or emission whose coefficients the host got wrong, or a colour the
/// host's FEATURE_SPECTRUM_TABLE rule missed (a NaN sample the film drops), is off by far more than the noise.
#[test]
fn a_coloured_closed_room_converges_to_its_spectral_fixed_point() {
    use pathwave::constants::{LAMBDA_MAX, LAMBDA_MIN};
    let (emission, albedo) = ([0.5f32, 0.35, 0.2], [0.6f32, 0.3, 0.1]);
    let mut b = common::gltf_builder::GltfBuilder::new();
    let m = b.material("wall", albedo, emission, false);
    b.cube("room", [-1.0; 3], [1.0; 3], m, true);
    b.camera([0.2, -0.1, 0.3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 60.0);
    let (_dir, path) = common::write_temp(&b, "room.gltf");
    let t = pathwave::spectrum::tables();
    let mut xyz = [0.0f64; 3];
    let steps = (LAMBDA_MAX - LAMBDA_MIN) as usize;
    for k in 0..=steps {
        let nm = LAMBDA_MIN + k as f32;
        let w = if k == 0 || k == steps { 0.5 } else { 1.0 };
        let l = t.emission(emission, nm) as f64 / (1.0 - t.reflectance(albedo, nm) as f64);
        let o = t.observer(nm);
        (0..3).for_each(|c| xyz[c] += w * o[c] as f64 * l);
    }
    let m = t.xyz_to_srgb();
    let want = [0, 1, 2].map(|r| (0..3).map(|k| m[r][k] as f64 * xyz[k]).sum::<f64>());
    let mut r = common::renderer(&path);
    let (film, stats) = r.render(&spectral(16, 16, 256, 9), &mut |_| {}).unwrap();
    assert_eq!(stats.nonfinite, 0, "samples came out non-finite: {}", stats.summary());
    assert_channels("coloured room", centre_means(&film), want, 0.0);
}

/// Colours survive the trip to spectra and back: a Lambertian sphere of albedo (0.8, 0.3, 0.1) in a white
/// environment shows that albedo (a reflectance upsampled on the device), and a white one in an environment of
/// (0.9, 0.4, 0.1) shows that colour (an emitter: the upsampled spectrum times D65). The tolerance is the table's
/// round trip, 0.004 (tests/spectrum.rs). Catches a device lookup that differs from the host's table (a wrong
/// node, corner or channel moves a colour by 0.05 or more).
#[test]
fn colours_keep_their_values_in_spectral_mode() {
    let lambert = |rgb: [f32; 3]| Material {
        base_color: glam::Vec3::from(rgb),
        ..common::lambert()
    };
    let mut r = common::scene_renderer(&sphere(lambert([0.8, 0.3, 0.1]), [1.0; 3]));
    let film = common::render(&mut r, &spectral(16, 16, 512, 5));
    assert_channels("albedo (0.8, 0.3, 0.1)", centre_means(&film), [0.8, 0.3, 0.1], 0.004);
    let mut r = common::scene_renderer(&sphere(lambert([1.0; 3]), [0.9, 0.4, 0.1]));
    let film = common::render(&mut r, &spectral(16, 16, 512, 6));
    assert_channels(
        "environment (0.9, 0.4, 0.1)",
        centre_means(&film),
        [0.9, 0.4, 0.1],
        0.004,
    );
}

/// The Cornell box with every colour made grey and its light white: spectra are then constant and RGB and spectral
/// transport estimate the same image; their means agree per channel within the two renders' noise. Catches spectral
/// transport that changes what grey surfaces do (a lobe, a light or the film weighted differently).
#[test]
fn a_neutral_scene_renders_the_same_in_rgb_and_spectral_mode() {
    let mut scene = pathwave::scene::load(&common::cornell(), None).unwrap();
    for m in &mut scene.materials {
        m.base_color = glam::Vec3::splat(m.base_color.element_sum() / 3.0);
        m.emission = glam::Vec3::splat(m.emission.max_element());
    }
    let mut r = common::scene_renderer(&scene);
    let rgb = common::render(&mut r, &common::settings(32, 32, 128, 11));
    let spec = common::render(&mut r, &spectral(32, 32, 128, 12));
    let stats = |f: &Film| -> [(f64, f64); 3] {
        let (mean, var) = (f.mean(), f.sample_variance());
        let n = mean.len() as f64;
        std::array::from_fn(|c| {
            let m = mean.iter().map(|p| p[c] as f64).sum::<f64>() / n;
            let v = var.iter().map(|p| p[c] as f64 / f.spp as f64).sum::<f64>() / (n * n);
            (m, v.sqrt())
        })
    };
    let (a, b) = (stats(&rgb), stats(&spec));
    for c in 0..3 {
        let se = (a[c].1 * a[c].1 + b[c].1 * b[c].1).sqrt();
        eprintln!(
            "channel {c}: RGB {:.5} ± {:.5}, spectral {:.5} ± {:.5}",
            a[c].0, a[c].1, b[c].0, b[c].1
        );
        assert!(
            (a[c].0 - b[c].0).abs() < 4.0 * se,
            "channel {c}: RGB {:?} against spectral {:?}",
            a[c],
            b[c]
        );
    }
    // Colour noise: spectral samples of a grey scene are not grey, RGB ones are.
    assert!(
        spec.mean().iter().any(|p| p[0] != p[2]),
        "the spectral render has no colour noise: is it spectral?"
    );
}

/// A spectral render is deterministic and its colours are not the RGB render's: the Cornell box's walls are coloured,
/// so the spectral products differ from RGB ones (Mitsuba 3's spectral and RGB variants differ by about 4 % in blue).
#[test]
fn spectral_renders_are_deterministic_and_differ_from_rgb() {
    let mut r: Renderer = common::renderer(&common::cornell());
    let a = common::render(&mut r, &spectral(24, 24, 16, 1));
    let b = common::render(&mut r, &spectral(24, 24, 16, 1));
    assert_eq!(a.sum, b.sum, "the same spectral render twice gave different sums");
    let rgb = common::render(&mut r, &common::settings(24, 24, 16, 1));
    assert_ne!(a.sum, rgb.sum, "spectral and RGB gave the same image");
}

/// The IOR KHR_materials_dispersion gives at nm (spectrum.glsl's dispersive_ior): Cauchy's form through the IOR at the
/// Fraunhofer d line, with n_F − n_C = (ior − 1) / V and V = 20 / dispersion.
fn dispersive_ior(ior: f64, dispersion: f64, nm: f64) -> f64 {
    let (d, f, c) = (587.56f64, 486.13f64, 656.27f64);
    let b = (ior - 1.0) * dispersion / 20.0 / (1.0 / (f * f) - 1.0 / (c * c));
    (ior + b * (1.0 / (nm * nm) - 1.0 / (d * d))).max(1.0)
}

/// Snell's law through a slab: a ray meeting a slab of thickness `d` at `theta` leaves it parallel to itself, moved
/// sideways by d sin(θ − θt) / cos θt, with sin θt = sin θ / n; and the share of its light that crosses both faces.
fn slab_shift(d: f64, theta: f64, n: f64) -> (f64, f64) {
    let theta_t = (theta.sin() / n).asin();
    let fresnel = |ci: f64, ct: f64, eta: f64| {
        let rs = (ci - eta * ct) / (ci + eta * ct);
        let rp = (eta * ci - ct) / (eta * ci + ct);
        0.5 * (rs * rs + rp * rp)
    };
    let f = fresnel(theta.cos(), theta_t.cos(), n);
    (d * (theta - theta_t).sin() / theta_t.cos(), (1.0 - f) * (1.0 - f))
}

/// A thin white line seen through a glass slab tilted 45°, by an orthographic camera (512×8 pixels over 0.5 × 1/128
/// units): every wavelength's image moves sideways by what Snell's law gives for its IOR. The film's red and blue
/// channels each see a mix of wavelengths (their rows of the XYZ-to-sRGB matrix times the observer, D65 and the
/// slab's transmittance), so each channel's centroid is predicted as that mix of the per-wavelength shifts. With
/// dispersion 1 (Abbe number 20) the two centroids sit the predicted distance apart (5.8 pixels, within 0.15;
/// measured 0.03 off);
/// without dispersion, or in RGB mode, they coincide (within 0.1) at the shift for IOR 1.5. Catches dispersion that
/// bends the wrong wavelength (the order of red and blue reversed), the wrong formula or hero handling (a
/// separation off by more than 0.15 pixels), and refraction that is not Snell's (the mean position).
#[test]
fn dispersion_separates_red_and_blue_by_snells_law() {
    let (theta, thickness, ior, width_px, xmag) = (45f64.to_radians(), 0.5f64, 1.5f64, 512u32, 0.25f32);
    let scene = |dispersion: f32| {
        let mut b = common::gltf_builder::GltfBuilder::new();
        let line = b.material("line", [0.0; 3], [10.0; 3], false);
        let glass = b.glass_material("slab", [1.0; 3], ior as f32, 0.0, false, None);
        if dispersion > 0.0 {
            b.dispersion(glass, dispersion);
        }
        let w = 0.0015;
        b.quad("line", upright([-w, w], [-1.0, 1.0], -1.5), line, FACING_Z);
        let (s, c) = (theta.sin() as f32, theta.cos() as f32);
        let (n, u) = (glam::Vec3::new(s, 0.0, c), glam::Vec3::new(c, 0.0, -s));
        let mut corners = Vec::new();
        for a in [-0.5f32, 0.5] {
            for b in [-2.0f32, 2.0] {
                for y in [-1.0f32, 1.0] {
                    corners.push((n * a * thickness as f32 + u * b + glam::Vec3::Y * y).to_array());
                }
            }
        }
        let faces: [&[usize]; 6] = [
            &[0, 1, 3, 2],
            &[4, 5, 7, 6],
            &[0, 1, 5, 4],
            &[2, 3, 7, 6],
            &[0, 2, 6, 4],
            &[1, 3, 7, 5],
        ];
        b.convex_solid("slab", &corners, &faces, glass);
        let ymag = xmag * 8.0 / width_px as f32;
        b.orthographic_camera([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], xmag, ymag);
        let (dir, path) = common::write_temp(&b, "slab.gltf");
        let scene = pathwave::scene::load(&path, None).unwrap();
        drop(dir);
        scene
    };
    let px = |x: f64| (x + xmag as f64) / (2.0 * xmag as f64) * width_px as f64;
    // Per channel, the centroid in pixels of the columns within 24 pixels of `around`.
    let centroids = |film: &Film, around: f64| -> [f64; 3] {
        let mean = film.mean();
        std::array::from_fn(|c| {
            let (mut sum, mut weight) = (0.0, 0.0);
            for y in 0..film.height as usize {
                for x in 0..film.width as usize {
                    if (x as f64 + 0.5 - around).abs() < 24.0 {
                        let v = mean[y * film.width as usize + x][c] as f64;
                        sum += v * (x as f64 + 0.5);
                        weight += v;
                    }
                }
            }
            sum / weight
        })
    };
    let t = pathwave::spectrum::tables();
    let m = t.xyz_to_srgb();
    let predict = |dispersion: f64| -> [f64; 3] {
        let (mut sum, mut weight) = ([0.0; 3], [0.0; 3]);
        for k in 0..=4700 {
            let nm = 360.0 + k as f64 * 0.1;
            let (shift, through) = slab_shift(thickness, theta, dispersive_ior(ior, dispersion, nm));
            let o = t.observer(nm as f32);
            let e = t.illuminant(nm as f32) as f64 * through;
            for c in 0..3 {
                let w = (0..3).map(|j| m[c][j] as f64 * o[j] as f64).sum::<f64>() * e;
                sum[c] += w * px(shift);
                weight[c] += w;
            }
        }
        std::array::from_fn(|c| sum[c] / weight[c])
    };
    let settings = |spectral: bool| RenderSettings {
        spectral,
        ..common::settings(width_px, 8, 256, 9)
    };

    let dispersive = scene(1.0);
    assert!(
        dispersive.wants_spectral(),
        "a dispersive scene asks for spectral transport"
    );
    let mut r = common::scene_renderer(&dispersive);
    let want = predict(1.0);
    let got = centroids(&common::render(&mut r, &settings(true)), want[1]);
    eprintln!(
        "dispersion 1: red {:.3} blue {:.3} px (predicted {:.3}, {:.3})",
        got[0], got[2], want[0], want[2]
    );
    let (sep, want_sep) = (got[2] - got[0], want[2] - want[0]);
    assert!(
        want_sep > 1.5,
        "the test's geometry should separate red and blue by pixels, not {want_sep}"
    );
    assert!(
        (sep - want_sep).abs() < 0.15,
        "red and blue are {sep:.3} pixels apart, Snell's law says {want_sep:.3}"
    );
    for c in [0, 2] {
        assert!(
            (got[c] - want[c]).abs() < 0.15,
            "channel {c} at {:.3} px, predicted {:.3}",
            got[c],
            want[c]
        );
    }

    // The same slab in RGB mode ignores the dispersion, and a slab without it bends every wavelength alike.
    let rgb = centroids(&common::render(&mut r, &settings(false)), want[1]);
    let mut plain = common::scene_renderer(&scene(0.0));
    assert!(!scene(0.0).wants_spectral());
    let flat = centroids(&common::render(&mut plain, &settings(true)), want[1]);
    let at = px(slab_shift(thickness, theta, ior).0);
    eprintln!(
        "RGB: red {:.3} blue {:.3}; no dispersion: red {:.3} blue {:.3}; Snell at IOR 1.5: {at:.3} px",
        rgb[0], rgb[2], flat[0], flat[2]
    );
    for (what, c) in [("RGB", rgb), ("no dispersion", flat)] {
        assert!(
            (c[2] - c[0]).abs() < 0.1,
            "{what}: red and blue {:.3} pixels apart",
            c[2] - c[0]
        );
        assert!(
            (c[1] - at).abs() < 0.1,
            "{what}: the line at {:.3} px, Snell's law puts it at {at:.3}",
            c[1]
        );
    }
}
