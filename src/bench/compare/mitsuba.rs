//! Mitsuba 3 against pathwave at equal time: the comparison's calibration and rounds, its figures, text and JSON.
use super::helper::Helper;
use super::mitsuba_scene::write_mitsuba_scene;
use super::reference::{mitsuba_reference, mitsuba_render};
use super::{err, median};
use crate::error::Error;
use crate::render::{LightSampler, RenderSettings, Renderer};
use crate::scene::{self, Scene};
use crate::vk::{Context, DeviceChoice, Validation};
use serde_json::json;
use std::path::Path;

/// relMSE x time against Mitsuba 3 on the same scene and image, both unbiased and measured against Mitsuba's own
/// converged render (so any bias of ours counts against us).
#[derive(Clone, Debug, Default)]
pub struct MitsubaComparison {
    pub device: String,
    /// The scene's file stem (cornell-box, lamp-grid).
    pub scene: String,
    /// pathwave's light selection (--light-sampler).
    pub light_sampler: String,
    pub version: String,
    /// Mitsuba's variant, llvm_ad_rgb or (with pathwave spectral) llvm_ad_spectral.
    pub variant: String,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub reference_cached: bool,
    /// Per round, (spp, seconds, relMSE) of: pathwave, Mitsuba with its default `independent` sampler, and Mitsuba
    /// with `ldsampler` ((0,2)-sequences, like pathwave's sampler; its spp a power of four).
    pub rounds: Vec<[(u32, f64, f64); 3]>,
    /// Median over rounds of (relMSE x time of pathwave) / (relMSE x time of Mitsuba): below 1, pathwave wins.
    pub ratio: f64,
    /// The same against Mitsuba with `ldsampler`.
    pub ratio_ld: f64,
    /// Per channel: pathwave's image mean over all rounds relative to the reference's, minus one.
    pub mean_deviation: [f64; 3],
    /// One standard error of that deviation, from pathwave's per-pixel sample variance.
    pub mean_sigma: [f64; 3],
    /// The same deviation for Mitsuba's rounds: checks the reference and the scene translation.
    pub mitsuba_mean_deviation: [f64; 3],
}

impl MitsubaComparison {
    /// Median over rounds of pathwave's relMSE x time.
    pub fn pathwave_score(&self) -> f64 {
        median(self.rounds.iter().map(|r| r[0].1 * r[0].2).collect())
    }

    pub fn summary(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "equal time vs Mitsuba {} {} ({} {}x{}; pathwave {}, lights by {}; reference: Mitsuba at {} spp{}):\n",
            self.version,
            self.variant,
            self.scene,
            self.width,
            self.height,
            if self.variant.ends_with("spectral") {
                "--spectral"
            } else {
                "RGB"
            },
            self.light_sampler,
            self.reference_spp,
            if self.reference_cached { ", cached" } else { "" }
        );
        for (k, [(sp, tp, ep), (sm, tm, em), (sl, tl, el)]) in self.rounds.iter().enumerate() {
            s += &format!(
                "  round {}: pathwave {sp} spp {tp:.2} s relMSE {ep:.5} (x time {:.5}); Mitsuba {sm} spp {tm:.2} s \
                 relMSE {em:.5} (x time {:.5}), ratio {:.3}; Mitsuba ldsampler {sl} spp {tl:.2} s relMSE {el:.5} \
                 (x time {:.5}), ratio {:.3}\n",
                k + 1,
                ep * tp,
                em * tm,
                (ep * tp) / (em * tm),
                el * tl,
                (ep * tp) / (el * tl)
            );
        }
        let pct = |v: [f64; 3]| v.map(|x| format!("{:+.3}", 100.0 * x)).join(" ");
        s += &format!(
            "  median ratio of relMSE x time {:.3} (target <= 1.0); against Mitsuba with ldsampler {:.3}\n  channel \
             means vs reference, %: pathwave {} (one sigma {}, as if samples were independent); \
             Mitsuba {}\n",
            self.ratio,
            self.ratio_ld,
            pct(self.mean_deviation),
            self.mean_sigma.map(|x| format!("{:.3}", 100.0 * x)).join(" "),
            pct(self.mitsuba_mean_deviation)
        );
        s
    }

    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "light_sampler": self.light_sampler,
            "variant": self.variant,
            "version": self.version,
            "width": self.width,
            "height": self.height,
            "reference_spp": self.reference_spp,
            "reference_cached": self.reference_cached,
            "rounds": self.rounds.iter().map(|[(sp, tp, ep), (sm, tm, em), (sl, tl, el)]| serde_json::json!({
                "pathwave": {"spp": sp, "seconds": tp, "rel_mse": ep},
                "mitsuba": {"spp": sm, "seconds": tm, "rel_mse": em},
                "mitsuba_ldsampler": {"spp": sl, "seconds": tl, "rel_mse": el},
            })).collect::<Vec<_>>(),
            "ratio": self.ratio,
            "ratio_ldsampler": self.ratio_ld,
            "mean_deviation": self.mean_deviation,
            "mean_sigma": self.mean_sigma,
            "mitsuba_mean_deviation": self.mitsuba_mean_deviation,
        })
    }
}

