//! KHR_materials_clearcoat, _sheen, _iridescence, _diffuse_transmission and _unlit through the loader and the renderer: each new texture slot lands on the
//! pixels its texels cover, the clear coat's own normal map steers its highlight, unlit surfaces show and shed their
//! colour for every estimator, and malformed extension JSON is refused with the material named.
mod common;

use common::gltf_builder::{GltfBuilder, FACING_Z};
use common::screen;
use pathwave::scene::Environment;
use serde_json::{json, Value};

const N: usize = 8;
const NEAREST: u32 = 9728;

/// A black base (no specular layer either) whose material gets `ext_name` = `ext`, with `slot` in it naming a 2x1
/// nearest texture of `left` and `right` texels: the left half of the view sees the first, the right the second.
fn halves(ext_name: &'static str, ext: Value, slot: &str, left: [u8; 4], right: [u8; 4]) -> GltfBuilder {
    halves_over([0.0; 3], ext_name, ext, slot, left, right)
}

/// `halves` over a Lambertian base of colour `base`.
fn halves_over(
    base: [f32; 3],
    ext_name: &'static str,
    mut ext: Value,
    slot: &str,
    left: [u8; 4],
    right: [u8; 4],
) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let m = b.material("quad", base, [0.0; 3], false);
    let image = b.png_image(2, 1, &[left, right]);
    let t = b.texture(image, json!({ "magFilter": NEAREST, "minFilter": NEAREST }));
    ext[slot] = json!({ "index": t });
    b.material_json(m)["extensions"][ext_name] = ext;
    b.use_extension(ext_name);
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    b
}

fn render(
    b: &GltfBuilder,
    env: Option<[f32; 3]>,
    spp: u32,
    estimator: pathwave::Estimator,
    depth: u32,
) -> pathwave::Film {
    let mut scene = common::load_built(b, "layers.gltf");
    scene.environment = env.map(Environment::constant);
    let mut s = common::settings(N as u32, N as u32, spp, 5);
    s.max_depth = Some(depth);
    s.estimator = estimator;
    common::render(&mut common::scene_renderer(&scene), &s)
}

/// `halves` in a white environment, one bounce by BSDF sampling at `spp`: `halves_of` the film, printed.
fn white_halves(
    ext_name: &'static str,
    ext: Value,
    slot: &str,
    left: [u8; 4],
    right: [u8; 4],
    spp: u32,
) -> [(f64, f64); 2] {
    let b = halves(ext_name, ext, slot, left, right);
    let [l, r] = halves_of(&render(&b, Some([1.0; 3]), spp, pathwave::Estimator::Bsdf, 1));
    eprintln!("{slot}: left {l:?}, right {r:?}");
    [l, r]
}

/// Mean of channel 0 and the largest per-pixel variance over the left and the right half of the view.
fn halves_of(film: &pathwave::Film) -> [(f64, f64); 2] {
    let (mean, var) = (film.mean(), film.sample_variance());
    let mut out = [(0.0, 0.0f64); 2];
    for j in 0..N {
        for i in 0..N {
            let h = usize::from(i >= N / 2);
            out[h].0 += mean[j * N + i][0] as f64 / (N * N / 2) as f64;
            out[h].1 = out[h].1.max(var[j * N + i][0] as f64);
        }
    }
    out
}

