//! Scattering media (KHR_materials_scatter): furnaces, analytic bounds, transmittance, nesting, estimators, loading,
//! and agreement with Mitsuba 3.
mod common;

use common::gltf_builder::{square, upright, GltfBuilder, FACING_DOWN, FACING_UP, FACING_Z};
use glam::Vec3;
use pathwave::scene::{Environment, Material, Medium, Scene};
use pathwave::{Estimator, Film, LightSampler, RenderSettings, Renderer};
use serde_json::{json, Value};

const SCATTER: &str = "KHR_materials_scatter";
const VOLUME_SCATTER: &str = "KHR_materials_volume_scatter";

/// KHR_materials_scatter's fit from the multiple-scattering albedo rho_ms to the single-scattering one, written out
/// from the draft's README (not from src/scene/gltf/scatter.rs):
/// s = 4.09712 + 4.20863 rho_ms - sqrt(9.59217 + 41.6808 rho_ms + 17.7126 rho_ms^2), rho_ss = (1 - s^2) / (1 - g s^2).
fn rho_ss(rho_ms: f64, g: f64) -> f64 {
    let s = 4.09712 + 4.20863 * rho_ms - (9.59217 + 41.6808 * rho_ms + 17.7126 * rho_ms * rho_ms).sqrt();
    (1.0 - s * s) / (1.0 - g * s * s)
}

/// KHR_materials_scatter's object in the README's spelling.
fn scatter(strength: f32, colour: [f32; 3], g: f32) -> Value {
    json!({ "scatterStrengthFactor": strength, "multiscatterColorFactor": colour, "scatterAnisotropy": g })
}

/// An index-matched volumetric material: IOR 1, smooth, white, fully transmissive, so light crosses its boundary
/// unbent and unreflected (bsdf.glsl's glass_passes_through) and only the medium inside acts. KHR_materials_volume
/// attenuates to `attenuation.0` over `attenuation.1` metres (sigma_t = -ln(colour) / distance), and `scatter` is its
/// KHR_materials_scatter object.
fn medium_material(b: &mut GltfBuilder, name: &str, attenuation: ([f32; 3], f32), scatter: Value) -> usize {
    let m = b.glass_material(name, [1.0; 3], 1.0, 0.0, false, Some(attenuation));
    b.material_json(m)["extensions"][SCATTER] = scatter;
    b.use_extension(SCATTER);
    m
}

fn material<'a>(scene: &'a Scene, name: &str) -> &'a Material {
    (scene.materials.iter())
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material '{name}' in the scene"))
}

