//! Light sampling, BSDF sampling and MIS agree in expectation; MIS has the least variance; lights are picked by power.
mod common;

use common::stats::{chi2_p_value, chi2_statistic, image_mean_and_stderr};
use pathwave::{Estimator, Film};

/// Each estimator gets its own seed: with shared random numbers the renders would be correlated, and the
/// comparisons below, which assume independent estimates, would be blind.
fn render_with(path: &std::path::Path, estimator: Estimator, spp: u32) -> Film {
    let mut r = common::renderer(path);
    let mut s = common::settings(24, 24, spp, 5 + estimator as u32);
    s.estimator = estimator;
    common::render(&mut r, &s)
}

fn total_variance(film: &Film) -> f64 {
    film.sample_variance().iter().map(|v| (v[0] + v[1] + v[2]) as f64).sum()
}

#[test]
fn estimators_agree_and_mis_has_least_variance() {
    let (_dir, path) = common::write_temp(&common::scenes::two_lights(), "two-lights.gltf");
    let films: Vec<(Estimator, Film)> = [Estimator::Mis, Estimator::Light, Estimator::Bsdf]
        .into_iter()
        .map(|e| (e, render_with(&path, e, 256)))
        .collect();
    let stats: Vec<(Estimator, f64, f64, f64)> = films
        .iter()
        .map(|(e, f)| {
            let (m, se) = image_mean_and_stderr(f);
            (*e, m, se, total_variance(f))
        })
        .collect();
    for (e, m, se, v) in &stats {
        eprintln!("{e:?}: mean {m:.5} +- {se:.5}, summed per-sample variance {v:.3}");
        assert!(*m > 0.0 && *se > 0.0);
    }
    // Means agree within 4 combined standard errors (two-sided, ~6e-5 false alarm per pair).
    for i in 0..stats.len() {
        for j in i + 1..stats.len() {
            let (ei, mi, si, _) = stats[i];
            let (ej, mj, sj, _) = stats[j];
            let z = (mi - mj).abs() / (si * si + sj * sj).sqrt();
            assert!(
                z < 4.0,
                "{ei:?} mean {mi} and {ej:?} mean {mj} differ by {z:.2} standard errors"
            );
        }
    }
    // Per pixel, MIS and light sampling must agree too (a bias confined to some geometry would hide in the
    // image mean): the sum of squared z-scores over pixels is chi-square with one degree of freedom per pixel.
    let (mis, light) = (&films[0].1, &films[1].1);
    let (mm, mv, lm, lv) = (mis.mean(), mis.sample_variance(), light.mean(), light.sample_variance());
    let (mut chi2, mut dof) = (0.0, 0usize);
    for i in 0..mm.len() {
        let a = (mm[i][0] + mm[i][1] + mm[i][2]) as f64 / 3.0;
        let b = (lm[i][0] + lm[i][1] + lm[i][2]) as f64 / 3.0;
        let var = ((mv[i][0] + mv[i][1] + mv[i][2]) as f64 / 3.0 + (lv[i][0] + lv[i][1] + lv[i][2]) as f64 / 3.0)
            / mis.spp as f64;
        if var > 0.0 {
            chi2 += (a - b) * (a - b) / var;
            dof += 1;
        } else {
            assert_eq!(
                a, b,
                "pixel {i} has no variance in either estimator but different values"
            );
        }
    }
    let p = chi2_p_value(chi2, dof);
    eprintln!("per-pixel MIS vs light: chi2 {chi2:.1} over {dof} pixels, p = {p:.4}");
    assert!(
        p > 1e-4,
        "MIS and light sampling disagree per pixel: chi2 {chi2:.1}, dof {dof}, p = {p}"
    );

    let (_, _, _, v_mis) = stats[0];
    let (_, _, _, v_light) = stats[1];
    let (_, _, _, v_bsdf) = stats[2];
    assert!(
        v_mis < v_light,
        "MIS variance {v_mis} is not below light sampling's {v_light}"
    );
    assert!(
        v_mis < v_bsdf,
        "MIS variance {v_mis} is not below BSDF sampling's {v_bsdf}"
    );
}

