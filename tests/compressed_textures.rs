//! EXT_texture_webp and KHR_texture_basisu: scenes/textured.gltf with every image re-encoded by the reference
//! encoders (tests/data/webp: cwebp -lossless, required; webp-lossy: cwebp -q 80 with the PNGs kept as fallbacks;
//! ktx2-etc1s and ktx2-uastc: basisu 1.16, required; all made by ci/make-texture-scenes.py), each with what the
//! reference decoder (dwebp, the upstream Basis transcoder) makes of every image in reference/.
mod common;

use common::mutate::below;
use pathwave::scene::texture::{self, Image};
use pathwave::scene::{load, Scene};
use serde_json::Value;
use std::path::PathBuf;

const DIRS: [&str; 4] = ["webp", "webp-lossy", "ktx2-etc1s", "ktx2-uastc"];

fn data(dir: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(dir)
}

/// The encoded bytes of every WebP or KTX2 image in `dir`'s scene, in image order.
fn encoded_images(dir: &str) -> Vec<Vec<u8>> {
    use base64::Engine;
    let json: Value = serde_json::from_str(&std::fs::read_to_string(data(dir).join("textured.gltf")).unwrap()).unwrap();
    let uri = json["buffers"][0]["uri"].as_str().unwrap();
    let bin = (base64::engine::general_purpose::STANDARD)
        .decode(uri.split_once(',').unwrap().1)
        .unwrap();
    let images = json["images"].as_array().unwrap();
    images
        .iter()
        .filter(|im| im["mimeType"] != "image/png")
        .map(|im| {
            let view = &json["bufferViews"][im["bufferView"].as_u64().unwrap() as usize];
            let start = view["byteOffset"].as_u64().unwrap() as usize;
            bin[start..start + view["byteLength"].as_u64().unwrap() as usize].to_vec()
        })
        .collect()
}

/// What the reference decoder made of image `i` of `dir`.
fn reference(dir: &str, i: usize) -> Image {
    let png = image::open(data(dir).join("reference").join(format!("{i}.png")))
        .unwrap()
        .into_rgba8();
    Image {
        width: png.width(),
        height: png.height(),
        texels: png.pixels().map(|p| p.0).collect(),
    }
}

/// The largest difference of any channel of any texel.
fn max_difference(a: &Image, b: &Image) -> u8 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.texels
        .iter()
        .zip(&b.texels)
        .flat_map(|(x, y)| (0..4).map(move |c| x[c].abs_diff(y[c])))
        .max()
        .unwrap()
}

fn original() -> Scene {
    load(&common::scenes_dir().join("textured.gltf"), None).unwrap()
}

// The decoders against the reference decoders, image by image: image-webp against libwebp's dwebp, the basisu
// crate's transcoder against the upstream C++ one (both to RGBA8). Lossless WebP must also give back the PNG's
// texels exactly. Would catch a channel swap, a vertical flip, a wrong sRGB or alpha treatment, a mip level other
// than 0, or a decoder that drifts from its format's reference.
#[test]
fn decoders_match_the_reference_decoders() {
    let originals = original().images;
    for dir in DIRS {
        let encoded = encoded_images(dir);
        assert_eq!(encoded.len(), 5, "{dir}");
        for (i, bytes) in encoded.iter().enumerate() {
            let ours = texture::decode(bytes, 1 << 26, u64::MAX).unwrap_or_else(|e| panic!("{dir} image {i}: {e}"));
            let diff = max_difference(&ours, &reference(dir, i));
            eprintln!(
                "{dir} image {i} ({}x{}): largest difference from the reference {diff}",
                ours.width, ours.height
            );
            assert_eq!(diff, 0, "{dir} image {i}: {diff} levels from the reference decoder");
        }
    }
    // The scene's images in first-use order are its images in file order (each texture uses its own image).
    for (i, bytes) in encoded_images("webp").iter().enumerate() {
        assert_eq!(
            texture::decode(bytes, 1 << 26, u64::MAX).unwrap().texels,
            originals[i].texels,
            "lossless image {i}"
        );
    }
}

