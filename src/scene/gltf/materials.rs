//! Materials: the metallic-roughness core, what the gltf crate models of them, and their textures and images.
use super::{scene_err, uri, Loader};
use crate::error::Error;
use crate::scene::texture::{self, Texture, TextureRef};
use crate::scene::{
    AlphaMode, Anisotropy, Clearcoat, DiffuseTransmission, Iridescence, Material, Medium, Sheen, ThinScatter,
};
use glam::Vec3;
use gltf::json::Value;

/// A material's texture slots, resolved to scene textures.
struct Slots {
    base_color: Option<TextureRef>,
    metallic_roughness: Option<TextureRef>,
    emissive: Option<TextureRef>,
    normal: Option<TextureRef>,
    normal_scale: f32,
}

/// The dielectric coat: KHR_materials_ior and KHR_materials_specular.
struct Dielectric {
    ior: f32,
    specular: f32,
    specular_color: Vec3,
    specular_texture: Option<TextureRef>,
    specular_color_texture: Option<TextureRef>,
}

/// The metallic-roughness part of a material as it renders (specular-glossiness's when the material has it), with
/// its alpha.
struct Base {
    color: [f32; 4],
    slots: Slots,
    alpha: f32,
    alpha_mode: AlphaMode,
    dielectric: Dielectric,
    metallic: f32,
    roughness: f32,
}

/// KHR_materials_transmission and KHR_materials_volume.
struct Transmission {
    transmission: f32,
    texture: Option<TextureRef>,
    thin_walled: bool,
    attenuation: Vec3,
}

