//! glTF images, samplers and texture references: decoding to RGBA8 and reading KHR_texture_transform.
use glam::Vec4;

/// Largest side of an image pathwave decodes; bigger ones are refused rather than allocated blindly.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Decoded texels, row 0 at the top (glTF's uv (0, 0) is the image's top-left corner), RGBA8 as stored in the
/// file: sRGB-encoded colour for base colour and emission, linear data for the others. The shader decodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<[u8; 4]>,
}

/// A sampler's wrap mode along one axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// A glTF texture: an image and how it is sampled. Mipmaps are not built; minification is bilinear too.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    pub image: usize,
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// magFilter NEAREST: texel lookups without interpolation.
    pub nearest: bool,
}

/// A material's use of a texture: which texture, which TEXCOORD set, and the KHR_texture_transform as two rows of
/// an affine map, uv' = (row0 . (u, v, 1), row1 . (u, v, 1)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    pub texture: usize,
    pub tex_coord: u32,
    pub transform: [[f32; 3]; 2],
}

pub const IDENTITY_TRANSFORM: [[f32; 3]; 2] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];

/// The affine map of KHR_texture_transform: translation * rotation * scale. Rotation turns the uvs
/// counter-clockwise in a frame whose v points down, so its matrix rows are (c, s) and (-s, c): the extension's
/// example (offset (0, 1), rotation pi/2, scale 0.5) then selects the image's lower-left quadrant, as it says.
pub fn transform_matrix(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> [[f32; 3]; 2] {
    let (s, c) = rotation.sin_cos();
    [
        [c * scale[0], s * scale[1], offset[0]],
        [-s * scale[0], c * scale[1], offset[1]],
    ]
}

/// The sRGB transfer function's decoding, per channel in [0, 1].
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Image {
    /// Mean of the texels with the colour channels decoded from sRGB (alpha stays linear).
    pub fn average_linear(&self) -> Vec4 {
        let lut: Vec<f64> = (0..256).map(|i| srgb_to_linear(i as f32 / 255.0) as f64).collect();
        let mut sum = [0.0f64; 4];
        for t in &self.texels {
            for c in 0..3 {
                sum[c] += lut[t[c] as usize];
            }
            sum[3] += t[3] as f64 / 255.0;
        }
        let n = self.texels.len().max(1) as f64;
        Vec4::new(
            (sum[0] / n) as f32,
            (sum[1] / n) as f32,
            (sum[2] / n) as f32,
            (sum[3] / n) as f32,
        )
    }

    /// Whether any texel is less than fully opaque.
    pub fn has_alpha(&self) -> bool {
        self.texels.iter().any(|t| t[3] < 255)
    }
}

/// Decodes PNG or JPEG (by content, whatever the mimeType says) into RGBA8; 16-bit images are rounded to 8 bits.
/// The size is read from the header and checked against `max_pixels` (and `MAX_IMAGE_SIDE`) before any texel is
/// decoded, so a small file cannot make the reader allocate gigabytes. Errors are sentences for the caller.
pub fn decode(bytes: &[u8], max_pixels: u64) -> Result<Image, String> {
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| format!("cannot read the image: {e}"))
    };
    match reader()?.format() {
        Some(image::ImageFormat::Png | image::ImageFormat::Jpeg) => {}
        Some(f) => return Err(format!("{f:?} images are not glTF textures (PNG or JPEG)")),
        None => return Err("the image is neither PNG nor JPEG".into()),
    }
    let (width, height) = reader()?
        .into_dimensions()
        .map_err(|e| format!("cannot read the image's header: {e}"))?;
    check_size(width, height, max_pixels, "--max-texture-pixels")?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(width);
    limits.max_image_height = Some(height);
    // Room for 16-bit RGBA, the widest layout a PNG or JPEG decodes to.
    limits.max_alloc = Some(8 * width as u64 * height as u64 + (1 << 20));
    let mut reader = reader()?;
    reader.limits(limits);
    let decoded = reader.decode().map_err(|e| format!("cannot decode the image: {e}"))?;
    let rgba = decoded.into_rgba8();
    let (width, height) = rgba.dimensions();
    let texels = rgba.pixels().map(|p| p.0).collect();
    Ok(Image { width, height, texels })
}

/// Refuses an empty image, one with a side past `MAX_IMAGE_SIDE`, or one of more than `max_pixels` pixels
/// (the limit named by `option`).
pub fn check_size(width: u32, height: u32, max_pixels: u64, option: &str) -> Result<(), String> {
    let pixels = width as u64 * height as u64;
    if pixels == 0 {
        return Err("the image is empty".into());
    }
    if pixels > max_pixels {
        return Err(format!(
            "the image is {width}x{height} = {pixels} pixels, more than the {max_pixels} {option} allows"
        ));
    }
    if width.max(height) > MAX_IMAGE_SIDE {
        return Err(format!(
            "the image is {width}x{height}; a side may be at most {MAX_IMAGE_SIDE} pixels"
        ));
    }
    Ok(())
}

pub fn wrap_of(mode: gltf::texture::WrappingMode) -> Wrap {
    match mode {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
    }
}

/// KHR_texture_transform from an extension object's JSON (normal textures expose only raw extensions).
pub fn transform_from_json(v: &gltf::json::Value) -> Option<([[f32; 3]; 2], Option<u32>)> {
    let pair = |key: &str, default: [f32; 2]| -> Option<[f32; 2]> {
        match v.get(key) {
            None => Some(default),
            Some(a) => {
                let a = a.as_array()?;
                if a.len() != 2 {
                    return None;
                }
                Some([a[0].as_f64()? as f32, a[1].as_f64()? as f32])
            }
        }
    };
    let offset = pair("offset", [0.0, 0.0])?;
    let scale = pair("scale", [1.0, 1.0])?;
    let rotation = match v.get("rotation") {
        None => 0.0,
        Some(r) => r.as_f64()? as f32,
    };
    let tex_coord = match v.get("texCoord") {
        None => None,
        Some(t) => Some(u32::try_from(t.as_u64()?).ok()?),
    };
    Some((transform_matrix(offset, rotation, scale), tex_coord))
}