#[test]
fn lights_are_picked_in_proportion_to_power() {
    let (_dir, path) = common::write_temp(&common::scenes::unequal_lights(), "unequal.gltf");
    let scene = pathwave::scene::load(&path, None).unwrap();
    let packed = pathwave::render::gpu_scene::pack(&scene);
    // Expected probabilities from the scene itself: radiance (channel mean) times area, per emissive triangle.
    let order = &packed.bvh.order;
    let soup = scene.flatten();
    let weights: Vec<f64> = packed
        .lights
        .iter()
        .map(|l| {
            let orig = order[(l.id & pathwave::constants::LIGHT_INDEX_MASK) as usize] as usize;
            let m = &scene.materials[soup.material()[orig] as usize];
            let [a, b, c] = soup.positions()[orig];
            let area = 0.5 * (b - a).cross(c - a).length() as f64;
            (m.emission.x + m.emission.y + m.emission.z) as f64 / 3.0 * area
        })
        .collect();
    assert_eq!(weights.len(), 4, "two quads make four emissive triangles");
    let total: f64 = weights.iter().sum();
    let n = 200_000u32;
    let mut r = common::renderer(&path);
    let picks = r.probe_light_pick(n, 0, 1).unwrap();
    let mut counts = vec![0f64; weights.len()];
    for p in picks {
        counts[p as usize] += 1.0;
    }
    let expected: Vec<f64> = weights.iter().map(|w| w / total * n as f64).collect();
    let (stat, dof) = chi2_statistic(&counts, &expected, 5.0);
    let p = chi2_p_value(stat, dof);
    eprintln!("light picks {counts:?}, expected {expected:?}: chi2 {stat:.2}, dof {dof}, p = {p:.4}");
    assert!(p > 1e-3, "light selection frequencies do not follow power (p = {p})");
    // The bright quad has 12x the dim one's power.
    let bright: f64 = counts
        .iter()
        .zip(&weights)
        .filter(|(_, &w)| w > 0.5)
        .map(|(c, _)| c)
        .sum();
    let ratio = bright / (n as f64 - bright);
    assert!((ratio - 12.0).abs() < 0.5, "bright/dim pick ratio {ratio}, expected 12");
}

#[test]
fn chi2_p_values_match_known_quantiles() {
    // 95th percentiles of chi-square: dof 1 -> 3.841, dof 10 -> 18.307, dof 100 -> 124.342.
    assert!((chi2_p_value(3.841, 1) - 0.05).abs() < 1e-3);
    assert!((chi2_p_value(18.307, 10) - 0.05).abs() < 1e-3);
    assert!((chi2_p_value(124.342, 100) - 0.05).abs() < 1e-3);
    assert!((chi2_p_value(0.0, 5) - 1.0).abs() < 1e-12);
}

/// The sampler behind every path decision: within a pixel, any 2^k samples starting at a multiple of 2^k are a
/// (0,k,2)-net (one point in each of the 2^k boxes of every 2^-a x 2^-b shape); across pixels, and across
/// dimensions of one pixel, the points are uniform. Independent random points fail the first check with
/// overwhelming probability, and a sampler correlating its keys fails the others.
#[test]
fn sampler_stratifies_each_pixel_and_is_uniform_across_keys() {
    let (_dir, path) = common::write_temp(&common::scenes::two_lights(), "two-lights.gltf");
    let mut r = common::renderer(&path);
    const BITS: u32 = 24;
    for (pixel, bounce, dim, first, k) in [
        (0, 0, 2, 0, 8),
        (17, 3, 5, 0, 10),
        (4242, 1, 7, 512, 9),
        (9, 0, 3, 1024, 6),
    ] {
        let pts = r
            .probe_rand(pixel..pixel + 1, first..first + (1 << k), (bounce, dim), 7)
            .unwrap();
        for a in 0..=k {
            let b = k - a;
            let mut seen = vec![false; 1 << k];
            for p in &pts {
                let cell = ((p[0] >> (BITS - a)) << b) | (p[1] >> (BITS - b));
                assert!(
                    !seen[cell as usize],
                    "pixel {pixel}, bounce {bounce}, dimension {dim}: samples {first}..{} put two points in one \
                     2^-{a} x 2^-{b} box",
                    first + (1 << k)
                );
                seen[cell as usize] = true;
            }
        }
    }
    // Uniform over the square across pixels (sample 0 of 65,536 pixels), and with no pairing between two
    // dimensions of one pixel (their first coordinates over 4,096 samples), on a 16 x 16 grid.
    let grid = |points: &mut dyn Iterator<Item = (u32, u32)>| {
        let mut counts = vec![0f64; 256];
        let mut n = 0.0;
        for (x, y) in points {
            counts[((x >> (BITS - 4)) * 16 + (y >> (BITS - 4))) as usize] += 1.0;
            n += 1.0;
        }
        let expected = vec![n / 256.0; 256];
        let (stat, dof) = chi2_statistic(&counts, &expected, 5.0);
        chi2_p_value(stat, dof)
    };
    let across = r.probe_rand(0..65_536, 0..1, (2, 5), 3).unwrap();
    let p = grid(&mut across.iter().map(|p| (p[0], p[1])));
    assert!(p > 1e-3, "sample 0 across pixels is not uniform (p = {p})");
    let a = r.probe_rand(77..78, 0..4096, (1, 5), 3).unwrap();
    let b = r.probe_rand(77..78, 0..4096, (1, 6), 3).unwrap();
    let p = grid(&mut a.iter().zip(&b).map(|(a, b)| (a[0], b[0])));
    assert!(p > 1e-3, "two dimensions of one pixel are correlated (p = {p})");
}
