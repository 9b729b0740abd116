//! `pathwave diff`'s statistics: per-pixel tests of two renders, the family-wise verdict, heat maps, relMSE and FLIP.
//!
//! # The statistical test
//!
//! Each pixel and channel is one test of H0 "both renders estimate the same expectation"; with two sampled sides,
//! so is the mean of each 4x4 and 16x16 block, and each channel's image-wide mean difference is one more (see
//! [`statistical`]). Šidák's correction over all `m` tests gives the per-test threshold `1-(1-alpha)^(1/m)` and the
//! family-wise p-value `1-(1-p_min)^m` (Mitsuba 3's render tests do the same, over pixels only). Blocks add about
//! 7 % to `m` and see a bias over a region that no single pixel's noise lets through.
//!
//! Path-traced samples are skewed and heavy-tailed, and Šidák asks for per-test levels near 1e-7, so the tails of
//! the statistic's null distribution are all that matters. Two variance estimates each fail in one tail:
//!
//! * a side's own variance (Welch, or the one-sample t against an exact reference) collapses when that side missed
//!   the rare bright samples: its mean is low and its variance tiny at once, so |t| explodes on the low side;
//! * a variance learnt elsewhere (the other side's samples pooled in, or the neighbouring pixels' samples) is
//!   blind to a cluster of rare samples in this pixel: the mean is high and the variance does not follow, so |t|
//!   explodes on the high side (Poisson tail versus normal tail).
//!
//! A side's own variance grows exactly when rare samples pull its mean up, and a borrowed one holds when missing
//! them pulls the mean down, so the two are combined, differently where the borrowed one comes from:
//!
//! Two sampled sides: own = Welch `s1²/n1 + s2²/n2` (Welch-Satterthwaite df), borrowed = pooled
//! `s_p²(1/n1+1/n2)`, `s_p² = ((n1-1)s1² + (n2-1)s2²)/(n1+n2-2)` (df `n1+n2-2`); the test uses the LARGER of the
//! two, with its df. Both estimate the same pixel's distribution under H0, so the larger is never wrong by more than
//! its own noise, and for Gaussian samples the pooled t against Student t with `n1+n2-2` df is the exact test. With
//! equal counts the two are equal and this is the ordinary pooled t-test; they part when the counts differ, which is
//! where Welch alone fails (a 4096-spp reference makes `s2²/n2` tiny, so a 16-spp candidate that missed the rare
//! samples is "significant") and where pooling alone fails (the big side's variance hides the small side's
//! fireflies). Student t, not a normal: at the Šidák level of a 64x64 image (8e-7) t with 30 df needs 6.2 where a
//! normal needs 4.9, and treating one as the other multiplies the false positives by 35. The brief's
//! parallel-variance formula over all `n1+n2` samples (between-means term included) gives a statistic that is a
//! monotone function of the pooled t, bounded by `sqrt(n1+n2-1)`: calibrated exactly it is this test, and against
//! a normal it is conservative at small n (at 16+16 samples it needs 4.9 where the exact test's equivalent is 4.2)
//! yet still wrong with unequal counts (it pools; the simulations flag up to 10 % of null pairs).
//!
//! One side exact (a converged reference, no variance): own = the sampled side's `s²/n` (df n-1), borrowed = the
//! sampled side's per-sample variance pooled over a square window around the pixel (all samples of the window's
//! pixels, weighted by their df; the window grows from 3x3 until it holds WINDOW_SAMPLES samples, at most 33x33),
//! over this pixel's n. Here the borrowed estimate describes OTHER pixels, whose variance may be lower (a darker
//! texel beside a brighter one: taking the larger variance with the window's ~normal df flagged 5 % of null pairs
//! of textured Gaussian pixels at 16 spp), so the pixel must fail BOTH tests: the larger p decides. The own test
//! alone is exact for Gaussian samples; the window test vetoes the low-side explosion of rare events. Limits:
//! events rarer than about one in WINDOW_SAMPLES samples may be missed by a whole window, which then looks exactly
//! like a region that went dark and is flagged (render the candidate with more samples); conversely a region that
//! did go dark among rare events is only seen where its pixels each expect several hits; small n costs power, as
//! the own test needs t_{n-1} (8.0 at 16 spp against 4.9 for a normal at the 64x64 level).
//!
//! Numerics: a difference is never judged finer than SD_FLOOR_REL of the pixel's value (added in quadrature to the
//! standard error): f32 means, and constant pixels computed with a different rounding, must not count as changes.
//! Both-constant pixels that differ by more than that are rejected, as they should be, once there are samples
//! enough: with two sampled sides p never drops below 1/C(n1+n2, n1) (`permutation_floor`), the least that
//! n1+n2 samples can show without assuming their distribution, which is exactly what binary samples (a penumbra,
//! constant radiance seen or not) at low counts defeat. At 16+16 samples that is 1.7e-9, below the Šidák level of
//! any image under a million tests; at 4+4 it is 1/70, and nothing is rejected per pixel (blocks and the
//! image-wide test still can be).
//!
//! Counts: a pixel with count 0 on a side is not tested (`skipped`); count 1 gives a mean but no variance, so the
//! test uses whatever variance estimate remains (the other side's, pooled; the window's, for an exact reference)
//! and is skipped when none remains. Against a sampled side, the permutation floor (1/(n+1) for a single sample)
//! keeps a 1-sample pixel from being rejected on its own: any one sample may be the rare one. Its blocks can be.
//!
//! Independence: the test assumes a pixel's samples are independent. pathwave's Owen-scrambled Sobol samples make
//! the error of a pixel mean usually smaller than `s²/n`, which makes the test conservative, not wrong; pixels are
//! independent of each other (per-pixel keys, box filter), which the image-wide test relies on.

