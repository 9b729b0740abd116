//! glTF images, samplers and texture references: decoding to RGBA8 and reading KHR_texture_transform.

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

/// A glTF texture: an image and how it is sampled. Minified, it is read from the image's mip chain (trilinear,
/// `--texture-filter`) unless its sampler's minFilter is NEAREST or LINEAR, which glTF defines as without mipmaps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    pub image: usize,
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// magFilter NEAREST: texel lookups without interpolation.
    pub nearest: bool,
    /// minFilter absent or one of the *_MIPMAP_* filters: the texture may be read from coarser levels.
    pub mipmaps: bool,
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
    /// Whether any texel is less than fully opaque.
    pub fn has_alpha(&self) -> bool {
        self.texels.iter().any(|t| t[3] < 255)
    }
}

/// Decodes PNG, JPEG, WebP (EXT_texture_webp) or KTX2 with Basis Universal (KHR_texture_basisu), by content
/// whatever the mimeType says, into RGBA8; 16-bit images are rounded to 8 bits. The size is read from the header
/// and checked against `max_pixels` (and `MAX_IMAGE_SIDE`) before any texel is decoded, so a small file cannot make
/// the reader allocate gigabytes. Errors are sentences for the caller.
/// `host_bytes`: the host memory the image may take while it decodes (HOST_BYTES_PER_PIXEL_DECODING a pixel), checked
/// from its header like `max_pixels`.
pub fn decode(bytes: &[u8], max_pixels: u64, host_bytes: u64) -> Result<Image, String> {
    if bytes.starts_with(&KTX2_MAGIC) {
        return decode_ktx2(bytes, max_pixels, host_bytes);
    }
    let reader = || {
        image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| format!("cannot read the image: {e}"))
    };
    match reader()?.format() {
        Some(image::ImageFormat::Png | image::ImageFormat::Jpeg | image::ImageFormat::WebP) => {}
        Some(f) => return Err(format!("{f:?} images are not glTF textures (PNG, JPEG, WebP or KTX2)")),
        None => return Err("the image is not PNG, JPEG, WebP or KTX2".into()),
    }
    let (width, height) = reader()?
        .into_dimensions()
        .map_err(|e| format!("cannot read the image's header: {e}"))?;
    check_size(width, height, max_pixels, "--max-texture-pixels")?;
    check_host_bytes(width, height, host_bytes)?;
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

/// The identifier a KTX 2.0 file opens with.
const KTX2_MAGIC: [u8; 12] = [
    0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
];

