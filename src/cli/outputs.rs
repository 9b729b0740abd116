//! What `pathwave render` writes for a shot: the image, its AOVs as EXR layers, files of their own and PNG pictures,
//! all or nothing.
use super::render::{RenderArgs, Shot};
use crate::output::{self, Aov};
use anyhow::{Context as _, Result};
use std::path::PathBuf;

/// The shot's outputs and, for the AOVs asked for, their layers in each EXR and their files of their own (beside
/// every PNG output, and every output with --aov-files), all or nothing. Returns every path written.
pub fn write_outputs(
    args: &RenderArgs,
    shot: &Shot,
    film: &crate::Film,
    pixels: &[[f32; 3]],
    noisy: &[[f32; 3]],
    stats: Option<output::Stats>,
) -> Result<Vec<PathBuf>> {
    use output::{Content, OutFile};
    let coverage = match args.alpha {
        true => Some(
            film.aovs
                .as_ref()
                .context("the render has no coverage for --alpha")?
                .coverage(),
        ),
        false => None,
    };
    let contents = aov_contents(args, shot, film, noisy, coverage.as_deref())?;
    let aovs = args.aovs();
    let mut paths: Vec<(PathBuf, Option<usize>)> = Vec::new();
    for out in &shot.outputs {
        paths.push((out.clone(), None));
        let is_png = output::format_of(out)? == output::Format::Png;
        if is_png || args.aov_files {
            paths.extend((0..aovs.len()).map(|k| (output::aov_path(out, aovs[k]), Some(k))));
        }
    }
    let files: Vec<OutFile> = (paths.iter())
        .map(|(path, aov)| -> Result<OutFile> {
            let png = output::format_of(path)? == output::Format::Png;
            let content = match (aov, png) {
                (None, _) => Content::Image {
                    rgb: pixels,
                    display: output::Display {
                        exposure: args.exposure,
                        curve: args.tonemap,
                    },
                    stats,
                    layers: &contents.layers,
                    alpha: coverage.as_deref().map(|coverage| output::Alpha {
                        coverage,
                        // glTF holds no environment: only these options give one.
                        over_black: args.common.env.hide_env
                            || (args.common.env.env.is_none() && args.common.env.env_color.is_none()),
                    }),
                },
                (Some(k), false) => Content::Channels(&contents.own[*k]),
                (Some(k), true) => Content::Srgb8(&contents.pictures[*k]),
            };
            Ok(OutFile { path, content })
        })
        .collect::<Result<_>>()?;
    output::write_files(film.width, film.height, &files)?;
    Ok(paths.into_iter().map(|(p, _)| p).collect())
}

/// What the AOVs put in the files: their layers in each EXR (after --alpha's A), their channels in files of their
/// own, and their pictures for the PNGs of their own (made only when some output is a PNG).
struct AovContents {
    layers: Vec<output::Channel>,
    own: Vec<Vec<output::Channel>>,
    pictures: Vec<Vec<[u8; 3]>>,
}

fn aov_contents(
    args: &RenderArgs,
    shot: &Shot,
    film: &crate::Film,
    noisy: &[[f32; 3]],
    coverage: Option<&[f32]>,
) -> Result<AovContents> {
    let source = output::AovSource {
        film,
        noisy: Some(noisy),
    };
    let missing = |a: Aov| anyhow::anyhow!("the render has no {} AOV", a.name());
    let aovs = args.aovs();
    let mut layers = Vec::new();
    if let Some(c) = coverage {
        layers.push(output::Channel {
            name: "A".into(),
            samples: output::Samples::F32(c.to_vec()),
        });
    }
    let mut own = Vec::new();
    for &a in aovs {
        layers.extend(source.channels(a, true).ok_or_else(|| missing(a))?);
        own.push(source.channels(a, false).ok_or_else(|| missing(a))?);
    }
    let png = shot
        .outputs
        .iter()
        .any(|o| output::format_of(o).ok() == Some(output::Format::Png));
    let pictures = match png {
        true => (aovs.iter())
            .map(|&a| source.picture(a, args.exposure).ok_or_else(|| missing(a)))
            .collect::<Result<Vec<_>>>()?,
        false => Vec::new(),
    };
    Ok(AovContents { layers, own, pictures })
}