use std::fmt::Write as _;

mod plain;
#[cfg(test)]
mod simulation;
mod special;
#[cfg(test)]
mod tests;

pub use plain::*;
use special::*;

/// The finest relative difference a test resolves: f32 means carry ~6e-8, different float orders a few times more.
const SD_FLOOR_REL: f64 = 1e-5;
/// The same for values near zero, relative to the image's mean magnitude.
const SD_FLOOR_SCALE: f64 = 1e-9;
/// Samples a neighbourhood must hold before its variance may stand in for a pixel's: enough to see events of
/// probability 0.001 per sample 16 times (4096 flagged 20 % of null pairs of p = 0.002 events at 64 spp).
const WINDOW_SAMPLES: u64 = 16384;
const WINDOW_MAX_RADIUS: usize = 16;
/// Edges of the square blocks whose mean differences are tested besides pixels: a bias over a region is far below
/// one pixel's noise but not below its block's. The first also makes the image-wide test's blocks: pathwave's pixels
/// are independent (box filter, per-pixel sample keys), and 4x4 blocks keep their sums nearly independent should a
/// reconstruction filter spread samples over a pixel or two; small, because the self-normalised sum is bounded by
/// sqrt(blocks) and its bound must pass the Šidák level (2·exp(-T²/2) < threshold needs about 30 blocks).
const SCALES: [usize; 2] = [4, 16];
/// relMSE's epsilon: keeps near-black reference pixels from dominating the mean (on linear radiance).
pub const REL_MSE_EPSILON: f64 = 1e-2;
const CHANNEL_NAMES: [&str; 3] = ["R", "G", "B"];

/// A render with statistics: per pixel and channel the sample mean and unbiased per-sample variance, per pixel the
/// sample count. Row-major, top row first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sampled {
    pub mean: Vec<[f64; 3]>,
    /// Unbiased per-sample variance s² (not of the mean); ignored where the count is below 2.
    pub var: Vec<[f64; 3]>,
    pub count: Vec<u32>,
}

impl Sampled {
    /// A film's statistics as the test takes them: the mean from the exact sums in f64 (finer than the file's f32
    /// mean), the unbiased per-sample variance and the count.
    pub fn from_exact(film: &crate::render::film::ExactFilm) -> Sampled {
        let mean = (0..film.pixels())
            .map(|p| {
                let n = film.count[p].max(1) as f64;
                film.sums_f64(p).0.map(|s| s / n)
            })
            .collect();
        Sampled {
            mean,
            var: film.sample_variance(),
            count: film.count.clone(),
        }
    }
}

/// One side of a comparison.
#[derive(Clone, Debug, PartialEq)]
pub enum Side {
    /// Means only, taken as the true expectation (a converged reference).
    Exact(Vec<[f64; 3]>),
    Sampled(Sampled),
}

impl Side {
    fn mean(&self) -> &[[f64; 3]] {
        match self {
            Side::Exact(m) => m,
            Side::Sampled(s) => &s.mean,
        }
    }

