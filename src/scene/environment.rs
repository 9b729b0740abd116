//! The environment light: an equirectangular radiance map (or a constant colour) and its importance-sampling tables.
use crate::error::Error;
use std::path::Path;

/// Radiance arriving from infinitely far away, in linear RGB (W sr^-1 m^-2).
/// Row 0 is straight up (+y); column 0.5 * width looks down -z; u grows towards +x.
#[derive(Clone, Debug, PartialEq)]
pub struct Environment {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[f32; 3]>,
    /// Rotation about +y, in radians.
    pub rotation: f32,
}

fn env_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Scene {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

impl Environment {
    /// A uniform colour. The map is 64x32 rather than one texel so the sampling tables (which weight rows by
    /// sin theta) sample the sphere uniformly.
    pub fn constant(rgb: [f32; 3]) -> Self {
        Environment {
            width: 64,
            height: 32,
            texels: vec![rgb; 64 * 32],
            rotation: 0.0,
        }
    }

    /// Loads an equirectangular map, scaled by `intensity`, with the default size limit (see `load_limited`).
    pub fn load(path: &Path, intensity: f32) -> Result<Self, Error> {
        Self::load_limited(path, intensity, super::gltf::DEFAULT_MAX_TEXTURE_PIXELS)
    }

    /// Loads an equirectangular map, scaled by `intensity`: linear radiance from .hdr or .exr, or 8- or 16-bit
    /// .png, .jpg or .jpeg taken as sRGB-encoded (decoded to linear before `intensity`, as glTF's colour textures).
    /// The path must be a regular file (checked before it is opened: a FIFO would block), and the map at most
    /// `max_pixels`, read from its header before anything is decoded.
    pub fn load_limited(path: &Path, intensity: f32, max_pixels: u64) -> Result<Self, Error> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        let srgb = match ext.as_deref() {
            Some("hdr") | Some("exr") => false,
            Some("png") | Some("jpg") | Some("jpeg") => true,
            _ => {
                return Err(env_err(
                    path,
                    "environment maps must be .hdr, .exr, .png, .jpg or .jpeg",
                ))
            }
        };
        let rgb = read_map(path, max_pixels)?;
        let (width, height) = rgb.dimensions();
        if width == 0 || height == 0 {
            return Err(env_err(path, "the environment map has no pixels"));
        }
        // NaN first: `max(0.0)` below would turn it into black without a word.
        let nans = rgb.pixels().filter(|p| p.0.iter().any(|c| c.is_nan())).count();
        if let Some(i) = rgb.pixels().position(|p| p.0.iter().any(|c| c.is_nan())) {
            return Err(env_err(
                path,
                format!(
                    "{nans} texel{} of the environment map {} NaN (not a number), the first at ({}, {})",
                    if nans == 1 { "" } else { "s" },
                    if nans == 1 { "is" } else { "are" },
                    i as u32 % width,
                    i as u32 / width
                ),
            ));
        }
        // An 8-bit map's values are display-encoded: lit by them as they are, a scene would take mid-grey 0.5 for
        // 0.21 and come out about twice too bright in the dark.
        let decode = |c: f32| if srgb { crate::output::srgb_decode(c) } else { c };
        let texels: Vec<[f32; 3]> = (rgb.pixels())
            .map(|p| p.0.map(|c| (decode(c) * intensity).max(0.0)))
            .collect();
        if texels.iter().any(|t| !t.iter().all(|c| c.is_finite())) {
            return Err(env_err(path, "the environment map holds non-finite values"));
        }
        if let Some(i) = (texels.iter()).position(|t| t.iter().any(|c| *c > crate::scene::RADIANCE_MAX)) {
            return Err(env_err(
                path,
                format!(
                    "texel ({}, {}) holds radiance {:?} (after --env-intensity), above the limit of {:e} per channel",
                    i as u32 % width,
                    i as u32 / width,
                    texels[i],
                    crate::scene::RADIANCE_MAX
                ),
            ));
        }
        Ok(Environment {
            width,
            height,
            texels,
            rotation: 0.0,
        })
    }

    /// Why the renderer cannot use this environment (built by a caller rather than `load`), if it cannot: a rotation
    /// that is not finite, or radiance that is not finite or above RADIANCE_MAX.
    pub fn check(&self) -> Result<(), String> {
        if !self.rotation.is_finite() {
            return Err(format!("its rotation {} is not finite", self.rotation));
        }
        if self.texels.len() != self.width as usize * self.height as usize {
            return Err(format!(
                "it has {} texels for {}x{}",
                self.texels.len(),
                self.width,
                self.height
            ));
        }
        let bad = |c: &f32| !(c.is_finite() && (0.0..=crate::scene::RADIANCE_MAX).contains(c));
        if let Some(t) = self.texels.iter().find(|t| t.iter().any(bad)) {
            return Err(format!(
                "its radiance {t:?} is not finite or not within 0 to {:e} per channel",
                crate::scene::RADIANCE_MAX
            ));
        }
        Ok(())
    }

    /// Sampling weight of each texel: its mean radiance times sin theta at its centre (the equirectangular Jacobian).
    fn weights(&self) -> Vec<f64> {
        let (w, h) = (self.width as usize, self.height as usize);
        (0..w * h)
            .map(|i| {
                let theta = std::f64::consts::PI * ((i / w) as f64 + 0.5) / h as f64;
                let t = self.texels[i];
                (t[0] + t[1] + t[2]) as f64 / 3.0 * theta.sin()
            })
            .collect()
    }

    /// Power it sends into a scene bounded by a sphere of `radius`: 4 pi^2 r^2 times the mean radiance.
    pub fn power(&self, radius: f32) -> f64 {
        let (w, h) = (self.width as f64, self.height as f64);
        // mean over the sphere of the channel-mean radiance: sum of L sin(theta) dtheta dphi / (4 pi)
        let integral: f64 =
            self.weights().iter().sum::<f64>() * (std::f64::consts::PI / h) * (2.0 * std::f64::consts::PI / w);
        let mean = integral / (4.0 * std::f64::consts::PI);
        4.0 * std::f64::consts::PI * std::f64::consts::PI * (radius as f64).powi(2) * mean
    }

    /// The device buffer: rgba texels, the marginal cdf over rows, then each row's conditional cdf (see layout.glsl).
    pub fn device_data(&self) -> Vec<f32> {
        let (w, h) = (self.width as usize, self.height as usize);
        let weights = self.weights();
        let mut out = Vec::with_capacity(4 * w * h + (h + 1) + h * (w + 1));
        for t in &self.texels {
            out.extend_from_slice(&[t[0], t[1], t[2], 0.0]);
        }
        let row_sums: Vec<f64> = (0..h).map(|y| weights[y * w..(y + 1) * w].iter().sum()).collect();
        let total: f64 = row_sums.iter().sum();
        out.extend(cdf(&row_sums, total));
        for y in 0..h {
            out.extend(cdf(&weights[y * w..(y + 1) * w], row_sums[y]));
        }
        out
    }
}