/// A KTX2 file of Basis Universal data (ETC1S with BasisLZ, or UASTC, either optionally Zstandard-compressed: what
/// KHR_texture_basisu allows), its first mip level transcoded to RGBA8 by the `basisu` crate. The texels come out as
/// stored, sRGB-encoded or linear, like a PNG's: the material slot says which. KHR_texture_basisu requires the
/// top-left origin glTF uses, so no flip.
fn decode_ktx2(bytes: &[u8], max_pixels: u64, host_bytes: u64) -> Result<Image, String> {
    let side = |at: usize| {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let (width, height) = side(20).zip(side(24)).ok_or("the KTX2 file is truncated")?;
    check_size(width, height, max_pixels, "--max-texture-pixels")?;
    check_host_bytes(width, height, host_bytes)?;
    check_ktx2_layout(bytes, width, height)?;
    // The transcoder is new and ports C++ that trusted its input; a panic on a file the checks above let through is
    // this file's error, not the loader's end.
    std::panic::catch_unwind(|| transcode_ktx2(bytes, width, height))
        .unwrap_or_else(|_| Err("the KTX2 file is malformed (the transcoder failed on it)".into()))
}

fn transcode_ktx2(bytes: &[u8], width: u32, height: u32) -> Result<Image, String> {
    let why = |e: basisu::Error| format!("{e:?}");
    let ktx2 = basisu::Transcoder::new(bytes).map_err(|e| format!("cannot read the KTX2 file: {}", why(e)))?;
    if ktx2.layer_count() > 1 || ktx2.face_count() > 1 || ktx2.is_video() {
        return Err("the KTX2 file is an array, a cube map or a video; a glTF texture is one 2D image".into());
    }
    if ktx2.base_dimensions() != (width, height) {
        return Err("the KTX2 file's header is inconsistent".into());
    }
    let target = basisu::TargetFormat::Rgba32;
    if !ktx2.supports(target) {
        return Err(format!(
            "the KTX2 file holds {:?} data, which is not Basis Universal ETC1S or UASTC",
            ktx2.source_format()
        ));
    }
    let rgba = (ktx2.transcode(0, target, basisu::DecodeFlags::NONE))
        .map_err(|e| format!("cannot transcode the KTX2 file: {}", why(e)))?;
    if rgba.len() != 4 * width as usize * height as usize {
        return Err(format!("the KTX2 file's first level is not {width}x{height}"));
    }
    let texels = rgba.chunks_exact(4).map(|t| [t[0], t[1], t[2], t[3]]).collect();
    Ok(Image { width, height, texels })
}

/// What the transcoder trusts of a KTX2 file's layout, checked: every region the index names inside the file, the
/// key/value entries each inside the region with their padding, every level inside the file, and a Zstandard
/// level's uncompressedByteLength the UASTC size of its dimensions (16 bytes per 4x4 block). Unchecked, a corrupted
/// length made the transcoder allocate 120 TB and abort, and a key/value entry ending off alignment made it index
/// past its slice.
fn check_ktx2_layout(bytes: &[u8], width: u32, height: u32) -> Result<(), String> {
    let u32_at = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    let u64_at = |o: usize| {
        bytes
            .get(o..o + 8)
            .map(|b| u64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
    };
    const TRUNCATED: &str = "the KTX2 file is truncated";
    let levels = u32_at(40).ok_or(TRUNCATED)?.max(1);
    let scheme = u32_at(44).ok_or(TRUNCATED)?;
    if levels > 32 - width.max(height).leading_zeros() {
        return Err(format!(
            "the KTX2 file declares {levels} mip levels for a {width}x{height} image"
        ));
    }
    let inside = |offset: u64, length: u64| offset.checked_add(length).is_some_and(|end| end <= bytes.len() as u64);
    let region = |at: usize| Some((u32_at(at)? as u64, u32_at(at + 4)? as u64));
    let (dfd, kvd) = (region(48).ok_or(TRUNCATED)?, region(56).ok_or(TRUNCATED)?);
    let sgd = (u64_at(64).zip(u64_at(72))).ok_or(TRUNCATED)?;
    for (what, (offset, length)) in [("descriptor", dfd), ("key/value data", kvd), ("global data", sgd)] {
        if !inside(offset, length) {
            return Err(format!("the KTX2 file's {what} lies past its end"));
        }
    }
    // Each key/value entry: a u32 length, that many bytes, then padding to a multiple of 4 from the file's start.
    let (mut p, end) = (kvd.0 as usize, (kvd.0 + kvd.1) as usize);
    while p < end {
        let length = u32_at(p)
            .filter(|_| end - p >= 4)
            .ok_or("the KTX2 file's key/value data is malformed")?;
        p = (p + 4)
            .checked_add(length as usize)
            .map(|q| q.next_multiple_of(4))
            .filter(|&q| length >= 2 && q <= end)
            .ok_or("the KTX2 file's key/value data is malformed")?;
    }
    const ZSTANDARD: u32 = 2;
    for level in 0..levels {
        let at = 80 + 24 * level as usize;
        let (offset, length, uncompressed) = (u64_at(at), u64_at(at + 8), u64_at(at + 16));
        let (Some(offset), Some(length), Some(uncompressed)) = (offset, length, uncompressed) else {
            return Err(TRUNCATED.into());
        };
        if offset.checked_add(length).is_none_or(|end| end > bytes.len() as u64) {
            return Err(format!("the KTX2 file's mip level {level} lies past its end"));
        }
        let blocks = |side: u32| (side >> level).max(1).div_ceil(4) as u64;
        if scheme == ZSTANDARD && uncompressed != 16 * blocks(width) * blocks(height) {
            return Err(format!(
                "the KTX2 file's mip level {level} claims {uncompressed} bytes uncompressed, not the {} its size takes",
                16 * blocks(width) * blocks(height)
            ));
        }
    }
    Ok(())
}

/// Refuses an image whose decoding would take more than `host_bytes` of host memory.
fn check_host_bytes(width: u32, height: u32, host_bytes: u64) -> Result<(), String> {
    let need = width as u64 * height as u64 * crate::memory::HOST_BYTES_PER_PIXEL_DECODING;
    if need > host_bytes {
        return Err(format!(
            "decoding the {width}x{height} image would take {} of host memory, more than the {} --max-memory leaves \
             for it after the scene's buffers and the images before it",
            crate::memory::human(need),
            crate::memory::human(host_bytes)
        ));
    }
    Ok(())
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