    /// Samples behind pixel i, None for an exact side.
    fn count(&self, i: usize) -> Option<u32> {
        match self {
            Side::Exact(_) => None,
            Side::Sampled(s) => Some(s.count[i]),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Family-wise false-positive rate.
    pub alpha: f64,
    /// How many of the lowest-p pixel tests the report lists.
    pub worst: usize,
}

impl Default for Options {
    fn default() -> Self {
        Options { alpha: 0.01, worst: 10 }
    }
}

/// One pixel or block test, as listed among the worst.
#[derive(Clone, Debug, PartialEq)]
pub struct Worst {
    /// The pixel, or the block's top-left pixel.
    pub x: u32,
    pub y: u32,
    /// 1 for a pixel, else the block's edge (blocks at the right and bottom borders are clipped).
    pub size: u32,
    pub channel: usize,
    /// The pixel's means, or the block's mean of its pixels' means.
    pub candidate: f64,
    pub reference: f64,
    /// The t statistic (candidate minus reference over its standard error).
    pub stat: f64,
    /// Its degrees of freedom (infinite: normal).
    pub df: f64,
    pub p: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Family-wise p-value after Šidák's correction: the smallest per-test p, as a probability for all tests.
    pub p_value: f64,
    pub alpha: f64,
    /// Per-test level: a test is rejected when its p is at most this.
    pub threshold: f64,
    /// Tests performed: per channel, the pixels', the blocks' (SCALES) and the image-wide test.
    pub tests: usize,
    /// Pixel-channel tests not performed (a side without samples there, or no variance estimate at all).
    pub skipped: usize,
    pub rejected: usize,
    /// No test rejected: the difference is consistent with noise at the family-wise level alpha.
    pub consistent: bool,
    pub worst: Vec<Worst>,
    /// Per channel, the mean over the compared pixels: [candidate, reference].
    pub channel_means: [[f64; 2]; 3],
    /// Per channel, candidate mean over reference mean.
    pub mean_ratio: [f64; 3],
    /// The image-wide tests of the mean difference, per channel: statistic and p-value (part of the family).
    pub channel_stat: [f64; 3],
    pub channel_p: [f64; 3],
    /// Per pixel, the smallest p of its channels' tests and of the blocks it lies in (NaN where nothing was tested),
    /// for [`heatmap`].
    pub per_pixel: Vec<f64>,
}

fn pixel_name(width: usize, i: usize) -> String {
    format!("({}, {})", i % width, i / width)
}

fn check_side(name: &str, side: &Side, width: usize, pixels: usize) -> Result<(), String> {
    let bad = |i: usize, c: usize, what: &str, v: f64| {
        Err(format!(
            "{name} pixel {} channel {}: {what} is {v}",
            pixel_name(width, i),
            CHANNEL_NAMES[c]
        ))
    };
    match side {
        Side::Exact(mean) => {
            if mean.len() != pixels {
                return Err(format!("{name}: {} means for {pixels} pixels", mean.len()));
            }
            for (i, m) in mean.iter().enumerate() {
                if let Some(c) = (0..3).find(|&c| !m[c].is_finite()) {
                    return bad(i, c, "the mean", m[c]);
                }
            }
        }
        Side::Sampled(s) => {
            if s.mean.len() != pixels || s.var.len() != pixels || s.count.len() != pixels {
                return Err(format!(
                    "{name}: {} means, {} variances and {} counts for {pixels} pixels",
                    s.mean.len(),
                    s.var.len(),
                    s.count.len()
                ));
            }
            for i in 0..pixels {
                // A pixel without samples has no mean to check; its variance only counts from two samples.
                if s.count[i] == 0 {
                    continue;
                }
                for c in 0..3 {
                    let (m, v) = (s.mean[i][c], s.var[i][c]);
                    if !m.is_finite() {
                        return bad(i, c, "the mean", m);
                    }
                    // A variance from sums of squares may round slightly below zero; more than that is corruption.
                    if s.count[i] >= 2 && !(v.is_finite() && v >= -1e-6 * (m * m + f64::MIN_POSITIVE)) {
                        return bad(i, c, "the variance", v);
                    }
                }
            }
        }
    }
    Ok(())
}

/// A variance estimate of a difference of means, with its degrees of freedom.
#[derive(Clone, Copy)]
struct Est {
    var: f64,
    df: f64,
}

/// Two sampled sides: the larger of Welch's and the pooled variance.
fn two_sample(n1: u32, v1: f64, n2: u32, v2: f64) -> Option<Est> {
    let (f1, f2) = (n1 as f64, n2 as f64);
    let (v1, v2) = (v1.max(0.0), v2.max(0.0));
    // Below two samples a side has no variance; pooling still uses the other side's (df n1+n2-2 counts only theirs).
    let ss1 = if n1 >= 2 { (f1 - 1.0) * v1 } else { 0.0 };
    let ss2 = if n2 >= 2 { (f2 - 1.0) * v2 } else { 0.0 };
    let df_pooled = f1 + f2 - 2.0;
    if df_pooled < 1.0 {
        return None;
    }
    let pooled = Est {
        var: (ss1 + ss2) / df_pooled * (1.0 / f1 + 1.0 / f2),
        df: df_pooled,
    };
    let welch = (n1 >= 2 && n2 >= 2).then(|| {
        let (a, b) = (v1 / f1, v2 / f2);
        let denom = a * a / (f1 - 1.0) + b * b / (f2 - 1.0);
        let df = if denom > 0.0 {
            (a + b) * (a + b) / denom
        } else {
            df_pooled
        };
        Est { var: a + b, df }
    });
    // Equal counts make the two equal up to rounding: the pooled df is then the exact one for identical
    // distributions, so Welch must win clearly.
    match welch {
        Some(welch) if welch.var > pooled.var * (1.0 + 1e-9) => Some(welch),
        _ => Some(pooled),
    }
}

/// One sampled side against an exact one: its own variance and its neighbourhood's, as two tests that must both
/// reject (see the module's documentation for why not the larger variance, as with two sampled sides).
fn one_sample(n: u32, v: f64, window: Option<(f64, f64)>) -> [Option<Est>; 2] {
    let f = n as f64;
    let own = (n >= 2).then(|| Est {
        var: v.max(0.0) / f,
        df: f - 1.0,
    });
    let borrowed = window
        .filter(|w| w.1 > 0.0)
        .map(|(wv, wdf)| Est { var: wv / f, df: wdf });
    [own, borrowed]
}

/// The smallest p-value any test that assumes nothing about the samples' distribution can give two sides of n1 and
/// n2 samples: 1/C(n1+n2, n1), when the split of the pooled samples is the most extreme of all splits. A t-test
/// goes below it only by trusting the distribution's shape, and binary samples break that trust at low counts (a
/// penumbra at 4 spp: both sides constant, one lit and one dark, in 1 pixel of 128), so p never goes below it.
/// From 16+16 samples (1.7e-9) it only binds on images of more than a million tests.
fn permutation_floor(n1: u32, n2: u32) -> f64 {
    let (a, b) = (n1 as f64, n2 as f64);
    (ln_gamma(a + 1.0) + ln_gamma(b + 1.0) - ln_gamma(a + b + 1.0)).exp()
}

/// Per pixel and channel, the sampled side's per-sample variance pooled over a window that holds WINDOW_SAMPLES
/// samples, and its df. Windows are summed directly (no summed-area table): variances span many orders of
/// magnitude across an image, and differences of running sums would lose the dark regions to cancellation.
fn window_variance(w: usize, h: usize, s: &Sampled) -> Vec<[(f64, f64); 3]> {
    // Counts are integers: a summed-area table of them is exact, and picks each pixel's radius.
    let mut sat = vec![0u64; (w + 1) * (h + 1)];
    for y in 0..h {
        for x in 0..w {
            sat[(y + 1) * (w + 1) + x + 1] =
                s.count[y * w + x] as u64 + sat[y * (w + 1) + x + 1] + sat[(y + 1) * (w + 1) + x]
                    - sat[y * (w + 1) + x];
        }
    }
    let bounds = |x: usize, y: usize, r: usize| {
        (
            x.saturating_sub(r),
            y.saturating_sub(r),
            (x + r + 1).min(w),
            (y + r + 1).min(h),
        )
    };
    let radius: Vec<usize> = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (1..=WINDOW_MAX_RADIUS)
                .find(|&r| {
                    let (x0, y0, x1, y1) = bounds(x, y, r);
                    let n = sat[y1 * (w + 1) + x1] + sat[y0 * (w + 1) + x0]
                        - sat[y0 * (w + 1) + x1]
                        - sat[y1 * (w + 1) + x0];
                    n >= WINDOW_SAMPLES || (x0 == 0 && y0 == 0 && x1 == w && y1 == h)
                })
                .unwrap_or(WINDOW_MAX_RADIUS)
        })
        .collect();
    let dof: Vec<f64> = s
        .count
        .iter()
        .map(|&n| if n >= 2 { n as f64 - 1.0 } else { 0.0 })
        .collect();
    let mut out = vec![[(0.0, 0.0); 3]; w * h];
    let mut radii: Vec<usize> = radius.clone();
    radii.sort_unstable();
    radii.dedup();
    for &r in &radii {
        let df_sum = box_sum(w, h, r, &dof);
        let ss_sum: [Vec<f64>; 3] = std::array::from_fn(|c| {
            let ss: Vec<f64> = (0..w * h).map(|i| dof[i] * s.var[i][c].max(0.0)).collect();
            box_sum(w, h, r, &ss)
        });
        for i in (0..w * h).filter(|&i| radius[i] == r) {
            out[i] = std::array::from_fn(|c| match df_sum[i] > 0.0 {
                true => (ss_sum[c][i] / df_sum[i], df_sum[i]),
                false => (0.0, 0.0),
            });
        }
    }
    out
}

