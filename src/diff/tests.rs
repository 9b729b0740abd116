//! The module's unit tests: special functions against scipy, the correction, constant and rare pixels, bad inputs,
//! counts of 0 and 1, the report, heat maps and the plain metrics.
use super::plain::magma;
use super::simulation::Rng;
use super::*;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

/// (t, df, 2*scipy.stats.t.sf(|t|, df)), the two-sided tail, three cases a line: a table to read across rather than
/// sixteen lines of one shape.
#[rustfmt::skip]
const T_TAILS: [(f64, f64, f64); 16] = [
    (0.5, 3.0, 0.651447964848151), (2.0, 1.0, 0.2951672353008665), (3.0, 5.0, 0.030099247897462586),
    (10.0, 30.0, 4.575251408229618e-11), (6.5, 30.0, 3.4780470879720206e-07), (5.3, 126.0, 5.011519095509803e-07),
    (6.0, 1000.0, 2.7553691733774752e-09), (5.5, 20000.0, 3.8444253979204095e-08), (5.2, 1e6, 1.9932761357030384e-07),
    (50.0, 3.0, 1.761715204127197e-05), (8.0, 15.3, 7.527837732363312e-07), (1000.0, 2.0, 9.999985000025e-07),
    (4.93, 4335.0, 8.530289593427018e-07), (5.0, 499.0, 7.951451882128965e-07), (5.0, 500.0, 7.94641504790956e-07),
    (12.0, 2000.0, 4.3657024952174695e-32),
];

#[test]
fn special_functions_match_scipy() {
    // scipy.special.gammaln / erfc and 2*scipy.stats.t.sf.
    for (x, v) in [
        (0.5, 0.5723649429247),
        (2.5, 0.2846828704729192),
        (10.0, 12.801827480081469),
        (100.5, 361.43554046777757),
        (5e5, 6061176.046459176),
    ] {
        assert!(close(ln_gamma(x), v, 1e-13), "ln_gamma({x}) = {} want {v}", ln_gamma(x));
    }
    assert!(ln_gamma(1.0).abs() < 1e-14);
    for (x, v) in [
        (0.5, 0.4795001221869535),
        (1.0, 0.15729920705028516),
        (2.0, 0.004677734981047266),
        (5.0, 1.5374597944280347e-12),
        (10.0, 2.0884875837625446e-45),
        (20.0, 5.395865611607901e-176),
    ] {
        assert!(close(erfc(x), v, 1e-12), "erfc({x}) = {:e} want {v:e}", erfc(x));
    }
    assert_eq!(erfc(0.0), 1.0);
    for (t, df, v) in T_TAILS {
        // Exact below 500 df, Peizer-Pratt above.
        let tol = if df < 500.0 { 1e-9 } else { 5e-4 };
        let p = t_two_sided(t, df);
        assert!(close(p, v, tol), "t {t} df {df}: {p:e} want {v:e}");
        assert!(close(t_two_sided(-t, df), v, tol));
    }
    assert!(close(t_two_sided(5.2, f64::INFINITY), 1.9931e-7, 1e-3));
    assert_eq!(t_two_sided(0.0, 10.0), 1.0);
    assert_eq!(t_two_sided(f64::INFINITY, 10.0), 0.0);
}
fn sampled(mean: Vec<[f64; 3]>, var: Vec<[f64; 3]>, count: Vec<u32>) -> Side {
    Side::Sampled(Sampled { mean, var, count })
}

fn uniform(w: usize, h: usize, mean: f64, var: f64, n: u32) -> Sampled {
    Sampled {
        mean: vec![[mean; 3]; w * h],
        var: vec![[var; 3]; w * h],
        count: vec![n; w * h],
    }
}