/// A render that must keep every sample: a NaN or infinity from the free flights or the phase function would be
/// dropped by the film (and counted), biasing the image silently.
fn render(r: &mut Renderer, s: &RenderSettings) -> Film {
    let (film, stats) = r.render(s, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{}x{} {} spp: {}", s.width, s.height, s.spp, stats.summary());
    assert_eq!(stats.nonfinite, 0, "samples were not finite");
    film
}

/// Per channel, the mean over all pixels and its standard error (from the per-pixel sample variances).
fn channel_means(film: &Film) -> [(f64, f64); 3] {
    let (mean, var) = (film.mean(), film.sample_variance());
    let n = mean.len() as f64;
    std::array::from_fn(|c| {
        let m = mean.iter().map(|p| p[c] as f64).sum::<f64>() / n;
        let v = var.iter().map(|p| p[c] as f64 / film.spp as f64).sum::<f64>() / (n * n);
        (m, v.sqrt())
    })
}

/// Every pixel's channel average within `z` of its standard errors of `expected`, and the image mean within 4. A pixel
/// without variance fails: the medium was then not sampled at all, and the test would prove nothing.
fn assert_pixels_near(what: &str, film: &Film, expected: f64, z: f64) {
    let (mean, var) = (film.mean(), film.sample_variance());
    let mut worst = (0.0f64, 0usize);
    for (i, (m, v)) in mean.iter().zip(&var).enumerate() {
        let m = (m[0] + m[1] + m[2]) as f64 / 3.0;
        // A grey scene's channels are the same samples, so the channels' mean variance is the average's.
        let se = ((v[0] + v[1] + v[2]) as f64 / 3.0 / film.spp as f64).sqrt();
        assert!(
            se > 0.0,
            "{what}: pixel {i} has zero variance: no path scattered, the medium was not entered"
        );
        let dev = (m - expected).abs() / se;
        if dev > worst.0 {
            worst = (dev, i);
        }
    }
    let (img, img_se) = common::stats::image_mean_and_stderr(film);
    eprintln!(
        "{what}: image mean {img:.5} +- {img_se:.5} (expected {expected}); worst pixel {} at {:.2} sigma",
        worst.1, worst.0
    );
    assert!(
        worst.0 < z,
        "{what}: pixel {} is {:.2} standard errors from {expected} (mean {:?})",
        worst.1,
        worst.0,
        mean[worst.1]
    );
    assert!(
        (img - expected).abs() < 4.0 * img_se,
        "{what}: image mean {img} is {:.2} standard errors from {expected}",
        (img - expected).abs() / img_se
    );
}

/// A white (rho_ms = 1, so rho_ss exactly 1) index-matched medium of optical radius 4.6 inside a white furnace of
/// radiance 1: whatever enters leaves again, so every pixel converges to 1, for isotropic and strongly forward
/// (g = 0.7) scattering. 16x16 pixels, all on the sphere (25° view from distance 3: the corners' rays pass 0.90 from
/// the centre); z = 4.6 per pixel is a family-wise false alarm of 1e-3 over 256 pixels per render (512 samples make
/// each mean close to normal). Catches energy lost or gained in the free-flight weights (the channel mixture) or the
/// phase function's sampling, a depth cap or roulette that truncates long diffusive paths, and a medium stack that
/// is not pushed on entry (zero variance: the medium is never seen) or not popped on exit (paths keep scattering
/// outside, in no medium's boundary, and never reach the environment).
/// The third case puts the medium behind a smooth dielectric boundary (IOR 1.5: refraction, total internal
/// reflection, the radiance's 1/eta^2 on entering and eta^2 on leaving), which neither absorbs nor emits, so the
/// furnace still holds; it catches a boundary whose scaling or Fresnel does not balance around a medium. (Not a rough
/// one: the GGX glass lobe is single-scattering and loses 2 % of a furnace through a clear sphere at roughness 0.3,
/// and 6 % around a medium, whose paths meet the boundary from inside many times.)
#[test]
fn white_medium_in_a_white_furnace_stays_one() {
    for (g, ior, roughness, seed) in [(0.0f32, 1.0f32, 0.0f32, 7u32), (0.7, 1.0, 0.0, 8), (0.3, 1.5, 0.0, 9)] {
        let mut b = GltfBuilder::new();
        // sigma_t = -ln(0.1) / 0.5 = 4.6 per metre.
        let m = medium_material(&mut b, "white fog", ([0.1; 3], 0.5), scatter(1.0, [1.0; 3], g));
        if ior != 1.0 {
            b.material_json(m)["extensions"]["KHR_materials_ior"] = json!({ "ior": ior });
            b.material_json(m)["pbrMetallicRoughness"]["roughnessFactor"] = json!(roughness);
        }
        b.uv_sphere("ball", [0.0; 3], 1.0, m, false);
        b.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 25.0);
        let mut scene = common::load_built(&b, "white-fog.gltf");
        let medium = material(&scene, "white fog").medium;
        assert_eq!(medium.albedo, Vec3::ONE, "rho_ms = 1 must scatter everything");
        scene.environment = Some(Environment::constant([1.0; 3]));
        let mut r = common::scene_renderer(&scene);
        let film = render(&mut r, &common::settings(16, 16, 512, seed));
        assert_pixels_near(&format!("white medium, g = {g}, IOR {ior}"), &film, 1.0, 4.6);
    }
}

/// A white medium whose extinction differs per channel (sigma_t 4.6, 1.8 and 0.45 per metre: optical radii 4.6 to
/// 0.45) in the furnace: each channel must still return 1, in RGB and over wavelengths. A path draws all its free
/// flights from one channel's exponentials, so its weight in the others is right only if taken against every
/// channel's density of the whole path (medium_sample's ratios): dropping the ratios, or weighting each event by the
/// mean of its own densities while the channel stays fixed, biases the channels apart. Per channel, the image mean
/// within 4 standard errors of 1 (and 1 %).
#[test]
fn a_chromatic_white_medium_keeps_every_channel_at_one() {
    let mut b = GltfBuilder::new();
    let m = medium_material(
        &mut b,
        "tinted fog",
        ([0.1, 0.4, 0.8], 0.5),
        scatter(1.0, [1.0; 3], 0.4),
    );
    b.uv_sphere("ball", [0.0; 3], 1.0, m, false);
    b.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 25.0);
    let mut scene = common::load_built(&b, "tinted-fog.gltf");
    scene.environment = Some(Environment::constant([1.0; 3]));
    let mut r = common::scene_renderer(&scene);
    for spectral in [false, true] {
        let s = RenderSettings {
            spectral,
            ..common::settings(16, 16, 512, 10)
        };
        let film = render(&mut r, &s);
        for (c, (m, se)) in channel_means(&film).into_iter().enumerate() {
            eprintln!("spectral {spectral}: channel {c}: {m:.5} +- {se:.5}");
            // Spectral: white turned back into RGB is 1 within 0.2 % (tests/spectrum.rs).
            let white = if spectral { 0.002 } else { 0.0 };
            assert!(
                (m - 1.0).abs() < 4.0 * se + white && (m - 1.0).abs() < 0.01,
                "spectral {spectral}: channel {c} is {m} +- {se}"
            );
        }
    }
}