/// Sum over the (2r+1)² window clipped to the image, separably and without running differences.
fn box_sum(w: usize, h: usize, r: usize, src: &[f64]) -> Vec<f64> {
    let mut rows = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            rows[y * w + x] = src[y * w + x.saturating_sub(r)..y * w + (x + r + 1).min(w)]
                .iter()
                .sum();
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            out[y * w + x] = (y.saturating_sub(r)..(y + r + 1).min(h))
                .map(|yy| rows[yy * w + x])
                .sum();
        }
    }
    out
}

/// Compares two renders pixel by pixel. At least one side must be [`Side::Sampled`] (two exact images: [`plain`]).
///
/// Blocks (two sampled sides only): a block's mean difference is tested like a pixel's, its variance the sum of its
/// pixels' (each the larger of Welch's and the pooled), its df Welch-Satterthwaite's over them, and its p never
/// below the product of its pixels' permutation floors. Against an exact reference a block's variance could only
/// be learnt from other pixels, and a block that missed its rare samples is then judged by its surroundings:
/// across regions of different variance that flagged 9 of 20 null pairs (16 spp, the tests' Mixed scene), so an
/// exact reference gets pixel and image-wide tests only.
///
/// The image-wide test, per channel: a change of a few percent over the whole image is far below any block's noise
/// but clear over thousands of them. The difference is summed over 4x4 blocks, and `T = Σ D_b / sqrt(Σ D_b²)` is
/// the self-normalised sum, whose tail is bounded by `2·exp(-T²/2)` whatever the blocks' distribution when they
/// are symmetric (Hoeffding, conditionally on |D_b|; exact for equal-count sampled sides) and close to that
/// otherwise (blocks hold hundreds of samples). Raw differences rather than per-pixel t values: their expectation
/// is exactly zero under H0, whereas a t value's is not once its variance estimate correlates with its mean, a
/// bias that millions of pixels would detect. Its power is that of an unweighted sum: the noisiest regions dominate
/// it.
pub fn statistical(
    width: u32,
    height: u32,
    candidate: &Side,
    reference: &Side,
    opts: &Options,
) -> Result<Report, String> {
    let (w, h) = (width as usize, height as usize);
    let pixels = w.checked_mul(h).filter(|&p| p > 0).ok_or("the images have no pixels")?;
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(format!("alpha must lie in (0, 1), not {}", opts.alpha));
    }
    if let (Side::Exact(_), Side::Exact(_)) = (candidate, reference) {
        return Err("neither image has statistics: compare them with the plain metrics".into());
    }
    check_side("candidate", candidate, w, pixels)?;
    check_side("reference", reference, w, pixels)?;
    let (mc, mr) = (candidate.mean(), reference.mean());
    let present = |i: usize| candidate.count(i) != Some(0) && reference.count(i) != Some(0);

    let mut magnitude = 0.0;
    let mut present_pixels = 0usize;
    let mut sums = [[0.0f64; 2]; 3];
    for i in (0..pixels).filter(|&i| present(i)) {
        present_pixels += 1;
        for c in 0..3 {
            magnitude += mc[i][c].abs().max(mr[i][c].abs());
            sums[c][0] += mc[i][c];
            sums[c][1] += mr[i][c];
        }
    }
    let scale = magnitude / (3 * present_pixels.max(1)) as f64;
    let floor = |a: f64, b: f64| SD_FLOOR_REL * a.abs().max(b.abs()) + SD_FLOOR_SCALE * scale;

    let window = match (candidate, reference) {
        (Side::Sampled(s), Side::Exact(_)) | (Side::Exact(_), Side::Sampled(s)) => Some(window_variance(w, h, s)),
        _ => None,
    };
    // The tests a pixel must fail to be rejected: the one with the largest p decides.
    let estimates = |i: usize, c: usize| -> [Option<Est>; 2] {
        match (candidate, reference) {
            (Side::Sampled(a), Side::Sampled(b)) => {
                [two_sample(a.count[i], a.var[i][c], b.count[i], b.var[i][c]), None]
            }
            (Side::Sampled(s), _) | (_, Side::Sampled(s)) => {
                one_sample(s.count[i], s.var[i][c], window.as_ref().map(|win| win[i][c]))
            }
            _ => [None, None],
        }
    };

    // stat, df, p per pixel and channel; p is NaN where the test was skipped.
    let mut results = vec![[(0.0, 0.0, f64::NAN); 3]; pixels];
    let mut skipped = 0;
    let grids = SCALES.map(|s| (s, w.div_ceil(s), h.div_ceil(s)));
    let mut accs: [Vec<[Acc; 3]>; SCALES.len()] = grids.map(|(_, bw, bh)| vec![[Acc::default(); 3]; bw * bh]);
    let mut floor_memo = (0, 0, 1.0);
    for i in 0..pixels {
        for c in 0..3 {
            let ests = if present(i) { estimates(i, c) } else { [None, None] };
            let d = mc[i][c] - mr[i][c];
            let fl = floor(mc[i][c], mr[i][c]);
            let Some(mut decided) = ests
                .iter()
                .flatten()
                .map(|est| t_test(d, est, fl))
                .max_by(|a, b| a.2.total_cmp(&b.2))
            else {
                skipped += 1;
                continue;
            };
            let mut ln_floor = f64::NEG_INFINITY;
            if let (Some(n1), Some(n2)) = (candidate.count(i), reference.count(i)) {
                // Counts rarely change from pixel to pixel: keep the last floor.
                if (n1, n2) != (floor_memo.0, floor_memo.1) {
                    floor_memo = (n1, n2, permutation_floor(n1, n2));
                }
                decided.2 = decided.2.max(floor_memo.2);
                ln_floor = floor_memo.2.ln();
            }
            results[i][c] = decided;
            let magnitude = mc[i][c].abs().max(mr[i][c].abs());
            for ((s, bw, _), acc) in grids.iter().zip(accs.iter_mut()) {
                acc[(i / w / s) * bw + (i % w) / s][c].add(d, magnitude, ln_floor, &ests);
            }
        }
    }
    let pixel_tests = 3 * pixels - skipped;
    if pixel_tests == 0 {
        return Err("no pixel could be tested: every pixel lacks samples or a variance (counts below 2)".into());
    }
    // Not against an exact reference (see above).
    let blocks_tested = window.is_none();
    let block_results: [Vec<[(f64, f64, f64); 3]>; SCALES.len()] = accs.each_ref().map(|acc| {
        let untested = (0.0, 0.0, f64::NAN);
        acc.iter()
            .map(|b| {
                b.map(|a| {
                    if blocks_tested {
                        a.test(SD_FLOOR_SCALE * scale)
                    } else {
                        untested
                    }
                })
            })
            .collect()
    });
    let block_tests: usize = block_results
        .iter()
        .flatten()
        .flatten()
        .filter(|r| !r.2.is_nan())
        .count();

    // The image-wide test sums the finest blocks' differences.
    let mut channel_stat = [0.0; 3];
    let mut channel_p = [1.0; 3];
    for c in 0..3 {
        let sum: f64 = accs[0].iter().map(|b| b[c].d).sum();
        let sq: f64 = accs[0].iter().map(|b| b[c].d * b[c].d).sum();
        // The same resolution floor as per pixel, on the whole image: identical renders up to rounding agree.
        let fl = SD_FLOOR_REL * accs[0].iter().map(|b| b[c].magnitude).sum::<f64>();
        let denom = (sq + fl * fl).sqrt();
        channel_stat[c] = if denom > 0.0 { sum / denom } else { 0.0 };
        channel_p[c] = (2.0 * (-0.5 * channel_stat[c] * channel_stat[c]).exp()).min(1.0);
    }

    let tests = pixel_tests + block_tests + 3;
    let threshold = -((-opts.alpha).ln_1p() / tests as f64).exp_m1();
    // Level 0: pixels; level k: the blocks of SCALES[k-1].
    let level = |l: usize| if l == 0 { &results } else { &block_results[l - 1] };
    let all_p = || {
        (0..=SCALES.len())
            .flat_map(move |l| level(l).iter().flatten().map(|r| r.2))
            .filter(|p| !p.is_nan())
            .chain(channel_p)
    };
    let p_min = all_p().fold(1.0f64, f64::min);
    let p_value = (-(tests as f64 * (-p_min).ln_1p()).exp_m1()).clamp(0.0, 1.0);
    let rejected = all_p().filter(|&p| p <= threshold).count();

    // Underflowed p-values tie at zero: the larger |t| is the worse. A short sorted list, not a sort of millions.
    let worse = |a: &(usize, usize, usize), b: &(usize, usize, usize)| {
        let (ra, rb) = (level(a.0)[a.1][a.2], level(b.0)[b.1][b.2]);
        ra.2.total_cmp(&rb.2)
            .then(rb.0.abs().total_cmp(&ra.0.abs()))
            .then(a.cmp(b))
    };
    let mut order: Vec<(usize, usize, usize)> = Vec::with_capacity(opts.worst.min(1 << 10) + 1);
    for l in 0..=SCALES.len() {
        for (i, r) in level(l).iter().enumerate() {
            for (c, r) in r.iter().enumerate().filter(|(_, r)| !r.2.is_nan()) {
                let key = (l, i, c);
                let beaten = match order.last() {
                    _ if order.len() < opts.worst => true,
                    Some(last) => r.2 <= level(last.0)[last.1][last.2].2 && worse(&key, last).is_lt(),
                    None => false,
                };
                if beaten {
                    let at = order.partition_point(|o| worse(o, &key).is_lt());
                    order.insert(at, key);
                    order.truncate(opts.worst);
                }
            }
        }
    }
    let worst = order
        .iter()
        .map(|&(l, i, c)| {
            let (size, across) = if l == 0 {
                (1, w)
            } else {
                (grids[l - 1].0, grids[l - 1].1)
            };
            let (x, y) = ((i % across) * size, (i / across) * size);
            let mean = |m: &[[f64; 3]]| {
                let (x1, y1) = ((x + size).min(w), (y + size).min(h));
                let inside = (y..y1)
                    .flat_map(|yy| (x..x1).map(move |xx| yy * w + xx))
                    .filter(|&j| present(j));
                let (sum, n) = inside.fold((0.0, 0usize), |(s, n), j| (s + m[j][c], n + 1));
                sum / n.max(1) as f64
            };
            let r = level(l)[i][c];
            Worst {
                x: x as u32,
                y: y as u32,
                size: size as u32,
                channel: c,
                candidate: mean(mc),
                reference: mean(mr),
                stat: r.0,
                df: r.1,
                p: r.2,
            }
        })
        .collect();

    let n = present_pixels.max(1) as f64;
    let channel_means = sums.map(|s| [s[0] / n, s[1] / n]);
    // A pixel's p in the map is the smallest of its own tests and of the blocks it lies in, so a region that only
    // its blocks reveal still shows.
    let per_pixel = (0..pixels)
        .map(|i| {
            let own = results[i].iter().map(|t| t.2);
            let blocks = grids
                .iter()
                .zip(&block_results)
                .flat_map(|((s, bw, _), br)| br[(i / w / s) * bw + (i % w) / s].iter().map(|t| t.2));
            own.chain(blocks).filter(|p| !p.is_nan()).fold(f64::NAN, f64::min)
        })
        .collect();
    Ok(Report {
        p_value,
        alpha: opts.alpha,
        threshold,
        tests,
        skipped,
        rejected,
        consistent: rejected == 0,
        worst,
        channel_means,
        mean_ratio: channel_means.map(|m| m[0] / m[1]),
        channel_stat,
        channel_p,
        per_pixel,
    })
}

