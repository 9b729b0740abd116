//! KHR_mesh_quantization and EXT_meshopt_compression: the project's scenes as gltfpack writes them by default
//! (tests/data/gltfpack, made by ci/make-packed-scenes.sh: u16 positions under a dequantising node transform, i8
//! normals, u16 normalized texture coordinates, quantised morph targets, skin weights and rotations) and with `-cc`
//! (tests/data/gltfpack-cc: the same, meshopt-compressed with the octahedral, quaternion and exponential filters)
//! render like the originals; so does KHR_draco_mesh_compression as `gltf-pipeline -d` writes it (tests/data/draco,
//! made by the same script: edgebreaker connectivity, quantised positions, normals, texture coordinates, joints
//! and weights).
mod common;

use common::mutate::below;
use pathwave::scene::{load, PoseTime};

fn data(dir: &str, name: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(dir)
        .join(name)
}

// Same seeds, so the two renders share their random numbers and differ only by what quantisation moved (vertices by
// at most 1/65535 of a mesh's extent). Would catch an integer read as its raw value (a u16 texture coordinate of
// 65535 instead of 1 samples the wrong texel; an unnormalized u16 position read as normalized shrinks the mesh
// 65535 times), a signed normalized value clamped wrongly, or an attribute refused. (u16 texture coordinates read raw:
// the means still agree, but 113 of 1728 pixels of textured.gltf differ beyond 5 sigma.)
#[test]
fn gltfpack_output_renders_like_the_original() {
    compare_with_originals("gltfpack");
}

// Would catch a view decoded in the wrong mode or at the wrong offset, a filter not applied (octahedral normals left
// encoded, quaternion rotations as raw integers), or decoded bytes not landing where the accessors read. (Without
// the octahedral filter, glass.gltf's mean falls from 0.1226 to 0.1004.)
#[test]
fn meshopt_compressed_output_renders_like_the_original() {
    compare_with_originals("gltfpack-cc");
}

// Would catch decoded attributes landing on the wrong accessor (positions as normals), Draco's point order not
// followed by every attribute (or by uncompressed morph targets), quantised values left undequantised, or the
// decoded faces' winding flipped (one-sided emitters go dark).
#[test]
fn draco_compressed_output_renders_like_the_original() {
    compare_with_originals("draco");
}

// The decoder's output against the reference it was encoded from, on the geometry itself: gltf-pipeline's Draco
// quantises positions to 14 bits of each mesh's extent and reorders points and faces, so each scene must decode to
// bounds within a few quanta, the same total area and area-weighted normal, and the same triangles but those a quantum
// collapses (the encoder drops faces quantisation makes degenerate: 5 slivers of textured.gltf's 3986). Would catch
// a dropped or duplicated face, a flipped winding (the summed normal turns), or positions left quantised.
#[test]
fn draco_decodes_the_geometry_it_was_given() {
    for name in ["cornell-box.gltf", "textured.gltf", "glass.gltf", "animated.gltf"] {
        let summary = |path: std::path::PathBuf, sliver: f64| {
            let soup = load(&path, None)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
                .flatten();
            let (mut area, mut normal, mut slivers) = (0.0f64, glam::DVec3::ZERO, 0);
            for t in soup.positions() {
                let n = (t[1] - t[0]).cross(t[2] - t[0]).as_dvec3() * 0.5;
                area += n.length();
                normal += n;
                slivers += (n.length() < sliver) as usize;
            }
            (soup.len(), soup.bounds(), area, normal, slivers)
        };
        let original = common::scenes_dir().join(name);
        let (lo, hi) = load(&original, None).unwrap().flatten().bounds();
        let quantum = ((hi - lo).max_element() / 16383.0) as f64;
        // A triangle whose longest edge is a few quanta has its area, at most, within a few quanta squared of zero.
        let (n0, (lo0, hi0), a0, v0, slivers) = summary(original, 16.0 * quantum * quantum);
        let (n1, (lo1, hi1), a1, v1, _) = summary(data("draco", name), 0.0);
        let off = (lo1 - lo0).abs().max((hi1 - hi0).abs()).max_element() as f64;
        eprintln!(
            "{name}: {n0} -> {n1} triangles ({slivers} slivers), area {a0:.6} -> {a1:.6}, bounds off by {off:.2e} \
             (quantum {quantum:.2e})"
        );
        assert!(
            n1 <= n0 && n0 - n1 <= slivers,
            "{name}: {n0} triangles -> {n1}, {slivers} slivers"
        );
        // A few quanta: animated.gltf's skinned bar carries its bind-space error (2.0 quanta here) through its joints.
        assert!(off <= 3.0 * quantum, "{name}: bounds off by {off}");
        assert!((a1 / a0 - 1.0).abs() < 1e-3, "{name}: area {a0} -> {a1}");
        assert!((v1 - v0).length() < 1e-3 * a0, "{name}: summed normal {v0} -> {v1}");
    }
}

