//! The file's node hierarchy with its animations, skins and morph targets, and `Scene::pose`, which places the
//! scene at a time: instances, deformed meshes, cameras and lights.
use super::animation::{Animation, Property, Trs};
use super::pointer::{self, LightParts, MaterialParts, Target};
use super::{Camera, Instance, Mesh, Primitive, Projection, PunctualLight, Scene};
use crate::error::Error;
use glam::{Mat3, Mat4, Vec3, Vec4};

/// A light as its node carries it (its glTF index, colour, intensity and cone); `pose` places it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSpec {
    pub light: usize,
    pub parts: LightParts,
}

/// One glTF node, as the loader took it in.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// The parent, which `Rig::order` lists before this node.
    pub parent: Option<usize>,
    /// The file's local transform, composed as gltf composes it: what every node no channel drives keeps, so a
    /// file without animation places its meshes exactly as before animation was read.
    pub rest: Mat4,
    /// The file's translation, rotation and scale (decomposed from `matrix` when the file gives one), which
    /// channels replace one by one.
    pub trs: Trs,
    /// Whether the node is part of the rendered scene (otherwise it is only reachable as a joint).
    pub placed: bool,
    /// KHR_node_visibility's `visible` of this node alone: false hides its mesh and light and every node's below
    /// it (cameras stay). Animated through KHR_animation_pointer.
    pub visible: bool,
    /// Index into `Scene::meshes`.
    pub mesh: Option<usize>,
    pub skin: Option<usize>,
    /// A camera: its glTF index and projection.
    pub camera: Option<(usize, Projection)>,
    pub light: Option<LightSpec>,
    /// The node's morph-target weights, or its mesh's defaults (empty without targets).
    pub weights: Vec<f32>,
    /// EXT_mesh_gpu_instancing: the mesh is placed once per transform (relative to the node), not once.
    pub instancing: Vec<Mat4>,
}

/// A skeleton: joints (indices into `Rig::nodes`) and the inverse bind matrix of each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Skin {
    pub name: String,
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// What the scene is posed with: every channel of the file (`animation` None), or one animation's, at `time`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PoseTime {
    pub time: f32,
    pub animation: Option<usize>,
}

/// The nodes and what moves them.
#[derive(Clone, Debug, Default)]
pub struct Rig {
    /// By glTF node index.
    pub nodes: Vec<Node>,
    /// Every node with a world transform, parents first: the placed ones in the file's depth-first node order
    /// (the order instances, cameras and lights come in), then those only skins reach.
    pub order: Vec<usize>,
    pub animations: Vec<Animation>,
    pub skins: Vec<Skin>,
    /// `Scene::meshes[..file_meshes]` are the file's; `pose` appends the deformed (skinned or morphed) ones.
    pub file_meshes: usize,
    /// The Nth camera in node order that `pose` makes the scene's camera (default: the first).
    pub camera_choice: Option<usize>,
    /// A command-line camera that replaces (or changes the projection of) the chosen one in every pose.
    pub camera_override: Option<super::CameraOverride>,
    /// What the scene is posed with now.
    pub posed: PoseTime,
    /// The file's materials and their emission's parts, kept when an animation drives materials
    /// (KHR_animation_pointer): each pose starts from them.
    pub materials: Option<(Vec<super::Material>, Vec<MaterialParts>)>,
}

impl Rig {
    /// Whether a pose at another time can differ: the file has animations.
    pub fn animated(&self) -> bool {
        !self.animations.is_empty()
    }

    /// The animation `--animation` names, by index or by name.
    pub fn find_animation(&self, which: &str) -> Result<usize, String> {
        if let Some(i) = self.animations.iter().position(|a| a.name == which) {
            return Ok(i);
        }
        match which.parse::<usize>() {
            Ok(i) if i < self.animations.len() => Ok(i),
            _ => {
                let names: Vec<String> = (self.animations.iter().enumerate())
                    .map(|(i, a)| {
                        if a.name.is_empty() {
                            format!("{i}")
                        } else {
                            format!("{i} '{}'", a.name)
                        }
                    })
                    .collect();
                Err(if names.is_empty() {
                    format!("--animation {which}: the file has no animations")
                } else {
                    format!("--animation {which}: the file's animations are {}", names.join(", "))
                })
            }
        }
    }