// Every scene reads the extension's images, not the core fallback: each loaded image is the reference decode of
// its encoded one. webp-lossy is the one with PNG fallbacks, and 4 of its 5 decodes differ from the PNGs (the
// perforated screen's two colours survive exactly), so the check tells the two apart: without the preference it
// would silently render its PNGs. (The KTX2 scenes have no fallback; UASTC keeps 4 of these 5 simple images exact.)
#[test]
fn textures_take_the_extension_images() {
    let originals = original().images;
    for dir in DIRS {
        let scene = load(&data(dir).join("textured.gltf"), None).unwrap_or_else(|e| panic!("{dir}: {e}"));
        assert!(scene.warnings.is_empty(), "{dir}: {:?}", scene.warnings);
        assert_eq!(scene.images.len(), 5, "{dir}");
        let mut unlike_png = 0;
        for (i, im) in scene.images.iter().enumerate() {
            assert_eq!(im.texels, reference(dir, i).texels, "{dir} image {i}");
            unlike_png += (im.texels != originals[i].texels) as u32;
        }
        eprintln!("{dir}: {unlike_png} of 5 images differ from the PNGs");
        if dir == "webp-lossy" {
            assert!(unlike_png >= 3, "{dir}: only {unlike_png} images differ from the PNGs");
        }
    }
}

fn render(scene: &Scene) -> pathwave::Film {
    let mut r = common::scene_renderer(scene);
    common::render(&mut r, &common::settings(48, 36, 32, 5))
}

// Lossless WebP holds the PNGs' texels, so with the same seed the render is the original's, bit for bit; the lossy
// encodings move texels by a few levels, so their renders' means stay within a few per cent of the original's.
// (The texel-exact checks are the tests above; this one is that the images reach the renderer.)
#[test]
fn compressed_textures_render_like_the_originals() {
    let reference = render(&original());
    let (m0, _) = common::stats::image_mean_and_stderr(&reference);
    for dir in DIRS {
        let film = render(&load(&data(dir).join("textured.gltf"), None).unwrap());
        let (m, se) = common::stats::image_mean_and_stderr(&film);
        eprintln!("{dir}: mean {m:.5} +- {se:.5} against the original's {m0:.5}");
        if dir == "webp" {
            assert_eq!(film.sum, reference.sum, "lossless WebP must render the PNGs' bytes");
        } else {
            assert!((m / m0 - 1.0).abs() < 0.03, "{dir}: mean {m} against {m0}");
        }
    }
}

// Broken images are errors naming the image, never panics: truncated files, a few bytes overwritten anywhere in a
// KTX2 or WebP image (200 cases each), and an extension naming an image the file lacks.
#[test]
fn broken_images_are_refused_naming_the_image() {
    for (dir, i) in [("ktx2-etc1s", 0), ("ktx2-uastc", 1), ("webp-lossy", 2)] {
        let bytes = &encoded_images(dir)[i];
        for cut in [0, 12, bytes.len() / 2] {
            assert!(
                texture::decode(&bytes[..cut], 1 << 26, u64::MAX).is_err(),
                "{dir} image {i} cut at {cut}"
            );
        }
        let mut rng = common::rng::Rng(0x2545_f491_4f6c_dd1d);
        let mut refused = 0;
        for _ in 0..200 {
            let mut b = bytes.clone();
            for _ in 0..4 {
                let k = 12 + below(&mut rng, b.len() - 12);
                b[k] = below(&mut rng, 256) as u8;
            }
            refused += texture::decode(&b, 1 << 26, u64::MAX).is_err() as u32;
        }
        eprintln!("{dir} image {i}: {refused} of 200 corrupted copies refused, the rest decoded");
    }
    // A KTX2 file that claims more pixels than --max-texture-pixels allows is refused before it is transcoded.
    let e = texture::decode(&encoded_images("ktx2-uastc")[0], 100, u64::MAX).unwrap_err();
    assert!(e.contains("--max-texture-pixels"), "{e}");

    let json = std::fs::read_to_string(data("webp").join("textured.gltf")).unwrap();
    let mut doc: Value = serde_json::from_str(&json).unwrap();
    doc["textures"][0]["extensions"]["EXT_texture_webp"]["source"] = 99.into();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.gltf");
    std::fs::write(&path, doc.to_string()).unwrap();
    let e = load(&path, None).map(|_| ()).unwrap_err().to_string();
    assert!(
        e.contains("texture 0: EXT_texture_webp's source (99) is not an image"),
        "{e}"
    );

    // An image whose bytes are not an image: the error names it.
    let mut doc: Value = serde_json::from_str(&json).unwrap();
    let first_webp = doc["textures"][0]["extensions"]["EXT_texture_webp"]["source"]
        .as_u64()
        .unwrap() as usize;
    let view = doc["images"][first_webp]["bufferView"].as_u64().unwrap() as usize;
    doc["bufferViews"][view]["byteLength"] = 20.into();
    std::fs::write(&path, doc.to_string()).unwrap();
    let e = load(&path, None).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains(&format!("image {first_webp}")), "{e}");
}