fn compare_with_originals(dir: &str) {
    for (name, time) in [
        ("cornell-box.gltf", None),
        ("textured.gltf", None),
        ("glass.gltf", None),
        ("animated.gltf", Some(0.7)),
    ] {
        compare_pair(dir, name, common::scenes_dir().join(name), data(dir, name), time);
    }
}

// gltf-pipeline writes one Draco stream and one set of accessors for two meshes of one geometry (the Cornell box's
// short block top and a raised red copy of it): both primitives name them, and it must render like the uncompressed
// file. Would catch the second primitive refused ("decoded by another Draco primitive too", as it was) or decoded
// twice into the same accessors.
#[test]
fn draco_primitives_sharing_a_stream_render_like_the_original() {
    let original = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/shared-geometry.gltf");
    let packed = data("draco", "shared-geometry.gltf");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&packed).unwrap()).unwrap();
    let prim = |m: usize| {
        let p = &json["meshes"][m]["primitives"][0];
        (p["attributes"].clone(), p["indices"].clone(), p["extensions"].clone())
    };
    assert_eq!(
        prim(10),
        prim(16),
        "the fixture no longer shares one stream between the two meshes"
    );
    compare_pair("draco", "shared-geometry.gltf", original, packed, None);
}

fn compare_pair(dir: &str, name: &str, original: std::path::PathBuf, packed: std::path::PathBuf, time: Option<f32>) {
    {
        let mut films = Vec::new();
        for path in [original, packed] {
            let mut scene = load(&path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert!(scene.warnings.is_empty(), "{}: {:?}", path.display(), scene.warnings);
            if let Some(time) = time {
                scene.pose(PoseTime { time, animation: None }).unwrap();
            }
            let mut r = common::scene_renderer(&scene);
            films.push(common::render(&mut r, &common::settings(48, 36, 64, 9)));
        }
        let (a, b) = (&films[0], &films[1]);
        let (ma, sa) = common::stats::image_mean_and_stderr(a);
        let (mb, sb) = common::stats::image_mean_and_stderr(b);
        let se = (sa * sa + sb * sb).sqrt();
        eprintln!("{name}: original {ma:.5} +- {sa:.5}, {dir} {mb:.5} +- {sb:.5}");
        assert!(
            (ma - mb).abs() < 4.0 * se,
            "{name}: means {ma} and {mb} differ by more than 4 sigma ({se})"
        );
        // Pixel by pixel: beyond noise only where an edge moved, which is a few pixels at most.
        let (pa, pb, va, vb) = (a.mean(), b.mean(), a.sample_variance(), b.sample_variance());
        let outliers = (0..pa.len())
            .filter(|&i| {
                (0..3).any(|c| {
                    let s = ((va[i][c] + vb[i][c]) as f64 / a.spp as f64).sqrt();
                    (pa[i][c] - pb[i][c]).abs() as f64 > 5.0 * s + 1e-4
                })
            })
            .count();
        eprintln!("{name}: {outliers} of {} pixels beyond 5 sigma", pa.len());
        assert!(
            outliers * 100 <= pa.len(),
            "{name}: {outliers} pixels differ beyond noise"
        );
    }
}

// Hostile compressed views: each is refused naming the bufferView, with no panic and no read outside a buffer.
#[test]
fn malformed_meshopt_views_are_refused_naming_the_view() {
    let original = std::fs::read_to_string(data("gltfpack-cc", "cornell-box.gltf")).unwrap();
    let bin = std::fs::read(data("gltfpack-cc", "cornell-box.bin")).unwrap();
    type Mutation = fn(&mut serde_json::Value);
    let cases: [(&str, Mutation); 6] = [
        ("mode 'POINTS'", |e| e["mode"] = "POINTS".into()),
        ("does not suit mode", |e| e["byteStride"] = 6.into()),
        ("outside buffer", |e| e["byteLength"] = 1_000_000_000u64.into()),
        ("do not fit the view's byteLength", |e| {
            e["count"] = 1_000_000_000u64.into()
        }),
        ("filter 'WAVELET'", |e| e["filter"] = "WAVELET".into()),
        ("does not decode", |e| e["byteOffset"] = 1.into()),
    ];
    for (want, mutate) in cases {
        let mut json: serde_json::Value = serde_json::from_str(&original).unwrap();
        mutate(&mut json["bufferViews"][0]["extensions"]["EXT_meshopt_compression"]);
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("cornell-box.bin"), &bin).unwrap();
        let path = dir.path().join("bad.gltf");
        std::fs::write(&path, json.to_string()).unwrap();
        let e = load(&path, None).map(|_| ()).expect_err(want).to_string();
        assert!(
            e.contains("bufferView 0") && e.contains("EXT_meshopt_compression") && e.contains(want),
            "{want}: {e}"
        );
    }
}