    /// The first and last key time of the animations a pose plays ((0, 0) without any).
    pub fn range(&self, animation: Option<usize>) -> (f32, f32) {
        let ranges: Vec<(f32, f32)> = match animation {
            Some(a) => vec![self.animations[a].range()],
            None => self.animations.iter().map(Animation::range).collect(),
        };
        (ranges.iter().copied())
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
            .unwrap_or((0.0, 0.0))
    }
}

impl Scene {
    /// Places the scene as it is at `pose`: node transforms and morph weights from the channels, then instances,
    /// skinned and morphed meshes, cameras and lights, replacing those of the previous pose. Nodes no channel drives
    /// keep the file's transform. Fails only on a camera whose animated transform has no view.
    pub fn pose(&mut self, pose: PoseTime) -> Result<(), Error> {
        self.motion = None;
        // A scene built in code (tests, benchmarks) has no nodes: its instances are what it is.
        if self.rig.nodes.is_empty() {
            return Ok(());
        }
        let mut placed = self.place(pose, pose.time)?;
        if let Some(materials) = placed.materials.take() {
            self.materials = materials;
        }
        self.meshes.truncate(self.rig.file_meshes);
        self.meshes.extend(placed.meshes);
        self.instances = placed.instances;
        self.punctual = placed.punctual;
        self.camera_count = placed.camera_count;
        self.camera = placed.camera;
        self.rig.posed = pose;
        Ok(())
    }

    /// `pose` at the shutter's opening, `pose.time`, and the keys of the motion while it is open for `shutter`
    /// seconds: the scene placed at MOTION_SEGMENTS more evenly spaced times up to `pose.time + shutter`. A scene
    /// that does not move over that time gets no motion, and renders as a still one (at no cost).
    pub fn pose_shutter(&mut self, pose: PoseTime, shutter: f32) -> Result<(), Error> {
        self.pose(pose)?;
        if shutter <= 0.0 || !self.rig.animated() {
            return Ok(());
        }
        let segments = crate::constants::MOTION_SEGMENTS;
        let mut keys = Vec::with_capacity(segments as usize);
        for k in 1..=segments {
            let time = pose.time + shutter * k as f32 / segments as f32;
            keys.push(self.place(PoseTime { time, ..pose }, pose.time)?);
        }
        let moves = keys.iter().any(|key| {
            key.instances != self.instances
                || key.camera != self.camera
                || key.meshes[..] != self.meshes[self.rig.file_meshes..]
        });
        if moves {
            self.motion = Some(Motion { shutter, keys });
        }
        Ok(())
    }

    /// The mesh instance `i` of motion key `key` places (key 0: the scene's own).
    pub fn key_mesh(&self, key: usize, mesh: usize) -> &Mesh {
        match (key, &self.motion) {
            (k, Some(m)) if k > 0 && mesh >= self.rig.file_meshes => &m.keys[k - 1].meshes[mesh - self.rig.file_meshes],
            _ => &self.meshes[mesh],
        }
    }

    /// The scene as `pose` places it, without changing it; visibility, materials, lights and projections as they
    /// are at time `still`.
    fn place(&self, pose: PoseTime, still: f32) -> Result<Placed, Error> {
        let rig = &self.rig;
        let Sampled {
            trs,
            weights,
            mut visible,
            materials,
            lights,
            projections,
        } = self.sample_channels(pose, still);
        let world = world_transforms(rig, &trs, &mut visible);

        let mut instances = Vec::new();
        let mut posed_meshes = Vec::new();
        let mut cameras = Vec::new();
        let mut punctual = Vec::new();
        let file_meshes = rig.file_meshes;
        for &i in rig.order.iter().filter(|&&i| rig.nodes[i].placed) {
            let node = &rig.nodes[i];
            let w = world[i];
            if !w.is_finite() {
                return Err(self.pose_err(pose, format!("node {i} has a non-finite transform")));
            }
            if let Some(light) = node.light.filter(|_| visible[i]) {
                let (kind, intensity) = lights.get(&light.light).unwrap_or(&light.parts).resolved();
                punctual.push(PunctualLight {
                    kind,
                    position: w.transform_point3(Vec3::ZERO),
                    direction: w.transform_vector3(-Vec3::Z).normalize_or(-Vec3::Z),
                    intensity,
                });
            }
            if let Some((index, projection)) = node.camera {
                cameras.push(self.place_camera(pose, index, projection, &projections, w)?);
            }
            let Some(m) = node.mesh.filter(|_| visible[i]) else {
                continue;
            };
            let node_weights = weights[i].as_deref().unwrap_or(&node.weights);
            let Some(posed) = self.deformed(node, m, node_weights, &world) else {
                place_instances(&mut instances, node, m, w);
                continue;
            };
            posed_meshes.push(posed);
            // glTF: a skinned mesh is placed by its joints alone, its own node's transform is ignored.
            let w = if node.skin.is_some() { Mat4::IDENTITY } else { w };
            place_instances(&mut instances, node, file_meshes + posed_meshes.len() - 1, w);
        }
        let camera = self.chosen_camera(&cameras)?;
        Ok(Placed {
            instances,
            meshes: posed_meshes,
            camera,
            camera_count: cameras.len(),
            punctual,
            materials: materials.map(|(m, _)| m),
        })
    }