#[test]
fn sidak_threshold_and_family_p() {
    let a = Side::Sampled(uniform(4, 4, 1.0, 0.25, 64));
    let r = statistical(4, 4, &a, &a, &Options::default()).unwrap();
    // 48 pixel tests, one 4x4 and one 16x16 block per channel, and the image-wide test per channel.
    assert_eq!(r.tests, 4 * 4 * 3 + 3 + 3 + 3);
    assert!(close(r.threshold, 1.0 - 0.99f64.powf(1.0 / 57.0), 1e-12));
    assert_eq!((r.p_value, r.rejected, r.consistent, r.skipped), (1.0, 0, true, 0));
    // One pixel off by 5 standard errors: p ~ 1e-6 per test, family-wise 1-(1-p)^57.
    let mut b = uniform(4, 4, 1.0, 0.25, 64);
    b.mean[5][1] = 1.0 + 5.0 * (2.0 * 0.25f64 / 64.0).sqrt();
    let r = statistical(4, 4, &Side::Sampled(b), &a, &Options::default()).unwrap();
    let p = r.worst[0].p;
    assert!(close(p, t_two_sided(5.0, 126.0), 1e-6), "{p}");
    assert!(close(r.p_value, 1.0 - (1.0 - p).powi(57), 1e-9));
    assert_eq!((r.worst[0].x, r.worst[0].y, r.worst[0].channel), (1, 1, 1));
    assert!(!r.consistent && r.rejected == 1 && p < r.threshold);
    // 3.5 standard errors: p ~ 6e-4, above the threshold of 57 tests (1.8e-4).
    let mut b = uniform(4, 4, 1.0, 0.25, 64);
    b.mean[5][1] = 1.0 + 3.5 * (2.0 * 0.25f64 / 64.0).sqrt();
    let r = statistical(4, 4, &Side::Sampled(b), &a, &Options::default()).unwrap();
    assert!(
        r.consistent && r.worst[0].p > r.threshold && r.p_value > 0.01 && r.p_value < 0.05,
        "{}",
        r.p_value
    );
}

#[test]
fn constant_pixels() {
    // Both sides constant but different: a real change, whatever the variance says.
    let a = sampled(vec![[0.5; 3]], vec![[0.0; 3]], vec![16]);
    let b = sampled(vec![[0.6, 0.5, 0.5]], vec![[0.0; 3]], vec![16]);
    let r = statistical(1, 1, &b, &a, &Options::default()).unwrap();
    assert!(!r.consistent);
    assert_eq!(r.worst[0].channel, 0);
    // Identical constants, and constants one f32 rounding apart: no change.
    let c = sampled(
        vec![[0.5f32 as f64, (0.1f32 + 0.2f32) as f64, 0.3f32 as f64]],
        vec![[0.0; 3]],
        vec![16],
    );
    let d = sampled(
        vec![[0.5, 0.3f64 as f32 as f64, (0.3f32 * (1.0 + f32::EPSILON)) as f64]],
        vec![[0.0; 3]],
        vec![16],
    );
    let r = statistical(1, 1, &c, &d, &Options::default()).unwrap();
    assert!(r.consistent, "{}", r.summary());
    // All black on both sides: nothing to see, nothing flagged.
    let z = sampled(vec![[0.0; 3]; 4], vec![[0.0; 3]; 4], vec![8; 4]);
    let r = statistical(2, 2, &z, &z, &Options::default()).unwrap();
    assert!(r.consistent && r.p_value == 1.0);
}

/// A 24x24 rare-event candidate: hits of 50 with p = 0.02 over a base of 0.1 (expectation 1.1), 64 spp.
fn rare_candidate(seed: u64) -> Sampled {
    let mut rng = Rng::new(seed);
    let mut s = uniform(24, 24, 0.0, 0.0, 64);
    for i in 0..24 * 24 {
        for c in 0..3 {
            let k = rng.binomial(64, 0.02) as f64;
            s.mean[i][c] = 0.1 + 50.0 * k / 64.0;
            s.var[i][c] = 2500.0 * k * (64.0 - k) / (64.0 * 63.0);
        }
    }
    s
}

