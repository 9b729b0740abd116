//! The result of a render: the film (per-pixel sums and sums of squares, as floats or exact) and what the render
//! measured of itself.
use crate::constants::{EXACT_FILM_TEXELS, EXACT_OVERFLOW, EXACT_SQUARE_BITS, EXACT_SUM_BITS};
use crate::error::Error;
use std::ops::Range;
use std::time::Duration;

/// The accumulated image: per-pixel sums of samples and of their squares, so tests can bound the error.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Float sums (rgb, and the sample count in w); for an exact film, its sums rounded to f32.
    pub sum: Vec<[f32; 4]>,
    pub sum_sq: Vec<[f32; 4]>,
    /// The exact film's sums, when the render kept them (`RenderSettings::exact_film`).
    pub exact: Option<ExactFilm>,
    /// The AOVs, when the render surveyed them (`RenderSettings::aovs`).
    pub aovs: Option<super::Aovs>,
}

/// A sum of squares of the exact film: 160 bits, as the device keeps them (film.glsl).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Wide {
    pub lo: u128,
    pub hi: u32,
}

impl Wide {
    fn checked_add(self, other: Wide) -> Option<Wide> {
        let (lo, carry) = self.lo.overflowing_add(other.lo);
        let hi = self.hi.checked_add(other.hi)?.checked_add(carry as u32)?;
        Some(Wide { lo, hi })
    }

    pub fn to_f64(self) -> f64 {
        self.hi as f64 * 2f64.powi(128) + self.lo as f64
    }
}

/// The exact film (FEATURE_EXACT_FILM): per pixel the sample count and fixed-point integer sums of the samples
/// (units of 2^-EXACT_SUM_BITS) and of their squares (units of 2^-EXACT_SQUARE_BITS). Integer sums do not depend on
/// the order they are taken in, so films of disjoint sample ranges add up to the bits of one render of their union.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExactFilm {
    /// The sample indices it holds: sorted, disjoint and not adjacent (adjacent ranges are joined).
    pub samples: Vec<Range<u32>>,
    pub count: Vec<u32>,
    pub sum: Vec<[i128; 3]>,
    pub sum_sq: Vec<[Wide; 3]>,
}

impl ExactFilm {
    /// From the device's words (EXACT_FILM_TEXELS uvec4 a pixel, film.glsl); a pixel whose sums overflowed is an
    /// error.
    pub fn from_words(words: &[u32], samples: Range<u32>) -> Result<ExactFilm, Error> {
        let per = EXACT_FILM_TEXELS as usize * 4;
        let pixels = words.len() / per;
        let mut film = ExactFilm {
            samples: vec![samples],
            count: Vec::with_capacity(pixels),
            sum: Vec::with_capacity(pixels),
            sum_sq: Vec::with_capacity(pixels),
        };
        for (p, w) in words.chunks_exact(per).enumerate() {
            let word128 = |k: usize| (0..4).fold(0u128, |v, j| v | (w[k + j] as u128) << (32 * j));
            let count = w[27];
            if count & EXACT_OVERFLOW != 0 {
                return Err(Error::Settings(format!(
                    "pixel {p}: its exact sums overflowed (more than 9.2e18 in a pixel's sum, or 5.2e33 in its sum \
                     of squares)"
                )));
            }
            film.count.push(count);
            film.sum.push(std::array::from_fn(|c| word128(4 * c) as i128));
            film.sum_sq.push(std::array::from_fn(|c| Wide {
                lo: word128(12 + 4 * c),
                hi: w[24 + c],
            }));
        }
        Ok(film)
    }

    pub fn pixels(&self) -> usize {
        self.count.len()
    }

    /// Samples per pixel it holds (every pixel holds the same).
    pub fn spp(&self) -> u64 {
        self.samples.iter().map(|r| (r.end - r.start) as u64).sum()
    }

    /// Per-pixel mean (linear RGB), the same bits whichever parts the sums came from.
    pub fn mean(&self) -> Vec<[f32; 3]> {
        let unit = 2f64.powi(-(EXACT_SUM_BITS as i32));
        (self.sum.iter().zip(&self.count))
            .map(|(s, &n)| {
                s.map(|v| {
                    if n == 0 {
                        0.0
                    } else {
                        (v as f64 * unit / n as f64) as f32
                    }
                })
            })
            .collect()
    }

