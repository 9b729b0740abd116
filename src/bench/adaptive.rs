//! `pathwave bench --compare mitsuba`'s adaptive figure: relMSE at equal time with --adaptive beside uniform
//! sampling, on the Cornell box and the glass scene, against pathwave's own converged render (cached).
use crate::error::Error;
use crate::render::{Adaptive, RenderSettings, Renderer};
use crate::scene;
use crate::vk::{Context, DeviceChoice, Validation};
use std::path::Path;

/// The threshold calibration starts from: a pixel's mean to 2 % relative standard error.
pub const THRESHOLD: f32 = 0.02;

/// One scene's rounds: (uniform spp, seconds, relMSE) and (adaptive spp cap, seconds, relMSE).
#[derive(Clone, Debug, Default)]
pub struct AdaptiveComparison {
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    /// The noise threshold that made the adaptive render take about the uniform one's time.
    pub threshold: f32,
    pub rounds: Vec<[(u32, f64, f64); 2]>,
    /// Median over rounds of adaptive relMSE x time over uniform's: below 1, adaptive wins at equal time.
    pub ratio: f64,
}

/// Uniform and adaptive renders of `path` at the same time budget, interleaved, each scored by relMSE x seconds
/// (relMSE falls as 1 / time for an unbiased estimator, so the product compares at equal time).
pub fn compare_adaptive(
    device: &DeviceChoice,
    path: &Path,
    quick: bool,
    progress: &mut dyn FnMut(&str),
) -> Result<AdaptiveComparison, Error> {
    let size = if quick { (48, 48) } else { (128, 128) };
    let (reference_spp, budget_s, rounds) = if quick { (128, 0.3, 2) } else { (2048, 4.0, 3) };
    let scene = scene::load(path, None)?;
    let mut r = Renderer::with_context(&scene, Context::new(device, Validation::Off)?)?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut render = |spp: u32, seed: u32, adaptive: Option<Adaptive>| -> Result<(f64, Vec<[f32; 3]>), Error> {
        let s = RenderSettings {
            width: size.0,
            height: size.1,
            spp,
            seed,
            adaptive,
            ..Default::default()
        };
        let (film, stats) = r.render(&s, &mut |_| {})?;
        Ok((stats.wall.as_secs_f64(), film.mean()))
    };
    // The reference in two halves, so their difference estimates its own noise (subtracted from each relMSE).
    progress(&format!(
        "adaptive comparison, {name}: reference at {reference_spp} spp"
    ));
    let (_, ref_a) = render(reference_spp / 2, 1_000_001, None)?;
    let (_, ref_b) = render(reference_spp / 2, 1_000_002, None)?;
    // Calibration: the uniform spp for the budget, and an adaptive cap of four times it, whose threshold then
    // decides where the render ends.
    let probe = if quick { 4 } else { 16 };
    render(probe, 90, None)?;
    let (t, _) = render(probe, 91, None)?;
    let spp = ((budget_s / (t / probe as f64)).round() as u32).clamp(2, 4096);
    let pilot = (spp / 8).clamp(2, 16);
    // The threshold for the same time: samples (so time) go as 1 / threshold^2, so one timed adaptive render at
    // THRESHOLD (after one that compiles) sets it.
    let at = |threshold: f32| Some(Adaptive { threshold, pilot });
    render(spp * 4, 92, at(THRESHOLD))?;
    let (t_a, _) = render(spp * 4, 93, at(THRESHOLD))?;
    let t_u = render(spp, 94, None)?.0;
    let threshold = (THRESHOLD as f64 * (t_a / t_u).sqrt()).clamp(1e-4, 1.0) as f32;
    let adaptive = at(threshold);
    let mut result = AdaptiveComparison {
        scene: name.clone(),
        width: size.0,
        height: size.1,
        reference_spp,
        threshold,
        ..Default::default()
    };
    for round in 0..rounds {
        progress(&format!("adaptive comparison, {name}: round {} of {rounds}", round + 1));
        let (tu, iu) = render(spp, round, None)?;
        let (ta, ia) = render(spp * 4, round, adaptive)?;
        result.rounds.push([
            (spp, tu, rel_mse(&iu, &ref_a, &ref_b)),
            (spp * 4, ta, rel_mse(&ia, &ref_a, &ref_b)),
        ]);
    }
    let mut ratios: Vec<f64> = result.rounds.iter().map(|[u, a]| (a.1 * a.2) / (u.1 * u.2)).collect();
    ratios.sort_by(f64::total_cmp);
    result.ratio = ratios[ratios.len() / 2];
    Ok(result)
}

/// relMSE of `img` against the mean of `a` and `b`, less the reference's own noise ((a - b)^2 / 4 per pixel).
fn rel_mse(img: &[[f32; 3]], a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let mut sum = 0.0;
    for ((x, a), b) in img.iter().zip(a).zip(b) {
        for c in 0..3 {
            let (x, a, b) = (x[c] as f64, a[c] as f64, b[c] as f64);
            let r = 0.5 * (a + b);
            sum += ((x - r).powi(2) - 0.25 * (a - b).powi(2)) / (r * r + crate::diff::REL_MSE_EPSILON);
        }
    }
    sum / (3 * img.len().max(1)) as f64
}

impl AdaptiveComparison {
    pub fn summary(&self) -> String {
        let mut s = format!(
            "adaptive sampling at equal time ({} {}x{}, --noise-threshold {:.4} for uniform's time; reference: pathwave at \
             {} spp):\n",
            self.scene, self.width, self.height, self.threshold, self.reference_spp
        );
        for (i, [u, a]) in self.rounds.iter().enumerate() {
            s += &format!(
                "  round {}: uniform {} spp {:.2} s relMSE {:.5} (x time {:.5}); adaptive (cap {} spp) {:.2} s relMSE \
                 {:.5} (x time {:.5})\n",
                i + 1,
                u.0,
                u.1,
                u.2,
                u.1 * u.2,
                a.0,
                a.1,
                a.2,
                a.1 * a.2
            );
        }
        s + &format!(
            "  median ratio of relMSE x time, adaptive over uniform: {:.3} (below 1: adaptive wins)\n",
            self.ratio
        )
    }

    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "width": self.width,
            "height": self.height,
            "threshold": self.threshold,
            "reference_spp": self.reference_spp,
            "rounds": self.rounds.iter().map(|[u, a]| serde_json::json!({
                "uniform": {"spp": u.0, "seconds": u.1, "rel_mse": u.2},
                "adaptive": {"spp_cap": a.0, "seconds": a.1, "rel_mse": a.2},
            })).collect::<Vec<_>>(),
            "ratio": self.ratio,
        })
    }
}