#[test]
fn exact_reference_rare_events() {
    let reference = Side::Exact(vec![[1.1; 3]; 24 * 24]);
    let mut cand = rare_candidate(21);
    // The centre pixel missed every hit: mean 0.1, variance 0. Its own t is -inf; its window knows better.
    cand.mean[12 * 24 + 12] = [0.1; 3];
    cand.var[12 * 24 + 12] = [0.0; 3];
    let r = statistical(24, 24, &Side::Sampled(cand.clone()), &reference, &Options::default()).unwrap();
    assert!(r.consistent, "{}", r.summary());
    let pixels_without_hits = cand.var.iter().flatten().filter(|&&v| v == 0.0).count();
    assert!(
        pixels_without_hits > 300,
        "the scenario needs many hitless pixels: {pixels_without_hits}"
    );
    // Against an exact reference nothing aggregates pixels but the image-wide test (see statistical), so a region
    // that went dark in rare-event light at 64 spp is beyond it: each hitless pixel is as likely as any other.
    // In smooth light (sd 0.3 of the mean, 64 spp) a dark 6x6 region is rejected, and only there.
    let mut rng = Rng::new(4);
    let mut smooth = uniform(24, 24, 1.1, 0.0, 64);
    for i in 0..24 * 24 {
        for c in 0..3 {
            let (m, ss) = rng.normal_group(64, 1.1, 0.33);
            (smooth.mean[i][c], smooth.var[i][c]) = (m, ss / 63.0);
        }
    }
    let r = statistical(24, 24, &Side::Sampled(smooth.clone()), &reference, &Options::default()).unwrap();
    assert!(r.consistent, "{}", r.summary());
    for y in 9..15 {
        for x in 9..15 {
            smooth.mean[y * 24 + x] = [0.0; 3];
            smooth.var[y * 24 + x] = [0.0; 3];
        }
    }
    let r = statistical(24, 24, &Side::Sampled(smooth), &reference, &Options::default()).unwrap();
    for (i, &p) in r.per_pixel.iter().enumerate() {
        let inside = (9..15).contains(&(i % 24)) && (9..15).contains(&(i / 24));
        assert_eq!(p <= r.threshold, inside, "({}, {}) p {p}", i % 24, i / 24);
    }
}

#[test]
fn either_side_may_be_sampled() {
    let cand = rare_candidate(5);
    let mut mu = vec![[1.1; 3]; 24 * 24];
    mu[3] = [1.9, 1.1, 1.1];
    let a = statistical(
        24,
        24,
        &Side::Sampled(cand.clone()),
        &Side::Exact(mu.clone()),
        &Options::default(),
    )
    .unwrap();
    let b = statistical(24, 24, &Side::Exact(mu), &Side::Sampled(cand), &Options::default()).unwrap();
    assert_eq!(a.per_pixel, b.per_pixel);
    assert_eq!(a.worst[0].stat, -b.worst[0].stat);
    assert_eq!(a.channel_means[0], [b.channel_means[0][1], b.channel_means[0][0]]);
}

#[test]
fn bad_inputs_are_refused_with_the_pixel() {
    let good = uniform(4, 3, 1.0, 0.5, 16);
    let compare = |w: u32, h: u32, candidate: Side, reference: Side| {
        statistical(w, h, &candidate, &reference, &Options::default())
    };
    let mut bad = good.clone();
    bad.mean[2 * 4 + 3][1] = f64::NAN;
    let e = compare(4, 3, Side::Sampled(bad), Side::Sampled(good.clone())).unwrap_err();
    assert!(
        e.contains("candidate pixel (3, 2) channel G") && e.contains("NaN"),
        "{e}"
    );
    let mut bad = good.clone();
    bad.var[1][2] = f64::INFINITY;
    let e = compare(4, 3, Side::Sampled(good.clone()), Side::Sampled(bad)).unwrap_err();
    assert!(
        e.contains("reference pixel (1, 0) channel B") && e.contains("variance"),
        "{e}"
    );
    let mut bad = good.clone();
    bad.var[0][0] = -0.1;
    assert!(compare(4, 3, Side::Sampled(bad), Side::Sampled(good.clone())).is_err());
    let e = compare(
        4,
        3,
        Side::Exact(vec![[0.0, f64::NEG_INFINITY, 0.0]; 12]),
        Side::Sampled(good.clone()),
    )
    .unwrap_err();
    assert!(e.contains("candidate pixel (0, 0) channel G"), "{e}");
    let e = compare(4, 3, Side::Exact(vec![[0.0; 3]; 12]), Side::Exact(vec![[0.0; 3]; 12])).unwrap_err();
    assert!(e.contains("plain"), "{e}");
    assert!(compare(4, 4, Side::Sampled(good.clone()), Side::Sampled(good.clone())).is_err());
    assert!(compare(0, 3, Side::Sampled(good.clone()), Side::Sampled(good.clone())).is_err());
    let opts = Options { alpha: 0.0, worst: 3 };
    assert!(statistical(4, 3, &Side::Sampled(good.clone()), &Side::Sampled(good), &opts).is_err());
}

