//! Statistics for the tests: chi-square p-values (regularized incomplete gamma) and image summaries.
#![allow(dead_code)]

use pathwave::diff::special::ln_gamma;

/// Q(a, x) = 1 - P(a, x), the upper regularized incomplete gamma function.
fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    if x < a + 1.0 {
        // Series for P.
        let mut sum = 1.0 / a;
        let mut term = sum;
        let mut n = a;
        for _ in 0..10_000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-15 {
                break;
            }
        }
        1.0 - sum * (-x + a * x.ln() - ln_gamma(a)).exp()
    } else {
        // Continued fraction for Q (Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-15 {
                break;
            }
        }
        (-x + a * x.ln() - ln_gamma(a)).exp() * h
    }
}

/// Probability that a chi-square variable with `dof` degrees of freedom is at least `stat`.
pub fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 / 2.0, stat / 2.0)
}

/// Pearson's chi-square of observed counts against expected counts, pooling cells expected below
/// `min_expected` into one (the Mitsuba 3 convention). Returns (statistic, degrees of freedom).
pub fn chi2_statistic(observed: &[f64], expected: &[f64], min_expected: f64) -> (f64, usize) {
    let mut stat = 0.0;
    let mut cells = 0usize;
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        if e < min_expected {
            pool_o += o;
            pool_e += e;
        } else {
            stat += (o - e) * (o - e) / e;
            cells += 1;
        }
    }
    if pool_e > 0.0 {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        cells += 1;
    }
    (stat, cells.saturating_sub(1))
}

/// Mean over pixels of a channel average, with the standard error of that mean from per-pixel sample variances.
pub fn image_mean_and_stderr(film: &pathwave::Film) -> (f64, f64) {
    let mean = film.mean();
    let var = film.sample_variance();
    let p = mean.len() as f64;
    let m: f64 = mean.iter().map(|c| (c[0] + c[1] + c[2]) as f64 / 3.0).sum::<f64>() / p;
    // The channel average's variance is bounded by the mean of the channel variances (Cauchy-Schwarz), which keeps this honest without covariances.
    let v: f64 = var.iter().map(|c| (c[0] + c[1] + c[2]) as f64 / 3.0).sum::<f64>() / film.spp as f64 / (p * p);
    (m, v.sqrt())
}

/// Pixel channels of two renders with the same samples per pixel whose means differ by more than five standard
/// errors of the difference of two independent means, plus `floor`.
pub fn beyond_noise(a: &pathwave::Film, b: &pathwave::Film, floor: f32) -> u32 {
    let (ma, mb) = (a.mean(), b.mean());
    let (va, vb) = (a.sample_variance(), b.sample_variance());
    let mut bad = 0;
    for i in 0..ma.len() {
        for c in 0..3 {
            let se = ((va[i][c] + vb[i][c]) / a.spp as f32).sqrt();
            bad += ((ma[i][c] - mb[i][c]).abs() > 5.0 * se + floor) as u32;
        }
    }
    bad
}

/// Asserts that `a` renders what `b` does within noise (`what` names the case): at most three pixel channels
/// `beyond_noise` (floor 1e-3), and image means within four standard errors of their difference (each an upper bound:
/// see `image_mean_and_stderr`), which a mirrored emitter's front turned exceeds.
pub fn assert_same_within_noise(what: &str, a: &pathwave::Film, b: &pathwave::Film) {
    let bad = beyond_noise(a, b, 1e-3);
    let ((ma, sa), (mb, sb)) = (image_mean_and_stderr(a), image_mean_and_stderr(b));
    let z = (ma - mb) / (sa * sa + sb * sb).sqrt();
    eprintln!("{what}: {bad} channels beyond noise, means {ma} against {mb}, z {z:.2}");
    assert!(bad <= 3, "{what}: {bad} pixel channels differ beyond noise");
    assert!(
        z.abs() < 4.0,
        "{what}: mean {ma} against {mb}, {z:.1} standard errors apart"
    );
}
