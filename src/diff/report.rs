//! From the tests to the report: Šidák's verdict, the worst tests, the per-pixel map and the CI summary.
use super::*;
use std::fmt::Write as _;

/// A test's place: (level, index, channel), level 0 the pixels and level k the blocks of SCALES[k-1].
type Key = (usize, usize, usize);

/// Every pixel and block test's result, whether performed or not (NaN p).
pub(super) struct Levels {
    pub(super) pixels: Vec<[Test; 3]>,
    pub(super) blocks: [Vec<[Test; 3]>; SCALES.len()],
}

impl Levels {
    fn level(&self, l: usize) -> &[[Test; 3]] {
        if l == 0 {
            &self.pixels
        } else {
            &self.blocks[l - 1]
        }
    }

    fn get(&self, (l, i, c): Key) -> Test {
        self.level(l)[i][c]
    }

    /// The tests performed, pixels first and then the blocks scale by scale.
    fn performed(&self) -> impl Iterator<Item = (Key, Test)> + '_ {
        (0..=SCALES.len())
            .flat_map(move |l| {
                self.level(l)
                    .iter()
                    .enumerate()
                    .flat_map(move |(i, r)| r.iter().enumerate().map(move |(c, &t)| ((l, i, c), t)))
            })
            .filter(|(_, t)| !t.2.is_nan())
    }
}

pub(super) struct Verdict {
    pub(super) tests: usize,
    pub(super) threshold: f64,
    pub(super) p_value: f64,
    pub(super) rejected: usize,
}

/// Šidák's correction over the pixel tests, the block tests performed and the three image-wide tests.
pub(super) fn verdict(levels: &Levels, pixel_tests: usize, channel_p: [f64; 3], alpha: f64) -> Verdict {
    let block_tests: usize = levels
        .blocks
        .iter()
        .flatten()
        .flatten()
        .filter(|r| !r.2.is_nan())
        .count();
    let tests = pixel_tests + block_tests + 3;
    let threshold = -((-alpha).ln_1p() / tests as f64).exp_m1();
    let all_p = || levels.performed().map(|(_, t)| t.2).chain(channel_p);
    let p_min = all_p().fold(1.0f64, f64::min);
    Verdict {
        tests,
        threshold,
        p_value: (-(tests as f64 * (-p_min).ln_1p()).exp_m1()).clamp(0.0, 1.0),
        rejected: all_p().filter(|&p| p <= threshold).count(),
    }
}

/// The `count` tests of lowest p, pixels and blocks alike, worst first.
pub(super) fn worst_tests(levels: &Levels, count: usize) -> Vec<Key> {
    // Underflowed p-values tie at zero: the larger |t| is the worse. A short sorted list, not a sort of millions.
    let worse = |a: &Key, b: &Key| {
        let (ra, rb) = (levels.get(*a), levels.get(*b));
        ra.2.total_cmp(&rb.2)
            .then(rb.0.abs().total_cmp(&ra.0.abs()))
            .then(a.cmp(b))
    };
    let mut order: Vec<Key> = Vec::with_capacity(count.min(1 << 10) + 1);
    for (key, r) in levels.performed() {
        let beaten = match order.last() {
            _ if order.len() < count => true,
            Some(last) => r.2 <= levels.get(*last).2 && worse(&key, last).is_lt(),
            None => false,
        };
        if beaten {
            let at = order.partition_point(|o| worse(o, &key).is_lt());
            order.insert(at, key);
            order.truncate(count);
        }
    }
    order
}

/// A listed test, with the means of the pixels it covers.
pub(super) fn describe(pair: &Pair, grids: &[Grid; SCALES.len()], levels: &Levels, (l, i, c): Key) -> Worst {
    let (w, h) = (pair.w, pair.h);
    let (size, across) = if l == 0 {
        (1, w)
    } else {
        (grids[l - 1].size, grids[l - 1].across)
    };
    let (x, y) = ((i % across) * size, (i / across) * size);
    let mean = |m: &[[f64; 3]]| {
        let (x1, y1) = ((x + size).min(w), (y + size).min(h));
        let inside = (y..y1)
            .flat_map(|yy| (x..x1).map(move |xx| yy * w + xx))
            .filter(|&j| pair.present(j));
        let (sum, n) = inside.fold((0.0, 0usize), |(s, n), j| (s + m[j][c], n + 1));
        sum / n.max(1) as f64
    };
    let r = levels.get((l, i, c));
    Worst {
        x: x as u32,
        y: y as u32,
        size: size as u32,
        channel: c,
        candidate: mean(pair.candidate.mean()),
        reference: mean(pair.reference.mean()),
        stat: r.0,
        df: r.1,
        p: r.2,
    }
}

/// Per pixel, the smallest p of its own tests and of the blocks it lies in, so a region that only its blocks
/// reveal still shows; NaN where nothing was tested.
pub(super) fn per_pixel_map(pair: &Pair, grids: &[Grid; SCALES.len()], levels: &Levels) -> Vec<f64> {
    (0..pair.pixels)
        .map(|i| {
            let own = levels.pixels[i].iter().map(|t| t.2);
            let blocks = grids
                .iter()
                .zip(&levels.blocks)
                .flat_map(|(g, br)| br[g.block_of(pair.w, i)].iter().map(|t| t.2));
            own.chain(blocks).filter(|p| !p.is_nan()).fold(f64::NAN, f64::min)
        })
        .collect()
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
