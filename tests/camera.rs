//! Camera and emission conventions, checked exactly with max depth 0 (only the emission the camera sees).
mod common;

use common::gltf_builder::{upright, GltfBuilder, FACING_Z};

fn render_direct(b: &GltfBuilder, width: u32, height: u32) -> Vec<[f32; 3]> {
    let (_dir, path) = common::write_temp(b, "scene.gltf");
    let mut r = common::renderer(&path);
    let mut s = common::settings(width, height, 4, 0);
    s.max_depth = Some(0);
    common::render(&mut r, &s).mean()
}

#[test]
fn emission_leaves_the_front_face_only_unless_double_sided() {
    for (double_sided, eye_z, expected) in [
        (false, 2.0, 2.0),
        (false, -2.0, 0.0),
        (true, 2.0, 2.0),
        (true, -2.0, 2.0),
    ] {
        let mut b = GltfBuilder::new();
        let m = b.material("emitter", [0.5; 3], [2.0; 3], double_sided);
        b.quad("emitter", upright([-5.0, 5.0], [-5.0, 5.0], 0.0), m, FACING_Z);
        b.camera([0.0, 0.0, eye_z], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 30.0);
        let px = render_direct(&b, 8, 8);
        assert!(
            px.iter().all(|p| *p == [expected as f32; 3]),
            "double-sided {double_sided}, seen from z = {eye_z}: expected {expected}, got {:?}",
            px[0]
        );
    }
}

#[test]
fn yfov_is_vertical_and_the_width_follows_the_aspect_ratio() {
    // Camera at the origin looking down -z with yfov 90 degrees: at z = -1 the image spans y in [-1, 1] and,
    // at 40x20 (aspect 2), x in [-2, 2]. An emitter strip x in [-0.5, 0.5] covers exactly columns 15..25.
    // A second emitter only above y = 0.5 lights the top quarter of the rows: row 0 is the top.
    let mut b = GltfBuilder::new();
    let strip = b.material("strip", [0.0; 3], [1.0; 3], false);
    let top = b.material("top", [0.0; 3], [3.0; 3], false);
    b.quad("strip", upright([-0.5, 0.5], [-0.4, 0.4], -1.0), strip, FACING_Z);
    b.quad("top", upright([-9.0, 9.0], [0.5, 9.0], -1.0), top, FACING_Z);
    b.camera([0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 90.0);
    let (w, h) = (40usize, 20usize);
    let px = render_direct(&b, w as u32, h as u32);
    let at = |x: usize, y: usize| px[y * w + x][0];
    // Rows 0..5 are y in [0.5, 1]: the top emitter everywhere.
    for y in 0..5 {
        for x in 0..w {
            assert_eq!(at(x, y), 3.0, "pixel ({x}, {y}) should see the top emitter");
        }
    }
    // Rows 6..14 (y in [-0.4, 0.4] fully inside) see the strip in columns 15..25 and nothing elsewhere.
    for y in 6..14 {
        for x in 0..w {
            let expected = if (15..25).contains(&x) { 1.0 } else { 0.0 };
            assert_eq!(at(x, y), expected, "pixel ({x}, {y})");
        }
    }
}

/// Two equal strips x in [-0.5, 0.5], a near one (z = -1) in the top half and a far one (z = -6) in the bottom half,
/// seen by an orthographic camera at `eye_z` (ymag 1) and, when `perspective` is on, a perspective camera after it.
fn orthographic_strips(eye_z: f32, perspective: bool) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let m = b.material("strip", [0.0; 3], [1.0; 3], false);
    for (name, y, z) in [("near", [0.15, 0.85], -1.0), ("far", [-0.85, -0.15], -6.0)] {
        b.quad(name, upright([-0.5, 0.5], y, z), m, FACING_Z);
    }
    // xmag 3 disagrees with the image's aspect ratio on purpose: the width follows the image, as for yfov.
    b.orthographic_camera([0.0, 0.0, eye_z], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 3.0, 1.0);
    if perspective {
        b.camera([0.0, 0.0, eye_z], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 90.0);
    }
    b
}

/// Columns of row `y` that see an emitter.
fn lit_columns(px: &[[f32; 3]], w: usize, y: usize) -> Vec<usize> {
    (0..w).filter(|&x| px[y * w + x][0] > 0.0).collect()
}

#[test]
fn an_orthographic_camera_sees_sizes_independent_of_depth() {
    // ymag 1 at 40x20 (aspect 2): the image spans x in [-2, 2], y in [-1, 1] at every depth, so both strips, 1 wide,
    // cover exactly columns 15..25 whatever their distance or the camera's (a perspective one shows the far one a sixth
    // as wide as the near one). Would catch rays that diverge, a wrong extent or aspect, xmag being read for the width, or a flipped image.
    let (w, h) = (40usize, 20usize);
    for eye_z in [0.0, 3.0] {
        let b = orthographic_strips(eye_z, false);
        let px = render_direct(&b, w as u32, h as u32);
        for y in [3, 6, 13, 16] {
            assert_eq!(
                lit_columns(&px, w, y),
                (15..25).collect::<Vec<_>>(),
                "camera at z = {eye_z}, row {y}: {:?}",
                px[y * w..(y + 1) * w].iter().map(|p| p[0]).collect::<Vec<_>>()
            );
        }
        // Rows 0 (y in [0.9, 1]), 9 and 10 (y in [-0.1, 0.1]) are clear of both strips.
        assert!([0, 9, 10].iter().all(|&y| lit_columns(&px, w, y).is_empty()));
    }
}

