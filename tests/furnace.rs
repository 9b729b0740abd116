//! Furnace tests: in a closed room of emission Le and albedo a, every pixel converges to Le / (1 - a).
mod common;

use common::scenes::furnace;
use pathwave::Film;

/// Checks every pixel against `expected` within `z` standard errors, and the image mean within 4.
fn assert_pixels_near(film: &Film, expected: f64, z: f64) {
    let mean = film.mean();
    let var = film.sample_variance();
    let mut worst = (0.0f64, 0usize);
    for (i, (m, v)) in mean.iter().zip(&var).enumerate() {
        let se = (v[0] as f64 / film.spp as f64).sqrt();
        assert!(
            se > 0.0,
            "pixel {i} has zero variance: the estimator is not random, the test proves nothing"
        );
        let dev = (m[0] as f64 - expected).abs() / se;
        if dev > worst.0 {
            worst = (dev, i);
        }
        assert!(
            m[0] == m[1] && m[1] == m[2],
            "grey furnace gave colour at pixel {i}: {m:?}"
        );
    }
    let (img_mean, img_se) = common::stats::image_mean_and_stderr(film);
    eprintln!(
        "image mean {img_mean:.5} +- {img_se:.5} (expected {expected}); worst pixel {} at {:.2} sigma",
        worst.1, worst.0
    );
    assert!(
        worst.0 < z,
        "pixel {} is {:.2} standard errors from {expected} (mean {:?})",
        worst.1,
        worst.0,
        mean[worst.1]
    );
    assert!(
        (img_mean - expected).abs() < 4.0 * img_se,
        "image mean {img_mean} is {:.2} standard errors from {expected}",
        (img_mean - expected).abs() / img_se
    );
}

/// A renderer of the furnace room emitting `le` and reflecting `albedo`.
fn furnace_renderer(le: f32, albedo: f32) -> pathwave::Renderer {
    let (_dir, path) = common::write_temp(&furnace(le, albedo), "furnace.gltf");
    common::renderer(&path)
}

// 16x16 pixels: with a family-wise false-alarm rate of 1e-3 over 256 pixels, z = 4.6 per pixel (normal tails;
// 512 samples per pixel make the mean close to normal).
#[test]
fn furnace_unbounded_depth_converges_to_le_over_one_minus_albedo() {
    let mut r = furnace_renderer(0.5, 0.5);
    let film = common::render(&mut r, &common::settings(16, 16, 512, 7));
    assert_pixels_near(&film, 0.5 / (1.0 - 0.5), 4.6);
}

#[test]
fn furnace_high_albedo_needs_many_bounces() {
    // a = 0.8: Le / (1 - a) = 1.0 needs ~20 bounces on average to reach; a truncated path would fall short.
    let mut r = furnace_renderer(0.2, 0.8);
    let film = common::render(&mut r, &common::settings(8, 8, 1024, 11));
    assert_pixels_near(&film, 0.2 / (1.0 - 0.8), 4.6);
}

#[test]
fn furnace_with_max_depth_sums_exactly_that_many_bounces() {
    // With max depth D the estimator sums Le * a^k for k = 0..=D.
    let mut r = furnace_renderer(0.5, 0.5);
    for depth in [0u32, 1, 2] {
        let mut s = common::settings(8, 8, 256, 3);
        s.max_depth = Some(depth);
        let film = common::render(&mut r, &s);
        let expected: f64 = (0..=depth).map(|k| 0.5 * 0.5f64.powi(k as i32)).sum();
        if depth == 0 {
            // Only the emission seen by the camera: exact, no noise.
            assert!(
                film.mean().iter().all(|m| (m[0] as f64 - expected).abs() < 1e-6),
                "depth 0 must be exactly Le"
            );
        } else {
            assert_pixels_near(&film, expected, 4.6);
        }
    }
}
