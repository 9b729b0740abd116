//! Materials and textures for the device: each material's GpuMaterial with its texture slots, and the texture
//! table with every image's texels once.
use super::mipmaps;
use super::pack::v4;
use crate::constants::*;
use crate::layout::{GpuMaterial, GpuTexture, TextureSlot};
use crate::scene::{AlphaMode, Material, Scene, TextureRef, Wrap};

fn slot(r: Option<TextureRef>) -> TextureSlot {
    match r {
        Some(r) => TextureSlot {
            u: [
                r.transform[0][0],
                r.transform[0][1],
                r.transform[0][2],
                f32::from_bits(r.texture as u32),
            ],
            v: [
                r.transform[1][0],
                r.transform[1][1],
                r.transform[1][2],
                f32::from_bits(r.tex_coord),
            ],
        },
        None => TextureSlot {
            u: [1.0, 0.0, 0.0, f32::from_bits(TEXTURE_NONE)],
            v: [0.0, 1.0, 0.0, f32::from_bits(0)],
        },
    }
}

pub(super) fn gpu_material(m: &Material) -> GpuMaterial {
    let (mode, cutoff) = match m.alpha_mode {
        AlphaMode::Opaque => (ALPHA_OPAQUE, 0.0),
        AlphaMode::Mask(c) => (ALPHA_MASK, c),
        AlphaMode::Blend => (ALPHA_BLEND, 0.0),
    };
    GpuMaterial {
        base_color: v4(m.base_color, m.alpha),
        emission: v4(m.emission, if m.double_sided { 1.0 } else { 0.0 }),
        params: [m.metallic, m.roughness, m.ior, m.specular],
        specular_color: v4(m.specular_color, m.diffuse_roughness),
        // Dispersion bends light only through a volume (KHR_materials_dispersion needs KHR_materials_volume).
        transmission: [
            m.transmission,
            if m.thin_walled { 1.0 } else { 0.0 },
            if m.thin_walled { 0.0 } else { m.dispersion },
            if m.thin_walled { m.thin_scatter.strength } else { 0.0 },
        ],
        attenuation: v4(m.attenuation, 0.0),
        alpha: [
            f32::from_bits(mode),
            cutoff,
            m.normal_scale,
            f32::from_bits(if m.unlit { MATERIAL_UNLIT } else { 0 }),
        ],
        clearcoat: [m.clearcoat.factor, m.clearcoat.roughness, m.clearcoat.normal_scale, 0.0],
        sheen: v4(m.sheen.color, m.sheen.roughness),
        anisotropy: [
            m.anisotropy.strength,
            m.anisotropy.rotation.cos(),
            m.anisotropy.rotation.sin(),
            0.0,
        ],
        iridescence: [
            m.iridescence.factor,
            m.iridescence.ior,
            m.iridescence.thickness_min,
            m.iridescence.thickness_max,
        ],
        diffuse_transmission: v4(m.diffuse_transmission.color, m.diffuse_transmission.factor),
        textures: m.texture_refs().map(slot),
        // A volume's medium; on a thin wall, KHR_materials_scatter's colour and g (its strength in transmission.w).
        medium: if m.thin_walled {
            v4(m.thin_scatter.color, m.thin_scatter.anisotropy)
        } else {
            v4(m.medium.albedo, m.medium.anisotropy)
        },
        base_color_spectrum: known_spectrum(m.base_color.to_array().map(|c| c.clamp(0.0, 1.0))),
        emission_spectrum: {
            let e = m.emission.to_array();
            let scale = 2.0 * e[0].max(e[1]).max(e[2]);
            if scale > 0.0 {
                known_spectrum(e.map(|c| c / scale))
            } else {
                [0.0; 4]
            }
        },
    }
}

/// A colour's RGB-to-spectrum coefficients as the shaders would interpolate them, w 1; all zero for a grey (or NaN),
/// whose spectrum the shaders take as constant without them.
fn known_spectrum(rgb: [f32; 3]) -> [f32; 4] {
    if rgb.iter().any(|c| !c.is_finite()) || (rgb[0] == rgb[1] && rgb[1] == rgb[2]) {
        return [0.0; 4];
    }
    let c = crate::spectrum::tables().coefficients(rgb);
    [c[0], c[1], c[2], 1.0]
}

/// The slots whose texture holds sRGB-encoded colour (the shaders decode it; textures.glsl's callers pass `true`).
pub(super) const SRGB_SLOTS: [u32; 6] = [
    TEX_BASE_COLOR,
    TEX_EMISSIVE,
    TEX_SHEEN_COLOR,
    TEX_SPECULAR_COLOR,
    TEX_DIFFUSE_TRANSMISSION_COLOR,
    TEX_SCATTER_COLOR,
];

/// The texture table and every image's texels, each image once however many textures share it, its mip chain after
/// its level 0 (mipmaps.rs). An image some material reads as sRGB colour is averaged in linear light.
pub(super) fn pack_textures(scene: &Scene) -> (Vec<GpuTexture>, Vec<u32>) {
    let mut srgb = vec![false; scene.images.len()];
    for m in &scene.materials {
        for (slot, r) in m.texture_refs().iter().enumerate() {
            let image = r.and_then(|r| scene.textures.get(r.texture)).map(|t| t.image);
            if let Some(flag) = image.and_then(|i| srgb.get_mut(i)) {
                *flag |= SRGB_SLOTS.contains(&(slot as u32));
            }
        }
    }
    let mut offsets = Vec::with_capacity(scene.images.len());
    let mut texels = Vec::new();
    for (image, &srgb) in scene.images.iter().zip(&srgb) {
        offsets.push(texels.len() as u32);
        texels.extend(image.texels.iter().map(|t| u32::from_le_bytes(*t)));
        for level in mipmaps::chain(image, srgb) {
            texels.extend(level.iter().map(|t| u32::from_le_bytes(*t)));
        }
    }
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => WRAP_REPEAT,
        Wrap::ClampToEdge => WRAP_CLAMP,
        Wrap::MirroredRepeat => WRAP_MIRROR,
    };
    let textures = scene
        .textures
        .iter()
        .map(|t| {
            let image = &scene.images[t.image];
            // A sampler whose minFilter asks for no mipmaps reads level 0 however far the texture is.
            let levels = if t.mipmaps {
                mipmaps::level_count(image.width, image.height)
            } else {
                1
            };
            GpuTexture {
                offset: offsets[t.image],
                width: image.width,
                height: image.height,
                flags: wrap(t.wrap_s)
                    | wrap(t.wrap_t) << TEXTURE_WRAP_T_SHIFT
                    | if t.nearest { TEXTURE_NEAREST } else { 0 }
                    | (levels - 1) << TEXTURE_LEVELS_SHIFT,
            }
        })
        .collect();
    (textures, texels)
}
