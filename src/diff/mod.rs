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
//! alone is exact for Gaussian samples; the window test vetoes the low-side explosion of rare events.
//!
//! What a window cannot see. Real renders (tests/diff.rs: the Cornell box, the glass scene, the lamp grid at 16, 64 and
//! 256 spp against a 16384-spp reference without statistics) broke the window test in three ways, each now a floor
//! under its per-sample variance, all computed under H0, where the exact reference's mean r is the pixel's expectation.
//! Before them, 691 of 1800 seeds were flagged; after, 3.
//!
//! 1. Edges (straddle). A pixel on a light's edge has binary samples: the light with probability q, the wall beside
//!    it otherwise. When all n fell on the light (probability (1-q)^n: 2 % for q = 6 % at 64 spp) its own variance
//!    is zero and so is a window inside the light (the Cornell box at 16 spp: 174 of 200 seeds flagged). Its
//!    footprint mixes what lies around it, whose expectations are the reference's means over its 3x3 neighbourhood,
//!    from lo to hi, and a distribution on [lo, hi] with mean r has variance at most (r-lo)(hi-r) (Bhatia and
//!    Davis), reached by samples at the two ends only, which is what an edge pixel's are. Zero inside a region (lo =
//!    hi, or r at an end), so flat and smoothly shaded regions keep their power; from the reference alone, so the
//!    same for every candidate. With q = 6 %, 64 samples all on the light make t = 2, not 8; at 4096 spp, t = 16, a
//!    change. The normal is conservative on that side: the exact chance of no miss, e^-nq, is below its e^-nq/2.
//!
//! 2. Caustics (the window at the pixel's level). The window pools variances of pixels of every brightness, and a
//!    caustic's few bright pixels drown in the dull ones around them. Path-traced noise grows with radiance (a pixel
//!    made of spikes of size V with mean r has variance about rV), so the window's variance is also taken per unit
//!    of its mean, df-weighted, and scaled to r.
//!
//! 3. Unseen spikes, below the reference only. A pixel darker than its reference may have missed spikes that neither
//!    it nor its window saw (a caustic focus whose spikes have probability 1/60 and size 60; a firefly the reference
//!    caught and the candidate did not, 4 % of a pixel at 256 spp, in 100 of 200 seeds of the glass scene). Nothing
//!    about a pixel bounds the size of what it did not see, so the largest the sampled side shows anywhere stands
//!    in: the image's largest dispersion s²/m, which estimates a spike's size V whatever its probability (a light's
//!    edge shows the light's radiance). The floor is rV, the variance of spikes of that size with mean r. Above the
//!    reference it is not applied: spikes seen raise the pixel's own variance. Its price: a pixel darker than an
//!    exact reference is only rejected when spikes as large as the image's largest could not explain it, so in
//!    scenes with caustics or lights in view the pixel tests see a region going dark only if it goes very dark, and
//!    the image-wide test (which no floor touches) carries the power; a reference with statistics keeps all of it.
//!
//! The window's limits: events rarer than about one in WINDOW_SAMPLES samples may be missed by a whole window, which
//! then looks exactly like a region that went dark and is flagged (render the candidate with more samples); conversely
//! a region that did go dark among rare events is only seen where its pixels each expect several hits; small n costs
//! power, as the own test needs t_{n-1} (8.0 at 16 spp against 4.9 for a normal at the 64x64 level).
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

mod blocks;
mod plain;
mod report;
#[cfg(test)]
mod simulation;
pub mod special;
#[cfg(test)]
mod tests;
mod window;

use blocks::{block_tests, image_wide_tests, Acc, Grid, SCALES};
pub use plain::*;
use report::{describe, per_pixel_map, verdict, worst_tests, Levels};
use special::*;
use window::{neighbourhood_range, spike_scale, straddle_variance, window_variance, Window};