    /// What the channels `pose` plays set: node transforms and morph weights at `pose.time` (None where no channel
    /// drives them), and visibility, materials (remade from their parts), lights and projections at `still`.
    fn sample_channels(&self, pose: PoseTime, still: f32) -> Sampled {
        let rig = &self.rig;
        let mut trs: Vec<Option<Trs>> = vec![None; rig.nodes.len()];
        let mut weights: Vec<Option<Vec<f32>>> = vec![None; rig.nodes.len()];
        let playing: Vec<&Animation> = match pose.animation {
            Some(a) => vec![&rig.animations[a]],
            None => rig.animations.iter().collect(),
        };
        let mut visible: Vec<bool> = rig.nodes.iter().map(|n| n.visible).collect();
        let mut materials = rig.materials.clone();
        let mut lights: std::collections::HashMap<usize, LightParts> = Default::default();
        let mut projections: Vec<(usize, pointer::CameraValue, f32)> = Vec::new();
        let mut value = Vec::new();
        // In file order: where two animations drive the same property, the later one wins.
        for channel in playing.iter().flat_map(|a| &a.channels) {
            value.resize(channel.sampler.width, 0.0);
            // Over the shutter, only transforms and weights move: what else a channel drives holds its value at
            // the frame's time (`still`), so every key places the same instances.
            let time = if let Target::Node(..) = channel.target {
                pose.time
            } else {
                still
            };
            channel.sampler.sample(time, channel.target.rotation(), &mut value);
            match channel.target {
                Target::Node(n, Property::Weights) => weights[n] = Some(value.clone()),
                Target::Node(n, p) => trs[n].get_or_insert(rig.nodes[n].trs).set(p, &value),
                Target::Visible(n) => visible[n] = value[0] != 0.0,
                Target::Material(m, v) => {
                    if let Some((materials, parts)) = materials.as_mut() {
                        pointer::set_material(&mut materials[m], &mut parts[m], v, &value);
                    }
                }
                Target::Light(l, v) => {
                    if let Some(spec) = rig.nodes.iter().find_map(|n| n.light.filter(|s| s.light == l)) {
                        lights.entry(l).or_insert(spec.parts).set(v, &value);
                    }
                }
                Target::Camera(c, v) => projections.push((c, v, value[0])),
            }
        }
        if let Some((materials, parts)) = materials.as_mut() {
            for (m, p) in materials.iter_mut().zip(parts.iter()) {
                p.apply(m);
            }
        }
        Sampled {
            trs,
            weights,
            visible,
            materials,
            lights,
            projections,
        }
    }

    /// Camera `index` at world transform `w`, with the projection channels set (`projections`) in place of the
    /// file's; an error when `w` gives it no view.
    fn place_camera(
        &self,
        pose: PoseTime,
        index: usize,
        mut projection: Projection,
        projections: &[(usize, pointer::CameraValue, f32)],
        w: Mat4,
    ) -> Result<Camera, Error> {
        for &(_, v, x) in projections.iter().filter(|p| p.0 == index) {
            projection = match (projection, v) {
                // The loader's range: a view narrower than 0 or wider than pi forms no image.
                (Projection::Perspective { .. }, pointer::CameraValue::Yfov) => Projection::Perspective {
                    yfov: x.clamp(1e-4, std::f32::consts::PI - 1e-4),
                },
                (Projection::Orthographic { .. }, pointer::CameraValue::Ymag) => Projection::Orthographic {
                    ymag: x.abs().max(1e-6),
                },
                (p, _) => p,
            };
        }
        if let Err(why) = Camera::check_transform(&w) {
            return Err(self.pose_err(
                pose,
                format!("camera {index}: its node's world transform {why}, so it has no view"),
            ));
        }
        Ok(Camera {
            world_from_camera: w,
            projection,
        })
    }