    /// Per-pixel, per-channel sum and sum of squares as f64.
    pub fn sums_f64(&self, pixel: usize) -> ([f64; 3], [f64; 3]) {
        let unit = 2f64.powi(-(EXACT_SUM_BITS as i32));
        let square_unit = 2f64.powi(-(EXACT_SQUARE_BITS as i32));
        (
            self.sum[pixel].map(|v| v as f64 * unit),
            self.sum_sq[pixel].map(|v| v.to_f64() * square_unit),
        )
    }

    /// Unbiased per-sample variance per pixel and channel (0 below two samples).
    pub fn sample_variance(&self) -> Vec<[f64; 3]> {
        (0..self.pixels())
            .map(|p| {
                let n = self.count[p] as f64;
                let (s, q) = self.sums_f64(p);
                std::array::from_fn(|c| match n < 2.0 {
                    true => 0.0,
                    false => ((q[c] - s[c] * s[c] / n) / (n - 1.0)).max(0.0),
                })
            })
            .collect()
    }

    /// Adds `other`'s samples: the ranges must not overlap. Integer sums make the result independent of order.
    pub fn add(&mut self, other: &ExactFilm) -> Result<(), String> {
        if other.pixels() != self.pixels() {
            return Err(format!("{} pixels against {}", other.pixels(), self.pixels()));
        }
        let mut ranges: Vec<Range<u32>> = self.samples.iter().chain(&other.samples).cloned().collect();
        ranges.sort_by_key(|r| (r.start, r.end));
        let mut joined: Vec<Range<u32>> = Vec::with_capacity(ranges.len());
        for r in ranges {
            match joined.last_mut() {
                Some(last) if r.start < last.end => {
                    return Err(format!(
                        "samples {}..{} overlap samples {}..{}",
                        r.start, r.end, last.start, last.end
                    ))
                }
                Some(last) if r.start == last.end => last.end = r.end,
                _ => joined.push(r),
            }
        }
        let overflow = || "the sums overflow".to_string();
        for p in 0..self.pixels() {
            self.count[p] = (self.count[p].checked_add(other.count[p]))
                .filter(|&n| n & EXACT_OVERFLOW == 0)
                .ok_or_else(overflow)?;
            for c in 0..3 {
                self.sum[p][c] = self.sum[p][c].checked_add(other.sum[p][c]).ok_or_else(overflow)?;
                self.sum_sq[p][c] = self.sum_sq[p][c].checked_add(other.sum_sq[p][c]).ok_or_else(overflow)?;
            }
        }
        self.samples = joined;
        Ok(())
    }
}

impl Film {
    /// A film of exact sums, with the float sums derived from them.
    pub fn from_exact(width: u32, height: u32, exact: ExactFilm) -> Film {
        let (sum, sum_sq) = (0..exact.pixels())
            .map(|p| {
                let (s, q) = exact.sums_f64(p);
                let n = exact.count[p] as f32;
                (
                    [s[0] as f32, s[1] as f32, s[2] as f32, n],
                    [q[0] as f32, q[1] as f32, q[2] as f32, 0.0],
                )
            })
            .unzip();
        Film {
            width,
            height,
            spp: exact.spp().min(u32::MAX as u64) as u32,
            sum,
            sum_sq,
            exact: Some(exact),
            aovs: None,
        }
    }

    /// Per-pixel mean radiance (linear RGB), row 0 at the top.
    pub fn mean(&self) -> Vec<[f32; 3]> {
        if let Some(exact) = &self.exact {
            return exact.mean();
        }
        // Each pixel by its own count (w), which adaptive sampling makes differ; f32 counts are exact to 2^24.
        (self.sum.iter())
            .map(|s| {
                let inv = 1.0 / s[3].max(1.0);
                [s[0] * inv, s[1] * inv, s[2] * inv]
            })
            .collect()
    }

    /// Samples each pixel holds.
    pub fn sample_count(&self) -> Vec<u32> {
        match &self.exact {
            Some(exact) => exact.count.clone(),
            None => self.sum.iter().map(|s| s[3] as u32).collect(),
        }
    }

    /// The variance of each pixel's mean (the sample variance over the pixel's sample count), per channel: the
    /// variance AOV, and what adaptive sampling and `diff` weigh a pixel's error by.
    pub fn mean_variance(&self) -> Vec<[f32; 3]> {
        let counts = self.sample_count();
        (self.sample_variance().iter().zip(counts))
            .map(|(v, n)| v.map(|c| if n > 0 { c / n as f32 } else { 0.0 }))
            .collect()
    }

