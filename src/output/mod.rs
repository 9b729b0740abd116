//! Image files: linear float EXR and sRGB PNG, written to a temporary file and renamed so failures leave nothing behind.
use crate::error::Error;
use std::path::Path;

pub mod aov;
pub mod film_file;
pub mod tone;
pub use aov::{aov_path, Aov, AovSource, Channel, Samples};
pub use film_file::{read_film, FilmFile, FilmMeta, PartOf};
pub use tone::ToneCurve;

/// How a PNG shows linear radiance: scaled by 2^`exposure`, through `curve`, then sRGB-encoded to 8 bits.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Display {
    pub exposure: f32,
    pub curve: ToneCurve,
}

impl Display {
    /// Linear, clipped at 1, after `exposure` stops.
    pub fn linear(exposure: f32) -> Self {
        Display {
            exposure,
            curve: ToneCurve::None,
        }
    }

    /// The 8-bit sRGB pixel of linear radiance `c`.
    pub fn pixel(&self, c: [f32; 3]) -> [u8; 3] {
        let scale = 2f32.powf(self.exposure);
        let shown = self.curve.apply(c.map(|v| v * scale));
        shown.map(|v| (srgb_encode(v.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8)
    }
}

/// What EXR outputs carry besides the mean: the exact film and what made it (a film file, see `film_file`).
#[derive(Clone, Copy)]
pub struct Stats<'a> {
    pub film: &'a crate::render::film::ExactFilm,
    pub meta: &'a FilmMeta,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Exr,
    Png,
}

/// The format an output path asks for, by its extension.
pub fn format_of(path: &Path) -> Result<Format, Error> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("exr") => Ok(Format::Exr),
        Some("png") => Ok(Format::Png),
        _ => Err(Error::Output {
            path: path.to_path_buf(),
            message: "unknown output format; use a .exr or .png extension".into(),
        }),
    }
}

/// sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.0031308 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of `srgb_encode`.
pub fn srgb_decode(x: f32) -> f32 {
    if x <= 0.04045 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

fn output_err(path: &Path, message: String) -> Error {
    Error::Output {
        path: path.to_path_buf(),
        message,
    }
}

/// The folder an output goes into ("." for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// A temporary file beside `path`, which persisting renames onto it.
fn temporary_beside(path: &Path, format: Format) -> Result<tempfile::NamedTempFile, Error> {
    let dir = folder_of(path);
    if !dir.is_dir() {
        return Err(output_err(path, format!("directory {} does not exist", dir.display())));
    }
    if path.is_dir() {
        return Err(output_err(path, "is a directory".into()));
    }
    let suffix = if format == Format::Exr { ".exr" } else { ".png" };
    let mut builder = tempfile::Builder::new();
    // A temporary file is private (0600) by default; the image it becomes gets the permissions of any new file
    // (0666 less the umask), as if written in place.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    builder
        .prefix(".pathwave-")
        .suffix(suffix)
        .tempfile_in(dir)
        .map_err(|e| output_err(path, format!("cannot create a file in {}: {e}", dir.display())))
}

/// Refuses an output before any rendering: an unknown extension, a missing folder, or one this process cannot
/// create a file in (tried with a temporary file, removed at once), or a path that is a directory.
pub fn check_writable(path: &Path) -> Result<(), Error> {
    let format = format_of(path)?;
    drop(temporary_beside(path, format)?);
    Ok(())
}

/// Refuses an output that is one of the run's inputs (`inputs`: what each is, and its path), however it is named
/// (links, `..`): writing it would destroy what was read. An output that does not exist yet is no input.
pub fn check_not_input(out: &Path, inputs: &[(&str, &Path)]) -> Result<(), Error> {
    let Ok(o) = std::fs::canonicalize(out) else {
        return Ok(());
    };
    match inputs
        .iter()
        .find(|(_, i)| std::fs::canonicalize(i).is_ok_and(|i| i == o))
    {
        Some((what, _)) => Err(Error::Output {
            path: out.to_path_buf(),
            message: format!("this output is also the {what} being read; writing it would destroy the {what}"),
        }),
        None => Ok(()),
    }
}

/// Writes linear RGB pixels (row 0 at the top). PNG applies 2^exposure, clamps, and encodes sRGB.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]], exposure: f32) -> Result<(), Error> {
    write_images(&[path], width, height, rgb, exposure)
}

