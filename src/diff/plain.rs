//! Comparing images without statistics (relMSE, FLIP) and drawing heat maps.
use super::*;

/// The plain comparison of two images without statistics.
#[derive(Clone, Debug, PartialEq)]
pub struct Plain {
    /// Mean over pixels and channels of (c-r)²/(r²+REL_MSE_EPSILON), on linear radiance.
    pub rel_mse: f64,
    /// Mean LDR-FLIP error, of the images' clamped sRGB encodings (see [`srgb8`]).
    pub flip_mean: f64,
    /// FLIP's per-pixel error, in [0, 1].
    pub per_pixel: Vec<f32>,
}

/// The tone mapping FLIP sees: linear radiance clamped to [0, 1], sRGB-encoded, rounded to 8 bits, which is what an
/// image viewer shows of the EXR at exposure 0. nv-flip exposes LDR-FLIP only, so a change above 1.0 (a light, a
/// highlight) is invisible to FLIP; relMSE still counts it.
pub fn srgb8(linear: f32) -> u8 {
    (crate::output::srgb_encode(linear.clamp(0.0, 1.0)) * 255.0 + 0.5) as u8
}

/// The mean over pixels and channels of (c - r)² / (r² + REL_MSE_EPSILON), on linear radiance.
pub fn rel_mse(candidate: &[[f32; 3]], reference: &[[f32; 3]]) -> f64 {
    let sum: f64 = (candidate.iter().zip(reference))
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] as f64, b[c] as f64)))
        .map(|(a, b)| (a - b) * (a - b) / (b * b + REL_MSE_EPSILON))
        .sum();
    sum / (3 * candidate.len().max(1)) as f64
}

/// relMSE and FLIP of two images (FLIP at 67 pixels per degree, its default).
pub fn plain(width: u32, height: u32, candidate: &[[f32; 3]], reference: &[[f32; 3]]) -> Result<Plain, String> {
    let (w, h) = (width as usize, height as usize);
    let pixels = w.checked_mul(h).filter(|&p| p > 0).ok_or("the images have no pixels")?;
    for (name, img) in [("candidate", candidate), ("reference", reference)] {
        if img.len() != pixels {
            return Err(format!(
                "{name}: {} pixels where {width}x{height} needs {pixels}",
                img.len()
            ));
        }
        if let Some((i, c)) = (0..pixels)
            .flat_map(|i| (0..3).map(move |c| (i, c)))
            .find(|&(i, c)| !img[i][c].is_finite())
        {
            return Err(format!(
                "{name} pixel {} channel {}: {}",
                pixel_name(w, i),
                CHANNEL_NAMES[c],
                img[i][c]
            ));
        }
    }
    let rel_mse = rel_mse(candidate, reference);
    let encode = |img: &[[f32; 3]]| img.iter().flat_map(|p| p.map(srgb8)).collect::<Vec<u8>>();
    let test = nv_flip::FlipImageRgb8::with_data(width, height, &encode(candidate));
    let refr = nv_flip::FlipImageRgb8::with_data(width, height, &encode(reference));
    let per_pixel = nv_flip::flip(refr, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE).to_vec();
    let flip_mean = per_pixel.iter().map(|&v| v as f64).sum::<f64>() / pixels as f64;
    Ok(Plain {
        rel_mse,
        flip_mean,
        per_pixel,
    })
}

pub(super) fn magma() -> Vec<[u8; 3]> {
    nv_flip::magma_lut()
        .to_vec()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

/// Rejected pixels: pure green, which magma never reaches. Untested pixels: grey.
pub const HEAT_REJECTED: [u8; 3] = [0, 255, 0];
pub const HEAT_UNTESTED: [u8; 3] = [96, 96, 96];

/// The p-value map: magma over log p from p = 1 (black) to the threshold (pale yellow), so the colour says how
/// close a pixel came to rejection; rejected pixels in [`HEAT_REJECTED`].
pub fn heatmap(width: u32, height: u32, per_pixel_p: &[f64], threshold: f64) -> Vec<[u8; 3]> {
    let lut = magma();
    let pixels = width as usize * height as usize;
    let top = threshold.ln();
    per_pixel_p
        .iter()
        .take(pixels)
        .map(|&p| match p {
            p if p.is_nan() => HEAT_UNTESTED,
            p if p <= threshold => HEAT_REJECTED,
            p => lut[((p.ln() / top).clamp(0.0, 1.0) * 255.0) as usize],
        })
        .collect()
}

/// The FLIP error map in FLIP's own magma colouring (the FLIP tool's picture).
pub fn flip_heatmap(width: u32, height: u32, flip: &[f32]) -> Vec<[u8; 3]> {
    let map = nv_flip::FlipImageFloat::with_data(width, height, flip);
    map.apply_color_lut(&nv_flip::magma_lut())
        .to_vec()
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}