    /// Unbiased per-pixel variance of one sample, per channel.
    pub fn sample_variance(&self) -> Vec<[f32; 3]> {
        if let Some(exact) = &self.exact {
            return exact.sample_variance().iter().map(|v| v.map(|c| c as f32)).collect();
        }
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, q)| {
                let n = s[3] as f64;
                std::array::from_fn(|c| {
                    if n < 2.0 {
                        return 0.0;
                    }
                    let m = s[c] as f64 / n;
                    ((q[c] as f64 / n - m * m) * n / (n - 1.0)).max(0.0) as f32
                })
            })
            .collect()
    }
}

#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    pub wall: Duration,
    /// The first pass, which also pays for pipeline compilation on lavapipe.
    pub first_pass: Duration,
    pub passes: u32,
    pub samples: u64,
    pub extension_rays: u64,
    pub shadow_rays: u64,
    /// Samples the film took as zero because their radiance was not finite (or beyond SAMPLE_RADIANCE_MAX).
    pub nonfinite: u64,
    /// GPU time per stage in milliseconds, over all passes but the first (or the first, when it is the only one).
    pub stage_ms: Vec<(&'static str, f64)>,
    pub(super) first_pass_stage_ms: Vec<(&'static str, f64)>,
    /// The render stopped (`render_until`'s flag) before the samples it meant to take.
    pub interrupted: bool,
    /// Which light selection ran (bvh, power, uniform); None without lights.
    pub light_sampler: Option<&'static str>,
}

impl RenderStats {
    /// Adds a pass of `paths` paths: its ray tallies and (after the first pass, which also compiles) its GPU stage
    /// times.
    pub(super) fn add_pass(&mut self, done: &super::integrator::PassDone, paths: u32) {
        let tally = &done.tally;
        self.extension_rays += tally.extension_rays as u64;
        self.shadow_rays += tally.shadow_rays as u64;
        self.nonfinite += tally.nonfinite as u64;
        self.samples += paths as u64;
        if self.passes == 0 {
            self.first_pass = done.wall;
            // Kept apart (it includes compilation) and reported only if no other pass follows.
            self.first_pass_stage_ms = done.times.iter().map(|(l, ns)| (*l, ns * 1e-6)).collect();
        } else {
            for &(label, ns) in &done.times {
                crate::vk::add_labelled(&mut self.stage_ms, label, ns * 1e-6);
            }
        }
        self.passes += 1;
    }

    /// Time over the passes after the first, so compile time does not count against throughput.
    pub(super) fn steady(&self) -> Duration {
        self.wall.saturating_sub(self.first_pass)
    }
    pub fn samples_per_sec(&self) -> f64 {
        let (n, t) = self.steady_counts(self.samples);
        n / t
    }
    pub fn rays_per_sec(&self) -> f64 {
        let (n, t) = self.steady_counts(self.extension_rays + self.shadow_rays);
        n / t
    }
    /// Extension and shadow rays per second, apart.
    pub fn rays_per_sec_split(&self) -> (f64, f64) {
        let (e, t) = self.steady_counts(self.extension_rays);
        let (s, _) = self.steady_counts(self.shadow_rays);
        (e / t, s / t)
    }
    fn steady_counts(&self, total: u64) -> (f64, f64) {
        if self.passes > 1 && !self.steady().is_zero() {
            let per_pass = total as f64 / self.passes as f64;
            (per_pass * (self.passes - 1) as f64, self.steady().as_secs_f64())
        } else {
            (total as f64, self.wall.as_secs_f64().max(1e-9))
        }
    }
    /// The one-line summary every render ends with.
    pub fn summary(&self) -> String {
        let stages: Vec<String> = self.stage_ms.iter().map(|(n, ms)| format!("{n} {ms:.1}")).collect();
        let dropped = match self.nonfinite {
            0 => String::new(),
            n => format!(", {n} non-finite samples dropped (counted as zero)"),
        };
        format!(
            "{:.2} s (first pass {:.2} s), {:.0} samples/s, {:.2} Mrays/s ({} extension + {} shadow rays), GPU ms: {}{}",
            self.wall.as_secs_f64(),
            self.first_pass.as_secs_f64(),
            self.samples_per_sec(),
            self.rays_per_sec() / 1e6,
            self.extension_rays,
            self.shadow_rays,
            if stages.is_empty() {
                "n/a".to_string()
            } else {
                stages.join(", ")
            },
            dropped
        ) + &self.light_sampler.map(|l| format!(", lights by {l}")).unwrap_or_default()
    }
}
