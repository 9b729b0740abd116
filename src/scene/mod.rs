//! glTF loading into the host scene model: world-space triangles, materials, emitters and the camera.
mod environment;
mod tangent;
pub mod texture;

pub use environment::Environment;
pub use texture::{Image, Texture, TextureRef, Wrap};

use crate::Error;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

/// A glTF metallic-roughness material with emission (radiance in linear RGB, W sr^-1 m^-2).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub base_color: Vec3,
    pub emission: Vec3,
    /// Emission leaves both faces; otherwise only the counter-clockwise (front) face emits.
    pub double_sided: bool,
    pub metallic: f32,
    /// Perceptual roughness; the GGX alpha is its square.
    pub roughness: f32,
    /// KHR_materials_ior (1.5 by default: F0 = 0.04).
    pub ior: f32,
    /// KHR_materials_specular: weight of the dielectric coat (0 makes a pure Lambertian) and its F0 colour.
    pub specular: f32,
    pub specular_color: Vec3,
    /// KHR_materials_transmission: the fraction of the dielectric base that transmits (refracts) instead of diffusing.
    pub transmission: f32,
    /// No KHR_materials_volume (or thickness 0): a thin sheet, light passes without bending.
    pub thin_walled: bool,
    /// KHR_materials_volume absorption coefficient inside the object, per metre: -ln(attenuationColor) / distance.
    pub attenuation: Vec3,
    /// baseColorFactor's alpha: opacity under alphaMode MASK and BLEND.
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    /// sRGB colour and alpha, multiplying base_color and alpha.
    pub base_color_texture: Option<TextureRef>,
    /// Roughness in G and metallic in B, multiplying the factors.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normals; `normal_scale` scales their x and y.
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// sRGB colour multiplying the emission.
    pub emissive_texture: Option<TextureRef>,
}

/// glTF's alphaMode. Transparent parts are skipped by every ray, camera, extension and shadow alike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Opaque where alpha >= the cutoff, absent elsewhere.
    Mask(f32),
    /// Present with probability alpha (stochastic transparency: unbiased coverage, no sorting).
    Blend,
}

impl Material {
    /// Whether rays may pass through the surface: traversal then evaluates alpha at each candidate hit.
    pub fn alpha_tested(&self) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => false,
            AlphaMode::Mask(_) | AlphaMode::Blend => true,
        }
    }

    pub fn texture_refs(&self) -> [Option<TextureRef>; 4] {
        [
            self.base_color_texture,
            self.metallic_roughness_texture,
            self.normal_texture,
            self.emissive_texture,
        ]
    }
}

impl Default for Material {
    /// glTF's default material: white, fully metallic, fully rough.
    fn default() -> Self {
        Material {
            name: "(default)".into(),
            base_color: Vec3::ONE,
            emission: Vec3::ZERO,
            double_sided: false,
            metallic: 1.0,
            roughness: 1.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Vec3::ONE,
            transmission: 0.0,
            thin_walled: true,
            attenuation: Vec3::ZERO,
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            base_color_texture: None,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive_texture: None,
        }
    }
}

/// A pinhole camera in world space; the vertical field of view is fixed, the horizontal follows the image.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub world_from_camera: Mat4,
    pub yfov: f32,
}

impl Camera {
    pub fn origin(&self) -> Vec3 {
        self.world_from_camera.transform_point3(Vec3::ZERO)
    }
    /// Right, up and forward unit vectors; glTF cameras look down -Z with +Y up.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = self.world_from_camera.transform_vector3(-Vec3::Z).normalize();
        let up0 = self.world_from_camera.transform_vector3(Vec3::Y);
        let right = forward.cross(up0).normalize();
        let up = right.cross(forward);
        (right, up, forward)
    }
}

#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub path: PathBuf,
    /// World-space triangles; front faces wind counter-clockwise.
    pub triangles: Vec<[Vec3; 3]>,
    pub normals: Vec<[Vec3; 3]>,
    /// Per triangle and vertex: TEXCOORD_0 in xy and TEXCOORD_1 in zw (zero where the mesh has none).
    pub texcoords: Vec<[Vec4; 3]>,
    /// Per triangle and vertex: the tangent in xyz and the bitangent's sign in w, from the file or generated
    /// (MikkTSpace) for normal-mapped materials; zero elsewhere.
    pub tangents: Vec<[Vec4; 3]>,
    /// Per triangle and vertex: COLOR_0 as linear RGBA (white where the mesh has none); empty when no mesh has any.
    pub colors: Vec<[Vec4; 3]>,
    pub material_of: Vec<u32>,
    pub materials: Vec<Material>,
    pub camera: Option<Camera>,
    /// How many cameras the file holds (for `--camera`).
    pub camera_count: usize,
    /// Everything the file asked for that pathwave ignored, one sentence each.
    pub warnings: Vec<String>,
    /// Light from infinitely far away; glTF has none, so it comes from the caller (`--env`, `--env-color`).
    pub environment: Option<Environment>,
    /// KHR_lights_punctual lights, in world space.
    pub punctual: Vec<PunctualLight>,
    /// The textures materials use (indexed by TextureRef::texture) and their images.
    pub textures: Vec<Texture>,
    pub images: Vec<Image>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualKind {
    Point,
    /// Cone half-angles in radians; light falls off smoothly between them (the extension's formula).
    Spot {
        inner: f32,
        outer: f32,
    },
    Directional,
}

