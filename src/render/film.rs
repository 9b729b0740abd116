//! The result of a render: the film (per-pixel sums and sums of squares) and what the render measured of itself.
use std::time::Duration;

/// The accumulated image: per-pixel sums of samples and of their squares, so tests can bound the error.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub sum: Vec<[f32; 4]>,
    pub sum_sq: Vec<[f32; 4]>,
}

impl Film {
    /// Per-pixel mean radiance (linear RGB), row 0 at the top.
    pub fn mean(&self) -> Vec<[f32; 3]> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.sum.iter().map(|s| [s[0] * inv, s[1] * inv, s[2] * inv]).collect()
    }

    /// Unbiased per-pixel variance of one sample, per channel.
    pub fn sample_variance(&self) -> Vec<[f32; 3]> {
        let n = self.spp as f64;
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, q)| {
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
}

impl RenderStats {
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
        )
    }
}