/// The map's pixels as linear floats: refused when the file is not a regular one of at most `MAX_FILE_BYTES`, or its
/// header declares more than `max_pixels`, before anything is decoded.
fn read_map(path: &Path, max_pixels: u64) -> Result<image::Rgb32FImage, Error> {
    let len =
        super::gltf::regular_len(path).map_err(|e| env_err(path, format!("cannot read the environment map: {e}")))?;
    if len > super::gltf::MAX_FILE_BYTES {
        return Err(env_err(
            path,
            format!(
                "it holds {len} bytes, more than the {} bytes a map may hold",
                super::gltf::MAX_FILE_BYTES
            ),
        ));
    }
    let cannot = |e: &dyn std::fmt::Display| env_err(path, format!("cannot read the environment map: {e}"));
    let reader = || image::ImageReader::open(path).map_err(|e| cannot(&e));
    let (width, height) = reader()?.into_dimensions().map_err(|e| cannot(&e))?;
    super::texture::check_size(width, height, max_pixels, "--max-texture-pixels")
        .map_err(|e| env_err(path, format!("the environment map: {e}")))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    let mut reader = reader()?;
    reader.limits(limits);
    let img = reader.decode().map_err(|e| cannot(&e))?;
    Ok(img.into_rgb32f())
}

/// Inclusive cdf with a leading 0 and a last value of exactly 1; an all-zero row becomes uniform.
fn cdf(weights: &[f64], total: f64) -> Vec<f32> {
    let n = weights.len();
    let mut out = Vec::with_capacity(n + 1);
    out.push(0.0);
    let mut acc = 0.0;
    for (i, w) in weights.iter().enumerate() {
        acc += if total > 0.0 { w / total } else { 1.0 / n as f64 };
        out.push(if i + 1 == n { 1.0 } else { acc.min(1.0) as f32 });
    }
    out
}
