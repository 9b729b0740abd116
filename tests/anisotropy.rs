//! KHR_materials_anisotropy through the loader and the renderer: the stretch follows the mesh's tangent frame, its
//! rotation and its texture, and malformed JSON is refused naming the material.
mod common;

use common::gltf_builder::GltfBuilder;
use common::screen;
use common::stats::beyond_noise;
use serde_json::{json, Value};

const N: usize = 16;
const NEAREST: u32 = 9728;

/// A square brushed metal in [-1, 1]^2 at z = 0 filling the view, lit by a point light off to one side: the
/// highlight is stretched along the anisotropy direction. `uvs` give the tangent frame (the direction of growing u),
/// `ext` the material's KHR_materials_anisotropy (None: isotropic), `texel` an anisotropyTexture of one texel.
fn brushed(uvs: [[f32; 2]; 4], ext: Option<Value>, texel: Option<[u8; 4]>) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let m = b.pbr_material("brushed", [0.9, 0.9, 0.9], 1.0, 0.3, [0.0; 3], false);
    if let Some(mut ext) = ext {
        if let Some(t) = texel {
            let image = b.png_image(1, 1, &[t]);
            let tex = b.texture(image, json!({ "magFilter": NEAREST, "minFilter": NEAREST }));
            ext["anisotropyTexture"] = json!({ "index": tex });
        }
        b.material_json(m)["extensions"]["KHR_materials_anisotropy"] = ext;
        b.use_extension("KHR_materials_anisotropy");
    }
    b.textured_quad("quad", screen::corners(1.0, 0.0), uvs, m);
    b.point_light([1.0; 3], 4.0, [0.3, 0.2, 0.8]);
    screen::view(&mut b);
    b
}

/// u grows along +x (the tangent), v along -y.
const U_ALONG_X: [[f32; 2]; 4] = screen::UVS;
/// u grows along +y.
const U_ALONG_Y: [[f32; 2]; 4] = [[1.0, 0.0], [0.0, 0.0], [0.0, 1.0], [1.0, 1.0]];

fn render(b: &GltfBuilder, seed: u32) -> pathwave::Film {
    let scene = common::load_built(b, "brushed.gltf");
    common::render(
        &mut common::scene_renderer(&scene),
        &common::settings(N as u32, N as u32, 64, seed),
    )
}

/// How far the highlight reaches along x and along y: the image's second moments about its brightest pixel.
fn spread(film: &pathwave::Film) -> (f64, f64) {
    let mean = film.mean();
    let peak = (0..N * N).max_by(|&a, &b| mean[a][0].total_cmp(&mean[b][0])).unwrap();
    let (pi, pj) = ((peak % N) as f64, (peak / N) as f64);
    let (mut sx, mut sy, mut total) = (0.0, 0.0, 0.0);
    for j in 0..N {
        for i in 0..N {
            let w = mean[j * N + i][0] as f64;
            sx += w * (i as f64 - pi).powi(2);
            sy += w * (j as f64 - pj).powi(2);
            total += w;
        }
    }
    (sx / total, sy / total)
}

// Would catch: the shading frame not taken from the mesh's tangents (the stretch would not turn with the uvs), the
// rotation ignored or turned the wrong way, the texture's direction or strength (B) not applied, or the lobe stretched
// across its direction instead of along it.
#[test]
fn the_stretch_follows_tangents_rotation_and_texture() {
    let along = |rotation: f32| Some(json!({ "anisotropyStrength": 1.0, "anisotropyRotation": rotation }));
    let quarter = std::f32::consts::FRAC_PI_2;
    let x = render(&brushed(U_ALONG_X, along(0.0), None), 1);
    let y = render(&brushed(U_ALONG_X, along(quarter), None), 2);
    let (xs, ys) = (spread(&x), spread(&y));
    eprintln!("stretched along x: spread {xs:?}; turned a quarter to y: {ys:?}");
    assert!(
        xs.0 > 1.5 * xs.1,
        "a stretch along the tangent (x) must spread the highlight along x: {xs:?}"
    );
    assert!(
        ys.1 > 1.5 * ys.0,
        "turned a quarter turn it must spread along y: {ys:?}"
    );
    let cases = [
        (
            "tangent along y, no rotation",
            render(&brushed(U_ALONG_Y, along(0.0), None), 3),
        ),
        (
            "texture direction (0, 1), no rotation",
            render(&brushed(U_ALONG_X, along(0.0), Some([128, 255, 255, 255])), 4),
        ),
        (
            "texture direction (1, 0) turned a quarter",
            render(&brushed(U_ALONG_X, along(quarter), Some([255, 128, 255, 255])), 5),
        ),
    ];
    for (what, film) in &cases {
        let bad = beyond_noise(film, &y, 2e-3);
        eprintln!("{what}: {bad} channels beyond noise of the stretch along y");
        assert_eq!(bad, 0, "{what} must stretch along y as the rotated material does");
        assert!(
            beyond_noise(film, &x, 2e-3) > 20,
            "{what} must differ from the stretch along x"
        );
    }
    // The texture's B scales the strength: 0 leaves the isotropic lobe.
    let off = render(&brushed(U_ALONG_X, along(0.0), Some([255, 128, 0, 255])), 6);
    let iso = render(&brushed(U_ALONG_X, None, None), 7);
    assert_eq!(
        beyond_noise(&off, &iso, 2e-3),
        0,
        "strength times B = 0 must render the isotropic lobe"
    );
    assert!(
        beyond_noise(&iso, &x, 2e-3) > 20,
        "the isotropic lobe must differ from the stretched one"
    );
}

#[test]
fn malformed_anisotropy_is_refused_naming_the_material() {
    for (ext, expect) in [
        (
            json!({ "anisotropyStrength": "strong" }),
            "anisotropyStrength is not a finite number",
        ),
        (
            json!({ "anisotropyRotation": 1e30 }),
            "anisotropyRotation is not a finite angle",
        ),
        (
            json!({ "anisotropyTexture": { "index": 9 } }),
            "names texture 9, which does not exist",
        ),
    ] {
        let b = brushed(U_ALONG_X, Some(ext), None);
        let (_dir, path) = common::write_temp(&b, "bad.gltf");
        let e = pathwave::scene::load(&path, None)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("material 'brushed'") && e.contains(expect), "{e}");
    }
}