/// A point, spot or directional light. `intensity` is colour times the glTF intensity, read radiometrically:
/// W/sr for point and spot lights (the extension's candela), W/m^2 for directional ones (its lux).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PunctualLight {
    pub kind: PunctualKind,
    pub position: Vec3,
    /// Where the light points (its node's -z): spot and directional lights.
    pub direction: Vec3,
    pub intensity: Vec3,
}

impl Scene {
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for v in t {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        (lo, hi)
    }

    /// The file's camera, or one that frames the whole scene from +Z.
    pub fn camera_or_default(&self) -> Camera {
        if let Some(c) = self.camera {
            return c;
        }
        let (lo, hi) = if self.triangles.is_empty() {
            (Vec3::splat(-1.0), Vec3::splat(1.0))
        } else {
            self.bounds()
        };
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let yfov = 45f32.to_radians();
        let distance = radius / (yfov * 0.5).tan() * 1.1 + radius;
        Camera {
            world_from_camera: Mat4::from_translation(center + Vec3::Z * distance),
            yfov,
        }
    }

    pub fn emissive_triangle_count(&self) -> usize {
        self.material_of
            .iter()
            .filter(|&&m| self.materials[m as usize].emission.max_element() > 0.0)
            .count()
    }
}

/// Extensions whose meaning pathwave renders; every other used extension is named in a warning.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_volume",
    "KHR_texture_transform",
];

fn scene_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Scene {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Loads a .gltf or .glb. `camera` picks the Nth camera in node order (default: the first).
pub fn load(path: &Path, camera: Option<usize>) -> Result<Scene, Error> {
    if !path.exists() {
        return Err(scene_err(path, "file not found"));
    }
    let bytes = std::fs::read(path).map_err(|e| scene_err(path, format!("cannot read the file: {e}")))?;
    // gltf 1.4 subtracts the 12-byte header from the GLB's declared length without checking it.
    if bytes.starts_with(b"glTF")
        && bytes
            .get(8..12)
            .is_none_or(|l| u32::from_le_bytes([l[0], l[1], l[2], l[3]]) < 12)
    {
        return Err(scene_err(
            path,
            "not a valid glTF file: the GLB header is truncated or declares a length below 12 bytes",
        ));
    }
    let (json, blob) = parse(path, &bytes)?;
    pre_validate(path, &json)?;
    validate(path, &json)?;
    let document = gltf::Document::from_json_without_validation(json);
    let base = path.parent().unwrap_or(Path::new("."));
    check_buffer_uris(path, base, &document, blob.is_some())?;
    let buffers = gltf::import_buffers(&document, Some(base), blob)
        .map_err(|e| scene_err(path, format!("cannot load buffer data: {e}")))?;
    let mut scene = Scene {
        path: path.to_path_buf(),
        ..Default::default()
    };
    Loader {
        path,
        base,
        buffers: &buffers,
        scene: &mut scene,
        cameras: Vec::new(),
        texture_map: Default::default(),
        image_map: Default::default(),
    }
    .run(&document, camera)?;
    Ok(scene)
}

/// Parses a .gltf or .glb into its JSON root and the GLB's binary chunk.
///
/// An animation channel whose target has no `node` is valid glTF (the channel is ignored, e.g. under
/// KHR_animation_pointer), but gltf 1.4's schema requires `node`: such channels are dropped before parsing.
/// pathwave ignores animations anyway; a dropped channel's sampler index is still checked.
fn parse(path: &Path, bytes: &[u8]) -> Result<(gltf::json::Root, Option<Vec<u8>>), Error> {
    use gltf::json::deserialize::{from_slice, from_value};
    let invalid = |e: &dyn std::fmt::Display| scene_err(path, format!("not a valid glTF file: {e}"));
    let (json, blob) = if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| invalid(&e))?;
        (glb.json, glb.bin.map(std::borrow::Cow::into_owned))
    } else {
        (std::borrow::Cow::Borrowed(bytes), None)
    };
    let mut value: Option<gltf::json::Value> = from_slice(&json).ok();
    let dropped = match value.as_mut() {
        Some(v) => drop_untargeted_channels(path, v)?,
        None => 0,
    };
    let root = match value {
        Some(v) if dropped > 0 => from_value(v),
        // Unchanged JSON is parsed from its bytes, exactly as gltf does (e.g. duplicate keys are refused).
        _ => from_slice(&json),
    }
    .map_err(|e| invalid(&e))?;
    Ok((root, blob))
}

