//! The host's spectral tables: the RGB-to-spectrum fit's round trip over the sRGB gamut, wavelength sampling against
//! its density, and the CIE integration of constant spectra.
mod common;

use common::rng::Rng;
use common::stats::{chi2_p_value, chi2_statistic};
use pathwave::constants::RGB2SPEC_RES;
use pathwave::constants::{LAMBDA_MAX, LAMBDA_MIN};
use pathwave::spectrum::{self, fit};

fn to_f64(v: [f32; 3]) -> [f64; 3] {
    v.map(|x| x as f64)
}

/// Upsampled and projected back under D65 (the fit's 1 nm quadrature), every colour of a 33³ grid over the sRGB
/// gamut comes back close to itself. Catches a table built wrong or read with the wrong layout or interpolation
/// (either gives errors of 0.1 to 1), and a lookup that picks the wrong channel or node.
///
/// Measured: mean 0.00086, 99.9 % within 0.0031; the worst, 0.019, is next to white ((0.97, 1, 0.97)): there the
/// coefficients run from a narrow bump to the constant 1 within one node, and interpolating them is far from
/// interpolating colours. Away from the top face (every component ≤ 0.95) the worst is 0.0032.
#[test]
fn round_trip_over_the_gamut() {
    let t = spectrum::tables();
    let n = 33;
    let mut errors = Vec::new();
    let mut inner_worst = 0.0f64;
    for r in 0..n {
        for g in 0..n {
            for b in 0..n {
                let rgb = [r, g, b].map(|c| c as f32 / (n - 1) as f32);
                let back = t.fit.project(to_f64(t.coefficients(rgb)));
                let e = (0..3).map(|k| (back[k] - rgb[k] as f64).abs()).fold(0.0, f64::max);
                if rgb.iter().all(|&c| c <= 0.95) {
                    inner_worst = inner_worst.max(e);
                }
                errors.push(e);
            }
        }
    }
    errors.sort_by(|a, b| a.total_cmp(b));
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let p999 = errors[errors.len() * 999 / 1000];
    let worst = *errors.last().unwrap();
    eprintln!("round trip: mean {mean:.5}, 99.9 % {p999:.5}, inner worst {inner_worst:.5}, worst {worst:.5}");
    assert!(mean < 0.0012, "mean round-trip error {mean}");
    assert!(p999 < 0.004, "99.9th percentile {p999}");
    assert!(inner_worst < 0.004, "worst below the top face {inner_worst}");
    assert!(worst < 0.022, "worst {worst}");
}

/// Reflectances stay in [0, 1] at every wavelength, for colours inside the gamut and for those clamped into it
/// (negative, above 1, NaN), and greys are exactly constant. Catches a sigmoid or coefficients that overshoot.
#[test]
fn reflectances_are_bounded() {
    let t = spectrum::tables();
    let mut rng = Rng(7);
    let mut colours: Vec<[f32; 3]> = (0..2000).map(|_| [rng.next(), rng.next(), rng.next()]).collect();
    colours.extend([
        [0.0; 3],
        [1.0; 3],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [-1.0, 2.0, f32::NAN],
    ]);
    for rgb in colours {
        for k in 0..=470 {
            let v = t.reflectance(rgb, LAMBDA_MIN + k as f32);
            assert!(
                (0.0..=1.0).contains(&v),
                "{rgb:?} at {} nm gives {v}",
                LAMBDA_MIN + k as f32
            );
        }
    }
    for grey in [0.0f32, 0.18, 0.5, 0.8, 1.0] {
        for nm in [400.0, 555.5, 700.0] {
            assert!(
                (t.reflectance([grey; 3], nm) - grey).abs() < 1e-6,
                "grey {grey} at {nm} nm"
            );
        }
    }
}

