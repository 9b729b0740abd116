//! The glTF reader: refuses malformed files with a clear error, then takes in nodes, meshes, materials and lights.
mod animation;
mod draco;
mod estimate;
mod extensions;
mod materials;
mod meshes;
mod meshopt;
mod quantized;
mod scatter;
mod uri;
mod validate;

use super::animation::Trs;
use super::pointer::{LightParts, MaterialParts, Target};
use super::rig::{LightSpec, Node};
use super::{Material, PoseTime, Projection, PunctualKind, Scene};
use crate::error::Error;
use glam::{Mat4, Quat, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::Path;
pub(super) use uri::regular_len;
pub use uri::MAX_FILE_BYTES;
use uri::{import_buffers, UriPolicy};
use validate::{parse, pre_validate, validate};

/// Extensions whose meaning pathwave renders; every other used extension is named in a warning.
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "EXT_mesh_gpu_instancing",
    "EXT_meshopt_compression",
    "EXT_texture_webp",
    // Node transforms, weights and visibility, material factors, lights' colour, intensity and cones, cameras' yfov
    // and ymag (scene::pointer); other pointers are dropped with a warning naming them.
    "KHR_animation_pointer",
    "KHR_draco_mesh_compression",
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_diffuse_roughness",
    "KHR_materials_diffuse_transmission",
    // Rendered by spectral transport, which a scene using it gets by default (Scene::wants_spectral).
    "KHR_materials_dispersion",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    // Archived, but common in older assets: read as a dielectric with F0 the specular colour (materials.rs).
    "KHR_materials_pbrSpecularGlossiness",
    // A draft (glTF pull request 2579; scatter.rs pins the revision): both its volumetric and thin-walled modes, its
    // factors (its textures are named in a warning).
    "KHR_materials_scatter",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_materials_volume",
    // The draft KHR_materials_scatter replaced (glTF pull request 2453), read as that draft defines it.
    "KHR_materials_volume_scatter",
    "KHR_mesh_quantization",
    "KHR_meshopt_compression",
    // Animated through KHR_animation_pointer too.
    "KHR_node_visibility",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    // Metadata (XMP packets): nothing in them changes the image, so reading past them is the whole of supporting them.
    "KHR_xmp",
    "KHR_xmp_json_ld",
];

fn scene_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Scene {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Largest image, in pixels, the reader decodes by default (8192²); `--max-texture-pixels` changes it.
pub const DEFAULT_MAX_TEXTURE_PIXELS: u64 = 8192 * 8192;

/// How a scene is read: which camera, and how far its file may reach.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// The Nth camera in node order (default: the first).
    pub camera: Option<usize>,
    /// Lets buffer and image URIs name files outside the scene's folder (absolute paths, `..`, `file:`).
    pub allow_outside_paths: bool,
    /// Images with more pixels are refused from their header, before they are decoded.
    pub max_texture_pixels: u64,
    /// Host memory the buffers and decoded meshes may take; a file that would need more is refused before they are
    /// read (`--max-memory`).
    pub max_memory: u64,
    /// The KHR_materials_variants variant whose materials the primitives take (by name; default: none, the
    /// primitives' own materials).
    pub variant: Option<String>,
    /// Refuse a missing image file instead of leaving its textures out with a warning (`--strict`).
    pub strict: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            camera: None,
            allow_outside_paths: false,
            max_texture_pixels: DEFAULT_MAX_TEXTURE_PIXELS,
            max_memory: crate::memory::default_max_memory(),
            variant: None,
            strict: false,
        }
    }
}

/// Loads a .gltf or .glb with the default options. `camera` picks the Nth camera in node order (default: the first).
pub fn load(path: &Path, camera: Option<usize>) -> Result<Scene, Error> {
    load_with(
        path,
        &LoadOptions {
            camera,
            ..Default::default()
        },
    )
}