/// The finest relative difference a test resolves: f32 means carry ~6e-8, different float orders a few times more.
const SD_FLOOR_REL: f64 = 1e-5;
/// The same for values near zero, relative to the image's mean magnitude.
const SD_FLOOR_SCALE: f64 = 1e-9;
/// relMSE's epsilon: keeps near-black reference pixels from dominating the mean (on linear radiance).
pub const REL_MSE_EPSILON: f64 = crate::constants::ADAPTIVE_EPSILON as f64;
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
/// reject (see the module's documentation for why not the larger variance, as with two sampled sides). The
/// neighbourhood's per-sample variance is at least `floor`: what H0 says the pixel's samples may vary by that
/// neither they nor the window show (an edge's straddle, a caustic's level, spikes unseen).
fn one_sample(n: u32, v: f64, window: Option<Window>, floor: f64) -> [Option<Est>; 2] {
    let f = n as f64;
    let own = (n >= 2).then(|| Est {
        var: v.max(0.0) / f,
        df: f - 1.0,
    });
    let borrowed = match window.filter(|w| w.df > 0.0) {
        Some(win) => Some(Est {
            var: win.var.max(floor) / f,
            df: win.df,
        }),
        // No neighbour has two samples: the floor alone is the other test, a bound rather than an estimate.
        None => (floor > 0.0).then(|| Est {
            var: floor / f,
            df: f64::INFINITY,
        }),
    };
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
    let pixels = validate(w, h, candidate, reference, opts)?;
    let pair = Pair {
        w,
        h,
        pixels,
        candidate,
        reference,
    };
    let totals = totals(&pair);
    let grids = Grid::all(w, h);
    let PixelTests { results, skipped, accs } = pixel_tests(&pair, &grids, totals.scale);
    let tested = 3 * pixels - skipped;
    if tested == 0 {
        return Err("no pixel could be tested: every pixel lacks samples or a variance (counts below 2)".into());
    }
    // Not against an exact reference (see above).
    let blocks_tested = matches!((candidate, reference), (Side::Sampled(_), Side::Sampled(_)));
    let levels = Levels {
        pixels: results,
        blocks: block_tests(&accs, blocks_tested, totals.scale),
    };
    let (channel_stat, channel_p) = image_wide_tests(&accs[0]);
    let verdict = verdict(&levels, tested, channel_p, opts.alpha);
    let worst = worst_tests(&levels, opts.worst)
        .into_iter()
        .map(|key| describe(&pair, &grids, &levels, key))
        .collect();
    let n = totals.present_pixels.max(1) as f64;
    let channel_means = totals.sums.map(|s| [s[0] / n, s[1] / n]);
    Ok(Report {
        p_value: verdict.p_value,
        alpha: opts.alpha,
        threshold: verdict.threshold,
        tests: verdict.tests,
        skipped,
        rejected: verdict.rejected,
        consistent: verdict.rejected == 0,
        worst,
        channel_means,
        mean_ratio: channel_means.map(|m| m[0] / m[1]),
        channel_stat,
        channel_p,
        per_pixel: per_pixel_map(&pair, &grids, &levels),
    })
}

/// Refuses what cannot be compared, naming the first bad pixel; else the pixel count.
fn validate(w: usize, h: usize, candidate: &Side, reference: &Side, opts: &Options) -> Result<usize, String> {
    let pixels = w.checked_mul(h).filter(|&p| p > 0).ok_or("the images have no pixels")?;
    if !(opts.alpha > 0.0 && opts.alpha < 1.0) {
        return Err(format!("alpha must lie in (0, 1), not {}", opts.alpha));
    }
    if let (Side::Exact(_), Side::Exact(_)) = (candidate, reference) {
        return Err("neither image has statistics: compare them with the plain metrics".into());
    }
    check_side("candidate", candidate, w, pixels)?;
    check_side("reference", reference, w, pixels)?;
    Ok(pixels)
}

/// The images under comparison, built only once validated: sizes agree and every compared mean is finite.
struct Pair<'a> {
    w: usize,
    h: usize,
    pixels: usize,
    candidate: &'a Side,
    reference: &'a Side,
}

impl Pair<'_> {
    /// Only pixels with samples on both sides are compared (an exact side has them everywhere).
    fn present(&self, i: usize) -> bool {
        self.candidate.count(i) != Some(0) && self.reference.count(i) != Some(0)
    }
}

/// Sums over the compared pixels: the channels' for the report, and the mean magnitude, which sets the resolution
/// floor of values near zero.
struct Totals {
    present_pixels: usize,
    sums: [[f64; 2]; 3],
    scale: f64,
}

fn totals(pair: &Pair) -> Totals {
    let (mc, mr) = (pair.candidate.mean(), pair.reference.mean());
    let mut magnitude = 0.0;
    let mut present_pixels = 0usize;
    let mut sums = [[0.0f64; 2]; 3];
    for i in (0..pair.pixels).filter(|&i| pair.present(i)) {
        present_pixels += 1;
        for c in 0..3 {
            magnitude += mc[i][c].abs().max(mr[i][c].abs());
            sums[c][0] += mc[i][c];
            sums[c][1] += mr[i][c];
        }
    }
    Totals {
        present_pixels,
        sums,
        scale: magnitude / (3 * present_pixels.max(1)) as f64,
    }
}

