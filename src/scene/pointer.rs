//! KHR_animation_pointer: the JSON pointers into a glTF file that pathwave animates, what each drives, and how a
//! sampled value is applied to the pose.
use super::animation::Property;
use super::{Material, PunctualKind};
use glam::Vec3;

/// What an animation channel drives: a node's transform, morph weights or visibility (glTF's own channels and the
/// pointer's `/nodes/...`), a material's factor, a punctual light's colour, intensity or cone, or a camera's field
/// of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target {
    Node(usize, Property),
    /// KHR_node_visibility's `visible`: the node and everything below it shown while the value is not 0.
    Visible(usize),
    Material(usize, MaterialValue),
    Light(usize, LightValue),
    Camera(usize, CameraValue),
}

/// A material property by its glTF name (the pointer below `/materials/{}/`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialValue {
    BaseColor,
    Metallic,
    Roughness,
    Emissive,
    EmissiveStrength,
    AlphaCutoff,
    NormalScale,
    Transmission,
    Ior,
    Clearcoat,
    ClearcoatRoughness,
    SheenColor,
    SheenRoughness,
    Specular,
    SpecularColor,
    Iridescence,
    IridescenceIor,
    AnisotropyStrength,
    AnisotropyRotation,
    DiffuseTransmission,
    DiffuseTransmissionColor,
    DiffuseRoughness,
    /// KHR_texture_transform of the texture slot `TEXTURE_SLOTS[slot]`.
    TextureTransform(u8, TransformPart),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransformPart {
    Offset,
    Rotation,
    Scale,
}

/// The texture slots whose KHR_texture_transform a pointer may animate: their paths below `/materials/{}/`, in
/// the order `slot_mut` takes them.
pub const TEXTURE_SLOTS: [&str; 18] = [
    "pbrMetallicRoughness/baseColorTexture",
    "pbrMetallicRoughness/metallicRoughnessTexture",
    "normalTexture",
    "emissiveTexture",
    "extensions/KHR_materials_specular/specularTexture",
    "extensions/KHR_materials_specular/specularColorTexture",
    "extensions/KHR_materials_transmission/transmissionTexture",
    "extensions/KHR_materials_clearcoat/clearcoatTexture",
    "extensions/KHR_materials_clearcoat/clearcoatRoughnessTexture",
    "extensions/KHR_materials_clearcoat/clearcoatNormalTexture",
    "extensions/KHR_materials_sheen/sheenColorTexture",
    "extensions/KHR_materials_sheen/sheenRoughnessTexture",
    "extensions/KHR_materials_anisotropy/anisotropyTexture",
    "extensions/KHR_materials_iridescence/iridescenceTexture",
    "extensions/KHR_materials_iridescence/iridescenceThicknessTexture",
    "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionTexture",
    "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionColorTexture",
    "extensions/KHR_materials_diffuse_roughness/diffuseRoughnessTexture",
];

/// The material's texture in slot `TEXTURE_SLOTS[slot]`.
fn slot_mut(m: &mut Material, slot: usize) -> Option<&mut Option<super::texture::TextureRef>> {
    Some(match slot {
        0 => &mut m.base_color_texture,
        1 => &mut m.metallic_roughness_texture,
        2 => &mut m.normal_texture,
        3 => &mut m.emissive_texture,
        4 => &mut m.specular_texture,
        5 => &mut m.specular_color_texture,
        6 => &mut m.transmission_texture,
        7 => &mut m.clearcoat.texture,
        8 => &mut m.clearcoat.roughness_texture,
        9 => &mut m.clearcoat.normal_texture,
        10 => &mut m.sheen.color_texture,
        11 => &mut m.sheen.roughness_texture,
        12 => &mut m.anisotropy.texture,
        13 => &mut m.iridescence.texture,
        14 => &mut m.iridescence.thickness_texture,
        15 => &mut m.diffuse_transmission.texture,
        16 => &mut m.diffuse_transmission.color_texture,
        17 => &mut m.diffuse_roughness_texture,
        _ => return None,
    })
}