// In a white environment, one bounce: what the quad returns is its layer's albedo. Would catch a slot read from the
// wrong texture, channel or colour space, or a layer's texture ignored.
#[test]
fn clearcoat_and_sheen_textures_land_on_their_halves() {
    // clearcoatTexture's R scales the factor: no coat over black is black; a full smooth coat returns its Fresnel.
    let [l, r] = white_halves(
        "KHR_materials_clearcoat",
        json!({ "clearcoatFactor": 1.0 }),
        "clearcoatTexture",
        [0, 255, 255, 255],
        [255, 0, 0, 255],
        16,
    );
    assert!(l.0 == 0.0, "no coat over black must be black, got {}", l.0);
    assert!(
        (0.035..0.07).contains(&r.0),
        "a smooth coat in white light returns its Fresnel (~0.04), got {}",
        r.0
    );

    // clearcoatRoughnessTexture's G scales the roughness: a smooth coat is a delta (no variance but the pixel
    // footprint's), a rough one is sampled.
    let [l, r] = white_halves(
        "KHR_materials_clearcoat",
        json!({ "clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 1.0 }),
        "clearcoatRoughnessTexture",
        [255, 0, 255, 255],
        [0, 255, 0, 255],
        64,
    );
    assert!(
        l.1 < 1e-6 && r.1 > 100.0 * l.1.max(1e-9),
        "smooth left, rough right: variances {} and {}",
        l.1,
        r.1
    );

    // sheenColorTexture (sRGB) scales the colour: black sheen is none.
    let [l, r] = white_halves(
        "KHR_materials_sheen",
        json!({ "sheenColorFactor": [1.0, 1.0, 1.0], "sheenRoughnessFactor": 1.0 }),
        "sheenColorTexture",
        [0, 0, 0, 255],
        [255, 255, 255, 255],
        64,
    );
    assert!(
        l.0 == 0.0 && r.0 > 0.05,
        "black sheen left, white right: {} and {}",
        l.0,
        r.0
    );

    // sheenRoughnessTexture's A scales the roughness: a smooth sheen reflects almost nothing seen head-on.
    let [l, r] = white_halves(
        "KHR_materials_sheen",
        json!({ "sheenColorFactor": [1.0, 1.0, 1.0], "sheenRoughnessFactor": 1.0 }),
        "sheenRoughnessTexture",
        [255, 255, 255, 0],
        [0, 0, 0, 255],
        64,
    );
    assert!(
        r.0 > 0.05 && l.0 < 0.3 * r.0,
        "smooth sheen left, rough right: {} and {}",
        l.0,
        r.0
    );
}

// The textures of KHR_materials_specular and KHR_materials_transmission. Would catch a slot ignored, read from the
// wrong channel, or the specular colour not decoded from sRGB into the layer's F0.
#[test]
fn specular_and_transmission_textures_land_on_their_halves() {
    let white = Some([1.0; 3]);
    let bsdf = pathwave::Estimator::Bsdf;
    // specularTexture's A weighs the dielectric layer: over black, no layer is black.
    let [l, r] = white_halves(
        "KHR_materials_specular",
        json!({ "specularFactor": 1.0 }),
        "specularTexture",
        [255, 255, 255, 0],
        [0, 0, 0, 255],
        16,
    );
    assert!(
        l.0 == 0.0 && r.0 > 0.01,
        "no layer left, a layer right: {} and {}",
        l.0,
        r.0
    );
    // specularColorTexture tints F0 (not F90, which stays the layer's weight: a black F0 still reflects a little at
    // grazing): a red texel leaves green almost black.
    let b = halves(
        "KHR_materials_specular",
        json!({ "specularFactor": 1.0 }),
        "specularColorTexture",
        [0, 0, 0, 255],
        [255, 0, 0, 255],
    );
    let film = render(&b, white, 16, bsdf, 1);
    let [l, r] = halves_of(&film);
    let green_right = film.mean()[N - 1][1];
    eprintln!("specularColorTexture: left {l:?}, right {r:?}, right green {green_right}");
    assert!(
        l.0 < 0.05 * r.0 && r.0 > 0.01 && green_right < 0.2 * r.0 as f32,
        "black F0 left, red right: {} and {} (green {green_right})",
        l.0,
        r.0
    );
    // transmissionTexture's R: behind the quad an unlit red card, and nothing else lights the scene, so the diffuse
    // half is black and the transmitting half shows the card through its thin sheet.
    let mut b = halves_over(
        [1.0; 3],
        "KHR_materials_transmission",
        json!({ "transmissionFactor": 1.0 }),
        "transmissionTexture",
        [0, 0, 0, 255],
        [255, 0, 0, 255],
    );
    // Smooth, so the sheet passes the card straight through (a rough one spreads it past the card's edges).
    b.material_json(0)["pbrMetallicRoughness"]["roughnessFactor"] = json!(0.0);
    red_card_behind(&mut b, 3.0);
    let [l, r] = halves_of(&render(&b, None, 16, bsdf, 2));
    eprintln!("transmissionTexture: left {l:?}, right {r:?}");
    assert!(
        l.0 < 1e-3 && r.0 > 0.8,
        "opaque left, the red card through the right: {} and {}",
        l.0,
        r.0
    );
}

/// An unlit red card behind the screen (at z = -1, 2 `half` wide), facing it.
fn red_card_behind(b: &mut GltfBuilder, half: f32) {
    let card = b.unlit_material("card", [1.0, 0.0, 0.0]);
    b.quad("card", screen::corners(half, -1.0), card, FACING_Z);
}

/// Mean RGB over the left and the right half of the view.
fn rgb_halves(film: &pathwave::Film) -> [[f64; 3]; 2] {
    let mean = film.mean();
    let mut out = [[0.0; 3]; 2];
    for j in 0..N {
        for i in 0..N {
            for c in 0..3 {
                out[usize::from(i >= N / 2)][c] += mean[j * N + i][c] as f64 / (N * N / 2) as f64;
            }
        }
    }
    out
}

// KHR_materials_iridescence's textures on a smooth grey metal (a mirror: the white environment's reflection is its
// Fresnel, without noise). Would catch iridescenceTexture's R or iridescenceThicknessTexture's G ignored, read from
// the wrong channel, or the thickness not blended between the minimum and maximum.
#[test]
fn iridescence_textures_land_on_their_halves() {
    let white = Some([1.0; 3]);
    let bsdf = pathwave::Estimator::Bsdf;
    let grey_mirror = |b: &mut GltfBuilder| {
        b.material_json(0)["pbrMetallicRoughness"] =
            json!({ "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.0 });
    };
    let film =
        json!({ "iridescenceFactor": 1.0, "iridescenceThicknessMinimum": 0.0, "iridescenceThicknessMaximum": 400.0 });
    let spread = |c: [f64; 3]| c.iter().cloned().fold(f64::MIN, f64::max) - c.iter().cloned().fold(f64::MAX, f64::min);
    for (slot, left, right) in [
        ("iridescenceTexture", [0, 255, 255, 255], [255, 0, 0, 255]),
        ("iridescenceThicknessTexture", [255, 0, 255, 255], [0, 255, 0, 255]),
    ] {
        let mut b = halves("KHR_materials_iridescence", film.clone(), slot, left, right);
        grey_mirror(&mut b);
        let [l, r] = rgb_halves(&render(&b, white, 4, bsdf, 1));
        eprintln!("{slot}: left {l:?}, right {r:?}");
        // No film (factor 0, or thickness 0): the grey metal's own Fresnel, near 0.5 head-on, the same in every channel.
        assert!(
            spread(l) < 1e-3 && (0.45..0.6).contains(&l[0]),
            "{slot}: the left half has no film: {l:?}"
        );
        assert!(spread(r) > 0.05, "{slot}: a 400 nm film colours the right half: {r:?}");
    }
}

// KHR_materials_diffuse_transmission's textures: behind a thin white Lambertian quad an unlit red card, and nothing
// else lights the scene, so what the view sees is the card through the quad's diffuse transmission. Would catch
// diffuseTransmissionTexture's A or diffuseTransmissionColorTexture's (sRGB) RGB ignored or read from the wrong
// channel.
#[test]
fn diffuse_transmission_textures_land_on_their_halves() {
    let bsdf = pathwave::Estimator::Bsdf;
    for (slot, left, right) in [
        ("diffuseTransmissionTexture", [255, 255, 255, 0], [0, 0, 0, 255]),
        ("diffuseTransmissionColorTexture", [0, 0, 0, 255], [255, 255, 255, 255]),
    ] {
        let mut b = halves_over(
            [1.0; 3],
            "KHR_materials_diffuse_transmission",
            json!({ "diffuseTransmissionFactor": 1.0 }),
            slot,
            left,
            right,
        );
        red_card_behind(&mut b, 30.0);
        let film = render(&b, None, 64, bsdf, 2);
        let [l, r] = halves_of(&film);
        let green_right = film.mean()[N - 1][1];
        eprintln!("{slot}: left {l:?}, right {r:?}, right green {green_right}");
        // The card fills nearly all of the far hemisphere, so the quad passes nearly all of its red.
        assert!(l.0 < 1e-3, "{slot}: nothing through the left half: {}", l.0);
        assert!(
            r.0 > 0.9 && green_right == 0.0,
            "{slot}: the red card through the right half: {} (green {green_right})",
            r.0
        );
    }
}

// KHR_materials_scatter's textures on a thin wall (white, smooth, fully transmissive, no specular layer) before the unlit red
// card. scatterStrengthTexture's A takes the left half to plain transmission (the card seen through it) and the right
// to the draft's scatter_bsdf, which at g = -0.98 sends 99 % of the light back (dark); multiscatterColorTexture's
// (sRGB) RGB, at strength 1 and g = 0.98, is black on the left (nothing through) and white on the right (the card,
// diffusely). Would catch either texture ignored, read from the wrong channel, or only the factors applied.
#[test]
fn thin_wall_scatter_textures_land_on_their_halves() {
    let bsdf = pathwave::Estimator::Bsdf;
    let scatter = |g: f32| json!({ "scatterStrengthFactor": 1.0, "scatterAnisotropy": g });
    for (slot, g, left, right, through) in [
        (
            "scatterStrengthTexture",
            -0.98,
            [255, 255, 255, 0],
            [255, 255, 255, 255],
            [true, false],
        ),
        (
            "multiscatterColorTexture",
            0.98,
            [0, 0, 0, 255],
            [255, 255, 255, 255],
            [false, true],
        ),
    ] {
        let mut b = halves_over([1.0; 3], "KHR_materials_scatter", scatter(g), slot, left, right);
        // Smooth, so that plain transmission shows the card sharply and whole.
        b.material_json(0)["pbrMetallicRoughness"]["roughnessFactor"] = json!(0.0);
        let ext = &mut b.material_json(0)["extensions"];
        ext["KHR_materials_transmission"] = json!({ "transmissionFactor": 1.0 });
        b.use_extension("KHR_materials_transmission");
        red_card_behind(&mut b, 30.0);
        let scene = common::load_built(&b, "layers.gltf");
        assert!(scene.materials[0].thin_scatter.strength > 0.0 && scene.materials[0].thin_walled);
        let [l, r] = halves_of(&render(&b, None, 64, bsdf, 2));
        eprintln!("{slot}: left {l:?}, right {r:?}");
        for ((side, (red, _)), through) in ["left", "right"].iter().zip([l, r]).zip(through) {
            if through {
                assert!(red > 0.8, "{slot}: the red card through the {side} half: {red}");
            } else {
                assert!(red < 0.05, "{slot}: nothing through the {side} half: {red}");
            }
        }
    }
}

// A rough coat over black under a directional light 45 degrees towards +x: the highlight seen head-on needs a coat
// normal tilted 22.5 degrees towards the light. The coat's own normal map tilts it towards +x on one run and -x on the
// other; the base has no map, so only the coat's can do this. Would catch clearcoatNormalTexture ignored, or the coat
// evaluated about the base's shading normal.
#[test]
fn the_clear_coat_follows_its_own_normal_map() {
    let tilt = 22.5f64.to_radians();
    let mut lit = Vec::new();
    for sign in [1.0, -1.0] {
        let n = [sign * tilt.sin(), 0.0, tilt.cos()];
        let bytes = n.map(|c| ((c + 1.0) * 0.5 * 255.0).round() as u8);
        let mut b = GltfBuilder::new();
        let m = b.material("quad", [0.0; 3], [0.0; 3], false);
        let image = b.png_image(1, 1, &[[bytes[0], bytes[1], bytes[2], 255]]);
        let t = b.texture(image, json!({}));
        b.material_json(m)["extensions"]["KHR_materials_clearcoat"] = json!({
            "clearcoatFactor": 1.0,
            "clearcoatRoughnessFactor": 0.3,
            "clearcoatNormalTexture": { "index": t }
        });
        b.use_extension("KHR_materials_clearcoat");
        screen::quad(&mut b, m, 0.0);
        screen::light_along(&mut b, -glam::Vec3::new(1.0, 0.0, 1.0).normalize());
        screen::view(&mut b);
        let film = render(&b, None, 16, pathwave::Estimator::Mis, 1);
        let mean = film.mean().iter().map(|p| p[0] as f64).sum::<f64>() / (N * N) as f64;
        lit.push(mean);
    }
    eprintln!("coat tilted towards the light: {}, away: {}", lit[0], lit[1]);
    assert!(lit[0] > 0.02, "the highlight should be there: {}", lit[0]);
    assert!(
        lit[0] > 5.0 * lit[1],
        "tilting the coat away should lose the highlight: {lit:?}"
    );
}

// The camera sees an unlit quad's colour exactly (factor times texture), whatever lights the scene; inside a closed
// room of unlit walls of colour c, a white Lambert quad returns c for every estimator, since no light sampling aims
// at unlit surfaces and BSDF-sampled hits count in full. Would catch unlit surfaces shaded, weighted as lights, or
// reflecting.
#[test]
fn unlit_surfaces_show_and_shed_their_colour() {
    let mut b = GltfBuilder::new();
    let m = b.pbr_material("unlit", [0.5, 1.0, 0.25], 1.0, 0.2, [0.0; 3], false);
    b.material_json(m)["extensions"]["KHR_materials_unlit"] = json!({});
    b.use_extension("KHR_materials_unlit");
    let texels: Vec<[u8; 4]> = (0..4).map(|k| [60 * k as u8, 255 - 60 * k as u8, 128, 255]).collect();
    let image = b.png_image(4, 1, &texels);
    let t = b.texture(image, json!({ "magFilter": NEAREST, "minFilter": NEAREST }));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    screen::quad(&mut b, m, 0.0);
    screen::view(&mut b);
    let film = render(&b, Some([3.0, 2.0, 1.0]), 8, pathwave::Estimator::Mis, 8);
    let (mean, var) = (film.mean(), film.sample_variance());
    for j in 0..N {
        for i in 0..N {
            let t = texels[i * 4 / N];
            let want: [f32; 3] = [0.5, 1.0, 0.25];
            for c in 0..3 {
                let w = want[c] * pathwave::scene::texture::srgb_to_linear(t[c] as f32 / 255.0);
                let got = mean[j * N + i][c];
                assert!(
                    (got - w).abs() < 1e-5 && var[j * N + i][c] < 1e-8,
                    "pixel ({i}, {j}) channel {c}: {got}, want the unlit colour {w}"
                );
            }
        }
    }

    let c = [0.6, 0.3, 0.9];
    for estimator in [
        pathwave::Estimator::Mis,
        pathwave::Estimator::Bsdf,
        pathwave::Estimator::Light,
    ] {
        let mut b = GltfBuilder::new();
        let walls = b.unlit_material("walls", c);
        let white = b.material("white", [1.0; 3], [0.0; 3], false);
        b.cube("room", [-4.0; 3], [4.0; 3], walls, true);
        b.quad("card", screen::corners(1.0, 0.0), white, FACING_Z);
        screen::view(&mut b);
        let film = render(&b, None, 256, estimator, 1);
        let (m, se) = common::stats::image_mean_and_stderr(&film);
        eprintln!("{estimator:?}: card {m:.4} +- {se:.4}, want {}", c[0]);
        assert!(
            (m - c[0] as f64).abs() < 4.0 * se + 1e-4,
            "{estimator:?}: a white card among unlit walls of {} returns {m} +- {se}",
            c[0]
        );
    }
}

#[test]
fn malformed_layer_extensions_are_refused_naming_the_material() {
    let cases = [
        (
            "KHR_materials_clearcoat",
            json!({ "clearcoatFactor": "thick" }),
            "clearcoatFactor",
        ),
        (
            "KHR_materials_clearcoat",
            json!({ "clearcoatTexture": { "index": 99 } }),
            "clearcoatTexture",
        ),
        (
            "KHR_materials_clearcoat",
            json!({ "clearcoatNormalTexture": {} }),
            "clearcoatNormalTexture",
        ),
        (
            "KHR_materials_sheen",
            json!({ "sheenColorFactor": [1.0, 0.5] }),
            "sheenColorFactor",
        ),
        (
            "KHR_materials_sheen",
            json!({ "sheenRoughnessTexture": { "index": -1 } }),
            "sheenRoughnessTexture",
        ),
        (
            "KHR_materials_iridescence",
            json!({ "iridescenceIor": "oily" }),
            "iridescenceIor",
        ),
        (
            "KHR_materials_iridescence",
            json!({ "iridescenceIor": 0.5 }),
            "iridescenceIor",
        ),
        (
            "KHR_materials_iridescence",
            json!({ "iridescenceThicknessMaximum": -5.0 }),
            "iridescenceThicknessMaximum",
        ),
        (
            "KHR_materials_iridescence",
            json!({ "iridescenceThicknessMinimum": 1e9 }),
            "iridescenceThicknessMinimum",
        ),
        (
            "KHR_materials_iridescence",
            json!({ "iridescenceThicknessTexture": { "index": 7 } }),
            "iridescenceThicknessTexture",
        ),
    ];
    for (ext_name, ext, key) in cases {
        let mut b = GltfBuilder::new();
        let m = b.material("velvet", [0.5; 3], [0.0; 3], false);
        b.material_json(m)["extensions"][ext_name] = ext;
        b.use_extension(ext_name);
        screen::quad(&mut b, m, 0.0);
        screen::view(&mut b);
        let (_dir, path) = common::write_temp(&b, "bad.gltf");
        let e = pathwave::scene::load(&path, None)
            .map(|_| ())
            .expect_err(key)
            .to_string();
        assert!(
            e.contains("velvet") && e.contains(key) && e.contains("bad.gltf"),
            "{key}: {e}"
        );
    }
}

// KHR_materials_iridescence's `iridescenceIor` (the schema's spelling) reaches the film: a smooth black plastic
// (IOR 1.5) under a film 50 um thick, far past light's coherence, mirrors the white environment by the incoherent
// sum of the film's two interfaces' Fresnel reflections, which the film's IOR sets: 0.024 at 1.33, 0.127 at 2.0.
// Would catch the IOR read under another name (until this test the loader read `iridescenceIOR` and every film had
// the default 1.3: the two films rendered the same bytes).
#[test]
fn the_films_ior_is_read_from_iridescence_ior() {
    let fresnel = |cos_i: f64, eta: f64| {
        let cos_t = (1.0 - (1.0 - cos_i * cos_i) / (eta * eta)).sqrt();
        let parallel = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
        let perpendicular = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
        0.5 * (parallel * parallel + perpendicular * perpendicular)
    };
    let mut seen = Vec::new();
    for film in [1.33f64, 2.0] {
        let mut b = GltfBuilder::new();
        let m = b.material("black plastic", [0.0; 3], [0.0; 3], false);
        let mj = b.material_json(m);
        mj["pbrMetallicRoughness"] =
            json!({ "baseColorFactor": [0.0, 0.0, 0.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.0 });
        mj["extensions"]["KHR_materials_specular"] = json!({ "specularFactor": 1.0 });
        mj["extensions"]["KHR_materials_iridescence"] = json!({
            "iridescenceFactor": 1.0, "iridescenceIor": film,
            "iridescenceThicknessMinimum": 50000.0, "iridescenceThicknessMaximum": 50000.0
        });
        b.use_extension("KHR_materials_iridescence");
        screen::quad(&mut b, m, 0.0);
        screen::view(&mut b);
        let f = render(&b, Some([1.0; 3]), 4, pathwave::Estimator::Bsdf, 1);
        let mean = f.mean();
        // The four pixels at the centre, seen 3.6 degrees off the normal.
        let cos_i = 2.0 / (4.0f64 + 2.0 * 0.125 * 0.125).sqrt();
        let cos_film = (1.0 - (1.0 - cos_i * cos_i) / (film * film)).sqrt();
        let (r12, r23) = (fresnel(cos_i, film), fresnel(cos_film, 1.5 / film));
        let expected = r12 + (1.0 - r12).powi(2) * r23 / (1.0 - r12 * r23);
        for (x, y) in [(3, 3), (4, 3), (3, 4), (4, 4)] {
            let got = mean[y * N + x];
            eprintln!("film IOR {film}: pixel ({x}, {y}) {got:?}, incoherent sum {expected:.5}");
            for c in got {
                assert!(
                    (c as f64 - expected).abs() < 3e-3,
                    "film IOR {film}: pixel ({x}, {y}) reflects {got:?}, optics says {expected}"
                );
            }
        }
        seen.push(mean[3 * N + 3][1]);
    }
    assert!(seen[1] > 3.0 * seen[0], "the two films must differ: {seen:?}");
}