/// Writes the same pixels to several files, all or nothing: each is encoded to a temporary file beside it first,
/// and only when every one is complete are they renamed into place. A failure before that removes the temporaries
/// and leaves every path as it was; a rename failing removes the files already moved into place.
pub fn write_images<P: AsRef<Path>>(
    paths: &[P],
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    exposure: f32,
) -> Result<(), Error> {
    write_images_with(paths, width, height, rgb, Display::linear(exposure), None)
}

/// `write_images`, PNGs shown by `display`, with the EXR outputs carrying `stats` when given (film files); PNG
/// outputs hold the image only.
pub fn write_images_with<P: AsRef<Path>>(
    paths: &[P],
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    display: Display,
    stats: Option<Stats>,
) -> Result<(), Error> {
    let files: Vec<OutFile> = (paths.iter())
        .map(|p| OutFile {
            path: p.as_ref(),
            content: Content::Image {
                rgb,
                display,
                stats,
                layers: &[],
                alpha: None,
            },
        })
        .collect();
    write_files(width, height, &files)
}

/// What one output file holds.
#[derive(Clone, Copy)]
pub enum Content<'a> {
    /// The beauty image: as EXR with the film statistics (`stats`, a film file) and extra channels (`layers`, the
    /// AOVs) when given; as PNG as `display` shows it, the image alone.
    Image {
        rgb: &'a [[f32; 3]],
        display: Display,
        stats: Option<Stats<'a>>,
        layers: &'a [Channel],
        /// With `--alpha`: the PNG is RGBA (the EXR's A channel comes among `layers`).
        alpha: Option<Alpha<'a>>,
    },
    /// An EXR of these channels alone (an AOV's own file).
    Channels(&'a [Channel]),
    /// 8-bit sRGB pixels, as PNG.
    Srgb8(&'a [[u8; 3]]),
}

/// Each pixel's coverage (the fraction of its camera samples that hit the scene) for an RGBA PNG.
#[derive(Clone, Copy)]
pub struct Alpha<'a> {
    pub coverage: &'a [f32],
    /// The colour is premultiplied over black (the environment hidden from camera rays): PNG's alpha is straight,
    /// so the colour is divided by the coverage before its tone curve. Otherwise the colour is written as it is.
    pub over_black: bool,
}

/// A file to write and what goes in it.
#[derive(Clone, Copy)]
pub struct OutFile<'a> {
    pub path: &'a Path,
    pub content: Content<'a>,
}

/// Writes every file, all or nothing: each is encoded to a temporary file beside it first, and only when every one is
/// complete are they renamed into place. A failure before that removes the temporaries and leaves every path as it
/// was; a rename failing removes the files already moved into place.
pub fn write_files(width: u32, height: u32, files: &[OutFile]) -> Result<(), Error> {
    let pixels = width as usize * height as usize;
    let mut encoded = Vec::with_capacity(files.len());
    for file in files {
        let path = file.path;
        let format = format_of(path)?;
        let tmp = temporary_beside(path, format)?;
        match (format, file.content) {
            (
                Format::Exr,
                Content::Image {
                    rgb,
                    stats: Some(s),
                    layers,
                    ..
                },
            ) => {
                assert_eq!(rgb.len(), pixels);
                film_file::encode_film(tmp.path(), path, width, height, rgb, s.film, s.meta, layers)?
            }
            (Format::Exr, Content::Image { rgb, layers, .. }) if !layers.is_empty() => {
                let mut list = rgb_channels(rgb, "");
                list.extend_from_slice(layers);
                encode_channels(tmp.path(), path, width, height, &list, None)?
            }
            (
                Format::Png,
                Content::Image {
                    rgb,
                    display,
                    alpha: Some(a),
                    ..
                },
            ) => {
                assert_eq!(rgb.len(), pixels);
                assert_eq!(a.coverage.len(), pixels);
                let bytes: Vec<u8> = (rgb.iter().zip(a.coverage))
                    .flat_map(|(c, &k)| {
                        let straight = match a.over_black && k > 0.0 {
                            true => c.map(|v| v / k),
                            false => *c,
                        };
                        let [r, g, b] = display.pixel(straight);
                        [r, g, b, (k.clamp(0.0, 1.0) * 255.0 + 0.5) as u8]
                    })
                    .collect();
                png_8bit(&tmp, path, width, height, &bytes, png::ColorType::Rgba)?
            }
            (_, Content::Image { rgb, display, .. }) => {
                assert_eq!(rgb.len(), pixels);
                encode(&tmp, path, format, width, height, rgb, display)?
            }
            (Format::Exr, Content::Channels(list)) => encode_channels(tmp.path(), path, width, height, list, None)?,
            (Format::Png, Content::Srgb8(px)) => {
                assert_eq!(px.len(), pixels);
                png_rgb8(&tmp, path, width, height, px.as_flattened())?
            }
            (Format::Png, Content::Channels(_)) | (Format::Exr, Content::Srgb8(_)) => {
                return Err(output_err(path, "this content cannot be written in this format".into()))
            }
        }
        encoded.push((path, tmp));
    }
    let mut placed: Vec<&Path> = Vec::with_capacity(encoded.len());
    for (path, tmp) in encoded {
        if let Err(e) = tmp.persist(path) {
            for done in placed {
                let _ = std::fs::remove_file(done);
            }
            return Err(output_err(
                path,
                format!("cannot move the finished file into place: {}", e.error),
            ));
        }
        placed.push(path);
    }
    Ok(())
}