/// The pointers below `/materials/{}/` pathwave animates, with the value each names.
pub const MATERIAL_POINTERS: [(&str, MaterialValue); 22] = [
    ("pbrMetallicRoughness/baseColorFactor", MaterialValue::BaseColor),
    ("pbrMetallicRoughness/metallicFactor", MaterialValue::Metallic),
    ("pbrMetallicRoughness/roughnessFactor", MaterialValue::Roughness),
    ("emissiveFactor", MaterialValue::Emissive),
    (
        "extensions/KHR_materials_emissive_strength/emissiveStrength",
        MaterialValue::EmissiveStrength,
    ),
    ("alphaCutoff", MaterialValue::AlphaCutoff),
    ("normalTexture/scale", MaterialValue::NormalScale),
    (
        "extensions/KHR_materials_transmission/transmissionFactor",
        MaterialValue::Transmission,
    ),
    ("extensions/KHR_materials_ior/ior", MaterialValue::Ior),
    (
        "extensions/KHR_materials_clearcoat/clearcoatFactor",
        MaterialValue::Clearcoat,
    ),
    (
        "extensions/KHR_materials_clearcoat/clearcoatRoughnessFactor",
        MaterialValue::ClearcoatRoughness,
    ),
    (
        "extensions/KHR_materials_sheen/sheenColorFactor",
        MaterialValue::SheenColor,
    ),
    (
        "extensions/KHR_materials_sheen/sheenRoughnessFactor",
        MaterialValue::SheenRoughness,
    ),
    (
        "extensions/KHR_materials_specular/specularFactor",
        MaterialValue::Specular,
    ),
    (
        "extensions/KHR_materials_specular/specularColorFactor",
        MaterialValue::SpecularColor,
    ),
    (
        "extensions/KHR_materials_iridescence/iridescenceFactor",
        MaterialValue::Iridescence,
    ),
    (
        "extensions/KHR_materials_iridescence/iridescenceIor",
        MaterialValue::IridescenceIor,
    ),
    (
        "extensions/KHR_materials_anisotropy/anisotropyStrength",
        MaterialValue::AnisotropyStrength,
    ),
    (
        "extensions/KHR_materials_anisotropy/anisotropyRotation",
        MaterialValue::AnisotropyRotation,
    ),
    (
        "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionFactor",
        MaterialValue::DiffuseTransmission,
    ),
    (
        "extensions/KHR_materials_diffuse_transmission/diffuseTransmissionColorFactor",
        MaterialValue::DiffuseTransmissionColor,
    ),
    (
        "extensions/KHR_materials_diffuse_roughness/diffuseRoughnessFactor",
        MaterialValue::DiffuseRoughness,
    ),
];

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightValue {
    Color,
    Intensity,
    InnerCone,
    OuterCone,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraValue {
    Yfov,
    Ymag,
}

impl Target {
    /// How many floats a key of this target holds, or None for morph weights (one per target of the node's mesh).
    pub fn width(&self) -> Option<usize> {
        use MaterialValue::*;
        Some(match *self {
            Target::Node(_, Property::Translation | Property::Scale) => 3,
            Target::Node(_, Property::Rotation) => 4,
            Target::Node(_, Property::Weights) => return None,
            Target::Visible(_) => 1,
            Target::Material(_, BaseColor) => 4,
            Target::Material(_, Emissive | SheenColor | SpecularColor | DiffuseTransmissionColor) => 3,
            Target::Material(_, TextureTransform(_, TransformPart::Offset | TransformPart::Scale)) => 2,
            Target::Material(..) => 1,
            Target::Light(_, LightValue::Color) => 3,
            Target::Light(..) | Target::Camera(..) => 1,
        })
    }

    /// Whether LINEAR keys are slerped (a quaternion) rather than blended.
    pub fn rotation(&self) -> bool {
        matches!(self, Target::Node(_, Property::Rotation))
    }
}

/// The target a KHR_animation_pointer pointer names, or why pathwave does not animate it. Indices are checked
/// against the file's counts (nodes, materials, lights, cameras).
pub fn parse(pointer: &str, counts: [usize; 4]) -> Result<Target, String> {
    let [nodes, materials, lights, cameras] = counts;
    let Some(rest) = pointer.strip_prefix('/') else {
        return Err("it is not a JSON pointer (it does not start with /)".into());
    };
    // RFC 6901: ~1 is '/', ~0 is '~' (in that order); glTF property names have neither, so the unescaped parts
    // only need comparing.
    let parts: Vec<String> = rest
        .split('/')
        .map(|p| p.replace("~1", "/").replace("~0", "~"))
        .collect();
    let parts: Vec<&str> = parts.iter().map(String::as_str).collect();
    let index = |s: &str, count: usize, what: &str| -> Result<usize, String> {
        // JSON pointer array indices: decimal without leading zeros.
        let ok = !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()) && (s == "0" || !s.starts_with('0'));
        match s.parse::<usize>() {
            Ok(i) if ok && i < count => Ok(i),
            _ => Err(format!("{what} {s} does not exist (the file has {count})")),
        }
    };
    match parts.as_slice() {
        ["nodes", n, "translation"] => Ok(Target::Node(index(n, nodes, "node")?, Property::Translation)),
        ["nodes", n, "rotation"] => Ok(Target::Node(index(n, nodes, "node")?, Property::Rotation)),
        ["nodes", n, "scale"] => Ok(Target::Node(index(n, nodes, "node")?, Property::Scale)),
        ["nodes", n, "weights"] => Ok(Target::Node(index(n, nodes, "node")?, Property::Weights)),
        ["nodes", n, "extensions", "KHR_node_visibility", "visible"] => Ok(Target::Visible(index(n, nodes, "node")?)),
        ["materials", m, tail @ ..] => {
            let m = index(m, materials, "material")?;
            if let [slot @ .., "extensions", "KHR_texture_transform", part] = tail {
                let part = match *part {
                    "offset" => Some(TransformPart::Offset),
                    "rotation" => Some(TransformPart::Rotation),
                    "scale" => Some(TransformPart::Scale),
                    _ => None,
                };
                let index = TEXTURE_SLOTS.iter().position(|p| p.split('/').eq(slot.iter().copied()));
                if let (Some(part), Some(index)) = (part, index) {
                    return Ok(Target::Material(m, MaterialValue::TextureTransform(index as u8, part)));
                }
            }
            match MATERIAL_POINTERS
                .iter()
                .find(|(p, _)| p.split('/').eq(tail.iter().copied()))
            {
                Some(&(_, v)) => Ok(Target::Material(m, v)),
                None => Err(format!(
                    "pathwave does not animate the material property {}",
                    tail.join("/")
                )),
            }
        }
        ["extensions", "KHR_lights_punctual", "lights", l, tail @ ..] => {
            let l = index(l, lights, "light")?;
            match tail {
                ["color"] => Ok(Target::Light(l, LightValue::Color)),
                ["intensity"] => Ok(Target::Light(l, LightValue::Intensity)),
                ["spot", "innerConeAngle"] => Ok(Target::Light(l, LightValue::InnerCone)),
                ["spot", "outerConeAngle"] => Ok(Target::Light(l, LightValue::OuterCone)),
                ["range"] => Err("a light's range is ignored (light falls off with the inverse square)".into()),
                _ => Err(format!(
                    "pathwave does not animate the light property {}",
                    tail.join("/")
                )),
            }
        }
        ["cameras", c, "perspective", "yfov"] => Ok(Target::Camera(index(c, cameras, "camera")?, CameraValue::Yfov)),
        ["cameras", c, "orthographic", "ymag"] => Ok(Target::Camera(index(c, cameras, "camera")?, CameraValue::Ymag)),
        ["cameras", _, _, "aspectRatio" | "xmag"] => {
            Err("the image's aspect ratio comes from its size, not the camera".into())
        }
        ["cameras", _, _, "znear" | "zfar"] => Err("a path tracer's camera has no clipping planes".into()),
        _ => Err("pathwave does not animate what it points to".into()),
    }
}