/// 400,000 wavelengths from sample_visible, in 94 bins of 5 nm, against the counts visible_pdf predicts
/// (Simpson's rule per bin): chi-square at p > 0.001. Each of a path's four hero wavelengths has the same marginal
/// density, checked the same way. Catches a sampler whose inverse CDF and density disagree (a wrong constant or
/// normalisation moves a bin's share by far more than the test's noise, 0.5 % of the busiest bins).
#[test]
fn wavelengths_follow_their_density() {
    let bins = 94;
    let width = (LAMBDA_MAX - LAMBDA_MIN) / bins as f32;
    let n = 400_000;
    let expected: Vec<f64> = (0..bins)
        .map(|b| {
            let a = LAMBDA_MIN + b as f32 * width;
            let p = |nm: f32| spectrum::visible_pdf(nm) as f64;
            let mass = width as f64 / 6.0 * (p(a) + 4.0 * p(a + width / 2.0) + p(a + width));
            mass * n as f64
        })
        .collect();
    let total: f64 = expected.iter().sum::<f64>() / n as f64;
    assert!((total - 1.0).abs() < 1e-4, "the density integrates to {total}");
    for slot in 0..5 {
        let mut rng = Rng(11 + slot as u64);
        let mut observed = vec![0.0; bins];
        for _ in 0..n {
            let nm = if slot == 4 {
                spectrum::sample_visible(rng.next())
            } else {
                let (nm, pdf) = spectrum::sample_wavelengths(rng.next());
                assert_eq!(pdf[slot], spectrum::visible_pdf(nm[slot]));
                nm[slot]
            };
            assert!((LAMBDA_MIN..=LAMBDA_MAX).contains(&nm));
            observed[(((nm - LAMBDA_MIN) / width) as usize).min(bins - 1)] += 1.0;
        }
        let (stat, dof) = chi2_statistic(&observed, &expected, 5.0);
        let p = chi2_p_value(stat, dof);
        eprintln!("slot {slot}: chi-square {stat:.1} on {dof} degrees of freedom, p = {p:.3}");
        assert!(p > 0.001, "slot {slot}: chi-square {stat} on {dof} dof, p = {p}");
    }
}

/// The hero wavelengths stratify the sampling CDF: consecutive ones sit a quarter of it apart.
#[test]
fn hero_wavelengths_are_a_quarter_apart() {
    let cdf = |nm: f32| {
        let a = (0.0072 * (LAMBDA_MIN as f64 - 538.0)).tanh();
        let b = (0.0072 * (LAMBDA_MAX as f64 - 538.0)).tanh();
        ((0.0072 * (nm as f64 - 538.0)).tanh() - a) / (b - a)
    };
    let mut rng = Rng(3);
    for _ in 0..1000 {
        let u = rng.next();
        let (nm, _) = spectrum::sample_wavelengths(u);
        for (k, &l) in nm.iter().enumerate() {
            let want = (u as f64 + k as f64 / 4.0).fract();
            assert!(
                (cdf(l) - want).abs() < 1e-4,
                "u {u}: wavelength {k} at CDF {} not {want}",
                cdf(l)
            );
        }
    }
}

/// A constant reflectance of 1 under the scaled D65 integrates to the D65 white, which is linear sRGB (1, 1, 1), and
/// an emitter of RGB (1, 1, 1) is that: by quadrature, and as the film estimates it (the mean over hero wavelengths
/// of observer × emission / density) within its noise. Catches a wrong normalisation of D65 or of the observer, or
/// a film weight that forgets the density.
#[test]
fn constant_spectra_integrate_to_white() {
    let t = spectrum::tables();
    let m = t.xyz_to_srgb();
    let to_rgb = |xyz: [f64; 3]| [0, 1, 2].map(|r| (0..3).map(|k| m[r][k] as f64 * xyz[k]).sum::<f64>());
    let mut xyz = [0.0f64; 3];
    for k in 0..4700 {
        let nm = LAMBDA_MIN + (k as f32 + 0.5) * 0.1;
        let o = t.observer(nm);
        let e = t.emission([1.0; 3], nm) as f64;
        (0..3).for_each(|c| xyz[c] += o[c] as f64 * e * 0.1);
    }
    let rgb = to_rgb(xyz);
    assert!(rgb.iter().all(|c| (c - 1.0).abs() < 2e-3), "quadrature: {rgb:?}");
    assert!((t.fit.project([0.0, 0.0, f64::INFINITY])[1] - 1.0).abs() < 1e-9);

    let mut rng = Rng(5);
    let n = 100_000;
    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
    for _ in 0..n {
        let (nm, pdf) = spectrum::sample_wavelengths(rng.next());
        let mut s = [0.0f64; 3];
        for k in 0..4 {
            let o = t.observer(nm[k]);
            let e = t.emission([1.0; 3], nm[k]) as f64 / pdf[k] as f64 / 4.0;
            (0..3).for_each(|c| s[c] += o[c] as f64 * e);
        }
        let s = to_rgb(s);
        (0..3).for_each(|c| {
            sum[c] += s[c];
            sum2[c] += s[c] * s[c];
        });
    }
    for c in 0..3 {
        let mean = sum[c] / n as f64;
        let stderr = ((sum2[c] / n as f64 - mean * mean) / n as f64).sqrt();
        eprintln!("channel {c}: {mean:.5} ± {stderr:.5}");
        assert!(
            (mean - 1.0).abs() < 4.0 * stderr + 2e-3,
            "channel {c}: {mean} ± {stderr}"
        );
    }
}