    /// Mesh `m` as `node`'s skin (its joints where `world` puts them) and morph weights `node_weights` deform it,
    /// or None when neither does and instances place the file's mesh itself.
    fn deformed(&self, node: &Node, m: usize, node_weights: &[f32], world: &[Mat4]) -> Option<Mesh> {
        let rig = &self.rig;
        let mesh = &self.meshes[m];
        let morphing =
            mesh.primitives.iter().any(|p| !p.morph_targets.is_empty()) && node_weights.iter().any(|&w| w != 0.0);
        let skin = node.skin.map(|s| &rig.skins[s]);
        if skin.is_none() && !morphing {
            return None;
        }
        let mut posed = mesh.clone();
        for p in &mut posed.primitives {
            if morphing {
                morph(p, node_weights);
            }
            if let Some(skin) = skin {
                let joints: Vec<Mat4> = (skin.joints.iter().zip(&skin.inverse_bind))
                    .map(|(&j, ibm)| world[j] * *ibm)
                    .collect();
                skin_primitive(p, &joints);
            }
            p.morph_targets.clear();
            p.skin.clear();
        }
        Some(posed)
    }

    /// The camera `--camera` picks among `cameras` (default: the first), as a command-line camera changes it; an
    /// error when the file has fewer.
    fn chosen_camera(&self, cameras: &[Camera]) -> Result<Option<Camera>, Error> {
        let camera = match self.rig.camera_choice {
            None => cameras.first().copied(),
            Some(i) => Some(*cameras.get(i).ok_or_else(|| Error::Scene {
                path: self.path.clone(),
                message: format!("--camera {i}: the file has {} camera(s)", cameras.len()),
            })?),
        };
        let camera = match self.rig.camera_override {
            Some(o) => o.apply(camera),
            None => camera,
        };
        Ok(camera)
    }

    fn pose_err(&self, pose: PoseTime, message: String) -> Error {
        let at = if self.rig.animated() {
            format!(" at time {} s", pose.time)
        } else {
            String::new()
        };
        Error::Scene {
            path: self.path.clone(),
            message: format!("{message}{at}"),
        }
    }
}

/// What the channels of one pose set, by node (transforms, morph weights, visibility), by material, by glTF light
/// and by glTF camera; see `Scene::sample_channels`.
struct Sampled {
    trs: Vec<Option<Trs>>,
    weights: Vec<Option<Vec<f32>>>,
    visible: Vec<bool>,
    materials: Option<(Vec<super::Material>, Vec<MaterialParts>)>,
    lights: std::collections::HashMap<usize, LightParts>,
    projections: Vec<(usize, pointer::CameraValue, f32)>,
}

/// Every node's world transform (the identity for those `Rig::order` leaves out), from `trs` where a channel set
/// it and the file's rest transform elsewhere. Hides in `visible` every node below a hidden one.
fn world_transforms(rig: &Rig, trs: &[Option<Trs>], visible: &mut [bool]) -> Vec<Mat4> {
    let mut world = vec![Mat4::IDENTITY; rig.nodes.len()];
    for &i in &rig.order {
        let node = &rig.nodes[i];
        let local = trs[i].map_or(node.rest, |t| t.matrix());
        let parent = node.parent.map_or(Mat4::IDENTITY, |p| world[p]);
        world[i] = parent * local;
        // Parents come first: a node is shown when it and every node above it are.
        visible[i] &= node.parent.is_none_or(|p| visible[p]);
    }
    world
}

/// Places `mesh` at `w` in `instances`: once, or with EXT_mesh_gpu_instancing once per `node`'s instance transform,
/// each after `w`.
fn place_instances(instances: &mut Vec<Instance>, node: &Node, mesh: usize, w: Mat4) {
    if node.instancing.is_empty() {
        instances.push(Instance {
            mesh,
            world_from_object: w,
        });
    }
    for local in &node.instancing {
        instances.push(Instance {
            mesh,
            world_from_object: w * *local,
        });
    }
}

/// Adds each morph target's displacements times its weight to the base vertices (glTF's morphing equation).
fn morph(p: &mut Primitive, weights: &[f32]) {
    let targets = std::mem::take(&mut p.morph_targets);
    for (target, &w) in targets.iter().zip(weights) {
        if w == 0.0 {
            continue;
        }
        if let Some(d) = &target.positions {
            for (v, d) in p.positions.iter_mut().zip(d) {
                *v += *d * w;
            }
        }
        if let (Some(ns), Some(d)) = (&mut p.normals, &target.normals) {
            for (n, d) in ns.iter_mut().zip(d) {
                *n += *d * w;
            }
        }
        if let (Some(ts), Some(d)) = (&mut p.tangents, &target.tangents) {
            for (t, d) in ts.iter_mut().zip(d) {
                *t += d.extend(0.0) * w;
            }
        }
    }
    // Placing normalises normals and tangents again; a morphed one of length 0 falls back to the face normal.
    p.morph_targets = targets;
}