/// KHR_texture_transform's parts, which channels replace one at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexTransform {
    pub offset: [f32; 2],
    pub rotation: f32,
    pub scale: [f32; 2],
}

impl Default for TexTransform {
    fn default() -> Self {
        TexTransform {
            offset: [0.0; 2],
            rotation: 0.0,
            scale: [1.0; 2],
        }
    }
}

/// What a material's values are made of before they are combined: emissiveFactor and
/// KHR_materials_emissive_strength's strength, and each texture slot's transform, which channels replace one at a
/// time; `moved` marks the slots a channel set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialParts {
    pub factor: Vec3,
    pub strength: f32,
    pub transforms: [TexTransform; TEXTURE_SLOTS.len()],
    pub moved: u32,
}

impl MaterialParts {
    /// A material's parts from its glTF JSON (the default material's from `null`).
    pub fn from_json(material: &serde_json::Value) -> MaterialParts {
        let number =
            |v: Option<&serde_json::Value>, default: f32| v.and_then(|x| x.as_f64()).map_or(default, |x| x as f32);
        let pair = |v: Option<&serde_json::Value>, default: [f32; 2]| {
            v.and_then(|a| a.as_array())
                .filter(|a| a.len() == 2)
                .map_or(default, |a| {
                    [number(a.first(), default[0]), number(a.get(1), default[1])]
                })
        };
        let mut transforms = [TexTransform::default(); TEXTURE_SLOTS.len()];
        for (t, slot) in transforms.iter_mut().zip(TEXTURE_SLOTS) {
            let Some(x) = material.pointer(&format!("/{slot}/extensions/KHR_texture_transform")) else {
                continue;
            };
            *t = TexTransform {
                offset: pair(x.get("offset"), [0.0; 2]),
                rotation: number(x.get("rotation"), 0.0),
                scale: pair(x.get("scale"), [1.0; 2]),
            };
        }
        let factor = material.get("emissiveFactor").and_then(|a| a.as_array());
        MaterialParts {
            factor: factor.filter(|a| a.len() == 3).map_or(Vec3::ZERO, |a| {
                Vec3::new(number(a.first(), 0.0), number(a.get(1), 0.0), number(a.get(2), 0.0))
            }),
            strength: number(
                material.pointer("/extensions/KHR_materials_emissive_strength/emissiveStrength"),
                1.0,
            ),
            transforms,
            moved: 0,
        }
    }