/// The R, G and B channels of `rgb`, their names after `prefix`.
fn rgb_channels(rgb: &[[f32; 3]], prefix: &str) -> Vec<Channel> {
    (["R", "G", "B"].iter().enumerate())
        .map(|(c, n)| Channel {
            name: format!("{prefix}{n}"),
            samples: Samples::F32(rgb.iter().map(|p| p[c]).collect()),
        })
        .collect()
}

/// An EXR of `list`'s channels (and the metadata attribute when given), losslessly compressed, written in a fixed
/// order so the same image gives the same bytes.
fn encode_channels(
    file: &Path,
    path: &Path,
    width: u32,
    height: u32,
    list: &[Channel],
    meta: Option<(&str, String)>,
) -> Result<(), Error> {
    use exr::prelude::*;
    let pixels = width as usize * height as usize;
    let channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = (list.iter())
        .map(|c| {
            assert_eq!(
                match &c.samples {
                    Samples::F32(v) => v.len(),
                    Samples::U32(v) => v.len(),
                },
                pixels
            );
            let samples = match &c.samples {
                Samples::F32(v) => FlatSamples::F32(v.clone()),
                Samples::U32(v) => FlatSamples::U32(v.clone()),
            };
            AnyChannel::new(c.name.as_str(), samples)
        })
        .collect();
    let mut attributes = LayerAttributes::default();
    if let Some((name, json)) = meta {
        let text = Text::new_or_none(json).ok_or_else(|| output_err(path, "metadata not ASCII".into()))?;
        attributes.other.insert(Text::from(name), AttributeValue::Text(text));
    }
    let layer = Layer::new(
        (width as usize, height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    // Not exr's parallel writer: it stores chunks in the order they finish compressing (see `encode`).
    Image::from_layer(layer)
        .write()
        .non_parallel()
        .to_file(file)
        .map_err(|e| output_err(path, format!("EXR encoding failed: {e}")))
}

/// Writes 8-bit sRGB pixels (a heat map, say) as a PNG, through a temporary file like every output.
pub fn write_srgb8(path: &Path, width: u32, height: u32, pixels: &[[u8; 3]]) -> Result<(), Error> {
    assert_eq!(pixels.len(), width as usize * height as usize);
    let tmp = temporary_beside(path, Format::Png)?;
    png_rgb8(&tmp, path, width, height, pixels.as_flattened())?;
    tmp.persist(path)
        .map_err(|e| output_err(path, format!("cannot move the finished file into place: {}", e.error)))?;
    Ok(())
}

fn png_rgb8(tmp: &tempfile::NamedTempFile, path: &Path, width: u32, height: u32, bytes: &[u8]) -> Result<(), Error> {
    png_8bit(tmp, path, width, height, bytes, png::ColorType::Rgb)
}

fn png_8bit(
    tmp: &tempfile::NamedTempFile,
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
    color: png::ColorType,
) -> Result<(), Error> {
    let err = |message: String| output_err(path, message);
    let file = std::io::BufWriter::new(tmp.as_file());
    let mut enc = png::Encoder::new(file, width, height);
    enc.set_color(color);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut w = enc
        .write_header()
        .map_err(|e| err(format!("PNG encoding failed: {e}")))?;
    w.write_image_data(bytes)
        .map_err(|e| err(format!("PNG encoding failed: {e}")))?;
    w.finish().map_err(|e| err(format!("PNG encoding failed: {e}")))
}

fn encode(
    tmp: &tempfile::NamedTempFile,
    path: &Path,
    format: Format,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    display: Display,
) -> Result<(), Error> {
    let err = |message: String| output_err(path, message);
    match format {
        Format::Exr => {
            use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage};
            let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
                let p = rgb[y * width as usize + x];
                (p[0], p[1], p[2])
            });
            // Not exr's parallel writer: it stores chunks in the order they finish compressing, so the same image
            // gave different file bytes from run to run.
            Image::from_channels((width as usize, height as usize), channels)
                .write()
                .non_parallel()
                .to_file(tmp.path())
                .map_err(|e| err(format!("EXR encoding failed: {e}")))?;
        }
        Format::Png => {
            let bytes: Vec<u8> = rgb.iter().flat_map(|p| display.pixel(*p)).collect();
            png_rgb8(tmp, path, width, height, &bytes)?;
        }
    }
    Ok(())
}

