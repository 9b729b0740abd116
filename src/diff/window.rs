//! The neighbourhood variance an exact reference's pixel tests borrow (see the module documentation).
use super::*;

/// Samples a neighbourhood must hold before its variance may stand in for a pixel's: enough to see events of
/// probability 0.001 per sample 16 times (4096 flagged 20 % of null pairs of p = 0.002 events at 64 spp).
const WINDOW_SAMPLES: u64 = 16384;
const WINDOW_MAX_RADIUS: usize = 16;

/// One pixel's window: the pooled per-sample variance, its df, and the window's mean (of its pixels' means,
/// weighted as their variances are).
#[derive(Clone, Copy, Default)]
pub(super) struct Window {
    pub(super) var: f64,
    pub(super) df: f64,
    pub(super) mean: f64,
}

/// Per pixel and channel, the sampled side's per-sample variance pooled over a window that holds WINDOW_SAMPLES
/// samples, its df and mean. Windows are summed directly (no summed-area table): variances span many orders of
/// magnitude across an image, and differences of running sums would lose the dark regions to cancellation.
pub(super) fn window_variance(w: usize, h: usize, s: &Sampled) -> Vec<[Window; 3]> {
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
    let mut out = vec![[Window::default(); 3]; w * h];
    let mut radii: Vec<usize> = radius.clone();
    radii.sort_unstable();
    radii.dedup();
    for &r in &radii {
        let df_sum = box_sum(w, h, r, &dof);
        let ss_sum: [Vec<f64>; 3] = std::array::from_fn(|c| {
            let ss: Vec<f64> = (0..w * h).map(|i| dof[i] * s.var[i][c].max(0.0)).collect();
            box_sum(w, h, r, &ss)
        });
        let mean_sum: [Vec<f64>; 3] = std::array::from_fn(|c| {
            let m: Vec<f64> = (0..w * h).map(|i| dof[i] * s.mean[i][c]).collect();
            box_sum(w, h, r, &m)
        });
        for i in (0..w * h).filter(|&i| radius[i] == r) {
            out[i] = std::array::from_fn(|c| match df_sum[i] > 0.0 {
                true => Window {
                    var: ss_sum[c][i] / df_sum[i],
                    df: df_sum[i],
                    mean: mean_sum[c][i] / df_sum[i],
                },
                false => Window::default(),
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

/// Per pixel and channel, the least and greatest of the exact reference's means over the pixel's 3x3 neighbourhood
/// (itself included, clipped at the borders): under H0 the expectations around it, which its footprint can mix.
/// The reference's alone: the sampled side's means would add their noise to the range.
pub(super) fn neighbourhood_range(w: usize, h: usize, exact: &[[f64; 3]]) -> Vec<[(f64, f64); 3]> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            std::array::from_fn(|c| {
                let mut range = (f64::INFINITY, f64::NEG_INFINITY);
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for v in &exact[yy * w + x.saturating_sub(1)..yy * w + (x + 2).min(w)] {
                        range = (range.0.min(v[c]), range.1.max(v[c]));
                    }
                }
                range
            })
        })
        .collect()
}
/// The largest per-sample variance a pixel whose samples lie in `range` can have with expectation `mean` (Bhatia and
/// Davis 2000: (mean - lo)(hi - mean), reached by samples only at the two ends): a pixel straddling an edge between
/// neighbours of those values. Under H0 the exact reference's mean is the pixel's expectation, so this is the
/// variance a pixel on a light's edge really has, which neither its own samples (all on the light: zero) nor a window
/// inside the light (zero too) show.
pub(super) fn straddle_variance(mean: f64, range: (f64, f64)) -> f64 {
    ((mean - range.0) * (range.1 - mean)).max(0.0)
}

/// Per channel, the largest dispersion s²/m (per-sample variance over mean) of the sampled side's pixels with two
/// samples or more and a positive mean: the size of the brightest rare samples (spikes) it shows anywhere. Samples
/// that are a spike V with probability q and 0 otherwise have mean qV and variance qV² - (qV)², so s²/m estimates V
/// whatever q (a pixel on a light's edge shows about the light's radiance; smooth noise, about m·CV²).
pub(super) fn spike_scale(s: &Sampled) -> [f64; 3] {
    let mut v = [0.0f64; 3];
    for i in (0..s.count.len()).filter(|&i| s.count[i] >= 2) {
        for (c, v) in v.iter_mut().enumerate().filter(|(c, _)| s.mean[i][*c] > 0.0) {
            *v = v.max(s.var[i][c].max(0.0) / s.mean[i][c]);
        }
    }
    v
}