/// Loads a .gltf or .glb. The file must be a regular one of at most `MAX_FILE_BYTES`, checked before it is opened.
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, Error> {
    let bytes = uri::read_regular(path, MAX_FILE_BYTES, "a scene file may hold").map_err(|e| scene_err(path, e))?;
    check_glb_header(path, &bytes)?;
    let (json, blob, untargeted) = parse(path, &bytes)?;
    drop(bytes);
    pre_validate(path, &json)?;
    let tolerated = validate(path, &json)?;
    let document = gltf::Document::from_json_without_validation(json);
    let need = estimate::load_estimate(&document);
    if need > options.max_memory {
        return Err(Error::Limit(format!(
            "{}: reading it would need about {} of host memory (its buffers and decoded meshes), over the limit of {} \
             (--max-memory)",
            path.display(),
            crate::memory::human(need),
            crate::memory::human(options.max_memory)
        )));
    }
    let uris = UriPolicy::new(path.parent().unwrap_or(Path::new(".")), options.allow_outside_paths);
    let mut buffers = import_buffers(path, &uris, &document, blob)?;
    meshopt::decompress(path, &document, &mut buffers)?;
    let document = match draco::used(&document) {
        true => {
            let mut json = document.into_json();
            draco::decompress(path, &mut json, &mut buffers)?;
            gltf::Document::from_json_without_validation(json)
        }
        false => document,
    };
    let mut scene = Scene {
        path: path.to_path_buf(),
        warnings: tolerated,
        ..Default::default()
    };
    Loader {
        path,
        document: &document,
        uris: &uris,
        max_texture_pixels: options.max_texture_pixels,
        image_memory: options.max_memory.saturating_sub(need),
        buffers: &buffers,
        scene: &mut scene,
        cameras: 0,
        texture_map: Default::default(),
        image_map: Default::default(),
        gloss_map: Default::default(),
        mesh_map: Default::default(),
        variant: None,
        strict: options.strict,
        missing_textures: Default::default(),
        skipped_primitives: 0,
        untargeted,
    }
    .run(&document, options.camera, options.variant.as_deref())?;
    Ok(scene)
}

/// Refuses a GLB whose header is truncated or declares a length other than the file's; a JSON glTF passes.
fn check_glb_header(path: &Path, bytes: &[u8]) -> Result<(), Error> {
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
    // The header's length is the whole file's (glTF 2.0, "Binary glTF Layout"); bytes past it are no part of the
    // asset, and a shorter file is truncated. The Khronos validator calls either an error (GLB_LENGTH_MISMATCH).
    if bytes.starts_with(b"glTF") {
        let declared = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize;
        if declared != bytes.len() {
            return Err(scene_err(
                path,
                format!(
                    "not a valid glTF file: the GLB header declares a length of {declared} bytes, but the file holds {}",
                    bytes.len()
                ),
            ));
        }
    }
    Ok(())
}

struct Loader<'a> {
    path: &'a Path,
    document: &'a gltf::Document,
    /// Resolves image URIs inside the scene's folder.
    uris: &'a UriPolicy,
    max_texture_pixels: u64,
    /// Host bytes --max-memory leaves for the images not yet decoded (after the buffers and meshes, `load_estimate`).
    image_memory: u64,
    buffers: &'a [gltf::buffer::Data],
    scene: &'a mut Scene,
    /// Cameras placed so far, for the warning when there is none.
    cameras: usize,
    /// glTF texture index to scene texture (None: no readable image); glTF image index to scene image.
    texture_map: HashMap<usize, Option<usize>>,
    image_map: HashMap<usize, usize>,
    /// Roughness textures made from specular-glossiness textures: (source texture, glossiness bits) to texture.
    gloss_map: HashMap<(usize, u32), usize>,
    /// glTF mesh index to scene mesh: a mesh is read once, at the first node that places it.
    mesh_map: HashMap<usize, usize>,
    /// The selected KHR_materials_variants variant's index.
    variant: Option<u32>,
    /// `LoadOptions::strict`, and the glTF textures left out because their image file is missing (already warned).
    strict: bool,
    missing_textures: HashSet<usize>,
    /// Primitives skipped for their mode (points, lines), for the error when nothing else is left.
    skipped_primitives: usize,
    /// Animation channels without a node (KHR_animation_pointer's among them), taken out before parsing.
    untargeted: Vec<validate::Untargeted>,
}