/// Emission of any RGB integrates back to that RGB (within the fit's round trip): the conventions Mitsuba 3 and
/// pbrt-v4 use for lights, so a scene's emitters keep their colour and brightness in spectral mode.
#[test]
fn emission_keeps_its_colour() {
    let t = spectrum::tables();
    let m = t.xyz_to_srgb();
    for rgb in [
        [1.0f32, 1.0, 1.0],
        [17.0, 12.0, 4.0],
        [0.0, 0.0, 3.0],
        [0.8, 0.2, 0.1],
        [5.0, 0.5, 0.5],
    ] {
        let mut xyz = [0.0f64; 3];
        for k in 0..=470 {
            let nm = LAMBDA_MIN + k as f32;
            let w = if k == 0 || k == 470 { 0.5 } else { 1.0 };
            let o = t.observer(nm);
            let e = t.emission(rgb, nm) as f64;
            (0..3).for_each(|c| xyz[c] += w * o[c] as f64 * e);
        }
        let back = [0, 1, 2].map(|r| (0..3).map(|k| m[r][k] as f64 * xyz[k]).sum::<f64>());
        let largest = rgb.iter().fold(0.0f32, |a, &b| a.max(b)) as f64;
        for c in 0..3 {
            assert!(
                (back[c] - rgb[c] as f64).abs() < 0.01 * largest,
                "{rgb:?} comes back as {back:?}"
            );
        }
    }
}

/// The table in data/ is the fit's output: 24 of its columns (picked by a fixed seed over the three largest channels,
/// grey columns aside) solved again by fit::solve_column match it to f32 rounding, and every grey node is continued
/// from the diagonal as fit::continue_grey_nodes does. Catches a table left stale after the fit or the CIE tables
/// changed (run `cargo run --release --example rgb2spec`).
#[test]
fn the_kept_table_is_the_fits_output() {
    let t = spectrum::tables();
    let table = t.coefficient_table();
    let res = RGB2SPEC_RES as usize;
    let mut rng = Rng(17);
    let mut checked = 0;
    while checked < 24 {
        let pick = |rng: &mut Rng, n: usize| ((rng.next() * n as f32) as usize).min(n - 1);
        let (l, x, y) = (pick(&mut rng, 3), pick(&mut rng, res), pick(&mut rng, res));
        if x == res - 1 && y == res - 1 {
            continue;
        }
        for (z, c) in fit::solve_column(&t.fit, res, l, x, y).iter().enumerate() {
            let i = (((l * res + z) * res + y) * res + x) * 3;
            for k in 0..3 {
                let kept = table[i + k] as f64;
                assert!(
                    (kept - c[k]).abs() <= 1e-6 * c[k].abs().max(1.0),
                    "column (l {l}, x {x}, y {y}) node {z}: kept {kept}, the fit gives {}",
                    c[k]
                );
            }
        }
        checked += 1;
    }
    let mut continued = table.to_vec();
    fit::continue_grey_nodes(&mut continued, res);
    assert!(continued == table, "the grey nodes are not continued from the diagonal");
}