#[test]
fn camera_picks_between_an_orthographic_and_a_perspective_camera() {
    use pathwave::scene::Projection;
    let b = orthographic_strips(3.0, true);
    let (_dir, path) = common::write_temp(&b, "cameras.gltf");
    let ortho = pathwave::scene::load(&path, None).unwrap();
    assert_eq!(ortho.camera_count, 2);
    assert_eq!(ortho.camera.unwrap().projection, Projection::Orthographic { ymag: 1.0 });
    let persp = pathwave::scene::load(&path, Some(1)).unwrap();
    assert_eq!(
        persp.camera.unwrap().projection,
        Projection::Perspective {
            yfov: 90f32.to_radians()
        }
    );
    assert!(
        pathwave::scene::load(&path, Some(2)).is_err(),
        "there is no third camera"
    );
    // The perspective camera (yfov 90: x in [-2d, 2d], y in [-d, d] at depth d) sees the near strip, 4 away, over
    // x in [-0.125, 0.125] and y in [0.0375, 0.2125]: in row 8 (y in [0.1, 0.2]) columns 19 and 20 whole and a
    // quarter of 18 and 21. The orthographic one sees it in row 3 over columns 15..25.
    let whole = |scene: &pathwave::scene::Scene, row: usize| {
        let mut r = common::scene_renderer(scene);
        let mut s = common::settings(40, 20, 4, 0);
        s.max_depth = Some(0);
        let px = common::render(&mut r, &s).mean();
        (0..40).filter(|&x| px[row * 40 + x][0] == 1.0).collect::<Vec<_>>()
    };
    assert_eq!(whole(&persp, 8), vec![19, 20]);
    assert_eq!(whole(&ortho, 3), (15..25).collect::<Vec<_>>());
}

/// Emitters whose edge runs down the image centre: a near one (z = -2) in the top half, a far one (z = -8) below.
fn two_edges() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let m = b.material("emitter", [0.0; 3], [1.0; 3], false);
    b.quad("near", upright([-5.0, 0.0], [0.0, 5.0], -2.0), m, FACING_Z);
    b.quad("far", upright([-20.0, 0.0], [-20.0, 0.0], -8.0), m, FACING_Z);
    b.camera([0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 60.0);
    b
}

fn render_lens(aperture: f32, focus: Option<f32>) -> pathwave::Film {
    let (_dir, path) = common::write_temp(&two_edges(), "edges.gltf");
    let mut r = common::renderer(&path);
    let mut s = common::settings(64, 64, 256, 3);
    s.max_depth = Some(0);
    s.aperture = aperture;
    s.focus_distance = focus;
    common::render(&mut r, &s)
}

/// Pixels of row `y` strictly between 10 % and 90 % of full brightness: the width of the edge's blur.
fn edge_width(film: &pathwave::Film, y: usize) -> usize {
    let w = film.width as usize;
    film.mean()[y * w..(y + 1) * w]
        .iter()
        .filter(|p| p[0] > 0.1 && p[0] < 0.9)
        .count()
}

#[test]
fn aperture_zero_is_the_pinhole_byte_for_byte() {
    let pinhole = render_lens(0.0, None);
    assert_eq!(
        render_lens(0.0, Some(2.0)).sum,
        pinhole.sum,
        "aperture 0 must not depend on the focus distance"
    );
    assert!(
        render_lens(0.2, Some(2.0)).sum != pinhole.sum,
        "a real aperture must change the image"
    );
}

#[test]
fn the_plane_in_focus_is_sharp_and_a_far_one_is_blurred() {
    // Aperture radius 0.2 focused at 2: a point at 8 spreads over a disk of radius 0.2 * (8 - 2) / 8 = 0.15 at the
    // focus plane, 0.075 rad, about 4 pixels of this 64-pixel, 60-degree image.
    let film = render_lens(0.2, Some(2.0));
    let (near, far) = (edge_width(&film, 16), edge_width(&film, 48));
    let pinhole = render_lens(0.0, None);
    let (near_pin, far_pin) = (edge_width(&pinhole, 16), edge_width(&pinhole, 48));
    eprintln!("edge widths (pixels between 10 % and 90 %): in focus {near}, far {far}; pinhole {near_pin}, {far_pin}");
    assert!(
        near <= 1,
        "the plane at the focus distance should stay sharp, edge width {near}"
    );
    assert!(
        far >= 4,
        "a plane four times farther should blur over several pixels, edge width {far}"
    );
    assert!(near_pin <= 1 && far_pin <= 1, "a pinhole keeps both sharp");
}
