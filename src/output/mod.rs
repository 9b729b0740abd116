//! Image files: linear float EXR and sRGB PNG, written to a temporary file and renamed so failures leave nothing behind.
use crate::error::Error;
use std::path::Path;

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

/// Writes linear RGB pixels (row 0 at the top). PNG applies 2^exposure, clamps, and encodes sRGB.
pub fn write_image(path: &Path, width: u32, height: u32, rgb: &[[f32; 3]], exposure: f32) -> Result<(), Error> {
    let format = format_of(path)?;
    assert_eq!(rgb.len(), width as usize * height as usize);
    let err = |message: String| Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(err(format!("directory {} does not exist", dir.display())));
    }
    let suffix = if format == Format::Exr { ".exr" } else { ".png" };
    let mut builder = tempfile::Builder::new();
    // A temporary file is private (0600) by default; the image it becomes gets the permissions of any new file
    // (0666 less the umask), as if written in place.
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
    let tmp = builder
        .prefix(".pathwave-")
        .suffix(suffix)
        .tempfile_in(dir)
        .map_err(|e| err(format!("cannot create a file here: {e}")))?;
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
            let scale = 2f32.powf(exposure);
            let bytes: Vec<u8> = rgb
                .iter()
                .flat_map(|p| p.map(|c| (srgb_encode((c * scale).clamp(0.0, 1.0)) * 255.0 + 0.5) as u8))
                .collect();
            let file = std::io::BufWriter::new(tmp.as_file());
            let mut enc = png::Encoder::new(file, width, height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
            let mut w = enc
                .write_header()
                .map_err(|e| err(format!("PNG encoding failed: {e}")))?;
            w.write_image_data(&bytes)
                .map_err(|e| err(format!("PNG encoding failed: {e}")))?;
            w.finish().map_err(|e| err(format!("PNG encoding failed: {e}")))?;
        }
    }
    tmp.persist(path)
        .map_err(|e| err(format!("cannot move the finished file into place: {}", e.error)))?;
    Ok(())
}

/// The most pixels `read_exr` takes: the pixels are allocated from the header's size before any is read.
pub const MAX_READ_PIXELS: usize = 1 << 28;

/// Reads an RGB EXR back as (width, height, pixels); used by tests and tools.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 3]>), crate::error::Error> {
    use exr::prelude::*;
    let err = |message: String| crate::error::Error::Output {
        path: path.to_path_buf(),
        message,
    };
    let meta = exr::meta::MetaData::read_from_file(path, false).map_err(|e| err(format!("cannot read EXR: {e}")))?;
    for header in &meta.headers {
        let size = header.layer_size;
        if size
            .width()
            .checked_mul(size.height())
            .is_none_or(|n| n > MAX_READ_PIXELS)
        {
            return Err(err(format!(
                "the EXR declares {}x{} pixels, more than the {MAX_READ_PIXELS} pathwave reads",
                size.width(),
                size.height()
            )));
        }
    }
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
