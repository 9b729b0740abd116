//! Materials: the metallic-roughness factors, the extensions pathwave renders, and their textures and images.
use super::{scene_err, uri, Loader};
use crate::error::Error;
use crate::scene::texture::{self, Texture, TextureRef};
use crate::scene::{AlphaMode, Anisotropy, Clearcoat, DiffuseTransmission, Iridescence, Material, Sheen};
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

/// KHR_materials_pbrSpecularGlossiness (archived, read from its JSON; the gltf crate's model of it is not used):
/// what replaces the metallic-roughness part of a material that has it.
struct SpecGloss {
    diffuse: [f32; 4],
    diffuse_texture: Option<TextureRef>,
    specular: Vec3,
    glossiness: f32,
    texture: Option<TextureRef>,
}

const SPEC_GLOSS: &str = "KHR_materials_pbrSpecularGlossiness";

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
        let Base {
            color: c,
            slots,
            alpha,
            alpha_mode,
            dielectric: d,
            metallic,
            roughness,
        } = self.base(&name, m)?;
        let t = self.transmission(&name, m)?;
        let clearcoat = self.clearcoat(&name, m)?;
        let sheen = self.sheen(&name, m)?;
        let anisotropy = self.anisotropy(&name, m)?;
        let iridescence = self.iridescence(&name, m)?;
        let diffuse_transmission = self.diffuse_transmission(&name, m)?;
        let (diffuse_roughness, diffuse_roughness_texture) = self.diffuse_roughness(&name, m)?;
        let dispersion = self.dispersion(&name, m)?;
        let unlit = m.extension_value("KHR_materials_unlit").is_some();
        let mut pbr_metallic = metallic;
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
            name,
            base_color: Vec3::new(c[0], c[1], c[2]).clamp(Vec3::ZERO, Vec3::ONE),
            emission: emission.max(Vec3::ZERO),
            double_sided: m.double_sided(),
            metallic: pbr_metallic,
            roughness,
            ior: d.ior,
            dispersion: if unlit { 0.0 } else { dispersion },
            specular,
            specular_color: d.specular_color.max(Vec3::ZERO),
            alpha,
            alpha_mode,
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

    /// KHR_materials_clearcoat, read from its JSON (the gltf crate does not model it).
    fn clearcoat(&mut self, name: &str, m: &gltf::Material) -> Result<Clearcoat, Error> {
        let Some(ext) = m.extension_value("KHR_materials_clearcoat") else {
            return Ok(Clearcoat::default());
        };
        let what = "KHR_materials_clearcoat";
        let factor = self.json_factor(name, what, ext, "clearcoatFactor", 0.0)?;
        let roughness = self.json_factor(name, what, ext, "clearcoatRoughnessFactor", 0.0)?;
        let texture = self.json_texture(name, what, ext, "clearcoatTexture")?;
        let roughness_texture = self.json_texture(name, what, ext, "clearcoatRoughnessTexture")?;
        let normal_texture = self.json_texture(name, what, ext, "clearcoatNormalTexture")?;
        let normal_scale = match ext.get("clearcoatNormalTexture").and_then(|t| t.get("scale")) {
            None => 1.0,
            Some(v) => v.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                scene_err(
                    self.path,
                    format!("material '{name}': {what}.clearcoatNormalTexture.scale is not a finite number"),
                )
            })? as f32,
        };
        Ok(Clearcoat {
            factor,
            roughness,
            texture,
            roughness_texture,
            normal_texture,
            normal_scale,
        })
    }

    /// KHR_materials_sheen, read from its JSON.
    fn sheen(&mut self, name: &str, m: &gltf::Material) -> Result<Sheen, Error> {
        let Some(ext) = m.extension_value("KHR_materials_sheen") else {
            return Ok(Sheen::default());
        };
        let what = "KHR_materials_sheen";
        let color = match ext.get("sheenColorFactor") {
            None => Vec3::ZERO,
            Some(v) => json_color(v).ok_or_else(|| {
                scene_err(
                    self.path,
                    format!("material '{name}': {what}.sheenColorFactor is not three finite numbers"),
                )
            })?,
        };
        Ok(Sheen {
            color: color.clamp(Vec3::ZERO, Vec3::ONE),
            roughness: self.json_factor(name, what, ext, "sheenRoughnessFactor", 0.0)?,
            color_texture: self.json_texture(name, what, ext, "sheenColorTexture")?,
            roughness_texture: self.json_texture(name, what, ext, "sheenRoughnessTexture")?,
        })
    }

    /// KHR_materials_anisotropy, read from its JSON.
    fn anisotropy(&mut self, name: &str, m: &gltf::Material) -> Result<Anisotropy, Error> {
        let Some(ext) = m.extension_value("KHR_materials_anisotropy") else {
            return Ok(Anisotropy::default());
        };
        let what = "KHR_materials_anisotropy";
        let rotation = match ext.get("anisotropyRotation") {
            None => 0.0,
            // Any angle is meaningful, but one beyond a million radians has lost its fraction of a turn in f32.
            Some(v) => v.as_f64().filter(|x| x.is_finite() && x.abs() <= 1e6).ok_or_else(|| {
                scene_err(
                    self.path,
                    format!("material '{name}': {what}.anisotropyRotation is not a finite angle in radians"),
                )
            })? as f32,
        };
        Ok(Anisotropy {
            strength: self.json_factor(name, what, ext, "anisotropyStrength", 0.0)?,
            rotation,
            texture: self.json_texture(name, what, ext, "anisotropyTexture")?,
        })
    }

    /// KHR_materials_iridescence, read from its JSON.
    fn iridescence(&mut self, name: &str, m: &gltf::Material) -> Result<Iridescence, Error> {
        let Some(ext) = m.extension_value("KHR_materials_iridescence") else {
            return Ok(Iridescence::default());
        };
        let what = "KHR_materials_iridescence";
        let d = Iridescence::default();
        // A film's IOR of at least 1 and a thickness of at most 100 um (thousands of wavelengths: any thicker and the
        // interference has long averaged out), so the phase stays finite.
        let number = |key: &str, default: f32, lo: f64, hi: f64| -> Result<f32, Error> {
            match ext.get(key) {
                None => Ok(default),
                Some(v) => v
                    .as_f64()
                    .filter(|x| x.is_finite() && (lo..=hi).contains(x))
                    .map(|x| x as f32)
                    .ok_or_else(|| {
                        scene_err(
                            self.path,
                            format!("material '{name}': {what}.{key} is not a number in [{lo}, {hi}]"),
                        )
                    }),
            }
        };
        let ior = number("iridescenceIor", d.ior, 1.0, 10.0)?;
        let thickness_min = number("iridescenceThicknessMinimum", d.thickness_min, 0.0, 1e5)?;
        let thickness_max = number("iridescenceThicknessMaximum", d.thickness_max, 0.0, 1e5)?;
        Ok(Iridescence {
            factor: self.json_factor(name, what, ext, "iridescenceFactor", 0.0)?,
            ior,
            thickness_min,
            thickness_max,
            texture: self.json_texture(name, what, ext, "iridescenceTexture")?,
            thickness_texture: self.json_texture(name, what, ext, "iridescenceThicknessTexture")?,
        })
    }

    /// KHR_materials_dispersion, read from its JSON: `dispersion` is 20 / V (V the Abbe number); 0 is none.
    fn dispersion(&mut self, name: &str, m: &gltf::Material) -> Result<f32, Error> {
        let Some(ext) = m.extension_value("KHR_materials_dispersion") else {
            return Ok(0.0);
        };
        // Glass has 20 / V of 0.2 to 0.6 and diamond 0.45; 100 (an Abbe number of 0.2) is far past any material and
        // keeps the IOR's change across the visible range finite.
        match ext.get("dispersion") {
            None => Ok(0.0),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite() && (0.0..=100.0).contains(x))
                .map(|x| x as f32)
                .ok_or_else(|| {
                    scene_err(
                        self.path,
                        format!("material '{name}': KHR_materials_dispersion.dispersion is not a number in [0, 100]"),
                    )
                }),
        }
    }

    /// KHR_materials_diffuse_transmission, read from its JSON.
    fn diffuse_transmission(&mut self, name: &str, m: &gltf::Material) -> Result<DiffuseTransmission, Error> {
        let Some(ext) = m.extension_value("KHR_materials_diffuse_transmission") else {
            return Ok(DiffuseTransmission::default());
        };
        let what = "KHR_materials_diffuse_transmission";
        let color = match ext.get("diffuseTransmissionColorFactor") {
            None => Vec3::ONE,
            Some(v) => json_color(v).ok_or_else(|| {
                scene_err(
                    self.path,
                    format!("material '{name}': {what}.diffuseTransmissionColorFactor is not three finite numbers"),
                )
            })?,
        };
        Ok(DiffuseTransmission {
            factor: self.json_factor(name, what, ext, "diffuseTransmissionFactor", 0.0)?,
            color: color.clamp(Vec3::ZERO, Vec3::ONE),
            texture: self.json_texture(name, what, ext, "diffuseTransmissionTexture")?,
            color_texture: self.json_texture(name, what, ext, "diffuseTransmissionColorTexture")?,
        })
    }

    /// KHR_materials_diffuse_roughness, read from its JSON: the factor (0 by default, Lambertian) and the texture whose R
    /// multiplies it. The factor is EON's roughness r as it is (Babylon.js and OpenPBR's base_diffuse_roughness read
    /// it so too).
    fn diffuse_roughness(&mut self, name: &str, m: &gltf::Material) -> Result<(f32, Option<TextureRef>), Error> {
        let what = "KHR_materials_diffuse_roughness";
        let Some(ext) = m.extension_value(what) else {
            return Ok((0.0, None));
        };
        Ok((
            self.json_factor(name, what, ext, "diffuseRoughnessFactor", 0.0)?,
            self.json_texture(name, what, ext, "diffuseRoughnessTexture")?,
        ))
    }

    /// KHR_materials_pbrSpecularGlossiness's factors and textures, when the material has the extension.
    fn spec_gloss(&mut self, name: &str, m: &gltf::Material) -> Result<Option<SpecGloss>, Error> {
        let Some(ext) = m.extension_value(SPEC_GLOSS).cloned() else {
            return Ok(None);
        };
        let bad = |key: &str, what: &str| scene_err(self.path, format!("material '{name}': {SPEC_GLOSS}.{key} {what}"));
        let diffuse = match ext.get("diffuseFactor") {
            None => [1.0; 4],
            Some(v) => json_numbers::<4>(v).ok_or_else(|| bad("diffuseFactor", "is not four finite numbers"))?,
        };
        let specular = match ext.get("specularFactor") {
            None => Vec3::ONE,
            Some(v) => json_color(v).ok_or_else(|| bad("specularFactor", "is not three finite numbers"))?,
        };
        let glossiness = self.json_factor(name, SPEC_GLOSS, &ext, "glossinessFactor", 1.0)?;
        let diffuse_texture = self.json_texture(name, SPEC_GLOSS, &ext, "diffuseTexture")?;
        let texture = self.json_texture(name, SPEC_GLOSS, &ext, "specularGlossinessTexture")?;
        Ok(Some(SpecGloss {
            diffuse: diffuse.map(|x| x.clamp(0.0, 1.0)),
            diffuse_texture,
            specular: specular.clamp(Vec3::ZERO, Vec3::ONE),
            glossiness,
            texture,
        }))
    }

    /// A metallic-roughness texture whose green (roughness, linear) is 1 - `glossiness` times the alpha of `r`'s
    /// texels (the specular-glossiness texture's linear glossiness), made once per texture and factor, sampled
    /// and placed like `r`. Its texels count against the host's image budget like a decoded image's.
    fn roughness_from_glossiness(&mut self, name: &str, r: TextureRef, glossiness: f32) -> Result<TextureRef, Error> {
        let key = (r.texture, glossiness.to_bits());
        let texture = match self.gloss_map.get(&key) {
            Some(&t) => t,
            None => {
                let source = self.scene.textures[r.texture];
                let image = &self.scene.images[source.image];
                let kept = image.width as u64 * image.height as u64 * crate::memory::HOST_BYTES_PER_PIXEL_KEPT;
                if kept > self.image_memory {
                    return Err(scene_err(
                        self.path,
                        format!(
                            "material '{name}': the roughness image made from {SPEC_GLOSS}.specularGlossinessTexture \
                             needs {kept} bytes, more than the {} left of the memory limit",
                            self.image_memory
                        ),
                    ));
                }
                self.image_memory -= kept;
                let texels = (image.texels.iter())
                    .map(|p| {
                        [
                            0,
                            ((1.0 - glossiness * p[3] as f32 / 255.0) * 255.0 + 0.5) as u8,
                            0,
                            255,
                        ]
                    })
                    .collect();
                let made = texture::Image {
                    width: image.width,
                    height: image.height,
                    texels,
                };
                self.scene.images.push(made);
                self.scene.textures.push(Texture {
                    image: self.scene.images.len() - 1,
                    ..source
                });
                let t = self.scene.textures.len() - 1;
                self.gloss_map.insert(key, t);
                t
            }
        };
        Ok(TextureRef { texture, ..r })
    }

    /// A factor in [0, 1] of an extension's JSON (clamped there), `default` when absent.
    fn json_factor(&self, name: &str, ext_name: &str, ext: &Value, key: &str, default: f32) -> Result<f32, Error> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() => Ok((x as f32).clamp(0.0, 1.0)),
                _ => Err(scene_err(
                    self.path,
                    format!("material '{name}': {ext_name}.{key} is not a finite number"),
                )),
            },
        }
    }

    /// A textureInfo of an extension's JSON: the texture index (checked), texCoord and KHR_texture_transform.
    fn json_texture(
        &mut self,
        name: &str,
        ext_name: &str,
        ext: &Value,
        key: &str,
    ) -> Result<Option<TextureRef>, Error> {
        let Some(info) = ext.get(key) else {
            return Ok(None);
        };
        let slot = format!("{ext_name}.{key}");
        let bad = |why: &str| scene_err(self.path, format!("material '{name}': {slot} {why}"));
        let index = info
            .get("index")
            .and_then(Value::as_u64)
            .ok_or_else(|| bad("has no texture index"))?;
        let texture = usize::try_from(index)
            .ok()
            .and_then(|i| self.document.textures().nth(i))
            .ok_or_else(|| bad(&format!("names texture {index}, which does not exist")))?;
        let tex_coord = match info.get("texCoord") {
            None => 0,
            Some(t) => t
                .as_u64()
                .and_then(|t| u32::try_from(t).ok())
                .ok_or_else(|| bad("has a texCoord that is not a small unsigned integer"))?,
        };
        let transform = match info.get("extensions").and_then(|e| e.get("KHR_texture_transform")) {
            Some(v) => {
                Some(texture::transform_from_json(v).ok_or_else(|| bad("has a malformed KHR_texture_transform"))?)
            }
            None => None,
        };
        self.texture_ref(name, &slot, &texture, tex_coord, transform)
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
    fn texture_ref(
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

/// N finite numbers of an extension's JSON.
fn json_numbers<const N: usize>(v: &Value) -> Option<[f32; N]> {
    let a = v.as_array().filter(|a| a.len() == N)?;
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64().map(|x| x as f32).filter(|x| x.is_finite())?;
    }
    Some(out)
}

/// Three finite numbers of an extension's JSON, as a colour.
fn json_color(v: &Value) -> Option<Vec3> {
    let a = v.as_array().filter(|a| a.len() == 3)?;
    let c = a
        .iter()
        .map(|x| x.as_f64().map(|x| x as f32))
        .collect::<Option<Vec<f32>>>()?;
    Some(Vec3::new(c[0], c[1], c[2])).filter(|c| c.is_finite())
}
