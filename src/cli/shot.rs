//! One shot of `pathwave render`: rendered (the film, the image denoised when asked, what a film file records) before
//! anything is written, then written; the command line and the Python module both go through it.
use super::render::{RenderArgs, Shot};
use crate::{output, RenderSettings, Renderer};
use anyhow::{Context as _, Result};
use std::path::PathBuf;
use std::time::Instant;

/// One shot rendered, before anything is written: what `render` writes, and what the Python module hands over.
pub struct Rendered {
    pub film: crate::Film,
    pub stats: crate::RenderStats,
    /// The image: the film's mean, denoised with --denoise.
    pub pixels: Vec<[f32; 3]>,
    /// The film's mean before denoising.
    pub noisy: Vec<[f32; 3]>,
    /// What a film file records of the render, when the film is exact.
    pub meta: Option<output::FilmMeta>,
    pub denoise_s: Option<f64>,
    /// The device, and whether it traced with ray queries.
    pub device: String,
    /// What the renderer learned while rendering (e.g. falling back to the wavefront schedule).
    pub warnings: Vec<String>,
}

impl Rendered {
    /// The film statistics a film file carries, when the film is exact.
    pub fn film_stats(&self) -> Option<output::Stats<'_>> {
        (self.film.exact.as_ref().zip(self.meta.as_ref())).map(|(film, meta)| output::Stats { film, meta })
    }

    /// Writes the shot's outputs (and AOV files) as `render` does, all or nothing; returns every path written.
    pub fn write(&self, args: &RenderArgs, shot: &Shot) -> Result<Vec<PathBuf>> {
        super::outputs::write_outputs(args, shot, &self.film, &self.pixels, &self.noisy, self.film_stats())
    }
}

/// Renders `settings` until done or `stop` is set (between passes), reporting the samples per pixel done after
/// each pass, then denoises with `denoiser` and, for an exact film, records what a film file names it by.
pub fn render_shot(
    renderer: &mut Renderer,
    settings: &RenderSettings,
    args: &RenderArgs,
    denoiser: Option<&crate::denoise::Denoiser>,
    progress: &mut dyn FnMut(u32),
    stop: &std::sync::atomic::AtomicBool,
) -> Result<Rendered> {
    let device = match renderer.traversal() {
        crate::render::Traversal::RayQuery => format!("{} (ray queries)", renderer.context().device_name()),
        _ => renderer.context().device_name(),
    };
    let warned = renderer.warnings.len();
    let (film, stats) = renderer.render_until(settings, progress, stop)?;
    let warnings = renderer.warnings[warned..].to_vec();
    let noisy = film.mean();
    let (pixels, denoise_s) = match denoiser {
        Some(d) => {
            let t = Instant::now();
            (denoise(d, &film, &noisy)?, Some(t.elapsed().as_secs_f64()))
        }
        None => (noisy.clone(), None),
    };
    let meta = match &film.exact {
        Some(exact) => Some(super::film::film_meta(
            renderer,
            settings,
            exact,
            args.film_settings(),
            args.part_of()?,
        )?),
        None => None,
    };
    Ok(Rendered {
        film,
        stats,
        pixels,
        noisy,
        meta,
        denoise_s,
        device,
        warnings,
    })
}

/// The film's mean through the denoiser, guided by its albedo and normal AOVs.
fn denoise(d: &crate::denoise::Denoiser, film: &crate::Film, noisy: &[[f32; 3]]) -> Result<Vec<[f32; 3]>> {
    let aovs = film
        .aovs
        .as_ref()
        .context("the render has no AOVs to guide the denoiser")?;
    let (albedo, normal) = (aovs.albedo(), aovs.normal());
    let guides = crate::denoise::Guides {
        albedo: Some(&albedo),
        normal: Some(&normal),
        clean: false,
    };
    Ok(d.denoise(film.width, film.height, noisy, guides)?)
}