/// What a Mitsuba comparison renders: a scene file (lit by emissive Lambertian triangles only), spectral or RGB,
/// and pathwave's light selection.
pub struct MitsubaCase<'a> {
    pub scene: &'a Path,
    pub spectral: bool,
    pub light_sampler: LightSampler,
    /// Image size and the reference's samples per pixel (both smaller with --quick).
    pub size: (u32, u32),
    pub reference_spp: u32,
}

/// Mitsuba 3 against pathwave at equal time on `case`'s scene: both calibrated to one time budget, then rounds of
/// each, interleaved, scored against Mitsuba's converged reference.
pub fn compare_mitsuba(
    python: &Path,
    device: &DeviceChoice,
    case: MitsubaCase,
    quick: bool,
    progress: &mut dyn FnMut(&str),
) -> Result<MitsubaComparison, Error> {
    let MitsubaCase {
        scene: path,
        spectral,
        light_sampler,
        size,
        reference_spp,
    } = case;
    let variant = if spectral { "llvm_ad_spectral" } else { "llvm_ad_rgb" };
    let size = if quick { (64, 64) } else { size };
    let (reference_spp, budget_s, rounds) = if quick { (256, 0.5, 2) } else { (reference_spp, 8.0, 3) };
    let mut h = Helper::start(python)?;
    let scene = scene::load(path, None)?;
    let (desc, version) = load_in_mitsuba(&mut h, &scene, size, variant)?;
    let pixels = (size.0 * size.1) as usize;
    // The RGB reference keeps its old name; the spectral one is another image.
    let key_text = format!("{desc}{version}{reference_spp}{}", if spectral { variant } else { "" });
    let (ref_a, ref_b, reference_cached) = mitsuba_reference(&mut h, pixels, &key_text, reference_spp, progress)?;
    let mut mitsuba = MitsubaSide { h, pixels };

    let ctx = Context::new(device, Validation::Off)?;
    let device = ctx.device_name();
    let r = Renderer::with_context(&scene, ctx)?;
    let sampler_name = (r.light_sampler_run(&RenderSettings {
        light_sampler,
        ..Default::default()
    }))
    .unwrap_or("none");
    let mut pathwave = PathwaveSide {
        r,
        size,
        spectral,
        light_sampler,
    };
    let spp = calibrate(&mut pathwave, &mut mitsuba, quick, budget_s, progress)?;

    let mut result = MitsubaComparison {
        device,
        scene: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        light_sampler: sampler_name.into(),
        version,
        variant: variant.into(),
        width: size.0,
        height: size.1,
        reference_spp,
        reference_cached,
        ..Default::default()
    };
    let reference = (ref_a.as_slice(), ref_b.as_slice());
    score_rounds(
        &mut result,
        &mut pathwave,
        &mut mitsuba,
        spp,
        rounds,
        reference,
        progress,
    )?;
    Ok(result)
}