/// tests/data/draco/cornell-box.gltf, its JSON mutated by `mutate` (the first primitive, its Draco extension and the
/// document), written to a temporary folder.
fn mutated_draco(mutate: impl Fn(&mut serde_json::Value)) -> (tempfile::TempDir, std::path::PathBuf) {
    let original = std::fs::read_to_string(data("draco", "cornell-box.gltf")).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&original).unwrap();
    mutate(&mut json);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.gltf");
    std::fs::write(&path, json.to_string()).unwrap();
    (dir, path)
}

// Hostile Draco primitives: each is refused naming the mesh, the primitive and the extension, with no panic.
#[test]
fn malformed_draco_primitives_are_refused_naming_them() {
    type Mutation = fn(&mut serde_json::Value);
    let cases: [(&str, Mutation); 8] = [
        ("bufferView 99 does not exist", |j| {
            j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"] = 99.into()
        }),
        ("the stream has no attribute 7", |j| {
            j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["POSITION"] =
                7.into()
        }),
        ("compresses NORMAL, which the primitive does not name", |j| {
            j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"]["NORMAL"] =
                1.into()
        }),
        ("POSITION is not compressed", |j| {
            j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["attributes"] =
                serde_json::json!({})
        }),
        ("only triangle lists", |j| {
            j["meshes"][0]["primitives"][0]["mode"] = 5.into()
        }),
        ("points where the accessors declare", |j| {
            let a = j["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            j["accessors"][a]["count"] = 3.into();
        }),
        ("decoded by another Draco primitive too, from another stream", |j| {
            // The short block's top names the floor's accessors but keeps its own stream.
            let floor = j["meshes"][0]["primitives"][0].clone();
            j["meshes"][10]["primitives"][0]["attributes"] = floor["attributes"].clone();
            j["meshes"][10]["primitives"][0]["indices"] = floor["indices"].clone();
        }),
        ("does not decode", |j| {
            let v = j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
                .as_u64()
                .unwrap() as usize;
            // The stream starts 5 bytes in, past its "DRACO" magic.
            j["bufferViews"][v]["byteOffset"] = (j["bufferViews"][v]["byteOffset"].as_u64().unwrap_or(0) + 5).into();
        }),
    ];
    for (want, mutate) in cases {
        let (_dir, path) = mutated_draco(mutate);
        let e = load(&path, None).map(|_| ()).expect_err(want).to_string();
        assert!(
            e.contains("KHR_draco_mesh_compression") && e.contains(want),
            "{want}: {e}"
        );
    }
}

// Every byte of a Draco stream overwritten in turn (and a few random runs): the decoder refuses or decodes
// something, bounded by the accessors, and never panics, hangs or allocates past what the file declares.
#[test]
fn corrupt_draco_streams_never_panic() {
    let original = std::fs::read_to_string(data("draco", "glass.gltf")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&original).unwrap();
    let uri = json["buffers"][0]["uri"].as_str().unwrap();
    let bytes = base64_decode(uri.split_once(',').unwrap().1);
    let prim = &json["meshes"][1]["primitives"][0];
    let v = prim["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
        .as_u64()
        .unwrap() as usize;
    let start = json["bufferViews"][v]["byteOffset"].as_u64().unwrap_or(0) as usize;
    let len = json["bufferViews"][v]["byteLength"].as_u64().unwrap() as usize;
    let mut rng = common::rng::Rng(0x9e37_79b9_7f4a_7c15);
    let (mut refused, mut read) = (0, 0);
    let dir = tempfile::tempdir().unwrap();
    for k in 0..160 {
        let mut b = bytes.clone();
        // The first 64 cases walk the stream's header byte by byte; the rest scatter 8 random bytes over it.
        if k < 64 {
            b[start + k % len] ^= 0xff;
        } else {
            for _ in 0..8 {
                b[start + below(&mut rng, len)] = below(&mut rng, 256) as u8;
            }
        }
        let mut j = json.clone();
        j["buffers"][0]["uri"] = format!("data:application/octet-stream;base64,{}", base64_encode(&b)).into();
        let path = dir.path().join("corrupt.gltf");
        std::fs::write(&path, j.to_string()).unwrap();
        match load(&path, None) {
            Ok(_) => read += 1,
            Err(e) => {
                assert!(e.to_string().contains("corrupt.gltf"), "{e}");
                refused += 1
            }
        }
    }
    eprintln!("corrupt Draco streams: {refused} refused, {read} read");
    assert!(refused > 0, "corruption must be noticed at least sometimes");
}

fn base64_decode(s: &str) -> Vec<u8> {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.decode(s).unwrap()
}

fn base64_encode(b: &[u8]) -> String {
    use base64::Engine;
    base64::engine::general_purpose::STANDARD.encode(b)
}

/// KHR_meshopt_compression, EXT's successor: a quad whose COLOR_0 (normalized RGBA8) is stored through the COLOR
/// filter (YCoCg, 8 bits; meshoptimizer's own encoder, as gltfpack calls it) and the version-1 vertex codec, in a
/// view whose buffer is a fallback. Its colours must load as the originals within the filter's quantisation (a few
/// 255ths: would catch the filter not applied, where the bytes are YCoCg, or the extension not read, where the
/// fallback's zeros are), and the same file under EXT_meshopt_compression, which has no COLOR filter, is refused.
#[test]
fn khr_meshopt_colour_filter_decodes_vertex_colours() {
    use serde_json::json;
    let colors: [[f32; 4]; 4] = [
        [0.9, 0.1, 0.2, 1.0],
        [0.2, 0.8, 0.3, 0.5],
        [0.1, 0.3, 0.95, 0.25],
        [0.6, 0.6, 0.05, 0.0],
    ];
    let filtered: Vec<[u8; 4]> = meshopt::encoding::encode_filter_color::<u8>(&colors, 8);
    let compressed = meshopt::encoding::encode_vertex_buffer_level(&filtered, 2, Some(1)).unwrap();
    let positions: [[f32; 3]; 4] = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin: Vec<u8> = bytemuck::cast_slice(&positions).to_vec();
    bin.extend_from_slice(bytemuck::cast_slice(&indices));
    let packed_at = bin.len().next_multiple_of(4);
    bin.resize(packed_at, 0);
    bin.extend_from_slice(&compressed);
    bin.resize(bin.len().next_multiple_of(4), 0);
    let file = |ext: &str| {
        json!({
            "asset": { "version": "2.0" },
            "extensionsUsed": [ext],
            "extensionsRequired": [ext],
            "buffers": [
                { "byteLength": bin.len(), "uri": "quad.bin" },
                { "byteLength": 16, "extensions": { ext: { "fallback": true } } },
            ],
            "bufferViews": [
                { "buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962 },
                { "buffer": 0, "byteOffset": 48, "byteLength": 12, "target": 34963 },
                { "buffer": 1, "byteOffset": 0, "byteLength": 16, "byteStride": 4, "target": 34962,
                  "extensions": { ext: { "buffer": 0, "byteOffset": packed_at, "byteLength": compressed.len(),
                      "byteStride": 4, "count": 4, "mode": "ATTRIBUTES", "filter": "COLOR" } } },
            ],
            "accessors": [
                { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                  "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0] },
                { "bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR" },
                { "bufferView": 2, "componentType": 5121, "normalized": true, "count": 4, "type": "VEC4" },
            ],
            "materials": [{ "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0] } }],
            "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0, "COLOR_0": 2 }, "indices": 1, "material": 0 }] }],
            "nodes": [{ "mesh": 0 }],
            "scenes": [{ "nodes": [0] }],
        })
    };
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("quad.bin"), &bin).unwrap();
    let path = dir.path().join("quad.gltf");
    std::fs::write(&path, file("KHR_meshopt_compression").to_string()).unwrap();
    let scene = load(&path, None).unwrap_or_else(|e| panic!("{e}"));
    let loaded = scene.meshes[0].primitives[0].colors.clone().expect("COLOR_0 is read");
    for (got, want) in loaded.iter().zip(&colors) {
        for c in 0..4 {
            assert!(
                (got[c] - want[c]).abs() <= 3.0 / 255.0,
                "COLOR_0 {got} against the original {want:?}"
            );
        }
    }
    std::fs::write(&path, file("EXT_meshopt_compression").to_string()).unwrap();
    let e = load(&path, None)
        .map(|_| ())
        .expect_err("EXT has no COLOR filter")
        .to_string();
    assert!(
        e.contains("EXT_meshopt_compression") && e.contains("filter 'COLOR'"),
        "{e}"
    );
}
