//! The film commands: `merge` (parts of one render into one film file) and `diff` (a render against a reference),
//! and the metadata `render` writes into a film file.
use crate::output::{self, FilmMeta};
use crate::render::film::ExactFilm;
use crate::{RenderSettings, Renderer};
use anyhow::{bail, Context as _, Result};
use std::path::PathBuf;

/// What a film file records of the render that made `film`.
pub fn film_meta(
    renderer: &Renderer,
    settings: &RenderSettings,
    film: &ExactFilm,
    given: Vec<(String, String)>,
    part: Option<output::PartOf>,
) -> Result<FilmMeta> {
    let [scene, frame, shaders] = renderer.fingerprints(settings)?;
    Ok(FilmMeta {
        scene,
        frame,
        shaders,
        settings: given,
        seed: settings.seed,
        samples: film.samples.clone(),
        part,
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
    #[arg(long, default_value = "0", value_parser = crate::cli::values::parse_exposure, allow_hyphen_values = true)]
    exposure: f32,
    /// Tone curve of PNG output after --exposure, as for `render`.
    #[arg(long, value_enum, default_value = "none")]
    tonemap: output::ToneCurve,
}

/// Reads every part, refuses any that does not belong (naming it and what differs), adds their exact sums and
/// writes the result: integer sums make it the bits one render of the union writes, in whatever order the parts
/// come. Nothing is written when any part is refused.
pub fn merge(args: MergeArgs) -> Result<()> {
    let inputs: Vec<(&str, &std::path::Path)> = args.parts.iter().map(|p| ("film file", p.as_path())).collect();
    for out in &args.output {
        output::check_writable(out)?;
        output::check_not_input(out, &inputs)?;
    }
    let (width, height, film, meta) = sum_parts(&args.parts)?;
    let mean = film.mean();
    let stats = output::Stats {
        film: &film,
        meta: &meta,
    };
    let display = output::Display {
        exposure: args.exposure,
        curve: args.tonemap,
    };
    output::write_images_with(&args.output, width, height, &mean, display, Some(stats))?;
    eprintln!(
        "{}: {} parts merged, {width}x{height}, {} samples per pixel (samples {})",
        args.output
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        args.parts.len(),
        film.spp(),
        ranges_text(&film.samples)
    );
    Ok(())
}

/// The parts' films summed, with the sum's metadata, before anything is written: refuses a part that does not belong
/// or an incomplete set of `--part I/N`, and warns where the sum is valid but not what one render from sample 0 on
/// one device gives.
fn sum_parts(paths: &[PathBuf]) -> Result<(u32, u32, ExactFilm, FilmMeta)> {
    let mut merged: Option<(u32, u32, ExactFilm, FilmMeta, PathBuf)> = None;
    let mut devices: Vec<String> = Vec::new();
    let mut parts: Vec<(output::PartOf, &PathBuf)> = Vec::new();
    for path in paths {
        let file = output::read_film(path)?;
        let Some((film, meta)) = file.stats else {
            bail!(
                "{}: carries no film statistics; render parts with --samples A..B or --part I/N (or --film-stats)",
                path.display()
            );
        };
        if let Some(part) = meta.part {
            parts.push((part, path));
        }
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
    check_parts_complete(&parts, paths.len())?;
    meta.samples = film.samples.clone();
    meta.part = None;
    if film.samples.len() > 1 || film.samples[0].start != 0 {
        eprintln!(
            "warning: the parts hold samples {}, not one range from 0: the merge is a valid film of those samples",
            ranges_text(&film.samples)
        );
    }
    if devices.len() > 1 {
        // Each device rounds differently: the merge is a valid film, but no single render gives these bits.
        eprintln!(
            "warning: the parts come from {} devices: {}",
            devices.len(),
            devices.join(", ")
        );
        meta.device = devices.join("; ");
    }
    Ok((width, height, film, meta))
}

fn ranges_text(ranges: &[std::ops::Range<u32>]) -> String {
    let text: Vec<String> = ranges.iter().map(|r| format!("{}..{}", r.start, r.end)).collect();
    text.join(", ")
}

/// Parts of `--part I/N` must all be there, once each, of one N and one --spp: a farm task that never ran, or one
/// given another --spp, would otherwise leave a merge of other samples than asked for, which nothing downstream
/// could tell.
fn check_parts_complete(parts: &[(output::PartOf, &PathBuf)], files: usize) -> Result<()> {
    let Some(&(first, first_path)) = parts.first() else {
        return Ok(());
    };
    let (n, spp) = (first.count, first.spp);
    if let Some((other, path)) = parts.iter().find(|(p, _)| (p.count, p.spp) != (n, spp)) {
        bail!(
            "{}: part of {} of --spp {} against {}'s part of {n} of --spp {spp}",
            path.display(),
            other.count,
            other.spp,
            first_path.display()
        );
    }
    if parts.len() != files {
        bail!("some parts come from --part I/{n} and some from --samples; merge parts of one kind");
    }
    let missing: Vec<String> = (0..n)
        .filter(|i| !parts.iter().any(|(p, _)| p.index == *i))
        .map(|i| format!("{i}/{n}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "missing part {} of {n}: every part of --part I/{n} must be merged",
            missing.join(", ")
        );
    }
    Ok(())
}

#[derive(clap::Args)]
pub struct DiffArgs {
    /// The render under test (EXR; a film file for the statistical test).
    pub candidate: PathBuf,
    /// The reference (EXR); one without film statistics counts as exact (converged).
    pub reference: PathBuf,
    /// Write a PNG of where they differ: the tests' p-values (green where rejected), or FLIP's error map in plain mode.
    #[arg(long)]
    pub heatmap: Option<PathBuf>,
    #[command(flatten)]
    pub options: CompareOptions,
}

/// How `diff` compares, apart from the files.
#[derive(clap::Args, Clone, Debug)]
pub struct CompareOptions {
    /// The statistical test's family-wise false-positive rate: the chance that two renders of one expectation are
    /// called different.
    #[arg(long, default_value = "0.01", value_parser = crate::cli::values::parse_alpha)]
    pub alpha: f64,
    /// Compare without statistics even when the files carry them: relMSE and FLIP against the thresholds below.
    #[arg(long)]
    pub plain: bool,
    /// Plain mode: the largest relMSE, mean of (c - r)^2 / (r^2 + 0.01), that passes.
    #[arg(long, default_value = "0.001", value_parser = crate::cli::values::parse_threshold)]
    pub max_rel_mse: f64,
    /// Plain mode: the largest mean FLIP error (0 to 1, of the images' sRGB at exposure 0) that passes.
    #[arg(long, default_value = "0.05", value_parser = crate::cli::values::parse_threshold)]
    pub max_flip: f64,
    /// How many of the worst tests to list.
    #[arg(long, default_value = "10")]
    pub worst: usize,
}

impl CompareOptions {
    /// Parses `diff`'s comparison options (without the files) as the command line does, with its checks and messages.
    pub fn parse_from<I, T>(args: I) -> Result<CompareOptions, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        use clap::{Args as _, FromArgMatches as _};
        let command = CompareOptions::augment_args(clap::Command::new("diff"));
        let matches =
            command.try_get_matches_from(std::iter::once("diff".into()).chain(args.into_iter().map(Into::into)))?;
        CompareOptions::from_arg_matches(&matches)
    }
}

/// A film file as the statistical test takes it: sampled (mean, per-sample variance, count from the exact sums, in
/// f64) when it carries statistics, exact otherwise.
fn side(file: &output::FilmFile) -> crate::diff::Side {
    use crate::diff::{Sampled, Side};
    match &file.stats {
        Some((film, _)) => Side::Sampled(Sampled::from_exact(film)),
        None => Side::Exact(file.mean.iter().map(|p| p.map(f64::from)).collect()),
    }
}

/// What a comparison found, before anything is printed or written.
pub struct Verdict {
    pub consistent: bool,
    /// What `diff` prints on standard output: the verdict and what it rests on.
    pub summary: String,
    /// Notes and warnings on how the files compare (`diff` prints them on standard error).
    pub notes: Vec<String>,
    /// The statistical test's report; None for a plain comparison.
    pub report: Option<crate::diff::Report>,
    /// The plain comparison; None for a statistical one.
    pub plain: Option<crate::diff::Plain>,
    /// Where they differ, as sRGB pixels of the images' size: the tests' p-values, or FLIP's error map.
    pub heat: Vec<[u8; 3]>,
}

/// Compares a candidate with a reference as `diff` does: the per-pixel statistical test when either carries film
/// statistics (and `plain` is not asked), else relMSE and FLIP against the thresholds. The names are what messages
/// call the two sides.
pub fn compare(
    (candidate_name, candidate): (&str, &output::FilmFile),
    (reference_name, reference): (&str, &output::FilmFile),
    options: &CompareOptions,
) -> Result<Verdict> {
    let (w, h) = (candidate.width, candidate.height);
    if (reference.width, reference.height) != (w, h) {
        bail!(
            "{candidate_name} is {w}x{h} and {reference_name} is {}x{}: only images of one size compare",
            reference.width,
            reference.height
        );
    }
    let mut notes = Vec::new();
    let statistics = candidate.stats.is_some() || reference.stats.is_some();
    if options.plain || !statistics {
        if !options.plain {
            notes.push(
                "note: neither file carries film statistics (render with --film-stats): comparing plainly".into(),
            );
        }
        let p = crate::diff::plain(w, h, &candidate.mean, &reference.mean).map_err(|e| anyhow::anyhow!(e))?;
        let ok = p.rel_mse <= options.max_rel_mse && p.flip_mean <= options.max_flip;
        let summary = format!(
            "{}\nrelMSE {:.4e} (at most {:e} passes), mean FLIP {:.4} (at most {} passes)\n",
            if ok {
                "CONSISTENT: within the thresholds"
            } else {
                "DIFFERENT: past a threshold"
            },
            p.rel_mse,
            options.max_rel_mse,
            p.flip_mean,
            options.max_flip
        );
        let heat = crate::diff::flip_heatmap(w, h, &p.per_pixel);
        return Ok(Verdict {
            consistent: ok,
            summary,
            notes,
            report: None,
            plain: Some(p),
            heat,
        });
    }
    if let (Some((_, a)), Some((_, b))) = (&candidate.stats, &reference.stats) {
        if a.seed == b.seed {
            notes.push(format!(
                "warning: both renders use seed {}: their noise is shared, so the test is lenient; render one with \
                 another --seed",
                a.seed
            ));
        }
        if a.scene != b.scene {
            notes.push("note: the files come from different scenes (fingerprints differ)".into());
        }
    }
    let test = crate::diff::Options {
        alpha: options.alpha,
        worst: options.worst,
    };
    let report = crate::diff::statistical(w, h, &side(candidate), &side(reference), &test)
        .map_err(|e| anyhow::anyhow!("{candidate_name} against {reference_name}: {e}"))?;
    let heat = crate::diff::heatmap(w, h, &report.per_pixel, report.threshold);
    Ok(Verdict {
        consistent: report.consistent,
        summary: report.summary(),
        notes,
        report: Some(report),
        plain: None,
        heat,
    })
}

/// Compares, prints the verdict and what it rests on, writes the heat map, and exits 1 when they differ (errors
/// return, and main exits 2 for them).
pub fn diff(args: DiffArgs) -> Result<()> {
    if let Some(h) = &args.heatmap {
        if output::format_of(h)? != output::Format::Png {
            bail!("--heatmap {}: the heat map is a PNG", h.display());
        }
        output::check_writable(h)?;
    }
    let candidate = output::read_film(&args.candidate)?;
    let reference = output::read_film(&args.reference)?;
    let verdict = compare(
        (&args.candidate.display().to_string(), &candidate),
        (&args.reference.display().to_string(), &reference),
        &args.options,
    )?;
    for note in &verdict.notes {
        eprintln!("{note}");
    }
    print!("{}", verdict.summary);
    if let Some(path) = &args.heatmap {
        output::write_srgb8(path, candidate.width, candidate.height, &verdict.heat)?;
    }
    if !verdict.consistent {
        std::process::exit(1);
    }
    Ok(())
}