impl Loader<'_> {
    fn warn(&mut self, w: String) {
        if !self.scene.warnings.contains(&w) {
            self.scene.warnings.push(w);
        }
    }

    fn run(&mut self, doc: &gltf::Document, camera: Option<usize>, variant: Option<&str>) -> Result<(), Error> {
        for ext in doc.extensions_used() {
            self.scene.extensions_used.push(ext.to_string());
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                self.warn(format!("extension {ext} is not supported yet and is ignored"));
            }
        }
        self.select_variant(doc, variant)?;
        for m in doc.materials() {
            self.material(&m)?;
        }
        let default_material = self.scene.materials.len() as u32;
        self.scene.materials.push(Material::default());

        let visited = self.place_nodes(doc, default_material)?;

        self.scene.rig.skins = doc.skins().map(|s| self.skin(&s)).collect::<Result<_, _>>()?;
        self.check_skins(&visited)?;
        self.scene.rig.animations = self.animations(doc)?;
        let animated_materials = (self.scene.rig.animations.iter())
            .flat_map(|a| &a.channels)
            .any(|c| matches!(c.target, Target::Material(..)));
        if animated_materials {
            // Each pose starts from the file's materials; the parts of their emission and texture transforms are
            // kept apart so that a channel may drive each.
            let parts = (doc.as_json().materials.iter())
                .map(|m| MaterialParts::from_json(&serde_json::to_value(m).unwrap_or_default()))
                .chain(std::iter::once(MaterialParts::from_json(&serde_json::Value::Null)))
                .collect();
            self.scene.rig.materials = Some((self.scene.materials.clone(), parts));
        }
        self.scene.rig.file_meshes = self.scene.meshes.len();
        self.scene.rig.camera_choice = camera;
        // With animations, at their start (time 0, every channel), as viewers show a file before it plays.
        self.scene.pose(PoseTime::default())?;
        if self.cameras == 0 {
            self.warn("the file has no camera; using one that frames the scene".into());
        }
        self.refuse_empty(doc)
    }

    /// Lists the file's KHR_materials_variants variants and selects `variant` among them; refused when it is not one.
    fn select_variant(&mut self, doc: &gltf::Document, variant: Option<&str>) -> Result<(), Error> {
        self.scene.variants = doc
            .variants()
            .map(|v| v.map(|v| v.name().to_string()).collect())
            .unwrap_or_default();
        if let Some(name) = variant {
            let i = self.scene.variants.iter().position(|v| v == name).ok_or_else(|| {
                let known = if self.scene.variants.is_empty() {
                    "the file has no KHR_materials_variants variants".to_string()
                } else {
                    format!("its variants are '{}'", self.scene.variants.join("', '"))
                };
                scene_err(
                    self.path,
                    format!("--variant '{name}' is not a variant of this file: {known}"),
                )
            })?;
            self.variant = Some(i as u32);
            self.scene.variant = Some(i);
        }
        Ok(())
    }

    /// Records every node's rest transform, places the scene's trees (the default scene's, else the first scene's,
    /// else every root's), then walks the other trees for their joints; returns the nodes visited.
    fn place_nodes(&mut self, doc: &gltf::Document, default_material: u32) -> Result<HashSet<usize>, Error> {
        self.scene.rig.nodes = doc.nodes().map(|n| rest_node(&n)).collect();
        let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
            Some(s) => s.nodes().collect(),
            None => {
                let children: HashSet<usize> = doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
                doc.nodes().filter(|n| !children.contains(&n.index())).collect()
            }
        };
        let mut visited = HashSet::new();
        self.walk(roots, true, default_material, &mut visited)?;
        // Joints may sit outside the rendered scene: the other trees give them their world transforms.
        let children: HashSet<usize> = doc.nodes().flat_map(|n| n.children().map(|c| c.index())).collect();
        let others: Vec<gltf::Node> = (doc.nodes())
            .filter(|n| !visited.contains(&n.index()) && !children.contains(&n.index()))
            .collect();
        self.walk(others, false, default_material, &mut visited)?;
        Ok(visited)
    }

    /// Refuses a scene with nothing to render, saying why when the file shows it.
    fn refuse_empty(&self, doc: &gltf::Document) -> Result<(), Error> {
        if self.scene.is_empty() {
            let scene = doc.default_scene().or_else(|| doc.scenes().next());
            let why = match scene {
                Some(s) if s.nodes().len() == 0 => format!(": scene {} has no nodes", s.index()),
                _ if self.skipped_primitives > 0 => format!(
                    ": its {} primitive{} {} points or lines, which pathwave skips (only triangles render)",
                    self.skipped_primitives,
                    if self.skipped_primitives == 1 { "" } else { "s" },
                    if self.skipped_primitives == 1 { "is" } else { "are" },
                ),
                _ => String::new(),
            };
            return Err(scene_err(
                self.path,
                format!("the scene has no triangles to render{why}"),
            ));
        }
        Ok(())
    }

    /// Depth-first in node order from `roots`, on an explicit stack so that a deep hierarchy cannot overflow the
    /// thread's stack: each node recorded in the rig's order with its parent. `placed` nodes are part of the scene.
    fn walk(
        &mut self,
        roots: Vec<gltf::Node>,
        placed: bool,
        default_material: u32,
        visited: &mut HashSet<usize>,
    ) -> Result<(), Error> {
        let mut stack: Vec<(gltf::Node, Option<usize>)> = roots.into_iter().rev().map(|n| (n, None)).collect();
        while let Some((node, parent)) = stack.pop() {
            if !visited.insert(node.index()) {
                return Err(scene_err(
                    self.path,
                    format!(
                        "node {} appears twice in the hierarchy (a cycle or a shared child)",
                        node.index()
                    ),
                ));
            }
            self.scene.rig.nodes[node.index()].parent = parent;
            self.scene.rig.order.push(node.index());
            // KHR_node_visibility hides whole trees: `pose` hides what is below a hidden node.
            self.scene.rig.nodes[node.index()].visible = self.visible(&node)?;
            if placed {
                self.node(&node, default_material)?;
            }
            let children: Vec<gltf::Node> = node.children().collect();
            stack.extend(children.into_iter().rev().map(|c| (c, Some(node.index()))));
        }
        Ok(())
    }

    /// Every skin's joints have world transforms, and every skinned mesh names only joints its skin has.
    fn check_skins(&self, visited: &HashSet<usize>) -> Result<(), Error> {
        for (s, skin) in self.scene.rig.skins.iter().enumerate() {
            if let Some(j) = skin.joints.iter().find(|j| !visited.contains(j)) {
                return Err(scene_err(
                    self.path,
                    format!("skin {s}: joint node {j} is in a cycle, outside every tree of nodes"),
                ));
            }
        }
        for (i, node) in self.scene.rig.nodes.iter().enumerate().filter(|(_, n)| n.placed) {
            let (Some(m), Some(s)) = (node.mesh, node.skin) else {
                continue;
            };
            let joints = self.scene.rig.skins[s].joints.len();
            let mesh = &self.scene.meshes[m];
            let most = (mesh.primitives.iter())
                .flat_map(|p| &p.skin)
                .flat_map(|set| set.joints.iter().flatten())
                .max();
            if let Some(&j) = most.filter(|&&j| j as usize >= joints) {
                return Err(scene_err(
                    self.path,
                    format!(
                        "node {i}: mesh '{}' names joint {j}, but skin {s} has {joints} joints",
                        mesh.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// KHR_node_visibility's `visible` of this node alone (true without the extension); refused when not a boolean.
    fn visible(&self, node: &gltf::Node) -> Result<bool, Error> {
        let Some(ext) = node.extensions().and_then(|e| e.get("KHR_node_visibility")) else {
            return Ok(true);
        };
        match ext.get("visible") {
            None => Ok(true),
            Some(serde_json::Value::Bool(b)) => Ok(*b),
            Some(v) => Err(scene_err(
                self.path,
                format!(
                    "node {}: KHR_node_visibility's visible is {v}, not true or false",
                    node.index()
                ),
            )),
        }
    }

    /// Takes in one placed node's light, camera, mesh and skin; `pose` places them (those of a hidden node too:
    /// an animation may show it).
    fn node(&mut self, node: &gltf::Node, default_material: u32) -> Result<(), Error> {
        let i = node.index();
        self.scene.rig.nodes[i].placed = true;
        if let Some(cam) = node.camera() {
            self.scene.rig.nodes[i].camera = self.camera(&cam);
        }
        if let Some(light) = node.light() {
            self.scene.rig.nodes[i].light = Some(self.punctual(&light)?);
        }
        if let Some(mesh) = node.mesh() {
            // Read at the first node that places it, so its warnings and errors come in node order as before.
            let index = match self.mesh_map.get(&mesh.index()) {
                Some(&i) => i,
                None => {
                    let m = self.mesh(&mesh, default_material)?;
                    self.scene.meshes.push(m);
                    self.mesh_map.insert(mesh.index(), self.scene.meshes.len() - 1);
                    self.scene.meshes.len() - 1
                }
            };
            let targets = mesh.primitives().map(|p| p.morph_targets().count()).max().unwrap_or(0);
            let instancing = self.instancing(node)?;
            let n = &mut self.scene.rig.nodes[i];
            n.instancing = instancing;
            n.mesh = Some(index);
            n.skin = node.skin().map(|s| s.index());
            if targets > 0 {
                let weights = node.weights().or(mesh.weights()).unwrap_or(&[]);
                n.weights = (0..targets).map(|t| weights.get(t).copied().unwrap_or(0.0)).collect();
            }
        }
        Ok(())
    }

    /// A camera's index and projection; one whose projection cannot form an image is ignored with a warning.
    fn camera(&mut self, cam: &gltf::Camera) -> Option<(usize, Projection)> {
        let (projection, problem) = match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let yfov = p.yfov();
                (
                    Projection::Perspective { yfov },
                    (!(yfov > 0.0 && yfov < std::f32::consts::PI)).then(|| format!("yfov {yfov} is out of range")),
                )
            }
            // glTF says ymag should not be negative and must not be zero; a negative one is read as its size.
            gltf::camera::Projection::Orthographic(o) => {
                let ymag = o.ymag().abs();
                (
                    Projection::Orthographic { ymag },
                    (!(ymag.is_normal() && ymag < f32::MAX))
                        .then(|| format!("ymag {} is zero or not finite", o.ymag())),
                )
            }
        };
        match problem {
            None => {
                self.cameras += 1;
                Some((cam.index(), projection))
            }
            Some(why) => {
                self.warn(format!("camera {}: {why} and the camera is ignored", cam.index()));
                None
            }
        }
    }

    fn punctual(&mut self, light: &gltf::khr_lights_punctual::Light) -> Result<LightSpec, Error> {
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
        if intensity.max_element() > crate::scene::RADIANCE_MAX {
            return Err(scene_err(
                self.path,
                format!(
                    "light '{name}': its intensity {intensity} (color times intensity) is above the limit of {:e} \
                     per channel",
                    crate::scene::RADIANCE_MAX
                ),
            ));
        }
        if light.range().is_some() {
            self.warn(format!(
                "light '{name}': range is ignored; light falls off with the inverse square of distance"
            ));
        }
        let color = Vec3::from(light.color());
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
        Ok(LightSpec {
            light: light.index(),
            parts: LightParts {
                color,
                intensity: light.intensity(),
                kind,
            },
        })
    }
}

/// A node before any placing: the file's local transform both composed (as gltf composes it) and decomposed.
fn rest_node(node: &gltf::Node) -> Node {
    let rest = Mat4::from_cols_array_2d(&node.transform().matrix());
    let trs = match node.transform() {
        gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        } => Trs {
            translation: Vec3::from(translation),
            rotation: Quat::from_array(rotation),
            scale: Vec3::from(scale),
        },
        // glTF forbids animating a node given by matrix; should a file do it, the channels replace the parts.
        gltf::scene::Transform::Matrix { .. } => {
            let (scale, rotation, translation) = rest.to_scale_rotation_translation();
            Trs {
                translation,
                rotation,
                scale,
            }
        }
    };
    Node {
        parent: None,
        rest,
        trs,
        placed: false,
        visible: true,
        mesh: None,
        skin: None,
        camera: None,
        light: None,
        weights: Vec::new(),
        instancing: Vec::new(),
    }
}
