//! The film commands: `merge` (parts of one render into one film file) and `diff` (a render against a reference),
//! and the metadata `render` writes into a film file.
use anyhow::{bail, Context as _, Result};
use pathwave::output::{self, FilmMeta};
use pathwave::render::film::ExactFilm;
use pathwave::{RenderSettings, Renderer};
use std::path::PathBuf;

/// What a film file records of the render that made `film`.
pub fn film_meta(
    renderer: &Renderer,
    settings: &RenderSettings,
    film: &ExactFilm,
    given: Vec<(String, String)>,
) -> Result<FilmMeta> {
    let [scene, frame, shaders] = renderer.fingerprints(settings)?;
    Ok(FilmMeta {
        scene,
        frame,
        shaders,
        settings: given,
        seed: settings.seed,
        samples: film.samples.clone(),
        device: renderer.context().device_name(),
        version: env!("CARGO_PKG_VERSION").to_string(),
    })
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// Film files (from `render --samples` or `--part`) of one scene and one set of options, in any order.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// The merged film file (.exr); repeat to also write a .png of the mean.
    #[arg(short, long, required = true)]
    output: Vec<PathBuf>,
    /// Exposure in stops applied to PNG output, -64 to 64.
    #[arg(long, default_value = "0", value_parser = crate::cli_values::parse_exposure, allow_hyphen_values = true)]
    exposure: f32,
}

/// Reads every part, refuses any that does not belong (naming it and what differs), adds their exact sums and
/// writes the result: integer sums make it the bits one render of the union writes, in whatever order the parts
/// come. Nothing is written when any part is refused.
pub fn merge(args: MergeArgs) -> Result<()> {
    for out in &args.output {
        output::check_writable(out)?;
    }
    let mut merged: Option<(u32, u32, ExactFilm, FilmMeta, PathBuf)> = None;
    let mut devices: Vec<String> = Vec::new();
    for path in &args.parts {
        let file = output::read_film(path)?;
        let Some((film, meta)) = file.stats else {
            bail!(
                "{}: carries no film statistics; render parts with --samples A..B or --part I/N (or --film-stats)",
                path.display()
            );
        };
        if !devices.contains(&meta.device) {
            devices.push(meta.device.clone());
        }
        match &mut merged {
            None => merged = Some((file.width, file.height, film, meta, path.clone())),
            Some((w, h, sum, first, first_path)) => {
                let whose = || format!("{} against {}", path.display(), first_path.display());
                if let Some(why) = first.incompatibility(&meta) {
                    bail!("{}: not a part of the same render: {why} ({})", path.display(), whose());
                }
                if (file.width, file.height) != (*w, *h) {
                    bail!(
                        "{}: {}x{} pixels against {w}x{h} ({})",
                        path.display(),
                        file.width,
                        file.height,
                        whose()
                    );
                }
                sum.add(&film)
                    .map_err(|why| anyhow::anyhow!("{}: {why}", path.display()))?;
            }
        }
    }
    let (width, height, film, mut meta, _) = merged.context("no parts")?;
    meta.samples = film.samples.clone();
    if devices.len() > 1 {
        // Each device rounds differently: the merge is a valid film, but no single render gives these bits.
        eprintln!(
            "warning: the parts come from {} devices: {}",
            devices.len(),
            devices.join(", ")
        );
        meta.device = devices.join("; ");
    }
    let mean = film.mean();
    let stats = output::Stats {
        film: &film,
        meta: &meta,
    };
    output::write_images_with(&args.output, width, height, &mean, args.exposure, Some(stats))?;
    let ranges: Vec<String> = film.samples.iter().map(|r| format!("{}..{}", r.start, r.end)).collect();
    eprintln!(
        "{}: {} parts merged, {width}x{height}, {} samples per pixel (samples {})",
        args.output
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        args.parts.len(),
        film.spp(),
        ranges.join(", ")
    );
    Ok(())
}