#[test]
fn counts_zero_and_one() {
    let opts = Options::default();
    // Count 0: no samples, so the mean means nothing (even NaN): skipped.
    let mut a = uniform(2, 1, 1.0, 0.5, 16);
    a.count[1] = 0;
    a.mean[1] = [f64::NAN; 3];
    let b = uniform(2, 1, 5.0, 0.5, 16);
    let r = statistical(2, 1, &Side::Sampled(a.clone()), &Side::Sampled(b.clone()), &opts).unwrap();
    assert_eq!((r.skipped, r.tests), (3, 3 + 3));
    assert!(r.per_pixel[1].is_nan() && !r.consistent);
    // Count 1 on one side: its variance (here NaN) is ignored, the other side's carries the test with its df.
    let mut one = uniform(2, 1, 1.0, f64::NAN, 1);
    one.mean[0] = [1.2; 3];
    let r = statistical(
        2,
        1,
        &Side::Sampled(one.clone()),
        &Side::Sampled(uniform(2, 1, 1.0, 0.01, 16)),
        &opts,
    )
    .unwrap();
    assert_eq!(r.skipped, 0);
    assert_eq!(r.worst[0].df, 15.0);
    assert!(close(
        r.worst[0].stat,
        0.2 / (0.01f64 * (1.0 + 1.0 / 16.0)).sqrt(),
        1e-6
    ));
    // Count 1 on both sides: no variance anywhere, nothing testable.
    let e = statistical(2, 1, &Side::Sampled(one.clone()), &Side::Sampled(one.clone()), &opts).unwrap_err();
    assert!(e.contains("no pixel"), "{e}");
    // Count 1 against an exact reference: only the window's variance, here from the other pixels' samples.
    let mut mixed = uniform(3, 1, 1.0, 0.25, 64);
    mixed.count[1] = 1;
    mixed.var[1] = [f64::NAN; 3];
    let r = statistical(3, 1, &Side::Sampled(mixed), &Side::Exact(vec![[1.0; 3]; 3]), &opts).unwrap();
    assert_eq!(r.skipped, 0);
    assert!(r.consistent);
}

#[test]
fn report_lists_the_worst_and_says_so() {
    let a = uniform(8, 8, 1.0, 0.25, 256);
    let mut b = a.clone();
    b.mean[9][2] = 1.5;
    b.mean[20][0] = 1.3;
    b.mean[30][1] = 1.02;
    let r = statistical(
        8,
        8,
        &Side::Sampled(b),
        &Side::Sampled(a),
        &Options { alpha: 0.01, worst: 2 },
    )
    .unwrap();
    assert_eq!(r.worst.len(), 2);
    assert_eq!((r.worst[0].x, r.worst[0].y, r.worst[0].channel), (1, 1, 2));
    assert_eq!((r.worst[1].x, r.worst[1].y, r.worst[1].channel), (4, 2, 0));
    assert!(r.worst[0].p <= r.worst[1].p);
    assert_eq!(r.rejected, 2);
    let text = r.summary();
    for needle in [
        "DIFFERENT",
        "family-wise p-value",
        "Šidák",
        "rejected tests: 2",
        "worst tests",
        "rejected",
    ] {
        assert!(text.contains(needle), "{needle} missing from:\n{text}");
    }
    assert!(close(r.mean_ratio[2], (63.0 + 1.5) / 64.0, 1e-12));
}

#[test]
fn heatmap_colours() {
    let p = [1.0, 1e-3, 1e-9, f64::NAN];
    let img = heatmap(2, 2, &p, 1e-6);
    let lut = magma();
    assert_eq!(img[0], lut[0]);
    assert_eq!(img[1], lut[127]);
    assert_eq!(img[2], HEAT_REJECTED);
    assert_eq!(img[3], HEAT_UNTESTED);
    assert!(!lut.contains(&HEAT_REJECTED) && !lut.contains(&HEAT_UNTESTED));
    let flip = flip_heatmap(2, 1, &[0.0, 1.0]);
    assert_eq!(flip, vec![lut[0], lut[255]]);
}