/// Writes `scene` into the helper's folder and has Mitsuba load it with `variant`: the text that names the scene's
/// content, and Mitsuba's version.
fn load_in_mitsuba(h: &mut Helper, scene: &Scene, size: (u32, u32), variant: &str) -> Result<(String, String), Error> {
    let dir = h.dir.path().to_path_buf();
    let (desc_path, desc) = write_mitsuba_scene(scene, size, &dir)?;
    let loaded = h
        .call(json!({"cmd": "mitsuba_load", "scene": desc_path, "variant": variant}))
        .map_err(|e| {
            err(format!(
                "{e}; Mitsuba 3 needs `pip install mitsuba` and, for {variant}, `apt-get install libllvm19`"
            ))
        })?;
    let version = loaded["version"].as_str().unwrap_or("?").to_string();
    Ok((desc, version))
}

/// pathwave's side of a comparison: its renderer and what every one of its renders shares.
struct PathwaveSide {
    r: Renderer,
    size: (u32, u32),
    spectral: bool,
    light_sampler: LightSampler,
}

impl PathwaveSide {
    /// One render: its seconds, its pixels' means and their sample variances (RGB floats).
    fn render(&mut self, spp: u32, seed: u32) -> Result<(f64, Vec<f32>, Vec<f32>), Error> {
        let settings = RenderSettings {
            width: self.size.0,
            height: self.size.1,
            spp,
            seed,
            spectral: self.spectral,
            light_sampler: self.light_sampler,
            ..Default::default()
        };
        let (film, stats) = self.r.render(&settings, &mut |_| {})?;
        let img: Vec<f32> = film.mean().into_iter().flatten().collect();
        let var: Vec<f32> = film.sample_variance().into_iter().flatten().collect();
        Ok((stats.wall.as_secs_f64(), img, var))
    }
}

/// Mitsuba's side: the helper with the scene loaded, and the image's pixel count.
struct MitsubaSide {
    h: Helper,
    pixels: usize,
}

impl MitsubaSide {
    fn render_with(&mut self, sampler: &str, spp: u32, seed: u32) -> Result<(f64, Vec<f32>), Error> {
        mitsuba_render(&mut self.h, self.pixels, sampler, spp, seed)
    }

    /// A render with Mitsuba's default sampler, `independent`.
    fn render(&mut self, spp: u32, seed: u32) -> Result<(f64, Vec<f32>), Error> {
        self.render_with("independent", spp, seed)
    }
}

/// Warm-up, which also calibrates: both renderers compile on their first render, so the second one's time per
/// sample sets each one's spp for the budget. pathwave's first four passes also choose its schedule on a CPU
/// device (render::Schedule), so it warms up for four renders of one pass each. Returns the spp of pathwave, of
/// Mitsuba and of Mitsuba with ldsampler.
fn calibrate(
    pathwave: &mut PathwaveSide,
    mitsuba: &mut MitsubaSide,
    quick: bool,
    budget_s: f64,
    progress: &mut dyn FnMut(&str),
) -> Result<(u32, u32, u32), Error> {
    progress("Mitsuba comparison: warming up");
    let probe_spp = if quick { 4 } else { 16 };
    for seed in 0..4 {
        pathwave.render(probe_spp, 99 - seed)?;
    }
    let (t_ours, _, _) = pathwave.render(probe_spp, 95)?;
    mitsuba.render(probe_spp, 99)?;
    let (t_theirs, _) = mitsuba.render(probe_spp, 98)?;
    mitsuba.render_with("ldsampler", probe_spp, 99)?;
    let spp_for = |t: f64| ((budget_s / (t / probe_spp as f64)).round() as u32).clamp(1, 4096);
    let (spp_ours, spp_theirs) = (spp_for(t_ours), spp_for(t_theirs));
    // ldsampler takes a power of four; the nearest one to the budget (time is part of the figure either way).
    let spp_ld = 1u32 << (2 * (spp_theirs as f64).log(4.0).round() as u32);
    Ok((spp_ours, spp_theirs, spp_ld))
}

