//! The neighbourhood variance an exact reference's pixel tests borrow (see the module documentation).
use super::*;

/// Samples a neighbourhood must hold before its variance may stand in for a pixel's: enough to see events of
/// probability 0.001 per sample 16 times (4096 flagged 20 % of null pairs of p = 0.002 events at 64 spp).
const WINDOW_SAMPLES: u64 = 16384;
const WINDOW_MAX_RADIUS: usize = 16;

/// Per pixel and channel, the sampled side's per-sample variance pooled over a window that holds WINDOW_SAMPLES
/// samples, and its df. Windows are summed directly (no summed-area table): variances span many orders of
/// magnitude across an image, and differences of running sums would lose the dark regions to cancellation.
pub(super) fn window_variance(w: usize, h: usize, s: &Sampled) -> Vec<[(f64, f64); 3]> {
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