    /// The material with its emission and moved texture transforms made from the parts.
    pub fn apply(&self, m: &mut Material) {
        m.emission = (self.factor * self.strength).clamp(Vec3::ZERO, Vec3::splat(super::RADIANCE_MAX));
        for (slot, t) in self
            .transforms
            .iter()
            .enumerate()
            .filter(|(i, _)| self.moved & (1 << i) != 0)
        {
            if let Some(Some(r)) = slot_mut(m, slot) {
                r.transform = super::texture::transform_matrix(t.offset, t.rotation, t.scale);
            }
        }
    }
}

/// Sets a material's property from a sampled value, clamped to the range the loader allows for it (keys outside
/// it, which the extension leaves undefined, render as the nearest value inside).
pub fn set_material(m: &mut Material, parts: &mut MaterialParts, value: MaterialValue, v: &[f32]) {
    use MaterialValue::*;
    let unit = |x: f32| x.clamp(0.0, 1.0);
    let rgb = |v: &[f32]| Vec3::new(v[0], v[1], v[2]).clamp(Vec3::ZERO, Vec3::ONE);
    match value {
        BaseColor => {
            m.base_color = rgb(v);
            m.alpha = unit(v[3]);
        }
        Metallic => m.metallic = unit(v[0]),
        Roughness => m.roughness = unit(v[0]),
        Emissive => parts.factor = rgb(v),
        EmissiveStrength => parts.strength = v[0].max(0.0),
        TextureTransform(slot, part) => {
            let t = &mut parts.transforms[slot as usize];
            match part {
                TransformPart::Offset => t.offset = [v[0], v[1]],
                TransformPart::Rotation => t.rotation = v[0],
                TransformPart::Scale => t.scale = [v[0], v[1]],
            }
            parts.moved |= 1 << slot;
        }
        AlphaCutoff => {
            if let super::AlphaMode::Mask(cutoff) = &mut m.alpha_mode {
                *cutoff = v[0].max(0.0);
            }
        }
        NormalScale => m.normal_scale = v[0],
        Transmission => m.transmission = unit(v[0]),
        // 0 means F0 = 1 in KHR_materials_ior, which the loader reads as 1e30 (see `dielectric`).
        Ior => m.ior = if v[0] == 0.0 { 1e30 } else { v[0].max(1.0) },
        Clearcoat => m.clearcoat.factor = unit(v[0]),
        ClearcoatRoughness => m.clearcoat.roughness = unit(v[0]),
        SheenColor => m.sheen.color = rgb(v),
        SheenRoughness => m.sheen.roughness = unit(v[0]),
        Specular => m.specular = unit(v[0]),
        SpecularColor => m.specular_color = Vec3::new(v[0], v[1], v[2]).max(Vec3::ZERO),
        Iridescence => m.iridescence.factor = unit(v[0]),
        IridescenceIor => m.iridescence.ior = v[0].max(1.0),
        AnisotropyStrength => m.anisotropy.strength = unit(v[0]),
        AnisotropyRotation => m.anisotropy.rotation = v[0],
        DiffuseTransmission => m.diffuse_transmission.factor = unit(v[0]),
        DiffuseTransmissionColor => m.diffuse_transmission.color = rgb(v),
        DiffuseRoughness => m.diffuse_roughness = unit(v[0]),
    }
}

