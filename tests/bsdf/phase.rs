//! Henyey-Greenstein on the device (media.glsl, through Renderer::probe_phase): its density against the published
//! formula, and its sampling against the density by chi-square.
use crate::common::rng::Rng;
use crate::common::stats::{chi2_p_value, chi2_statistic};
use crate::renderer_with;
use glam::Vec3;
use pathwave::scene::Material;
use std::f64::consts::PI;

const ANISOTROPIES: [f32; 7] = [-0.95, -0.6, -0.2, 0.0, 0.3, 0.7, 0.95];

/// Henyey and Greenstein (1941), with mu the cosine between the propagation directions before and after scattering:
/// p(mu) = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)). Written here from the paper's form, not from media.glsl.
fn hg(mu: f64, g: f64) -> f64 {
    (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))
}

/// The probability that mu is at most x: the integral of 2 pi p over [-1, x], in closed form
/// ((1 - g^2) / 2g) ((1 + g^2 - 2 g x)^(-1/2) - 1 / (1 + g)), and (x + 1) / 2 for g = 0.
fn hg_cdf(x: f64, g: f64) -> f64 {
    if g.abs() < 1e-9 {
        return (x + 1.0) / 2.0;
    }
    ((1.0 - g * g) / (2.0 * g) * ((1.0 + g * g - 2.0 * g * x).powf(-0.5) - 1.0 / (1.0 + g))).clamp(0.0, 1.0)
}

/// The incoming propagation direction the tests scatter: off every axis, so no frame's special case hides an error.
fn d_in() -> Vec3 {
    Vec3::new(0.3, -0.5, 0.8).normalize()
}

/// The device's phase function at directions all around d_in equals the formula, and integrates to 1 over the sphere.
/// Would catch the sign of g turned (the usual slip between the propagation and the pbrt convention), a missing 1/4pi,
/// or a power other than 3/2.
#[test]
fn the_phase_function_is_henyey_greensteins_and_normalised() {
    let mut r = renderer_with(vec![Material::default()]);
    let d = d_in();
    let (t, b) = d.any_orthonormal_pair();
    for g in ANISOTROPIES {
        // A midpoint grid in (mu, phi), fine at the peak (mu = +-1 for g of either sign: cells in mu = 1 - 2 s^4 there).
        let side = if g < 0.0 { -1.0 } else { 1.0 };
        let (n_s, n_phi) = (400usize, 16usize);
        let mut dirs = Vec::new();
        let mut cells = Vec::new();
        for i in 0..n_s {
            for j in 0..n_phi {
                let s = (i as f64 + 0.5) / n_s as f64;
                let mu = side * (1.0 - 2.0 * s.powi(4));
                let dmu = 8.0 * s.powi(3) / n_s as f64;
                let phi = 2.0 * PI * (j as f64 + 0.5) / n_phi as f64;
                let sin = (1.0 - mu * mu).max(0.0).sqrt();
                let w = d * mu as f32 + (t * phi.cos() as f32 + b * phi.sin() as f32) * sin as f32;
                dirs.push(w);
                cells.push(dmu * 2.0 * PI / n_phi as f64);
            }
        }
        let out = r.probe_phase(d, g, &dirs, true).unwrap();
        let mut integral = 0.0;
        for ((w, p), dw) in out.iter().zip(&cells) {
            // The cosine of the direction as sent (in f32), so the comparison is of the functions alone.
            let mu = w.normalize().as_dvec3().dot(d.as_dvec3()).clamp(-1.0, 1.0);
            let want = hg(mu, g as f64);
            assert!(
                ((*p as f64) - want).abs() <= 5e-4 * want + 1e-7,
                "g {g}: phase {p} at mu {mu} (direction {w}), Henyey-Greenstein gives {want}"
            );
            integral += *p as f64 * dw;
        }
        assert!(
            (integral - 1.0).abs() < 2e-3,
            "g {g}: the phase function integrates to {integral}"
        );
    }
}

/// Sampled directions against the density: chi-square over cells of equal probability in mu (edges found by bisection
/// on the closed-form CDF, not by the sampler's inversion) times 8 in azimuth, Sidak-corrected at 1 % over the
/// anisotropies; and the mean cosine against g within 4 standard errors. Would catch a sampler whose inversion
/// disagrees with the density it reports (a biased estimator), a turned frame, or azimuths that are not uniform.
#[test]
fn sampling_follows_the_phase_function() {
    let mut r = renderer_with(vec![Material::default()]);
    let d = d_in();
    let (t, b) = d.any_orthonormal_pair();
    let (n, mu_cells, phi_cells) = (160_000usize, 40usize, 8usize);
    let alpha = 1.0 - 0.99f64.powf(1.0 / ANISOTROPIES.len() as f64);
    for (k, g) in ANISOTROPIES.into_iter().enumerate() {
        let mut rng = Rng(4000 + k as u64);
        let u: Vec<Vec3> = (0..n).map(|_| Vec3::new(rng.next(), rng.next(), 0.0)).collect();
        let out = r.probe_phase(d, g, &u, false).unwrap();
        let edges: Vec<f64> = (1..mu_cells)
            .map(|c| {
                let target = c as f64 / mu_cells as f64;
                let (mut lo, mut hi) = (-1.0f64, 1.0f64);
                for _ in 0..60 {
                    let mid = 0.5 * (lo + hi);
                    if hg_cdf(mid, g as f64) < target {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            })
            .collect();
        let mut counts = vec![0.0f64; mu_cells * phi_cells];
        let (mut sum_mu, mut sum_mu2) = (0.0f64, 0.0f64);
        for ((w, pdf), _) in out.iter().zip(&u) {
            assert!(
                (w.length() - 1.0).abs() < 1e-4,
                "g {g}: a sample of length {}",
                w.length()
            );
            let mu = w.dot(d).clamp(-1.0, 1.0) as f64;
            assert!(
                ((*pdf as f64) - hg(mu, g as f64)).abs() <= 5e-4 * hg(mu, g as f64) + 1e-7,
                "g {g}: sampling reported pdf {pdf} where the density is {}",
                hg(mu, g as f64)
            );
            sum_mu += mu;
            sum_mu2 += mu * mu;
            let cell_mu = edges.partition_point(|&e| e < mu);
            let phi = (w.dot(b) as f64).atan2(w.dot(t) as f64).rem_euclid(2.0 * PI);
            let cell_phi = ((phi / (2.0 * PI) * phi_cells as f64) as usize).min(phi_cells - 1);
            counts[cell_mu * phi_cells + cell_phi] += 1.0;
        }
        let expected = vec![n as f64 / (mu_cells * phi_cells) as f64; mu_cells * phi_cells];
        let (stat, dof) = chi2_statistic(&counts, &expected, 5.0);
        let p = chi2_p_value(stat, dof);
        eprintln!("g {g}: chi-square {stat:.1} over {dof} degrees of freedom, p = {p:.4}");
        assert!(
            p > alpha,
            "g {g}: sampling does not follow the phase function (chi-square {stat:.1}, p = {p:.2e})"
        );
        let mean = sum_mu / n as f64;
        let se = ((sum_mu2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - g as f64).abs() < 4.0 * se + 1e-6,
            "g {g}: the mean cosine of the samples is {mean:.5} +- {se:.5}"
        );
    }
}
