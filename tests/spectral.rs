//! Spectral transport (FEATURE_SPECTRAL) end to end on the device: white furnaces stay white, colours upsampled to
//! spectra and integrated back by the film keep their values, and a neutral scene renders the same in RGB and
//! spectral mode. Each compares per-channel means against their standard errors (fixed seeds).
mod common;

use pathwave::scene::{Environment, Material, Scene};
use pathwave::{Film, RenderSettings, Renderer};

/// A faceted sphere filling the view in a uniform environment (the white-furnace scene of tests/environment.rs).
fn sphere(material: Material, env: [f32; 3]) -> Scene {
    let mut b = common::gltf_builder::GltfBuilder::new();
    let m = b.material("placeholder", [1.0; 3], [0.0; 3], false);
    b.uv_sphere("sphere", [0.0; 3], 1.0, m, false);
    b.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 30.0);
    let (_dir, path) = common::write_temp(&b, "sphere.gltf");
    let mut scene = pathwave::scene::load(&path, None).unwrap();
    scene.materials[0] = material;
    scene.environment = Some(Environment::constant(env));
    scene
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
        (
            "lambert",
            Material {
                metallic: 0.0,
                specular: 0.0,
                ..Material::default()
            },
        ),
        ("glass sphere", glass(false)),
        ("thin glass shell", glass(true)),
    ];
    for (name, m) in cases {
        let mut r = common::scene_renderer(&sphere(m, [1.0; 3]));
        let film = common::render(&mut r, &spectral(16, 16, 256, 3));
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

/// Colours survive the trip to spectra and back: a Lambertian sphere of albedo (0.8, 0.3, 0.1) in a white
/// environment shows that albedo (a reflectance upsampled on the device), and a white one in an environment of
/// (0.9, 0.4, 0.1) shows that colour (an emitter: the upsampled spectrum times D65). The tolerance is the table's
/// round trip, 0.004 (tests/spectrum.rs). Catches a device lookup that differs from the host's table (a wrong
/// node, corner or channel moves a colour by 0.05 or more).
#[test]
fn colours_keep_their_values_in_spectral_mode() {
    let lambert = |rgb: [f32; 3]| Material {
        metallic: 0.0,
        specular: 0.0,
        base_color: glam::Vec3::from(rgb),
        ..Material::default()
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