/// The most pixels `read_exr` takes: the pixels are allocated from the header's size before any is read.
pub const MAX_READ_PIXELS: usize = 1 << 28;

/// Refuses an EXR whose header declares more than MAX_READ_PIXELS pixels: readers allocate from the header's size
/// before any pixel is read.
fn check_declared_size(path: &Path) -> Result<(), Error> {
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| output_err(path, format!("cannot read EXR: {e}")))?;
    for header in &meta.headers {
        let size = header.layer_size;
        if size
            .width()
            .checked_mul(size.height())
            .is_none_or(|n| n > MAX_READ_PIXELS)
        {
            return Err(output_err(
                path,
                format!(
                    "the EXR declares {}x{} pixels, more than the {MAX_READ_PIXELS} pathwave reads",
                    size.width(),
                    size.height()
                ),
            ));
        }
    }
    Ok(())
}

/// Reads an RGB EXR back as (width, height, pixels); used by tests and tools.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>), crate::error::Error> {
    use exr::prelude::*;
    let err = |message: String| crate::error::Error::Output {
        path: path.to_path_buf(),
        message,
    };
    check_declared_size(path)?;
    let image = read_first_rgba_layer_from_file(
        path,
        |res, _| (res.width(), vec![[0f32; 3]; res.width() * res.height()]),
        |(w, px), pos, (r, g, b, _a): (f32, f32, f32, f32)| px[pos.y() * *w + pos.x()] = [r, g, b],
    )
    .map_err(|e| err(format!("cannot read EXR: {e}")))?;
    let size = image.layer_data.size;
    Ok((
        size.width() as u32,
        size.height() as u32,
        image.layer_data.channel_data.pixels.1,
    ))
}

/// `path` with the last run of `#` in its file name replaced by `frame`, zero-padded to the run's length (longer
/// numbers keep all their digits): `out.####.exr` and 7 give `out.0007.exr`. None when the name has no `#`.
pub fn frame_path(path: &Path, frame: u32) -> Option<std::path::PathBuf> {
    let name = path.file_name()?.to_str()?;
    let end = name.rfind('#')? + 1;
    let start = name[..end].trim_end_matches('#').len();
    let width = end - start;
    let numbered = format!("{}{frame:0width$}{}", &name[..start], &name[end..]);
    Some(path.with_file_name(numbered))
}

#[cfg(test)]
mod frame_tests {
    use super::frame_path;
    use std::path::Path;

    #[test]
    fn the_last_run_of_hashes_becomes_the_padded_frame_number() {
        let f = |p: &str, k| frame_path(Path::new(p), k).map(|p| p.display().to_string());
        assert_eq!(f("out.####.exr", 7).as_deref(), Some("out.0007.exr"));
        assert_eq!(f("dir#/a#b##.png", 123).as_deref(), Some("dir#/a#b123.png"));
        assert_eq!(f("x.#.png", 42).as_deref(), Some("x.42.png"));
        assert_eq!(f("renders/out.exr", 1), None);
    }
}
