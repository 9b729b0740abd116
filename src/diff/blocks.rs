//! The block and image-wide tests (see [`super::statistical`]): sums of the pixel tests over square blocks.
use super::*;

/// Edges of the square blocks whose mean differences are tested besides pixels: a bias over a region is far below
/// one pixel's noise but not below its block's. The first also makes the image-wide test's blocks: pathwave's pixels
/// are independent (box filter, per-pixel sample keys), and 4x4 blocks keep their sums nearly independent should a
/// reconstruction filter spread samples over a pixel or two; small, because the self-normalised sum is bounded by
/// sqrt(blocks) and its bound must pass the Šidák level (2·exp(-T²/2) < threshold needs about 30 blocks).
pub(super) const SCALES: [usize; 2] = [4, 16];

/// One scale's blocks: their edge, and how many fit across and down (those at the right and bottom are clipped).
#[derive(Clone, Copy)]
pub(super) struct Grid {
    pub(super) size: usize,
    pub(super) across: usize,
    down: usize,
}

impl Grid {
    /// The grids of all SCALES over a w x h image.
    pub(super) fn all(w: usize, h: usize) -> [Grid; SCALES.len()] {
        SCALES.map(|size| Grid {
            size,
            across: w.div_ceil(size),
            down: h.div_ceil(size),
        })
    }

    pub(super) fn blocks(&self) -> usize {
        self.across * self.down
    }

    /// The block that holds pixel i of an image w pixels wide.
    pub(super) fn block_of(&self, w: usize, i: usize) -> usize {
        (i / w / self.size) * self.across + (i % w) / self.size
    }
}

/// One block's sums, for the test of its mean difference: the pixels' differences and, per variance model, their
/// variances and the Welch-Satterthwaite terms.
#[derive(Clone, Copy, Default)]
pub(super) struct Acc {
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
    pub(super) fn add(&mut self, d: f64, magnitude: f64, ln_floor: f64, ests: &[Option<Est>; 2]) {
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
    fn test(&self, abs_floor: f64) -> Test {
        if self.pixels < 2.0 {
            return UNTESTED;
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
            return UNTESTED;
        };
        r.2 = r.2.max(self.ln_floor.exp());
        r
    }
}

/// Per scale, block and channel, the block's test; none against an exact reference (`tested` false), whose blocks
/// could only be judged by their surroundings.
pub(super) fn block_tests(
    accs: &[Vec<[Acc; 3]>; SCALES.len()],
    tested: bool,
    scale: f64,
) -> [Vec<[Test; 3]>; SCALES.len()] {
    accs.each_ref().map(|acc| {
        acc.iter()
            .map(|b| {
                b.map(|a| {
                    if tested {
                        a.test(SD_FLOOR_SCALE * scale)
                    } else {
                        UNTESTED
                    }
                })
            })
            .collect()
    })
}

/// Per channel, the image-wide test's statistic and p-value: the self-normalised sum of the finest blocks'
/// differences.
pub(super) fn image_wide_tests(finest: &[[Acc; 3]]) -> ([f64; 3], [f64; 3]) {
    let mut channel_stat = [0.0; 3];
    let mut channel_p = [1.0; 3];
    for c in 0..3 {
        let sum: f64 = finest.iter().map(|b| b[c].d).sum();
        let sq: f64 = finest.iter().map(|b| b[c].d * b[c].d).sum();
        // The same resolution floor as per pixel, on the whole image: identical renders up to rounding agree.
        let fl = SD_FLOOR_REL * finest.iter().map(|b| b[c].magnitude).sum::<f64>();
        let denom = (sq + fl * fl).sqrt();
        channel_stat[c] = if denom > 0.0 { sum / denom } else { 0.0 };
        channel_p[c] = (2.0 * (-0.5 * channel_stat[c] * channel_stat[c]).exp()).min(1.0);
    }
    (channel_stat, channel_p)
}