/// Removes the animation channels whose target has no `node` and which are otherwise well-formed; returns how many.
fn drop_untargeted_channels(path: &Path, root: &mut gltf::json::Value) -> Result<usize, Error> {
    use gltf::json::Value;
    let untargeted = |channel: &Value| {
        let Some(target) = channel.get("target").and_then(Value::as_object) else {
            return false;
        };
        if target.contains_key("node") {
            return false;
        }
        // Dropped only if a node is all it lacks, so every other defect is still reported by gltf's parser.
        let mut with_node = channel.clone();
        with_node["target"]["node"] = Value::from(0);
        gltf::json::deserialize::from_value::<gltf::json::animation::Channel>(with_node).is_ok()
    };
    let Some(animations) = root.get_mut("animations").and_then(Value::as_array_mut) else {
        return Ok(0);
    };
    let mut dropped = 0;
    for (a, animation) in animations.iter_mut().enumerate() {
        let samplers = animation.get("samplers").and_then(Value::as_array).map_or(0, Vec::len);
        let Some(channels) = animation.get_mut("channels").and_then(Value::as_array_mut) else {
            continue;
        };
        let mut kept = Vec::with_capacity(channels.len());
        for (c, channel) in std::mem::take(channels).into_iter().enumerate() {
            if !untargeted(&channel) {
                kept.push(channel);
                continue;
            }
            let sampler = channel.get("sampler").and_then(Value::as_u64);
            if sampler.is_none_or(|s| s >= samplers as u64) {
                return Err(scene_err(
                    path,
                    format!("not a valid glTF file: invalid glTF: animations[{a}].channels[{c}].sampler: Index out of bounds"),
                ));
            }
            dropped += 1;
        }
        *channels = kept;
    }
    Ok(dropped)
}

/// gltf 1.4's validation, except where it is stricter than glTF 2.0: an accessor without a bufferView (all
/// zeros; `check_accessor` handles it) and a texture without a source (pathwave never reads texture sources).
/// Every other finding refuses the file, listed as gltf would.
fn validate(path: &Path, root: &gltf::json::Root) -> Result<(), Error> {
    use gltf::json::validation::Validate;
    let mut findings = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |p, error| {
        let p = p();
        if !spec_valid(p.as_str(), error) {
            findings.push(format!("{p}: {error}"));
        }
    });
    if findings.is_empty() {
        return Ok(());
    }
    Err(scene_err(
        path,
        format!("not a valid glTF file: invalid glTF: {}", findings.join("; ")),
    ))
}

/// Whether a finding of gltf 1.4's validator is valid glTF 2.0: exactly `accessors[N].bufferView` or
/// `textures[N].source` reported missing.
fn spec_valid(path: &str, error: gltf::json::validation::Error) -> bool {
    let indexed = |array: &str, field: &str| {
        path.strip_prefix(array)
            .and_then(|rest| rest.strip_prefix('['))
            .and_then(|rest| rest.strip_suffix(field))
            .and_then(|rest| rest.strip_suffix("]."))
            .is_some_and(|i| !i.is_empty() && i.bytes().all(|b| b.is_ascii_digit()))
    };
    error == gltf::json::validation::Error::Missing
        && (indexed("accessors", "bufferView") || indexed("textures", "source"))
}