/// A t test of difference d with the variance estimate est and the resolution floor fl: (t, df, p).
fn t_test(d: f64, est: &Est, fl: f64) -> (f64, f64, f64) {
    let se = (est.var + fl * fl).sqrt();
    let stat = if se > 0.0 { d / se } else { 0.0 };
    (stat, est.df, t_two_sided(stat, est.df))
}

/// One block's sums, for the test of its mean difference: the pixels' differences and, per variance model, their
/// variances and the Welch-Satterthwaite terms.
#[derive(Clone, Copy, Default)]
struct Acc {
    pixels: f64,
    d: f64,
    magnitude: f64,
    ln_floor: f64,
    var: [f64; 2],
    var2_df: [f64; 2],
    /// A model some pixel lacked: the block cannot use it.
    missing: [bool; 2],
}

impl Acc {
    fn add(&mut self, d: f64, magnitude: f64, ln_floor: f64, ests: &[Option<Est>; 2]) {
        self.pixels += 1.0;
        self.d += d;
        self.magnitude += magnitude;
        self.ln_floor += ln_floor;
        for (k, est) in ests.iter().enumerate() {
            match est {
                Some(e) => {
                    self.var[k] += e.var;
                    self.var2_df[k] += e.var * e.var / e.df;
                }
                None => self.missing[k] = true,
            }
        }
    }