/// The rounds, each pathwave, Mitsuba, then Mitsuba with ldsampler at their calibrated spp, scored against the
/// reference's halves; then over the rounds, the median ratios and the channel means' deviations, all into `result`.
fn score_rounds(
    result: &mut MitsubaComparison,
    pathwave: &mut PathwaveSide,
    mitsuba: &mut MitsubaSide,
    (spp_ours, spp_theirs, spp_ld): (u32, u32, u32),
    rounds: u32,
    (ref_a, ref_b): (&[f32], &[f32]),
    progress: &mut dyn FnMut(&str),
) -> Result<(), Error> {
    let pixels = mitsuba.pixels;
    let reference_means = channel_means(&ref_a.iter().zip(ref_b).map(|(a, b)| 0.5 * (a + b)).collect::<Vec<_>>());
    let (mut ours_means, mut ours_var, mut theirs_means) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    for round in 0..rounds {
        progress(&format!("Mitsuba comparison: round {} of {rounds}", round + 1));
        let (t_p, img_p, var_p) = pathwave.render(spp_ours, round)?;
        let (t_m, img_m) = mitsuba.render(spp_theirs, round)?;
        let (t_l, img_l) = mitsuba.render_with("ldsampler", spp_ld, round)?;
        let e_p = rel_mse(&img_p, ref_a, ref_b);
        let e_m = rel_mse(&img_m, ref_a, ref_b);
        let e_l = rel_mse(&img_l, ref_a, ref_b);
        result
            .rounds
            .push([(spp_ours, t_p, e_p), (spp_theirs, t_m, e_m), (spp_ld, t_l, e_l)]);
        let (mp, mm) = (channel_means(&img_p), channel_means(&img_m));
        // Variance of the image mean: per-pixel sample variance / spp, summed, over pixels squared.
        let vp = channel_means(&var_p).map(|v| v / spp_ours as f64 / pixels as f64);
        for c in 0..3 {
            ours_means[c] += mp[c] / rounds as f64;
            theirs_means[c] += mm[c] / rounds as f64;
            ours_var[c] += vp[c] / (rounds * rounds) as f64;
        }
    }
    let ratio_to = |k: usize| {
        median(
            result
                .rounds
                .iter()
                .map(|r| (r[0].1 * r[0].2) / (r[k].1 * r[k].2))
                .collect(),
        )
    };
    (result.ratio, result.ratio_ld) = (ratio_to(1), ratio_to(2));
    for c in 0..3 {
        result.mean_deviation[c] = ours_means[c] / reference_means[c] - 1.0;
        result.mean_sigma[c] = ours_var[c].sqrt() / reference_means[c];
        result.mitsuba_mean_deviation[c] = theirs_means[c] / reference_means[c] - 1.0;
    }
    Ok(())
}

/// relMSE of `img` against the reference mean `r`, less what the reference's own noise adds: `a` and `b` are the
/// reference's two halves, so (a - b)^2 / 4 estimates the variance of their mean per pixel.
fn rel_mse(img: &[f32], a: &[f32], b: &[f32]) -> f64 {
    let mut sum = 0.0;
    for ((x, a), b) in img.iter().zip(a).zip(b) {
        let r = 0.5 * (*a as f64 + *b as f64);
        let d = *x as f64 - r;
        let ref_var = 0.25 * (*a as f64 - *b as f64).powi(2);
        sum += (d * d - ref_var) / (r * r + 1e-2);
    }
    sum / img.len().max(1) as f64
}

fn channel_means(img: &[f32]) -> [f64; 3] {
    let mut m = [0.0; 3];
    for px in img.chunks_exact(3) {
        for c in 0..3 {
            m[c] += px[c] as f64;
        }
    }
    m.map(|s| s / (img.len() / 3).max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rel_mse_subtracts_the_reference_noise() {
        // Halves 1 and 3 average to 2 and say the reference's own variance is (3 - 1)^2 / 4 = 1.
        let (a, b) = (vec![1.0f32; 4], vec![3.0f32; 4]);
        let exact = rel_mse(&[2.0; 4], &a, &b);
        assert!((exact + 1.0 / 4.01).abs() < 1e-9, "{exact}");
        let off = rel_mse(&[4.0; 4], &a, &b);
        assert!((off - 3.0 / 4.01).abs() < 1e-9, "{off}");
        assert_eq!(rel_mse(&[2.0; 4], &[2.0; 4], &[2.0; 4]), 0.0);
    }
}
