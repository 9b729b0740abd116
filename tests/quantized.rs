//! KHR_mesh_quantization: the project's scenes as gltfpack writes them by default (tests/data/gltfpack, made by
//! ci/make-packed-scenes.sh: u16 positions under a dequantising node transform, i8 normals, u16 normalized texture
//! coordinates, quantised morph targets, skin weights and rotations) render like the originals.
mod common;

use pathwave::scene::{load, PoseTime};

fn data(name: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltfpack")
        .join(name)
}

// Same seeds, so the two renders share their random numbers and differ only by what quantisation moved (vertices by
// at most 1/65535 of a mesh's extent). Would catch an integer read as its raw value (a u16 texture coordinate of
// 65535 instead of 1 samples the wrong texel; an unnormalized u16 position read as normalized shrinks the mesh
// 65535 times), a signed normalized value clamped wrongly, or an attribute refused. (u16 texture coordinates read raw:
// the means still agree, but 113 of 1728 pixels of textured.gltf differ beyond 5 sigma.)
#[test]
fn gltfpack_output_renders_like_the_original() {
    for (name, time) in [
        ("cornell-box.gltf", None),
        ("textured.gltf", None),
        ("glass.gltf", None),
        ("animated.gltf", Some(0.7)),
    ] {
        let mut films = Vec::new();
        for path in [common::scenes_dir().join(name), data(name)] {
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
        eprintln!("{name}: original {ma:.5} +- {sa:.5}, gltfpack {mb:.5} +- {sb:.5}");
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
