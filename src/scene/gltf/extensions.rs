//! The material extensions the gltf crate does not model, each read from its JSON: clearcoat to specular-glossiness.
use super::{scene_err, Loader};
use crate::error::Error;
use crate::scene::texture::{self, Texture, TextureRef};
use crate::scene::{Anisotropy, Clearcoat, DiffuseTransmission, Iridescence, Sheen};
use glam::Vec3;
use gltf::json::Value;

/// KHR_materials_pbrSpecularGlossiness (archived, read from its JSON; the gltf crate's model of it is not used):
/// what replaces the metallic-roughness part of a material that has it.
pub(super) struct SpecGloss {
    pub(super) diffuse: [f32; 4],
    pub(super) diffuse_texture: Option<TextureRef>,
    pub(super) specular: Vec3,
    pub(super) glossiness: f32,
    pub(super) texture: Option<TextureRef>,
}

const SPEC_GLOSS: &str = "KHR_materials_pbrSpecularGlossiness";

impl Loader<'_> {
    /// KHR_materials_clearcoat, read from its JSON (the gltf crate does not model it).
    pub(super) fn clearcoat(&mut self, name: &str, m: &gltf::Material) -> Result<Clearcoat, Error> {
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
    pub(super) fn sheen(&mut self, name: &str, m: &gltf::Material) -> Result<Sheen, Error> {
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
    pub(super) fn anisotropy(&mut self, name: &str, m: &gltf::Material) -> Result<Anisotropy, Error> {
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
    pub(super) fn iridescence(&mut self, name: &str, m: &gltf::Material) -> Result<Iridescence, Error> {
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
    pub(super) fn dispersion(&mut self, name: &str, m: &gltf::Material) -> Result<f32, Error> {
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
    pub(super) fn diffuse_transmission(
        &mut self,
        name: &str,
        m: &gltf::Material,
    ) -> Result<DiffuseTransmission, Error> {
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
    pub(super) fn diffuse_roughness(
        &mut self,
        name: &str,
        m: &gltf::Material,
    ) -> Result<(f32, Option<TextureRef>), Error> {
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
    pub(super) fn spec_gloss(&mut self, name: &str, m: &gltf::Material) -> Result<Option<SpecGloss>, Error> {
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
    pub(super) fn roughness_from_glossiness(
        &mut self,
        name: &str,
        r: TextureRef,
        glossiness: f32,
    ) -> Result<TextureRef, Error> {
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
    pub(super) fn json_texture(
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