/// A punctual light's glTF colour, intensity and cone, which channels replace one at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightParts {
    pub color: Vec3,
    pub intensity: f32,
    pub kind: PunctualKind,
}

impl LightParts {
    pub fn set(&mut self, value: LightValue, v: &[f32]) {
        match value {
            LightValue::Color => self.color = Vec3::new(v[0], v[1], v[2]).max(Vec3::ZERO),
            LightValue::Intensity => self.intensity = v[0].max(0.0),
            LightValue::InnerCone | LightValue::OuterCone => {
                if let PunctualKind::Spot { inner, outer } = &mut self.kind {
                    if value == LightValue::InnerCone {
                        *inner = v[0];
                    } else {
                        *outer = v[0];
                    }
                }
            }
        }
    }

    /// The light's kind (cones clamped as the loader clamps them) and radiometric intensity (colour times
    /// intensity, at most RADIANCE_MAX per channel).
    pub fn resolved(&self) -> (PunctualKind, Vec3) {
        let kind = match self.kind {
            PunctualKind::Spot { inner, outer } => {
                let outer = outer.clamp(1e-4, std::f32::consts::FRAC_PI_2);
                PunctualKind::Spot {
                    inner: inner.clamp(0.0, outer),
                    outer,
                }
            }
            k => k,
        };
        let intensity = (self.color * self.intensity).clamp(Vec3::ZERO, Vec3::splat(super::RADIANCE_MAX));
        (kind, intensity)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Catches: a pointer spelled otherwise than the extension's examples, escapes not undone, indices not checked.
    #[test]
    fn pointers_parse_as_the_extension_spells_them() {
        let counts = [3, 2, 1, 1];
        let ok = |p: &str| parse(p, counts).unwrap();
        assert_eq!(ok("/nodes/2/rotation"), Target::Node(2, Property::Rotation));
        assert_eq!(
            ok("/nodes/0/extensions/KHR_node_visibility/visible"),
            Target::Visible(0)
        );
        assert_eq!(
            ok("/materials/1/pbrMetallicRoughness/baseColorFactor"),
            Target::Material(1, MaterialValue::BaseColor)
        );
        assert_eq!(
            ok("/extensions/KHR_lights_punctual/lights/0/spot/outerConeAngle"),
            Target::Light(0, LightValue::OuterCone)
        );
        assert_eq!(ok("/cameras/0/perspective/yfov"), Target::Camera(0, CameraValue::Yfov));
        for bad in [
            "/nodes/3/rotation",
            "/nodes/01/rotation",
            "nodes/0/rotation",
            "/materials/0/occlusionTexture/strength",
        ] {
            assert!(parse(bad, counts).is_err(), "{bad}");
        }
        // An escaped '/' is part of a name, never a separator.
        assert!(parse("/materials/0/pbrMetallicRoughness~1baseColorFactor", counts).is_err());
    }
}