impl Loader<'_> {
    pub(super) fn material(&mut self, m: &gltf::Material) -> Result<(), Error> {
        let name = m
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("#{}", m.index().unwrap_or(0)));
        let emission = self.emission(&name, m)?;
        let base = self.base(&name, m)?;
        let (c, slots, d) = (base.color, base.slots, base.dielectric);
        let t = self.transmission(&name, m)?;
        let clearcoat = self.clearcoat(&name, m)?;
        let sheen = self.sheen(&name, m)?;
        let anisotropy = self.anisotropy(&name, m)?;
        let iridescence = self.iridescence(&name, m)?;
        let diffuse_transmission = self.diffuse_transmission(&name, m)?;
        let (diffuse_roughness, diffuse_roughness_texture) = self.diffuse_roughness(&name, m)?;
        let dispersion = self.dispersion(&name, m)?;
        let (medium, thin_scatter) = self.scatter(&name, m, t.thin_walled)?;
        let unlit = m.extension_value("KHR_materials_unlit").is_some();
        let mut pbr_metallic = base.metallic;
        let mut specular = d.specular.clamp(0.0, 1.0);
        if unlit {
            // Nothing reflects: keep the lobes' feature bits clear so the scene's stages fold them away.
            pbr_metallic = 0.0;
            specular = 0.0;
        }
        self.scene.materials.push(Material {
            transmission: t.transmission.clamp(0.0, 1.0),
            thin_walled: t.thin_walled,
            attenuation: t.attenuation,
            medium: if unlit { Medium::default() } else { medium },
            thin_scatter: if unlit { ThinScatter::default() } else { thin_scatter },
            name,
            base_color: Vec3::new(c[0], c[1], c[2]).clamp(Vec3::ZERO, Vec3::ONE),
            emission: emission.max(Vec3::ZERO),
            double_sided: m.double_sided(),
            metallic: pbr_metallic,
            roughness: base.roughness,
            ior: d.ior,
            dispersion: if unlit { 0.0 } else { dispersion },
            specular,
            specular_color: d.specular_color.max(Vec3::ZERO),
            alpha: base.alpha,
            alpha_mode: base.alpha_mode,
            base_color_texture: slots.base_color,
            metallic_roughness_texture: slots.metallic_roughness,
            normal_texture: slots.normal,
            normal_scale: if slots.normal_scale.is_finite() {
                slots.normal_scale
            } else {
                1.0
            },
            emissive_texture: slots.emissive,
            specular_texture: if unlit { None } else { d.specular_texture },
            specular_color_texture: if unlit { None } else { d.specular_color_texture },
            transmission_texture: t.texture,
            clearcoat: if unlit { Clearcoat::default() } else { clearcoat },
            sheen: if unlit { Sheen::default() } else { sheen },
            anisotropy: if unlit { Anisotropy::default() } else { anisotropy },
            iridescence: if unlit { Iridescence::default() } else { iridescence },
            diffuse_transmission: if unlit {
                DiffuseTransmission::default()
            } else {
                diffuse_transmission
            },
            diffuse_roughness: if unlit { 0.0 } else { diffuse_roughness },
            diffuse_roughness_texture: if unlit { None } else { diffuse_roughness_texture },
            unlit,
        });
        Ok(())
    }

    /// The emission: emissiveFactor times KHR_materials_emissive_strength, refused when not finite or above the
    /// radiance limit.
    fn emission(&self, name: &str, m: &gltf::Material) -> Result<Vec3, Error> {
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emission = Vec3::from(m.emissive_factor()) * strength;
        if !emission.is_finite() {
            return Err(scene_err(
                self.path,
                format!("material '{name}': the emission {emission} is not finite"),
            ));
        }
        if emission.max_element() > crate::scene::RADIANCE_MAX {
            return Err(scene_err(
                self.path,
                format!(
                    "material '{name}': the emission {emission} (emissiveFactor times emissiveStrength) is above \
                     the radiance limit of {:e} per channel",
                    crate::scene::RADIANCE_MAX
                ),
            ));
        }
        Ok(emission)
    }

    /// The metallic-roughness part of the material with its alpha mode: specular-glossiness's in its place when the
    /// material has that extension.
    fn base(&mut self, name: &str, m: &gltf::Material) -> Result<Base, Error> {
        let pbr = m.pbr_metallic_roughness();
        let mut c = pbr.base_color_factor();
        let mut slots = self.slots(name, m)?;
        // Specular-glossiness, when the material has it, is what its author meant (the extension's best practice):
        // the diffuse colour is the base colour of a dielectric whose F0 is the specular colour, with roughness
        // 1 - glossiness and no metal. The glossiness texture's alpha becomes a roughness texture of its own.
        let spec_gloss = self.spec_gloss(name, m)?;
        if let Some(sg) = &spec_gloss {
            c = sg.diffuse;
            slots.base_color = sg.diffuse_texture;
            slots.metallic_roughness = match sg.texture {
                Some(r) => Some(self.roughness_from_glossiness(name, r, sg.glossiness)?),
                None => None,
            };
        }
        if m.occlusion_texture().is_some() {
            self.warn(format!(
                "material '{name}': occlusionTexture is ignored (a path tracer computes occlusion)"
            ));
        }
        let alpha = c[3].clamp(0.0, 1.0);
        let alpha_mode = self.alpha_mode(name, m, alpha, slots.base_color)?;
        let mut d = self.dielectric(name, m)?;
        let mut roughness = pbr.roughness_factor().clamp(0.0, 1.0);
        let mut metallic = pbr.metallic_factor().clamp(0.0, 1.0);
        if let Some(sg) = &spec_gloss {
            // KHR_materials_specular's colour scales the IOR's F0 (clamped at 1): this one makes F0 the specular
            // colour itself, texture included (RGB, sRGB, as the specular colour texture is read).
            let r = (d.ior - 1.0) / (d.ior + 1.0);
            if r * r < 1e-6 {
                d.ior = 1.5;
            }
            let f0 = ((d.ior - 1.0) / (d.ior + 1.0)).powi(2);
            d.specular = 1.0;
            d.specular_color = sg.specular / f0;
            d.specular_texture = None;
            d.specular_color_texture = sg.texture;
            metallic = 0.0;
            roughness = if sg.texture.is_some() { 1.0 } else { 1.0 - sg.glossiness };
        }
        Ok(Base {
            color: c,
            slots,
            alpha,
            alpha_mode,
            dielectric: d,
            metallic,
            roughness,
        })
    }

    fn slots(&mut self, name: &str, m: &gltf::Material) -> Result<Slots, Error> {
        let pbr = m.pbr_metallic_roughness();
        let base_color = match pbr.base_color_texture() {
            Some(info) => self.info_ref(name, "baseColorTexture", &info)?,
            None => None,
        };
        let metallic_roughness = match pbr.metallic_roughness_texture() {
            Some(info) => self.info_ref(name, "metallicRoughnessTexture", &info)?,
            None => None,
        };
        let emissive = match m.emissive_texture() {
            Some(info) => self.info_ref(name, "emissiveTexture", &info)?,
            None => None,
        };
        let (normal, normal_scale) = match m.normal_texture() {
            Some(n) => {
                let ext = match n.extension_value("KHR_texture_transform") {
                    Some(v) => Some(texture::transform_from_json(v).ok_or_else(|| {
                        scene_err(
                            self.path,
                            format!("material '{name}': normalTexture's KHR_texture_transform is malformed"),
                        )
                    })?),
                    None => None,
                };
                let r = self.texture_ref(name, "normalTexture", &n.texture(), n.tex_coord(), ext)?;
                (r, n.scale())
            }
            None => (None, 1.0),
        };
        Ok(Slots {
            base_color,
            metallic_roughness,
            emissive,
            normal,
            normal_scale,
        })
    }

    fn alpha_mode(
        &self,
        name: &str,
        m: &gltf::Material,
        alpha: f32,
        base_color_texture: Option<TextureRef>,
    ) -> Result<AlphaMode, Error> {
        // Transparency that cannot happen (alpha 1 and no texture alpha below 1) costs nothing in traversal.
        let texture_alpha = base_color_texture.is_some_and(|r| {
            let image = self.scene.textures[r.texture].image;
            self.scene.images[image].has_alpha()
        });
        Ok(match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !cutoff.is_finite() {
                    return Err(scene_err(
                        self.path,
                        format!("material '{name}': alphaCutoff is not finite"),
                    ));
                }
                if alpha >= cutoff && !texture_alpha {
                    AlphaMode::Opaque
                } else {
                    AlphaMode::Mask(cutoff)
                }
            }
            gltf::material::AlphaMode::Blend if alpha >= 1.0 && !texture_alpha => AlphaMode::Opaque,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        })
    }

    fn dielectric(&mut self, name: &str, m: &gltf::Material) -> Result<Dielectric, Error> {
        let pbr = m.pbr_metallic_roughness();
        let ior = m.ior().unwrap_or(1.5);
        let (specular, specular_color) = match m.specular() {
            Some(s) => (s.specular_factor(), Vec3::from(s.specular_color_factor())),
            None => (1.0, Vec3::ONE),
        };
        let (mut specular_texture, mut specular_color_texture) = (None, None);
        if let Some(s) = m.specular() {
            if let Some(info) = s.specular_texture() {
                specular_texture = self.info_ref(name, "specularTexture", &info)?;
            }
            if let Some(info) = s.specular_color_texture() {
                specular_color_texture = self.info_ref(name, "specularColorTexture", &info)?;
            }
        }
        let finite = [pbr.metallic_factor(), pbr.roughness_factor(), ior, specular]
            .iter()
            .all(|x| x.is_finite())
            && specular_color.is_finite();
        if !finite {
            return Err(scene_err(
                self.path,
                format!("material '{name}': a factor is not finite"),
            ));
        }
        // IOR 0 means "F0 = 1" in KHR_materials_ior: 1e30 gives exactly that in ((ior - 1) / (ior + 1))^2 without
        // the NaN infinity would; other values below 1 are outside the extension's range.
        let ior = if ior == 0.0 { 1e30 } else { ior.max(1.0) };
        Ok(Dielectric {
            ior,
            specular,
            specular_color,
            specular_texture,
            specular_color_texture,
        })
    }

    fn transmission(&mut self, name: &str, m: &gltf::Material) -> Result<Transmission, Error> {
        let transmission = m.transmission().map(|t| t.transmission_factor()).unwrap_or(0.0);
        let (thin_walled, attenuation) = match m.volume() {
            Some(v) if v.thickness_factor() > 0.0 => {
                let d = v.attenuation_distance();
                let c = Vec3::from(v.attenuation_color()).clamp(Vec3::splat(1e-6), Vec3::ONE);
                // An infinite (default) distance means no absorption.
                let sigma = if d.is_finite() && d > 0.0 {
                    -Vec3::new(c.x.ln(), c.y.ln(), c.z.ln()) / d
                } else {
                    Vec3::ZERO
                };
                (false, sigma)
            }
            _ => (true, Vec3::ZERO),
        };
        let texture = match m.transmission().and_then(|t| t.transmission_texture()) {
            Some(info) => self.info_ref(name, "transmissionTexture", &info)?,
            None => None,
        };
        if !(transmission.is_finite() && attenuation.is_finite()) {
            return Err(scene_err(
                self.path,
                format!("material '{name}': a transmission or volume factor is not finite"),
            ));
        }
        Ok(Transmission {
            transmission,
            texture,
            thin_walled,
            attenuation,
        })
    }

    /// A textureInfo slot with its KHR_texture_transform.
    fn info_ref(
        &mut self,
        material: &str,
        slot: &str,
        info: &gltf::texture::Info,
    ) -> Result<Option<TextureRef>, Error> {
        let ext = info.texture_transform().map(|t| {
            (
                texture::transform_matrix(t.offset(), t.rotation(), t.scale()),
                t.tex_coord(),
            )
        });
        self.texture_ref(material, slot, &info.texture(), info.tex_coord(), ext)
    }

    /// Resolves one material slot, loading the texture's image on first use. `None`, with a warning, when the slot
    /// cannot be honoured: a texture without an image or a TEXCOORD set past 1.
    pub(super) fn texture_ref(
        &mut self,
        material: &str,
        slot: &str,
        tex: &gltf::Texture,
        tex_coord: u32,
        ext: Option<([[f32; 3]; 2], Option<u32>)>,
    ) -> Result<Option<TextureRef>, Error> {
        let (transform, tc_override) = ext.unwrap_or((texture::IDENTITY_TRANSFORM, None));
        let tex_coord = tc_override.unwrap_or(tex_coord);
        if !transform.iter().flatten().all(|x| x.is_finite()) {
            return Err(scene_err(
                self.path,
                format!("material '{material}': {slot}'s KHR_texture_transform is not finite"),
            ));
        }
        if tex_coord > 1 {
            self.warn(format!(
                "material '{material}': {slot} reads TEXCOORD_{tex_coord}; only sets 0 and 1 are supported, so it is ignored"
            ));
            return Ok(None);
        }
        let texture = match self.texture_map.get(&tex.index()) {
            Some(&t) => t,
            None => {
                let t = self.load_texture(tex)?;
                self.texture_map.insert(tex.index(), t);
                t
            }
        };
        if texture.is_none() && !self.missing_textures.contains(&tex.index()) {
            self.warn(format!(
                "material '{material}': {slot} uses texture {}, which names no image; it is ignored",
                tex.index()
            ));
        }
        Ok(texture.map(|texture| TextureRef {
            texture,
            tex_coord,
            transform,
        }))
    }

    /// The image a texture samples: the one its KHR_texture_basisu or EXT_texture_webp names when it names one
    /// (pathwave reads both, and the core source is then only a fallback for viewers that cannot), else its core
    /// source. None when it has neither.
    fn texture_source(&self, tex: &gltf::Texture) -> Result<Option<usize>, Error> {
        for ext in ["KHR_texture_basisu", "EXT_texture_webp"] {
            let Some(value) = tex.extension_value(ext) else {
                continue;
            };
            let source = value.get("source");
            let image = (source.and_then(Value::as_u64))
                .and_then(|i| usize::try_from(i).ok())
                .filter(|&i| i < self.document.images().len());
            return match image {
                Some(image) => Ok(Some(image)),
                None => Err(scene_err(
                    self.path,
                    format!(
                        "texture {}: {ext}'s source ({}) is not an image of the file",
                        tex.index(),
                        source.map_or("missing".to_string(), |s| s.to_string())
                    ),
                )),
            };
        }
        Ok(tex.source().map(|s| s.index()))
    }

    fn load_texture(&mut self, tex: &gltf::Texture) -> Result<Option<usize>, Error> {
        let document = self.document;
        let Some(source) = self.texture_source(tex)?.and_then(|i| document.images().nth(i)) else {
            return Ok(None);
        };
        let image = match self.image_map.get(&source.index()) {
            Some(&i) => i,
            None if !self.strict && self.image_file_missing(&source) => {
                // Blender and three.js render such a file too: the material keeps its factors.
                let name = source.name().map(|n| format!(" '{n}'")).unwrap_or_default();
                let uri = match source.source() {
                    gltf::image::Source::Uri { uri, .. } => uri::describe(uri),
                    gltf::image::Source::View { .. } => String::new(),
                };
                self.warn(format!(
                    "image {}{name} ({uri}): file not found; the materials that sample it render without it, with \
                     their factors (--strict refuses the scene instead)",
                    source.index()
                ));
                self.missing_textures.insert(tex.index());
                return Ok(None);
            }
            None => {
                let decoded = (self.image_bytes(&source))
                    .and_then(|bytes| texture::decode(&bytes, self.max_texture_pixels, self.image_memory))
                    .map_err(|e| {
                        let name = source.name().map(|n| format!(" '{n}'")).unwrap_or_default();
                        let from = match source.source() {
                            gltf::image::Source::View { view, .. } => format!("bufferView {}", view.index()),
                            gltf::image::Source::Uri { uri, .. } => uri::describe(uri),
                        };
                        scene_err(self.path, format!("image {}{name} ({from}): {e}", source.index()))
                    })?;
                let kept = decoded.width as u64 * decoded.height as u64 * crate::memory::HOST_BYTES_PER_PIXEL_KEPT;
                self.image_memory = self.image_memory.saturating_sub(kept);
                self.scene.images.push(decoded);
                let i = self.scene.images.len() - 1;
                self.image_map.insert(source.index(), i);
                i
            }
        };
        let sampler = tex.sampler();
        self.scene.textures.push(Texture {
            image,
            wrap_s: texture::wrap_of(sampler.wrap_s()),
            wrap_t: texture::wrap_of(sampler.wrap_t()),
            nearest: sampler.mag_filter() == Some(gltf::texture::MagFilter::Nearest),
            mipmaps: !matches!(
                sampler.min_filter(),
                Some(gltf::texture::MinFilter::Nearest | gltf::texture::MinFilter::Linear)
            ),
        });
        Ok(Some(self.scene.textures.len() - 1))
    }

    /// An image's encoded bytes, from its bufferView or its URI.
    /// Whether the image is a file the URI policy lets pathwave read and that does not exist (nothing else: a
    /// folder, a FIFO, a path leading out of the scene's folder or an undecodable file is still refused).
    fn image_file_missing(&self, image: &gltf::Image) -> bool {
        let gltf::image::Source::Uri { uri, .. } = image.source() else {
            return false;
        };
        matches!(self.uris.resolve(uri), Ok(uri::Target::File(f))
            if std::fs::symlink_metadata(&f).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound))
    }

    fn image_bytes(&self, image: &gltf::Image) -> Result<Vec<u8>, String> {
        match image.source() {
            gltf::image::Source::View { view, .. } => {
                let data = self.buffers.get(view.buffer().index()).map(|d| &d[..]).unwrap_or(&[]);
                let end = view.offset().checked_add(view.length());
                match end.and_then(|e| data.get(view.offset()..e)) {
                    Some(b) => Ok(b.to_vec()),
                    None => Err(format!("bufferView {} runs past the end of its buffer", view.index())),
                }
            }
            gltf::image::Source::Uri { uri, .. } => uri::image_bytes(self.uris, uri),
        }
    }
}