fn test_pair(w: usize, h: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let mut rng = Rng::new(99);
    let reference: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 / w as f32, (i / w) as f32 / h as f32);
            [x * 1.2, 0.5 * y + 0.2 * ((i / 5) % 2) as f32, (x * y * 9.0).sin().abs()]
        })
        .collect();
    let candidate = reference
        .iter()
        .map(|p| p.map(|v| (v * (1.0 + 0.3 * rng.normal() as f32)).max(0.0)))
        .collect();
    (candidate, reference)
}

#[test]
fn plain_metrics() {
    assert_eq!((srgb8(-1.0), srgb8(0.0), srgb8(1.0), srgb8(7.0)), (0, 0, 255, 255));
    assert_eq!(srgb8(0.5), 188);
    assert_eq!(srgb8(0.002), 7);
    let same = vec![[0.3f32, 0.5, 2.0]; 16];
    let r = plain(4, 4, &same, &same).unwrap();
    assert_eq!((r.rel_mse, r.flip_mean), (0.0, 0.0));
    let other = vec![[0.4f32, 0.5, 2.0]; 16];
    let r = plain(4, 4, &other, &same).unwrap();
    assert!(
        close(
            r.rel_mse,
            (0.1f32 as f64).powi(2) / (0.09 + REL_MSE_EPSILON) / 3.0,
            1e-5
        ),
        "{}",
        r.rel_mse
    );
    assert!(r.flip_mean > 0.0 && r.per_pixel.len() == 16);
    let (c, rf) = test_pair(40, 30);
    let r = plain(40, 30, &c, &rf).unwrap();
    assert!(r.flip_mean > 0.05 && r.flip_mean < 0.5, "{}", r.flip_mean);
    // Our mean is the plain mean of the map, as FLIP's pool reports it.
    let map = nv_flip::FlipImageFloat::with_data(40, 30, &r.per_pixel);
    assert!(close(
        r.flip_mean,
        nv_flip::FlipPool::from_image(&map).mean() as f64,
        1e-5
    ));
    let mut nan = c.clone();
    nan[41][2] = f32::NAN;
    let e = plain(40, 30, &nan, &rf).unwrap_err();
    assert!(e.contains("candidate pixel (1, 1) channel B"), "{e}");
    assert!(plain(40, 30, &c[1..], &rf).is_err());
}

/// Writes the sRGB bytes of a test pair and our FLIP map to pwdiff_flip_* in the temporary directory, for
/// checking against NVIDIA's flip-evaluator Python package (identical maps at ppd 67).
#[test]
fn binary_samples_at_low_counts() {
    // A penumbra at 4 spp: each sample sees the light (1.0) or not (0.0), p = 0.5, on both sides. 1 pixel in 128
    // has one side all lit and the other all dark: zero variance, different means. The t-test calls that certain;
    // the permutation floor 1/C(8, 4) = 1/70 does not.
    let (w, h, n) = (64usize, 64usize, 4u32);
    let mut rng = Rng::new(8);
    let mut draw = || {
        let mut s = uniform(w, h, 0.0, 0.0, n);
        for i in 0..w * h {
            for c in 0..3 {
                let k = rng.binomial(n, 0.5) as f64;
                s.mean[i][c] = k / n as f64;
                s.var[i][c] = k * (n as f64 - k) / (n as f64 * (n as f64 - 1.0));
            }
        }
        s
    };
    let (a, b) = (draw(), draw());
    let degenerate = (0..w * h)
        .flat_map(|i| (0..3).map(move |c| (i, c)))
        .filter(|&(i, c)| a.var[i][c] == 0.0 && b.var[i][c] == 0.0 && a.mean[i][c] != b.mean[i][c])
        .count();
    assert!(degenerate > 20, "{degenerate}");
    let all = Options {
        alpha: 0.01,
        worst: usize::MAX,
    };
    let r = statistical(w as u32, h as u32, &Side::Sampled(a), &Side::Sampled(b), &all).unwrap();
    assert!(r.consistent, "{}", r.summary());
    let pixel = r.worst.iter().find(|t| t.size == 1).unwrap();
    assert!(close(pixel.p, 1.0 / 70.0, 1e-9));
    assert!(close(permutation_floor(16, 16), 1.0 / 601_080_390.0, 1e-9));
}