/// (t, df, p) of one test; p is NaN where the test was not performed.
type Test = (f64, f64, f64);
const UNTESTED: Test = (0.0, 0.0, f64::NAN);

/// The pixel tests, and what the block and image-wide tests need of them.
struct PixelTests {
    /// Per pixel and channel.
    results: Vec<[Test; 3]>,
    skipped: usize,
    /// Per scale of SCALES, per block and channel.
    accs: [Vec<[Acc; 3]>; SCALES.len()],
}

fn pixel_tests(pair: &Pair, grids: &[Grid; SCALES.len()], scale: f64) -> PixelTests {
    let (mc, mr) = (pair.candidate.mean(), pair.reference.mean());
    let window = match (pair.candidate, pair.reference) {
        (Side::Sampled(s), Side::Exact(e)) | (Side::Exact(e), Side::Sampled(s)) => Some(Borrowed {
            window: window_variance(pair.w, pair.h, s),
            range: neighbourhood_range(pair.w, pair.h, e),
            spike: spike_scale(s),
        }),
        _ => None,
    };
    let mut results = vec![[UNTESTED; 3]; pair.pixels];
    let mut skipped = 0;
    let mut accs = grids.map(|g| vec![[Acc::default(); 3]; g.blocks()]);
    let mut floor_memo = (0, 0, 1.0);
    for i in 0..pair.pixels {
        for c in 0..3 {
            let ests = match pair.present(i) {
                true => estimates(pair, window.as_ref(), i, c),
                false => [None, None],
            };
            let d = mc[i][c] - mr[i][c];
            let magnitude = mc[i][c].abs().max(mr[i][c].abs());
            let fl = SD_FLOOR_REL * magnitude + SD_FLOOR_SCALE * scale;
            // The tests a pixel must fail to be rejected: the one with the largest p decides.
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
            if let (Some(n1), Some(n2)) = (pair.candidate.count(i), pair.reference.count(i)) {
                // Counts rarely change from pixel to pixel: keep the last floor.
                if (n1, n2) != (floor_memo.0, floor_memo.1) {
                    floor_memo = (n1, n2, permutation_floor(n1, n2));
                }
                decided.2 = decided.2.max(floor_memo.2);
                ln_floor = floor_memo.2.ln();
            }
            results[i][c] = decided;
            for (grid, acc) in grids.iter().zip(accs.iter_mut()) {
                acc[grid.block_of(pair.w, i)][c].add(d, magnitude, ln_floor, &ests);
            }
        }
    }
    PixelTests { results, skipped, accs }
}

/// What a sampled side's pixel borrows from its neighbourhood against an exact reference: the window's pooled
/// per-sample variance and df, and the range of the means around it.
struct Borrowed {
    window: Vec<[Window; 3]>,
    range: Vec<[(f64, f64); 3]>,
    spike: [f64; 3],
}

/// The variance estimates of pixel i's difference in channel c, per the sides' kinds (see the module's
/// documentation); `borrowed` is what an exact reference's pixel tests take from the neighbourhood.
fn estimates(pair: &Pair, borrowed: Option<&Borrowed>, i: usize, c: usize) -> [Option<Est>; 2] {
    match (pair.candidate, pair.reference) {
        (Side::Sampled(a), Side::Sampled(b)) => [two_sample(a.count[i], a.var[i][c], b.count[i], b.var[i][c]), None],
        (Side::Sampled(s), Side::Exact(e)) | (Side::Exact(e), Side::Sampled(s)) => {
            let floor = borrowed.map_or(0.0, |b| {
                let (r, win) = (e[i][c].max(0.0), b.window[i][c]);
                let scaled = if win.mean > 0.0 { win.var / win.mean * r } else { 0.0 };
                // Below the reference, unseen spikes can explain the deficit; above it, seen ones show in s².
                let unseen = if s.mean[i][c] < e[i][c] { r * b.spike[c] } else { 0.0 };
                straddle_variance(e[i][c], b.range[i][c]).max(scaled).max(unseen)
            });
            one_sample(s.count[i], s.var[i][c], borrowed.map(|b| b.window[i][c]), floor)
        }
        _ => [None, None],
    }
}

/// A t test of difference d with the variance estimate est and the resolution floor fl: (t, df, p).
fn t_test(d: f64, est: &Est, fl: f64) -> Test {
    let se = (est.var + fl * fl).sqrt();
    let stat = if se > 0.0 { d / se } else { 0.0 };
    (stat, est.df, t_two_sided(stat, est.df))
}
