//! The glTF reader: refuses malformed files with a clear error, then takes in nodes, meshes, materials and lights.
mod materials;
mod meshes;
mod uri;
mod validate;

use super::{Camera, Instance, Material, PunctualKind, PunctualLight, Scene};
use crate::error::Error;
use glam::{Mat4, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::Path;
pub(super) use uri::regular_len;
pub use uri::MAX_FILE_BYTES;
use uri::{import_buffers, UriPolicy};
use validate::{parse, pre_validate, validate};

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

/// Largest image, in pixels, the reader decodes by default (8192²); `--max-texture-pixels` changes it.
pub const DEFAULT_MAX_TEXTURE_PIXELS: u64 = 8192 * 8192;

/// How a scene is read: which camera, and how far its file may reach.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// The Nth perspective camera in node order (default: the first).
    pub camera: Option<usize>,
    /// Lets buffer and image URIs name files outside the scene's folder (absolute paths, `..`, `file:`).
    pub allow_outside_paths: bool,
    /// Images with more pixels are refused from their header, before they are decoded.
    pub max_texture_pixels: u64,
    /// Host memory the buffers and decoded meshes may take; a file that would need more is refused before they are
    /// read (`--max-memory`).
    pub max_memory: u64,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            camera: None,
            allow_outside_paths: false,
            max_texture_pixels: DEFAULT_MAX_TEXTURE_PIXELS,
            max_memory: crate::memory::default_max_memory(),
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
    drop(bytes);
    pre_validate(path, &json)?;
    validate(path, &json)?;
    let document = gltf::Document::from_json_without_validation(json);
    let need = crate::memory::load_estimate(&document);
    if need > options.max_memory {
        return Err(scene_err(
            path,
            format!(
                "reading it would need about {} of host memory (its buffers and decoded meshes), over the limit \
                 of {} (--max-memory)",
                crate::memory::human(need),
                crate::memory::human(options.max_memory)
            ),
        ));
    }
    let uris = UriPolicy::new(path.parent().unwrap_or(Path::new(".")), options.allow_outside_paths);
    let buffers = import_buffers(path, &uris, &document, blob)?;
    let mut scene = Scene {
        path: path.to_path_buf(),
        ..Default::default()
    };
    Loader {
        path,
        uris: &uris,
        max_texture_pixels: options.max_texture_pixels,
        buffers: &buffers,
        scene: &mut scene,
        cameras: Vec::new(),
        texture_map: Default::default(),
        image_map: Default::default(),
        mesh_map: Default::default(),
    }
    .run(&document, options.camera)?;
    Ok(scene)
}

struct Loader<'a> {
    path: &'a Path,
    /// Resolves image URIs inside the scene's folder.
    uris: &'a UriPolicy,
    max_texture_pixels: u64,
    buffers: &'a [gltf::buffer::Data],
    scene: &'a mut Scene,
    cameras: Vec<Camera>,
    /// glTF texture index to scene texture (None: no readable image); glTF image index to scene image.
    texture_map: HashMap<usize, Option<usize>>,
    image_map: HashMap<usize, usize>,
    /// glTF mesh index to scene mesh: a mesh is read once, at the first node that places it.
    mesh_map: HashMap<usize, usize>,
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
        if self.scene.is_empty() {
            return Err(scene_err(self.path, "the scene has no triangles to render"));
        }
        Ok(())
    }

    /// Takes in one node's light, camera and mesh (as an instance); returns its world transform for its children.
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
            self.camera(&cam, world)?;
        }
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                self.warn("skins are ignored; skinned meshes render at their bind pose".into());
            }
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
            self.scene.instances.push(Instance {
                mesh: index,
                world_from_object: world,
            });
        }
        Ok(world)
    }

    fn camera(&mut self, cam: &gltf::Camera, world: Mat4) -> Result<(), Error> {
        match cam.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let yfov = p.yfov();
                if let Err(why) = Camera::check_transform(&world) {
                    return Err(scene_err(
                        self.path,
                        format!(
                            "camera {}: its node's world transform {why}, so it has no view",
                            cam.index()
                        ),
                    ));
                }
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
        Ok(())
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
}