    /// The block's test, as a pixel's: every model must reject, and p never drops below the product of its
    /// pixels' permutation floors (with two sampled sides). NaN p for a block with fewer than two tested pixels.
    fn test(&self, abs_floor: f64) -> (f64, f64, f64) {
        if self.pixels < 2.0 {
            return (0.0, 0.0, f64::NAN);
        }
        let n = self.pixels;
        let fl = SD_FLOOR_REL * self.magnitude / n + abs_floor;
        let tested = (0..2).filter(|&k| !self.missing[k]).map(|k| {
            let var = self.var[k] / (n * n);
            let df = if self.var2_df[k] > 0.0 {
                self.var[k] * self.var[k] / self.var2_df[k]
            } else {
                f64::INFINITY
            };
            t_test(self.d / n, &Est { var, df }, fl)
        });
        let Some(mut r) = tested.max_by(|a, b| a.2.total_cmp(&b.2)) else {
            return (0.0, 0.0, f64::NAN);
        };
        r.2 = r.2.max(self.ln_floor.exp());
        r
    }
}

impl Report {
    /// What a CI log shows: the verdict first, then what it rests on.
    pub fn summary(&self) -> String {
        let mut s = String::new();
        let verdict = match self.consistent {
            true => "CONSISTENT: the difference is within noise",
            false => "DIFFERENT: the candidate's expectation differs from the reference's",
        };
        let _ = writeln!(s, "{verdict}");
        let _ = writeln!(
            s,
            "family-wise p-value {:.3e} (alpha {}); per-test threshold {:.3e} (Šidák over {} tests, {} skipped)",
            self.p_value, self.alpha, self.threshold, self.tests, self.skipped
        );
        let _ = writeln!(s, "rejected tests: {}", self.rejected);
        let _ = writeln!(s, "channel  candidate mean  reference mean  ratio      image-wide t  p");
        for (c, name) in CHANNEL_NAMES.iter().enumerate() {
            let _ = writeln!(
                s,
                "{:<8} {:<15.6e} {:<15.6e} {:<10.6} {:<13.3} {:.3e}",
                name,
                self.channel_means[c][0],
                self.channel_means[c][1],
                self.mean_ratio[c],
                self.channel_stat[c],
                self.channel_p[c]
            );
        }
        if !self.worst.is_empty() {
            let _ = writeln!(s, "worst tests (pixels, or blocks of size x size pixels from x, y):");
            let _ = writeln!(
                s,
                "  x      y      size  ch  candidate      reference      t          df        p"
            );
            for wst in &self.worst {
                let _ = writeln!(
                    s,
                    "  {:<6} {:<6} {:<5} {:<3} {:<14.6e} {:<14.6e} {:<10.3} {:<9.1} {:.3e}{}",
                    wst.x,
                    wst.y,
                    wst.size,
                    CHANNEL_NAMES[wst.channel],
                    wst.candidate,
                    wst.reference,
                    wst.stat,
                    wst.df,
                    wst.p,
                    if wst.p <= self.threshold { "  rejected" } else { "" }
                );
            }
        }
        s
    }
}