/// A grey absorbing and scattering medium (rho_ms = 0.4 x 0.5 = 0.2, g = 0.3; sigma_t = 0.5 per metre in a sphere of
/// radius 1 m) in a white environment of radiance 1, seen by an orthographic camera. Along a ray whose chord is l,
/// with T = exp(-sigma_t l) and alpha = rho_ss, the radiance inside never exceeds 1 (albedo below 1) and is at least
/// what arrives uncollided across the whole diameter, exp(-2 sigma_t R), so
///   T + alpha (1 - T) exp(-2 sigma_t R) <= L <= T + alpha (1 - T).
/// The mean over pixels well inside the silhouette (farthest corner within 0.85 R) must lie between those bounds'
/// means (each averaged over an 8x8 grid in the pixel, as the box filter averages), within 4 standard errors, and
/// clearly below 1. The faceted sphere lies between the ball of radius cos(pi/32) R (no face's plane comes nearer the
/// centre: each face's corners are within pi/32 of its middle) and the sphere: the lower bound takes the sphere's
/// chord and diameter, the upper the inner ball's chord, both conservative. Catches scattering that adds energy (above
/// the upper bound), absorption applied twice or the extinction doubled (below the lower bound), and a medium ignored
/// (1, above the upper bound).
#[test]
fn absorbing_medium_darkens_between_the_analytic_bounds() {
    let sigma_t = 0.5f64;
    let (strength, colour, g) = (0.4f64, 0.5f64, 0.3f64);
    let alpha = rho_ss(strength * colour, g);
    let mut b = GltfBuilder::new();
    let attenuation = ([(-sigma_t).exp() as f32; 3], 1.0);
    let m = medium_material(
        &mut b,
        "haze",
        attenuation,
        scatter(strength as f32, [colour as f32; 3], g as f32),
    );
    b.uv_sphere("ball", [0.0; 3], 1.0, m, false);
    let ymag = 1.0f64;
    b.orthographic_camera([0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], ymag as f32, ymag as f32);
    let mut scene = common::load_built(&b, "haze.gltf");
    let haze = material(&scene, "haze");
    assert!(
        haze.medium
            .albedo
            .to_array()
            .iter()
            .all(|&a| (a as f64 - alpha).abs() < 1e-5),
        "albedo {} loaded, the fit gives {alpha}",
        haze.medium.albedo
    );
    assert!((haze.attenuation - Vec3::splat(sigma_t as f32)).abs().max_element() < 1e-5);
    scene.environment = Some(Environment::constant([1.0; 3]));
    let mut r = common::scene_renderer(&scene);
    let (w, h) = (32u32, 32u32);
    let film = render(&mut r, &common::settings(w, h, 256, 21));

    let r_in = (std::f64::consts::PI / 32.0).cos();
    let chord = |r2: f64, radius: f64| 2.0 * (radius * radius - r2).max(0.0).sqrt();
    let lower = |l: f64| {
        let t = (-sigma_t * l).exp();
        t + alpha * (1.0 - t) * (-sigma_t * 2.0).exp()
    };
    let upper = |l: f64| {
        let t = (-sigma_t * l).exp();
        t + alpha * (1.0 - t)
    };
    let (mean, var) = (film.mean(), film.sample_variance());
    let size = 2.0 * ymag / w as f64;
    let (mut sum, mut v, mut lo, mut up, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for py in 0..h as usize {
        for px in 0..w as usize {
            // Row 0 is the top of the image.
            let (x0, y0) = (-ymag + px as f64 * size, ymag - (py + 1) as f64 * size);
            let far = |a: f64| a.abs().max((a + size).abs());
            if far(x0).hypot(far(y0)) > 0.85 {
                continue;
            }
            let sub = 8;
            let (mut pl, mut pu) = (0.0, 0.0);
            for i in 0..sub {
                for j in 0..sub {
                    let x = x0 + (i as f64 + 0.5) / sub as f64 * size;
                    let y = y0 + (j as f64 + 0.5) / sub as f64 * size;
                    pl += lower(chord(x * x + y * y, 1.0));
                    pu += upper(chord(x * x + y * y, r_in));
                }
            }
            let k = py * w as usize + px;
            sum += (mean[k][0] + mean[k][1] + mean[k][2]) as f64 / 3.0;
            v += (var[k][0] + var[k][1] + var[k][2]) as f64 / 3.0 / film.spp as f64;
            lo += pl / (sub * sub) as f64;
            up += pu / (sub * sub) as f64;
            n += 1.0;
        }
    }
    let (m, se, lo, up) = (sum / n, v.sqrt() / n, lo / n, up / n);
    eprintln!("{n} pixels: mean {m:.5} +- {se:.5}, bounds [{lo:.5}, {up:.5}], alpha {alpha:.5}");
    assert!(n > 400.0 && se > 0.0);
    assert!(
        up < 0.9,
        "the test's medium must be dark enough that ignoring it (1) is outside the bounds"
    );
    assert!(
        m > lo - 4.0 * se,
        "mean {m} is below the lower bound {lo} by {:.1} standard errors: too much absorbed",
        (lo - m) / se
    );
    assert!(
        m < up + 4.0 * se,
        "mean {m} is above the upper bound {up} by {:.1} standard errors: scattering adds energy",
        (m - up) / se
    );
    assert!(m + 4.0 * se < 1.0, "mean {m}: the medium does not darken");
}

/// A slab 0.5 m thick of index-matched scattering medium (strength 1, colour 0.8), attenuating to `attenuation` over
/// its thickness, between an orthographic camera and a large emitter of radiance 1 facing it; the view (2 m square)
/// sees only the slab's faces and the emitter behind.
fn slab_scene(attenuation: [f32; 3]) -> Scene {
    let d = 0.5f32;
    let mut b = GltfBuilder::new();
    let slab = medium_material(&mut b, "slab", (attenuation, d), scatter(1.0, [0.8; 3], 0.0));
    let lamp = b.material("lamp", [0.0; 3], [1.0; 3], false);
    b.cube("slab", [-2.0, -2.0, -d / 2.0], [2.0, 2.0, d / 2.0], slab, false);
    b.quad("lamp", upright([-3.0, 3.0], [-3.0, 3.0], -1.0), lamp, FACING_Z);
    b.orthographic_camera([0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], 1.0, 1.0);
    let scene = common::load_built(&b, "slab.gltf");
    assert!(material(&scene, "slab").medium.scatters());
    scene
}

/// BSDF sampling only, max depth 2: the camera ray meets the slab's front (bounce 0), crosses it (bounce 1: the
/// free flight either scatters or reaches the back face) and meets the emitter (bounce 2, whose emission is gathered
/// before the depth check in path.glsl's shade_path). A path that scattered inside needs a further bounce to leave
/// the slab and another to reach the emitter, and next-event estimation is off, so only uncollided light arrives:
/// each channel's expectation is exactly emission x exp(-sigma_t d) = the attenuation colour. Each image mean per
/// channel within 4 standard errors and within 1 % of it, in RGB for a chromatic slab (0.8, 0.4, 0.1) and spectrally
/// for a grey one (0.3, the same at every wavelength; plus 0.2 % for spectral white's own round trip, which
/// tests/spectrum.rs bounds by quadrature, and 2048 samples for the wavelengths' colour noise). Catches a wrong
/// transmittance weight or a channel mixture pdf that is not the mean of the channels' (a chromatic slab shows it per
/// channel), a medium never entered (1), and extinction applied both by the medium and by the old leaving-the-volume
/// absorption (the square).
#[test]
fn straight_through_transmittance_is_exp_minus_sigma_t_d() {
    for (what, attenuation, spectral, spp, seed) in [
        ("RGB, chromatic slab", [0.8f32, 0.4, 0.1], false, 512u32, 31u32),
        ("spectral, grey slab", [0.3; 3], true, 2048, 32),
    ] {
        let s = RenderSettings {
            estimator: Estimator::Bsdf,
            max_depth: Some(2),
            spectral,
            ..common::settings(32, 32, spp, seed)
        };
        let mut r = common::scene_renderer(&slab_scene(attenuation));
        let film = render(&mut r, &s);
        for (c, (m, se)) in channel_means(&film).into_iter().enumerate() {
            let want = attenuation[c] as f64;
            let white = if spectral { 2e-3 * want } else { 0.0 };
            eprintln!("{what}: channel {c}: {m:.5} +- {se:.5}, expected {want}");
            assert!(
                se > 0.0,
                "{what}: channel {c} has no noise: the medium's free flights were not sampled"
            );
            assert!(
                (m - want).abs() < 4.0 * se + white && (m - want).abs() < 0.01 * want,
                "{what}: channel {c} transmits {m} +- {se}, exp(-sigma_t d) is {want}"
            );
        }
    }
}

/// Two index-matched slabs of grey scattering media, A (sigma_t ln 2 = 0.693 per metre) and B (ln 10 = 2.303), each
/// 100 m wide and spanning `a` and `b` in z, between the orthographic camera of `slab_scene` and its emitter.
fn two_slabs(a: [f32; 2], b_z: [f32; 2]) -> Scene {
    let mut b = GltfBuilder::new();
    let ma = medium_material(&mut b, "A", ([0.5; 3], 1.0), scatter(1.0, [0.8; 3], 0.0));
    let mb = medium_material(&mut b, "B", ([0.1; 3], 1.0), scatter(1.0, [0.8; 3], 0.0));
    let lamp = b.material("lamp", [0.0; 3], [1.0; 3], false);
    // Side faces apart, so that no two boundaries coincide.
    b.cube("A", [-50.0, -50.0, a[0]], [50.0, 50.0, a[1]], ma, false);
    b.cube("B", [-49.0, -49.0, b_z[0]], [49.0, 49.0, b_z[1]], mb, false);
    b.quad("lamp", upright([-3.0, 3.0], [-3.0, 3.0], -1.0), lamp, FACING_Z);
    b.orthographic_camera([0.0, 0.0, 5.0], [0.0; 3], [0.0, 1.0, 0.0], 1.0, 1.0);
    common::load_built(&b, "slabs.gltf")
}

/// The rule for nested and overlapping volumes (media.glsl's stack: a path travels in the volume it entered last and
/// has not left), by straight-through transmittance as in `straight_through_transmittance_is_exp_minus_sigma_t_d`
/// (BSDF sampling, depth 4: the camera's ray crosses four boundaries to the emitter, and a path that scattered needs
/// more bounces; the slabs are 100 m wide, so none leaves sideways). Seen from the camera (down -z):
/// - nested: B (z -0.2..0.2) inside A (-0.6..0.6): A over 0.8 m, B over 0.4 m, exp(-0.8 ln 2 - 0.4 ln 10) = 0.2287;
/// - overlapping: B (-0.2..0.6) entered first, then A (-0.6..0.2): from 0.6 to 0.2 B alone, from 0.2 to -0.2 both
///   and A entered last, then A alone: A over 0.8 m, B over 0.4 m, 0.2287 again.
///
/// Would catch the outer volume forgotten when the inner one is left (nested: 0.3018), B not taking over inside A
/// (0.4353), a first-entered-wins rule in the overlap (0.1201), or a stack not emptied at the last exit (the emitter's
/// light then crosses a medium that is not there). Each mean within 4 standard errors and 1 % of the answer.
#[test]
fn nested_and_overlapping_volumes_follow_the_last_entered() {
    let want = (-(0.8 * 2f64.ln() + 0.4 * 10f64.ln())).exp();
    for (what, a, b_z, seed) in [
        ("nested", [-0.6, 0.6], [-0.2, 0.2], 51u32),
        ("overlapping", [-0.6, 0.2], [-0.2, 0.6], 52),
    ] {
        let scene = two_slabs(a, b_z);
        let s = RenderSettings {
            estimator: Estimator::Bsdf,
            max_depth: Some(4),
            ..common::settings(32, 32, 512, seed)
        };
        let film = render(&mut common::scene_renderer(&scene), &s);
        for (c, (m, se)) in channel_means(&film).into_iter().enumerate() {
            eprintln!("{what}: channel {c}: {m:.5} +- {se:.5}, expected {want:.5}");
            assert!(se > 0.0, "{what}: no noise: the media's free flights were not sampled");
            assert!(
                (m - want).abs() < 4.0 * se && (m - want).abs() < 0.01 * want,
                "{what}: channel {c} transmits {m} +- {se}, expected {want}"
            );
        }
    }
}

/// A closed index-matched cube (2 m) of chromatic scattering medium (sigma_t 0.69, 1.05, 1.39 per metre; rho_ms 0.9,
/// 0.7, 0.5; g = 0.5) holding a double-sided emitter (0.8 m square) and a diffuse floor, with no environment; the
/// camera outside sees only the cube's front face, so every pixel looks into the lit medium or at the floor (none
/// where phase or BSDF sampling alone finds the light only rarely, which would leave its variance unestimated). Light
/// reaches the camera through scattering (next-event estimation at scattering points, or phase sampling finding the
/// emitter) and off the floor (its shadow rays crossing the medium).
fn lit_fog_scene() -> Scene {
    let mut b = GltfBuilder::new();
    let fog = medium_material(
        &mut b,
        "fog",
        ([0.5, 0.35, 0.25], 1.0),
        scatter(1.0, [0.9, 0.7, 0.5], 0.5),
    );
    let lamp = b.material("lamp", [0.0; 3], [10.0; 3], true);
    let floor = b.material("floor", [0.8; 3], [0.0; 3], false);
    b.cube("fog", [-1.0; 3], [1.0; 3], fog, false);
    b.quad("lamp", square(0.4, 0.4), lamp, FACING_DOWN);
    b.quad("floor", square(0.9, -0.7), floor, FACING_UP);
    // 30° from 3.5 m: the view's corners meet the front face (z = 1) within |x|, |y| < 0.75.
    b.camera([0.0, 0.3, 3.5], [0.0; 3], [0.0, 1.0, 0.0], 30.0);
    let scene = common::load_built(&b, "fog.gltf");
    assert!(material(&scene, "fog").medium.scatters());
    scene
}

/// Light sampling, phase (and BSDF) sampling and MIS estimate the same image of a lit medium, each render on its own
/// seed (tests/estimators.rs). MIS and phase sampling have finite variance (the power heuristic keeps MIS's
/// next-event estimate below half the emission times the throughput), so they are compared per pixel
/// (`assert_same_within_noise`: at most 3 channels beyond 5 standard errors) and by image mean (4 combined standard
/// errors). Light sampling alone does not: a scattering point at height h over an area light has no receiver cosine,
/// its next-event estimate's second moment grows as 1/h^2, and that diverges over the volume (tail index 3/2); it is
/// compared by image mean only, whose self-normalised z stays close to normal for such tails, within 4 combined
/// standard errors. Catches a wrong MIS weight at scattering points (the light's pdf there taken with a receiver
/// normal, or the phase pdf not the one the continuation was drawn with), a phase pdf inconsistent with hg_sample,
/// and shadow rays from scattering points or from the floor that miss the medium's transmittance (light sampling too
/// bright against phase sampling).
#[test]
fn nee_phase_sampling_and_mis_agree() {
    let scene = lit_fog_scene();
    let mut r = common::scene_renderer(&scene);
    let films: Vec<(Estimator, Film)> = [Estimator::Mis, Estimator::Light, Estimator::Bsdf]
        .into_iter()
        .map(|e| {
            let s = RenderSettings {
                estimator: e,
                ..common::settings(24, 24, 512, 41 + e as u32)
            };
            (e, render(&mut r, &s))
        })
        .collect();
    let stats: Vec<(Estimator, f64, f64)> = (films.iter())
        .map(|(e, f)| {
            let (m, se) = common::stats::image_mean_and_stderr(f);
            eprintln!("{e:?}: image mean {m:.5} +- {se:.5}");
            assert!(m > 0.0 && se > 0.0, "{e:?} rendered nothing");
            (*e, m, se)
        })
        .collect();
    for i in 0..stats.len() {
        for j in i + 1..stats.len() {
            let ((ei, mi, si), (ej, mj, sj)) = (stats[i], stats[j]);
            let z = (mi - mj).abs() / (si * si + sj * sj).sqrt();
            assert!(
                z < 4.0,
                "{ei:?} mean {mi} and {ej:?} mean {mj} differ by {z:.2} standard errors"
            );
        }
    }
    common::stats::assert_same_within_noise("MIS against phase sampling", &films[0].1, &films[2].1);
    // The light BVH picks at a scattering point without a receiver normal, and its pdf twin at an emitter a phase
    // sample hits must see the same (LIGHT_NORMAL_NONE in the path state): a mismatch biases MIS against the power
    // selection's image.
    let tree = RenderSettings {
        estimator: Estimator::Mis,
        light_sampler: LightSampler::Bvh,
        ..common::settings(24, 24, 512, 45)
    };
    let tree = render(&mut r, &tree);
    common::stats::assert_same_within_noise("MIS by the light BVH against MIS by power", &tree, &films[0].1);
}

/// A material for load_materials: its name, whether it is thin-walled, and its extension objects by name.
type MaterialSpec<'a> = (&'a str, bool, Vec<(&'static str, Value)>);

/// A scene of one cube per material (each made volumetric unless `thin`, with the given extension objects), and a
/// camera; returns it written, loaded (or the loading's error).
fn load_materials(materials: &[MaterialSpec]) -> Result<Scene, pathwave::Error> {
    let mut b = GltfBuilder::new();
    for (i, (name, thin, extensions)) in materials.iter().enumerate() {
        let m = b.glass_material(name, [1.0; 3], 1.0, 0.0, *thin, Some(([0.5; 3], 1.0)));
        for (ext, value) in extensions {
            b.material_json(m)["extensions"][*ext] = value.clone();
            b.use_extension(ext);
        }
        let x = 3.0 * i as f32;
        b.cube(name, [x, 0.0, 0.0], [x + 1.0, 1.0, 1.0], m, false);
    }
    b.camera([0.0, 0.0, 10.0], [0.0; 3], [0.0, 1.0, 0.0], 40.0);
    let (_dir, path) = common::write_temp(&b, "scatter.gltf");
    pathwave::scene::load(&path, None)
}

/// Values outside the draft's ranges (strength and colour in [0, 1], g in the open (-1, 1): +-1 is a delta, not HG)
/// and values that are not numbers are refused when the scene loads, the message naming the material and the
/// property. Catches a range check missing (a negative strength would make a medium that creates energy, g = 1 a
/// division by zero in the phase function) or an error that leaves the user guessing which material.
#[test]
fn scatter_values_out_of_range_are_refused_naming_the_material() {
    let cases = [
        ("scatterStrengthFactor", json!(-0.1)),
        ("scatterStrengthFactor", json!("strong")),
        ("scatterFactor", json!(1.5)),
        ("multiscatterColorFactor", json!([1.2, 0.0, 0.0])),
        ("multiscatterColorFactor", json!([0.5, 0.5])),
        ("scatterAnisotropy", json!(1.0)),
        ("scatterAnisotropy", json!(-1.0)),
        ("scatterAnisotropy", json!("forward")),
    ];
    for (key, value) in cases {
        let mut ext = json!({ "multiscatterColorFactor": [0.5, 0.5, 0.5], "scatterAnisotropy": 0.0 });
        // The README's spelling is read first when both are there: the schema's alone here, to check it too.
        if key != "scatterFactor" {
            ext["scatterStrengthFactor"] = json!(0.5);
        }
        ext[key] = value.clone();
        let err = match load_materials(&[("sea fog", false, vec![(SCATTER, ext)])]) {
            Ok(_) => panic!("{key} = {value} was accepted"),
            Err(e) => e.to_string(),
        };
        eprintln!("{key} = {value}: {err}");
        assert!(
            err.contains("sea fog") && err.contains(key),
            "{key} = {value}: the error names neither the material nor the property: {err}"
        );
    }
}

/// The strength in either spelling the draft uses (the README's scatterStrengthFactor, the schema's scatterFactor)
/// gives the fit's albedo; the superseded KHR_materials_volume_scatter is read as its draft defines it (no strength,
/// so white scatters everything, and an albedo fit without g); a material with both takes the newer; the new
/// extension without a strength scatters nothing (its default is 0); a thin-walled material (no KHR_materials_volume)
/// gets no medium but the thin-walled mode's factors, and the old extension, which has no thin-walled mode, a warning
/// naming the material. Catches a spelling not read (albedo 0), the old extension ignored or its strength defaulting
/// to the new one's 0, and a thin sheet given a medium it has no inside for.
#[test]
fn both_spellings_and_the_old_extension_are_read() {
    let white = [1.0f32; 3];
    let scene = load_materials(&[
        ("readme spelling", false, vec![(SCATTER, scatter(0.5, white, 0.3))]),
        (
            "schema spelling",
            false,
            vec![(
                SCATTER,
                json!({ "scatterFactor": 0.5, "multiscatterColorFactor": white, "scatterAnisotropy": 0.3 }),
            )],
        ),
        (
            "old white",
            false,
            vec![(VOLUME_SCATTER, json!({ "multiscatterColor": white }))],
        ),
        (
            "old grey",
            false,
            vec![(
                VOLUME_SCATTER,
                json!({ "multiscatterColor": [0.5, 0.5, 0.5], "scatterAnisotropy": 0.5 }),
            )],
        ),
        (
            "both",
            false,
            vec![
                (SCATTER, scatter(0.5, white, 0.0)),
                (VOLUME_SCATTER, json!({ "multiscatterColor": white })),
            ],
        ),
        (
            "no strength",
            false,
            vec![(SCATTER, json!({ "multiscatterColorFactor": white }))],
        ),
        ("thin sheet", true, vec![(SCATTER, scatter(1.0, white, 0.2))]),
        (
            "old thin",
            true,
            vec![(VOLUME_SCATTER, json!({ "multiscatterColor": white }))],
        ),
    ])
    .unwrap_or_else(|e| panic!("{e}"));
    let medium = |name: &str| -> Medium {
        let m = material(&scene, name);
        assert_eq!(
            m.thin_walled,
            name.contains("thin"),
            "{name}: the test's volume setting"
        );
        m.medium
    };
    let near = |name: &str, want: f64| {
        let a = medium(name).albedo;
        eprintln!("{name}: albedo {a}, expected {want}");
        assert!(
            a.to_array().iter().all(|&c| (c as f64 - want).abs() < 1e-5),
            "{name}: albedo {a}, expected {want} in every channel"
        );
    };
    near("readme spelling", rho_ss(0.5, 0.3));
    near("schema spelling", rho_ss(0.5, 0.3));
    assert_eq!(medium("readme spelling").anisotropy, 0.3);
    assert_eq!(medium("schema spelling").anisotropy, 0.3);
    assert_eq!(
        medium("old white").albedo,
        Vec3::ONE,
        "the old draft's white scatters everything"
    );
    near("old grey", rho_ss(0.5, 0.0));
    assert_eq!(medium("old grey").anisotropy, 0.5);
    near("both", rho_ss(0.5, 0.0));
    assert_eq!(medium("no strength").albedo, Vec3::ZERO, "the strength defaults to 0");
    assert_eq!(medium("thin sheet").albedo, Vec3::ZERO);
    let thin = material(&scene, "thin sheet").thin_scatter;
    assert_eq!((thin.strength, thin.color, thin.anisotropy), (1.0, Vec3::ONE, 0.2));
    assert_eq!(
        material(&scene, "old thin").thin_scatter.strength,
        0.0,
        "the old draft has no thin-walled mode"
    );
    eprintln!("warnings: {:?}", scene.warnings);
    assert!(
        (scene.warnings.iter()).any(|w| w.contains("old thin") && w.contains("only inside a volume")),
        "no warning names the old extension on a thin wall: {:?}",
        scene.warnings
    );
    assert!(
        scene.warnings.iter().all(|w| w.contains("old thin")),
        "warnings about other materials: {:?}",
        scene.warnings
    );
}

/// The scene of `agrees_with_mitsuba_volpath`: a faceted glass ball (IOR 1.5, smooth; flat normals, which glTF and
/// Mitsuba both derive from the triangles) of radius 0.5 m full of a chromatic, forward-scattering medium (attenuation
/// colour 0.3, 0.5, 0.7 over 0.25 m: sigma_t 4.8, 2.8, 1.4 per metre, optical diameters of 1.4 to 4.8; rho_ms 0.9,
/// 0.7, 0.5; g = 0.5) on a grey Lambertian floor, under a 3 m square light out of view. Smooth glass blocks shadow
/// rays, so the light inside the ball arrives by refraction and phase sampling alone, and leaves by refraction; the
/// light is large so that those paths find it often (a 1 m one left Mitsuba's image mean 0.5 % uncertain at 4096 spp).
fn glass_ball_of_medium() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let ball = b.glass_material("ball", [1.0; 3], 1.5, 0.0, false, Some(([0.3, 0.5, 0.7], 0.25)));
    b.material_json(ball)["extensions"][SCATTER] = scatter(1.0, [0.9, 0.7, 0.5], 0.5);
    b.use_extension(SCATTER);
    let floor = b.material("floor", [0.5; 3], [0.0; 3], false);
    let light = b.material("light", [0.0; 3], [1.0; 3], false);
    b.uv_sphere("ball", [0.0, 0.5, 0.0], 0.5, ball, false);
    b.quad("floor", square(2.0, 0.0), floor, FACING_UP);
    b.quad(
        "light",
        common::gltf_builder::level([-1.5, 1.5], 2.5, [-1.5, 1.5]),
        light,
        FACING_DOWN,
    );
    b.camera([0.0, 1.2, 3.0], [0.0, 0.45, 0.0], [0.0, 1.0, 0.0], 30.0);
    b
}

/// The Python that has Mitsuba 3 (ci/setup.sh makes this venv; PATHWAVE_MITSUBA_PYTHON names another).
fn mitsuba_python() -> Option<std::path::PathBuf> {
    let path = match std::env::var_os("PATHWAVE_MITSUBA_PYTHON") {
        Some(p) => std::path::PathBuf::from(p),
        None => std::path::PathBuf::from(std::env::var_os("HOME")?).join(".cache/pathwave/mitsuba-venv/bin/python"),
    };
    path.exists().then_some(path)
}

/// pathwave against Mitsuba 3's `volpathmis` with a `homogeneous` medium on `glass_ball_of_medium`, the Mitsuba scene
/// built by tests/mitsuba/render_gltf.py from the same glTF file read independently (its own glTF reader and its own
/// transcription of KHR_materials_volume's and KHR_materials_scatter's formulas), 64x48 pixels. Mitsuba renders 4096
/// spp as 32 independent batches, whose means give per-pixel variances; pathwave 1024 spp with exact film statistics.
/// `volpathmis`, not `volpath`: both are Mitsuba's unbiased volumetric path tracers, but `volpath` weights a chromatic
/// medium's free flights by per-channel ratios whose tail is heavy, and its image mean converges from below with a
/// variance that misjudges it: at 16384 spp it sat 2.1 % (red) and 0.8 % (blue) under `volpathmis`'s, 4 and 5 of its own
/// standard errors; `volpathmis` (spectral MIS over the channels, as pathwave's free flights) is 0.04-0.06 % uncertain
/// there.
/// Checked: each channel's image mean within 1 % of Mitsuba's, and pathwave's statistical diff (per pixel, per block
/// and image-wide, family-wise false alarm 1 %) finds the two consistent. Catches anything in the medium's transport
/// that moves light between places or channels rather than only losing it (the furnaces see losses): sigma_s and
/// sigma_a swapped or mis-scaled, the phase function's g applied backwards, spectral MIS weights of the chromatic
/// free flights, the boundary's refraction into and out of a medium, and the loader's mapping of the extension's
/// parameters.
#[test]
fn agrees_with_mitsuba_volpath() {
    let Some(python) = mitsuba_python() else {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "CI must compare with Mitsuba: ci/setup.sh installs it into ~/.cache/pathwave/mitsuba-venv"
        );
        eprintln!("note: no Mitsuba 3 (run ci/setup.sh or set PATHWAVE_MITSUBA_PYTHON); skipping");
        return;
    };
    let (w, h) = (64u32, 48u32);
    let (dir, path) = common::write_temp(&glass_ball_of_medium(), "ball.gltf");
    let out = dir.path().join("mitsuba");
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/mitsuba/render_gltf.py");
    let run = std::process::Command::new(&python)
        .arg(&script)
        .arg(&path)
        .arg(&out)
        .args([
            "--width",
            &w.to_string(),
            "--height",
            &h.to_string(),
            "--spp",
            "4096",
            "--batches",
            "32",
        ])
        .args(["--integrator", "volpathmis"])
        .output()
        .unwrap_or_else(|e| panic!("{}: {e}", python.display()));
    assert!(
        run.status.success(),
        "Mitsuba failed: {}\n{}",
        String::from_utf8_lossy(&run.stdout),
        String::from_utf8_lossy(&run.stderr)
    );
    eprintln!("Mitsuba: {}", String::from_utf8_lossy(&run.stdout).trim());
    let floats = |name: &str| -> Vec<[f64; 3]> {
        let bytes = std::fs::read(out.join(name)).unwrap();
        let v: Vec<f64> = (bytes.chunks_exact(4))
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()) as f64)
            .collect();
        assert_eq!(v.len(), (3 * w * h) as usize, "{name}");
        v.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect()
    };
    let mitsuba = pathwave::diff::Sampled {
        mean: floats("mean.f32"),
        var: floats("var.f32"),
        count: vec![32; (w * h) as usize],
    };

    let scene = pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"));
    assert!(material(&scene, "ball").medium.scatters());
    let mut r = common::scene_renderer(&scene);
    let settings = RenderSettings {
        exact_film: true,
        ..common::settings(w, h, 1024, 77)
    };
    let film = render(&mut r, &settings);
    let ours = pathwave::diff::Sampled::from_exact(film.exact.as_ref().expect("an exact film"));

    use pathwave::diff::Side;
    let report =
        pathwave::diff::statistical(w, h, &Side::Sampled(ours), &Side::Sampled(mitsuba), &Default::default()).unwrap();
    eprintln!("{}", report.summary());
    for c in 0..3 {
        let [p, m] = report.channel_means[c];
        assert!(
            (p / m - 1.0).abs() < 0.01,
            "channel {c}: pathwave's image mean {p} is {:+.2} % from Mitsuba's {m}",
            100.0 * (p / m - 1.0)
        );
    }
    assert!(
        report.consistent,
        "pathwave and Mitsuba differ beyond noise:\n{}",
        report.summary()
    );
}