/// What gltf 1.4's own validation assumes instead of checking (it indexes the POSITION accessor unchecked),
/// plus required extensions, refused here with a clearer message than its "Unsupported extension".
fn pre_validate(path: &Path, json: &gltf::json::Root) -> Result<(), Error> {
    for ext in &json.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(scene_err(
                path,
                format!("requires extension {ext}, which pathwave does not support"),
            ));
        }
    }
    let positions = gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(i) = prim
                .attributes
                .get(&positions)
                .filter(|i| i.value() >= json.accessors.len())
            {
                return Err(scene_err(
                    path,
                    format!(
                        "mesh {m} primitive {p}: POSITION refers to accessor {}, which does not exist",
                        i.value()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Refuses external buffer URIs gltf 1.4 would panic on (percent-escapes that decode to invalid UTF-8) or
/// could read forever from (anything but a regular file, e.g. /dev/zero or a FIFO), and buffers without a URI
/// beyond the GLB's one binary chunk (in a .gltf, the validator cannot see that their data is absent).
fn check_buffer_uris(path: &Path, base: &Path, doc: &gltf::Document, has_blob: bool) -> Result<(), Error> {
    let mut blobs_left = usize::from(has_blob);
    for buffer in doc.buffers() {
        let uri = match buffer.source() {
            gltf::buffer::Source::Uri(uri) => uri,
            gltf::buffer::Source::Bin if blobs_left > 0 => {
                blobs_left -= 1;
                continue;
            }
            gltf::buffer::Source::Bin => {
                return Err(scene_err(
                    path,
                    format!(
                        "buffer {} has no uri and no GLB binary chunk is left for it: its data is not in the file",
                        buffer.index()
                    ),
                ))
            }
        };
        let err = |m: &str| scene_err(path, format!("buffer {} ({uri}): {m}", buffer.index()));
        let file = if let Some(rest) = uri.strip_prefix("file://").or_else(|| uri.strip_prefix("file:")) {
            PathBuf::from(rest)
        } else if uri.contains(':') {
            continue; // data: URIs are decoded in memory; other schemes are refused by gltf
        } else {
            let decoded = percent_decode(uri).ok_or_else(|| err("the URI's percent-escapes do not decode to UTF-8"))?;
            base.join(decoded)
        };
        if std::fs::metadata(&file).is_ok_and(|m| !m.is_file()) {
            return Err(err("not a regular file"));
        }
    }
    Ok(())
}

/// Percent-decodes a relative URI as gltf 1.4 does (malformed escapes stay literal); `None` if not UTF-8.
fn percent_decode(uri: &str) -> Option<String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b.get(i + 1..i + 3).filter(|h| h.iter().all(u8::is_ascii_hexdigit));
        let hex = hex.and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}

/// What an accessor accepted by `Loader::check_accessor` holds.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Contents {
    /// Elements in a bufferView, which gltf's reader can read.
    Data,
    /// No bufferView and no sparse: every element is zero, and there is nothing to read.
    Zeros,
}

struct Loader<'a> {
    path: &'a Path,
    /// The folder relative URIs resolve against.
    base: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    scene: &'a mut Scene,
    cameras: Vec<Camera>,
    /// glTF texture index to scene texture (None: no readable image); glTF image index to scene image.
    texture_map: std::collections::HashMap<usize, Option<usize>>,
    image_map: std::collections::HashMap<usize, usize>,
}

impl Loader<'_> {
    fn warn(&mut self, w: String) {
        if !self.scene.warnings.contains(&w) {
            self.scene.warnings.push(w);
        }
    }

    fn run(&mut self, doc: &gltf::Document, camera: Option<usize>) -> Result<(), Error> {
        for ext in doc.extensions_used() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                self.warn(format!("extension {ext} is not supported yet and is ignored"));
            }
        }
        if doc.animations().next().is_some() {
            self.warn("animations are ignored; the scene renders at its rest pose".into());
        }
        if doc.skins().next().is_some() {
            self.warn("skins are ignored; skinned meshes render at their bind pose".into());
        }
        for m in doc.materials() {
            self.material(&m)?;
        }
        let default_material = self.scene.materials.len() as u32;
        self.scene.materials.push(Material::default());

        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                let children: HashSet<usize> = doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
                doc.nodes().filter(|n| !children.contains(&n.index())).collect()
            }
        };
        let mut visited = HashSet::new();
        // Depth-first in node order, on an explicit stack so a deep hierarchy cannot overflow the thread's stack.
        let mut stack: Vec<(gltf::Node, Mat4)> = roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY)).collect();
        while let Some((node, parent)) = stack.pop() {
            let world = self.node(&node, parent, default_material, &mut visited)?;
            let children: Vec<gltf::Node> = node.children().collect();
            stack.extend(children.into_iter().rev().map(|c| (c, world)));
        }
        self.scene.camera_count = self.cameras.len();
        self.scene.camera = match camera {
            None => self.cameras.first().copied(),
            Some(i) => Some(*self.cameras.get(i).ok_or_else(|| {
                scene_err(
                    self.path,
                    format!(
                        "--camera {i}: the file has {} perspective camera(s)",
                        self.cameras.len()
                    ),
                )
            })?),
        };
        if self.scene.camera.is_none() {
            self.warn("the file has no perspective camera; using one that frames the scene".into());
        }
        if self.scene.triangles.is_empty() {
            return Err(scene_err(self.path, "the scene has no triangles to render"));
        }
        Ok(())
    }

    fn material(&mut self, m: &gltf::Material) -> Result<(), Error> {
        let name = m
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("#{}", m.index().unwrap_or(0)));
        let pbr = m.pbr_metallic_roughness();
        let c = pbr.base_color_factor();
        let strength = m.emissive_strength().unwrap_or(1.0);
        let emission = Vec3::from(m.emissive_factor()) * strength;
        if !emission.is_finite() {
            return Err(scene_err(
                self.path,
                format!("material '{name}': the emission {emission} is not finite"),
            ));
        }
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => self.info_ref(&name, "baseColorTexture", &info)?,
            None => None,
        };
        let metallic_roughness_texture = match pbr.metallic_roughness_texture() {
            Some(info) => self.info_ref(&name, "metallicRoughnessTexture", &info)?,
            None => None,
        };
        let emissive_texture = match m.emissive_texture() {
            Some(info) => self.info_ref(&name, "emissiveTexture", &info)?,
            None => None,
        };
        let (normal_texture, normal_scale) = match m.normal_texture() {
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
                let r = self.texture_ref(&name, "normalTexture", &n.texture(), n.tex_coord(), ext)?;
                (r, n.scale())
            }
            None => (None, 1.0),
        };
        if m.occlusion_texture().is_some() {
            self.warn(format!(
                "material '{name}': occlusionTexture is ignored (a path tracer computes occlusion)"
            ));
        }
        let alpha = c[3].clamp(0.0, 1.0);
        // Transparency that cannot happen (alpha 1 and no texture alpha below 1) costs nothing in traversal.
        let texture_alpha = base_color_texture.is_some_and(|r| {
            let image = self.scene.textures[r.texture].image;
            self.scene.images[image].has_alpha()
        });
        let alpha_mode = match m.alpha_mode() {
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
        };
        let ior = m.ior().unwrap_or(1.5);
        let (specular, specular_color) = match m.specular() {
            Some(s) => (s.specular_factor(), Vec3::from(s.specular_color_factor())),
            None => (1.0, Vec3::ONE),
        };
        if let Some(s) = m.specular() {
            if s.specular_texture().is_some() || s.specular_color_texture().is_some() {
                self.warn(format!(
                    "material '{name}': specular textures are ignored (only the factors are read)"
                ));
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
        if m.transmission().is_some_and(|t| t.transmission_texture().is_some()) {
            self.warn(format!(
                "material '{name}': transmissionTexture is ignored (only the factor is read)"
            ));
        }
        if !(transmission.is_finite() && attenuation.is_finite()) {
            return Err(scene_err(
                self.path,
                format!("material '{name}': a transmission or volume factor is not finite"),
            ));
        }
        self.scene.materials.push(Material {
            transmission: transmission.clamp(0.0, 1.0),
            thin_walled,
            attenuation,
            name,
            base_color: Vec3::new(c[0], c[1], c[2]).clamp(Vec3::ZERO, Vec3::ONE),
            emission: emission.max(Vec3::ZERO),
            double_sided: m.double_sided(),
            metallic: pbr.metallic_factor().clamp(0.0, 1.0),
            roughness: pbr.roughness_factor().clamp(0.0, 1.0),
            ior,
            specular: specular.clamp(0.0, 1.0),
            specular_color: specular_color.max(Vec3::ZERO),
            alpha,
            alpha_mode,
            base_color_texture,
            metallic_roughness_texture,
            normal_texture,
            normal_scale: if normal_scale.is_finite() { normal_scale } else { 1.0 },
            emissive_texture,
        });
        Ok(())
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
    /// cannot be honoured: no core-glTF image (e.g. a KTX2 or WebP source in an extension) or a TEXCOORD set past 1.
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
        if texture.is_none() {
            self.warn(format!(
                "material '{material}': {slot} uses texture {} whose image is not PNG or JPEG in core glTF; it is ignored",
                tex.index()
            ));
        }
        Ok(texture.map(|texture| TextureRef {
            texture,
            tex_coord,
            transform,
        }))
    }

    fn load_texture(&mut self, tex: &gltf::Texture) -> Result<Option<usize>, Error> {
        let Some(source) = tex.source() else {
            return Ok(None);
        };
        let image = match self.image_map.get(&source.index()) {
            Some(&i) => i,
            None => {
                let decoded = texture::load_image(&source, self.base, self.buffers).map_err(|e| {
                    let name = source.name().map(|n| format!(" '{n}'")).unwrap_or_default();
                    scene_err(self.path, format!("image {}{name}: {e}", source.index()))
                })?;
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

    /// Takes in one node's camera and meshes; returns its world transform for its children.
    fn node(
        &mut self,
        node: &gltf::Node,
        parent: Mat4,
        default_material: u32,
        visited: &mut HashSet<usize>,
    ) -> Result<Mat4, Error> {
        if !visited.insert(node.index()) {
            return Err(scene_err(
                self.path,
                format!(
                    "node {} appears twice in the hierarchy (a cycle or a shared child)",
                    node.index()
                ),
            ));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        let world = parent * local;
        if !world.is_finite() {
            return Err(scene_err(
                self.path,
                format!("node {} has a non-finite transform", node.index()),
            ));
        }
        if let Some(light) = node.light() {
            self.punctual(&light, world)?;
        }
        if let Some(cam) = node.camera() {
            match cam.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let yfov = p.yfov();
                    if yfov > 0.0 && yfov < std::f32::consts::PI {
                        self.cameras.push(Camera {
                            world_from_camera: world,
                            yfov,
                        });
                    } else {
                        self.warn(format!(
                            "camera {}: yfov {yfov} is out of range and the camera is ignored",
                            cam.index()
                        ));
                    }
                }
                gltf::camera::Projection::Orthographic(_) => self.warn(format!(
                    "camera {}: orthographic cameras are not supported and it is ignored",
                    cam.index()
                )),
            }
        }
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                self.warn("skins are ignored; skinned meshes render at their bind pose".into());
            }
            for prim in mesh.primitives() {
                self.primitive(&mesh, &prim, world, default_material)?;
            }
        }
        Ok(world)
    }

    fn punctual(&mut self, light: &gltf::khr_lights_punctual::Light, world: Mat4) -> Result<(), Error> {
        use gltf::khr_lights_punctual::Kind;
        let name = light
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("#{}", light.index()));
        let intensity = Vec3::from(light.color()) * light.intensity();
        if !intensity.is_finite() {
            return Err(scene_err(
                self.path,
                format!("light '{name}': its intensity is not finite"),
            ));
        }
        if light.range().is_some() {
            self.warn(format!(
                "light '{name}': range is ignored; light falls off with the inverse square of distance"
            ));
        }
        let kind = match light.kind() {
            Kind::Point => PunctualKind::Point,
            Kind::Directional => PunctualKind::Directional,
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let outer = outer_cone_angle.clamp(1e-4, std::f32::consts::FRAC_PI_2);
                PunctualKind::Spot {
                    inner: inner_cone_angle.clamp(0.0, outer),
                    outer,
                }
            }
        };
        let direction = world.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z);
        self.scene.punctual.push(PunctualLight {
            kind,
            position: world.transform_point3(Vec3::ZERO),
            direction,
            intensity: intensity.max(Vec3::ZERO),
        });
        Ok(())
    }

    /// Checks an accessor against what its reader assumes, so malformed files give errors instead of panics.
    /// An accessor without bufferView and sparse holds zeros (valid glTF); it must not be given to the reader.
    fn check_accessor(
        &self,
        acc: &gltf::Accessor,
        what: &str,
        types: &[DataType],
        dims: Dimensions,
        normalized_ints: bool,
    ) -> Result<Contents, Error> {
        let err = |m: String| scene_err(self.path, format!("accessor {} ({what}): {m}", acc.index()));
        if acc.count() == 0 {
            return Err(err("count is 0".into()));
        }
        // Integer texture coordinates must be normalized; nothing else may be.
        let normalized_ok = acc.normalized() == (normalized_ints && acc.data_type() != DataType::F32);
        if !types.contains(&acc.data_type()) || acc.dimensions() != dims || !normalized_ok {
            return Err(err(format!(
                "expected {dims:?} of {types:?}, found {:?} of {:?}{}",
                acc.dimensions(),
                acc.data_type(),
                if acc.normalized() { " (normalized)" } else { "" }
            )));
        }
        if acc.view().is_none() && acc.sparse().is_none() {
            return Ok(Contents::Zeros);
        }
        if acc.sparse().is_some() {
            return Err(err("sparse accessors are not supported yet".into()));
        }
        let view = acc.view().ok_or_else(|| err("has no bufferView".into()))?;
        let size = acc.size();
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(err(format!(
                "byteStride {stride} is smaller than the element size {size}"
            )));
        }
        let buffer_len = self.buffers.get(view.buffer().index()).map(|b| b.len()).unwrap_or(0);
        let view_end = view.offset().checked_add(view.length());
        if view_end.is_none_or(|e| e > buffer_len) {
            return Err(err(format!(
                "bufferView {} runs past the end of its buffer",
                view.index()
            )));
        }
        let end = (acc.count() - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(size))
            .and_then(|x| x.checked_add(acc.offset()));
        if end.is_none_or(|e| e > view.length()) {
            return Err(err(format!("runs past the end of bufferView {}", view.index())));
        }
        Ok(Contents::Data)
    }

    fn primitive(
        &mut self,
        mesh: &gltf::Mesh,
        prim: &gltf::Primitive,
        world: Mat4,
        default_material: u32,
    ) -> Result<(), Error> {
        let mesh_name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("#{}", mesh.index()));
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warn(format!(
                "mesh '{mesh_name}': a primitive of mode {mode:?} is skipped (only triangles render)"
            ));
            return Ok(());
        }
        if prim.morph_targets().next().is_some() {
            self.warn(format!("mesh '{mesh_name}': morph targets are ignored"));
        }
        let mut color_acc = None;
        if let Some(acc) = prim.get(&gltf::Semantic::Colors(0)) {
            let dims = if acc.dimensions() == Dimensions::Vec3 {
                Dimensions::Vec3
            } else {
                Dimensions::Vec4
            };
            let types = [DataType::F32, DataType::U8, DataType::U16];
            if self.check_accessor(&acc, "COLOR_0", &types, dims, true)? == Contents::Data {
                color_acc = Some(acc);
            }
        }
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            self.warn(format!("mesh '{mesh_name}': a primitive without POSITION is skipped"));
            return Ok(());
        };
        // All-zero positions or indices make every triangle degenerate.
        if self.check_accessor(&pos_acc, "POSITION", &[DataType::F32], Dimensions::Vec3, false)? == Contents::Zeros {
            self.warn(format!(
                "mesh '{mesh_name}': POSITION accessor {} has no bufferView (all zeros); the primitive is skipped",
                pos_acc.index()
            ));
            return Ok(());
        }
        let mut normal_acc = prim.get(&gltf::Semantic::Normals);
        if let Some(n) = &normal_acc {
            if self.check_accessor(n, "NORMAL", &[DataType::F32], Dimensions::Vec3, false)? == Contents::Zeros {
                self.warn(format!(
                    "mesh '{mesh_name}': NORMAL accessor {} has no bufferView (all zeros); face normals are used",
                    n.index()
                ));
                normal_acc = None;
            }
        }
        if let Some(i) = prim.indices() {
            if self.check_accessor(
                &i,
                "indices",
                &[DataType::U8, DataType::U16, DataType::U32],
                Dimensions::Scalar,
                false,
            )? == Contents::Zeros
            {
                self.warn(format!(
                    "mesh '{mesh_name}': indices accessor {} has no bufferView (all zeros); the primitive is skipped",
                    i.index()
                ));
                return Ok(());
            }
        }
        let material = prim.material().index().map(|i| i as u32).unwrap_or(default_material);
        let mat = self.scene.materials[material as usize].clone();
        // Texture coordinates and tangents matter only to textured materials; other primitives skip reading them.
        let mut uv_accessors = [None, None];
        if mat.texture_refs().iter().any(Option::is_some) {
            for (set, slot) in uv_accessors.iter_mut().enumerate() {
                if let Some(acc) = prim.get(&gltf::Semantic::TexCoords(set as u32)) {
                    let what = format!("TEXCOORD_{set}");
                    let types = [DataType::F32, DataType::U8, DataType::U16];
                    if self.check_accessor(&acc, &what, &types, Dimensions::Vec2, true)? == Contents::Data {
                        *slot = Some(acc);
                    }
                }
            }
            for r in mat.texture_refs().iter().flatten() {
                if uv_accessors[r.tex_coord as usize].is_none() {
                    self.warn(format!(
                        "mesh '{mesh_name}': material '{}' reads TEXCOORD_{}, which the primitive lacks; its texture is \
                         sampled at uv (0, 0)",
                        mat.name, r.tex_coord
                    ));
                }
            }
        }
        let mut tangent_acc = None;
        if mat.normal_texture.is_some() {
            if let Some(acc) = prim.get(&gltf::Semantic::Tangents) {
                if self.check_accessor(&acc, "TANGENT", &[DataType::F32], Dimensions::Vec4, false)? == Contents::Data {
                    tangent_acc = Some(acc);
                }
            }
        }
        let buffers = self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
        let mut uv_sets: [Option<Vec<Vec2>>; 2] = [None, None];
        for (set, acc) in uv_accessors.iter().enumerate() {
            if acc.is_some() {
                let uvs: Vec<Vec2> = reader
                    .read_tex_coords(set as u32)
                    .map(|t| t.into_f32().map(Vec2::from).collect())
                    .unwrap_or_default();
                if uvs.iter().any(|uv| !uv.is_finite()) {
                    return Err(scene_err(
                        self.path,
                        format!("mesh '{mesh_name}': TEXCOORD_{set} holds a non-finite value"),
                    ));
                }
                uv_sets[set] = Some(uvs);
            }
        }
        let colors: Option<Vec<Vec4>> = match color_acc {
            Some(_) => reader.read_colors(0).map(|c| {
                c.into_rgba_f32()
                    .map(|c| Vec4::from(c).clamp(Vec4::ZERO, Vec4::ONE))
                    .collect()
            }),
            None => None,
        };
        let file_tangents: Option<Vec<Vec4>> = match tangent_acc {
            Some(_) => reader.read_tangents().map(|t| t.map(Vec4::from).collect()),
            None => None,
        };
        let positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| scene_err(self.path, format!("mesh '{mesh_name}': cannot read POSITION")))?
            .map(Vec3::from)
            .collect();
        let normals: Option<Vec<Vec3>> = if normal_acc.is_some() {
            reader.read_normals().map(|n| n.map(Vec3::from).collect())
        } else {
            None
        };
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let short = |n: usize| n != positions.len();
        if colors
            .as_ref()
            .is_some_and(|c| short(c.len()) || c.iter().any(|v| !v.is_finite()))
        {
            return Err(scene_err(
                self.path,
                format!("mesh '{mesh_name}': COLOR_0 has a different count from POSITION or a non-finite value"),
            ));
        }
        if uv_sets.iter().flatten().any(|u| short(u.len())) || file_tangents.as_ref().is_some_and(|t| short(t.len())) {
            return Err(scene_err(
                self.path,
                format!("mesh '{mesh_name}': TEXCOORD or TANGENT and POSITION have different counts"),
            ));
        }
        if normals.as_ref().is_some_and(|n| n.len() != positions.len()) {
            return Err(scene_err(
                self.path,
                format!("mesh '{mesh_name}': NORMAL and POSITION have different counts"),
            ));
        }
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= positions.len()) {
            return Err(scene_err(
                self.path,
                format!(
                    "mesh '{mesh_name}': index {bad} is out of range ({} vertices)",
                    positions.len()
                ),
            ));
        }
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(scene_err(
                self.path,
                format!("mesh '{mesh_name}': POSITION holds a non-finite value"),
            ));
        }
        let triangles: Vec<[u32; 3]> = match mode {
            Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            // Strips alternate winding; swapping odd triangles keeps every front face counter-clockwise.
            Mode::TriangleStrip => (2..indices.len())
                .map(|i| {
                    if i % 2 == 0 {
                        [indices[i - 2], indices[i - 1], indices[i]]
                    } else {
                        [indices[i - 1], indices[i - 2], indices[i]]
                    }
                })
                .collect(),
            _ => (2..indices.len())
                .map(|i| [indices[0], indices[i - 1], indices[i]])
                .collect(),
        };
        let normal_matrix = Mat3::from_mat4(world).inverse().transpose();
        // A mirroring transform turns counter-clockwise into clockwise; swap two vertices to keep the front face.
        let flip = Mat3::from_mat4(world).determinant() < 0.0;
        let first_triangle = self.scene.triangles.len();
        for [a, b, c] in triangles {
            let (a, b, c) = if flip { (a, c, b) } else { (a, b, c) };
            let v = [a, b, c].map(|i| world.transform_point3(positions[i as usize]));
            let face = (v[1] - v[0]).cross(v[2] - v[0]);
            if face.length_squared() == 0.0 || !face.is_finite() {
                continue; // degenerate: no area, cannot be hit or emit
            }
            let face_n = face.normalize();
            let n = match &normals {
                Some(ns) => [a, b, c].map(|i| {
                    let n = normal_matrix * ns[i as usize];
                    if n.is_finite() && n.length_squared() > 0.0 {
                        n.normalize()
                    } else {
                        face_n
                    }
                }),
                None => [face_n; 3],
            };
            let uv = |set: usize, i: u32| uv_sets[set].as_ref().map_or(Vec2::ZERO, |u| u[i as usize]);
            let texcoords = [a, b, c].map(|i| {
                let (t0, t1) = (uv(0, i), uv(1, i));
                Vec4::new(t0.x, t0.y, t1.x, t1.y)
            });
            let tangents = match &file_tangents {
                // A mirroring transform flips the bitangent relative to cross(normal, tangent).
                Some(ts) => [a, b, c].map(|i| {
                    let t = ts[i as usize];
                    let tw = (Mat3::from_mat4(world) * t.truncate()).normalize_or_zero();
                    let sign = if (t.w < 0.0) != flip { -1.0 } else { 1.0 };
                    tw.extend(sign)
                }),
                None => [Vec4::ZERO; 3],
            };
            self.scene.triangles.push(v);
            self.scene.normals.push(n);
            self.scene.texcoords.push(texcoords);
            self.scene.tangents.push(tangents);
            if let Some(cols) = &colors {
                // The first coloured mesh gives every earlier triangle white.
                let before = self.scene.triangles.len() - 1;
                self.scene.colors.resize(before, [Vec4::ONE; 3]);
                self.scene.colors.push([a, b, c].map(|i| cols[i as usize]));
            } else if !self.scene.colors.is_empty() {
                self.scene.colors.push([Vec4::ONE; 3]);
            }
            self.scene.material_of.push(material);
        }
        if let (Some(r), None) = (mat.normal_texture, &file_tangents) {
            let range = first_triangle..self.scene.triangles.len();
            let set = r.tex_coord as usize;
            let uvs: Vec<[Vec2; 3]> = self.scene.texcoords[range.clone()]
                .iter()
                .map(|t| {
                    t.map(|v| {
                        if set == 0 {
                            Vec2::new(v.x, v.y)
                        } else {
                            Vec2::new(v.z, v.w)
                        }
                    })
                })
                .collect();
            let generated = tangent::generate(
                &self.scene.triangles[range.clone()],
                &self.scene.normals[range.clone()],
                &uvs,
            );
            self.scene.tangents[range].copy_from_slice(&generated);
        }
        Ok(())
    }
}