/// Moves every vertex by its joints' matrices (joint world transform times inverse bind), blended by its weights,
/// into world space. Normals take the blend's inverse transpose, tangents the blend itself; a mirroring blend
/// swaps a triangle's winding so its front face stays counter-clockwise.
fn skin_primitive(p: &mut Primitive, joints: &[Mat4]) {
    let n = p.positions.len();
    let mut blends = vec![Mat4::ZERO; n];
    let mut totals = vec![0.0f32; n];
    for set in &p.skin {
        for (v, (js, ws)) in set.joints.iter().zip(&set.weights).enumerate() {
            for k in 0..4 {
                if ws[k] != 0.0 {
                    blends[v] += joints[js[k] as usize] * ws[k];
                    totals[v] += ws[k];
                }
            }
        }
    }
    // glTF's weights sum to 1; quantised ones only nearly, so they are normalised. A vertex no joint holds stays
    // where the mesh puts it.
    for (m, &total) in blends.iter_mut().zip(&totals) {
        *m = if total > 0.0 {
            *m * (1.0 / total)
        } else {
            Mat4::IDENTITY
        };
    }
    for (v, m) in p.positions.iter_mut().zip(&blends) {
        *v = m.transform_point3(*v);
    }
    if let Some(ns) = &mut p.normals {
        for (nrm, m) in ns.iter_mut().zip(&blends) {
            *nrm = Mat3::from_mat4(*m).inverse().transpose() * *nrm;
        }
    }
    if let Some(ts) = &mut p.tangents {
        for (t, m) in ts.iter_mut().zip(&blends) {
            let sign = if Mat3::from_mat4(*m).determinant() < 0.0 {
                -t.w
            } else {
                t.w
            };
            *t = (Mat3::from_mat4(*m) * t.truncate()).extend(sign);
        }
    }
    for tri in &mut p.triangles {
        if Mat3::from_mat4(blends[tri[0] as usize]).determinant() < 0.0 {
            tri.swap(1, 2);
        }
    }
}

/// The scene placed at one time: its instances, the skinned and morphed meshes they place (indexed from
/// `Rig::file_meshes` on), the camera and the lights.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed {
    pub instances: Vec<Instance>,
    pub meshes: Vec<Mesh>,
    pub camera: Option<Camera>,
    pub camera_count: usize,
    pub punctual: Vec<PunctualLight>,
    /// The materials as animations set them (KHR_animation_pointer), when any do.
    pub materials: Option<Vec<super::Material>>,
}

/// The scene while the shutter is open: placed again at MOTION_SEGMENTS evenly spaced times after the scene's own
/// (key 0), up to the shutter's closing. Every key places the same instances of the same meshes in the same order;
/// only transforms, deformed vertices and the camera differ. Punctual lights stay where key 0 has them.
#[derive(Clone, Debug, PartialEq)]
pub struct Motion {
    /// Seconds the shutter is open.
    pub shutter: f32,
    pub keys: Vec<Placed>,
}

/// One morph target's displacements of a primitive's vertices (each as long as its positions where present).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTarget {
    pub positions: Option<Vec<Vec3>>,
    pub normals: Option<Vec<Vec3>>,
    pub tangents: Option<Vec<Vec3>>,
}

/// One JOINTS_n / WEIGHTS_n pair: four joints (indices into the skin's joints) and their weights per vertex.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointSet {
    pub joints: Vec<[u16; 4]>,
    pub weights: Vec<Vec4>,
}

/// Every mesh the rig's placed nodes can deform, with how: for `pathwave info`.
pub fn deformation_counts(scene: &Scene) -> (usize, usize) {
    let file = &scene.meshes[..scene.rig.file_meshes.min(scene.meshes.len())];
    let morphed = file
        .iter()
        .filter(|m: &&Mesh| m.primitives.iter().any(|p| !p.morph_targets.is_empty()))
        .count();
    let skinned = file
        .iter()
        .filter(|m: &&Mesh| m.primitives.iter().any(|p| !p.skin.is_empty()))
        .count();
    (morphed, skinned)
}
