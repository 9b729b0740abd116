//! Packs a host Scene into the device layout: the triangles in BVH order with their shading data and motion keys,
//! and the whole (materials.rs, instances.rs and lights.rs pack the rest).
use super::emission::Emission;
use super::instances::{pack_instances, Instanced, MeshEmitters};
use super::lights::{light_table, light_tree, pack_punctual, Emitter};
use super::materials::{gpu_material, pack_textures};
use crate::bvh::lights::{LightBounds, LightTree};
use crate::bvh::{self, Bvh};
use crate::constants::*;
use crate::error::Error;
use crate::layout::{
    GpuInstance, GpuLight, GpuMaterial, GpuPunctual, GpuTexture, MotionKey, TriColors, TriShading, TriTangents,
    TriTexcoords, TriVerts,
};
use crate::scene::{Camera, Instancing, KeyTriangle, Material, Scene, TriangleSoup};

/// Everything the device needs from a scene, in upload order.
pub struct PackedScene {
    /// The placed triangles' bounding box (lo, hi); None when there are none.
    pub bounds: Option<(glam::Vec3, glam::Vec3)>,
    pub bvh: Bvh,
    /// Wall time of the BVH build alone (the rest of packing is copying).
    pub bvh_build: std::time::Duration,
    pub tri_verts: Vec<TriVerts>,
    pub tri_shading: Vec<TriShading>,
    pub materials: Vec<GpuMaterial>,
    /// Light selection's table (its first `light_count` entries), then each emissive instanced mesh's table of its
    /// triangles, which an instance's record points to.
    pub lights: Vec<GpuLight>,
    /// The entries of `lights` light selection picks from.
    pub light_count: u32,
    /// Sum of the lights' estimated power (W), what light selection is proportional to.
    pub total_light_power: f64,
    /// Probability that light selection picks the environment (0 without one).
    pub env_prob: f32,
    /// The light BVH over the table's finite emitters (BINDING_LIGHT_TREE); its infinite lights' table is the last
    /// part of `lights`.
    pub light_tree: LightTree,
    /// Probability that light selection through the tree picks the environment.
    pub env_prob_tree: f32,
    /// The environment's device buffer (see layout.glsl), empty without one.
    pub env_data: Vec<f32>,
    pub punctual: Vec<GpuPunctual>,
    pub textures: Vec<GpuTexture>,
    /// RGBA8 texels of every image, one u32 each (red in the low byte), as `TextureInfo.offset` indexes them.
    pub texels: Vec<u32>,
    /// Empty when no material has a texture (the shaders then never read them).
    pub tri_texcoords: Vec<TriTexcoords>,
    /// Empty when no material has a normal map.
    pub tri_tangents: Vec<TriTangents>,
    /// Empty when no mesh has COLOR_0.
    pub tri_colors: Vec<TriColors>,
    /// The camera's keys and every triangle's keys after the first, in BVH order (see BINDING_MOTION); empty when
    /// nothing moves.
    pub motion: Vec<MotionKey>,
    /// The scene's own camera moves over the shutter (its keys in `motion` are the ones to use).
    pub camera_moves: bool,
    /// The instance records (the header first); empty when no mesh is instanced.
    pub instances: Vec<GpuInstance>,
    /// Each instanced mesh's triangles after the world's: (its BVH's root node, first triangle, count), which an
    /// instance record's info.x names. Ray-query traversal builds one bottom-level structure from each.
    pub meshes: Vec<MeshTriangles>,
}

/// An instanced mesh's place in the packed triangles (see `PackedScene::meshes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MeshTriangles {
    pub root: u32,
    pub first: u32,
    pub count: u32,
}

impl PackedScene {
    /// The FEATURE_* bits of what the scene's materials and lights use, for SCENE_FEATURES: a cleared bit promises
    /// that the value it guards is zero for every material (or that no such light exists).
    pub fn features(&self) -> u32 {
        // Only materials some triangle uses (the loader always adds a default one).
        let mut used = vec![false; self.materials.len()];
        for t in &self.tri_verts {
            if let Some(u) = used.get_mut(t.v0[3].to_bits() as usize) {
                *u = true;
            }
        }
        let any = |f: fn(&GpuMaterial) -> bool| self.materials.iter().zip(&used).any(|(m, &u)| u && f(m));
        let mut bits = 0;
        if any(|m| m.params[3] != 0.0) {
            bits |= FEATURE_COAT;
        }
        if any(|m| m.params[0] != 0.0) {
            bits |= FEATURE_METAL;
        }
        if any(|m| m.transmission[0] != 0.0) {
            bits |= FEATURE_TRANSMISSION;
        }
        if any(|m| m.clearcoat[0] != 0.0) {
            bits |= FEATURE_CLEARCOAT;
        }
        if any(|m| m.sheen[..3].iter().any(|&c| c != 0.0)) {
            bits |= FEATURE_SHEEN;
        }
        if any(|m| m.anisotropy[0] != 0.0) {
            bits |= FEATURE_ANISOTROPY;
        }
        if any(|m| m.iridescence[0] != 0.0) {
            bits |= FEATURE_IRIDESCENCE;
        }
        if any(|m| m.diffuse_transmission[3] != 0.0) {
            bits |= FEATURE_DIFFUSE_TRANSMISSION;
        }
        if any(|m| m.specular_color[3] != 0.0) {
            bits |= FEATURE_DIFFUSE_ROUGHNESS;
        }
        // A scattering medium only matters where a path can enter it: through a volume's transmitting boundary.
        if any(|m| {
            let enterable = m.transmission[1] == 0.0 && (m.transmission[0] != 0.0 || m.diffuse_transmission[3] != 0.0);
            enterable && m.medium[..3].iter().any(|&a| a > 0.0)
        }) {
            bits |= FEATURE_MEDIA;
        }
        // Its diffuse share is the diffuse-transmission lobe's code.
        if any(|m| m.transmission[1] != 0.0 && m.transmission[3] > 0.0 && m.transmission[0] > 0.0) {
            bits |= FEATURE_THIN_SCATTER | FEATURE_DIFFUSE_TRANSMISSION;
        }
        fn dielectric_layer(m: &GpuMaterial) -> bool {
            let textured = |slot: u32| slot_used(m, slot);
            m.params[3] != 0.0
                && (m.params[1] > 0.0 || m.anisotropy[0] != 0.0)
                && (m.params[0] < 1.0 || textured(TEX_METALLIC_ROUGHNESS))
                && (m.transmission[0] < 1.0 || textured(TEX_TRANSMISSION))
        }
        if any(dielectric_layer) {
            bits |= FEATURE_DIELECTRIC_MS;
        }
        if any(|m| m.alpha[3].to_bits() & MATERIAL_UNLIT != 0) {
            bits |= FEATURE_UNLIT;
        }
        if !self.punctual.is_empty() {
            bits |= FEATURE_PUNCTUAL;
        }
        if !self.env_data.is_empty() {
            bits |= FEATURE_ENV;
        }
        if self.bvh.stats.max_waiting > REGISTER_STACK {
            bits |= FEATURE_DEEP_STACK;
        }
        if !self.motion.is_empty() {
            bits |= FEATURE_MOTION;
        }
        if !self.instances.is_empty() {
            bits |= FEATURE_INSTANCES;
        }
        if self.needs_spectrum_table(&used) {
            bits |= FEATURE_SPECTRUM_TABLE;
        }
        bits
    }

    /// Whether spectral transport would meet a colour that only the RGB-to-spectrum table can turn into a spectrum
    /// (FEATURE_SPECTRUM_TABLE): every call of spectrum.glsl's spectrum_reflectance, spectrum_unbounded and
    /// spectrum_illuminant with a colour that is not grey, but for the base colours and emissions whose coefficients
    /// the material holds. A colour missed here renders as a non-finite sample, which the film drops and counts.
    fn needs_spectrum_table(&self, used: &[bool]) -> bool {
        let grey = |c: &[f32]| c[0] == c[1] && c[1] == c[2];
        let colour_textured = |m: &GpuMaterial| super::materials::SRGB_SLOTS.iter().any(|&s| slot_used(m, s));
        let material = |m: &GpuMaterial| {
            let unlit = m.alpha[3].to_bits() & MATERIAL_UNLIT != 0;
            colour_textured(m)
                || (!grey(&m.base_color) && (m.base_color_spectrum[3] == 0.0 || unlit))
                || (!grey(&m.emission) && m.emission_spectrum[3] == 0.0)
                || [
                    &m.specular_color,
                    &m.sheen,
                    &m.diffuse_transmission,
                    &m.attenuation,
                    &m.medium,
                ]
                .iter()
                .any(|c| !grey(&c[..]))
        };
        let materials = self.materials.iter().zip(used).any(|(m, &u)| u && material(m));
        materials
            || !self.tri_colors.is_empty()
            || !self.env_data.is_empty()
            || self.punctual.iter().any(|p| !grey(&p.intensity))
    }
}

/// Whether material `m` has a texture in slot TEX_* `slot` (textures.glsl's slot_used).
fn slot_used(m: &GpuMaterial, slot: u32) -> bool {
    m.textures[slot as usize].u[3].to_bits() != TEXTURE_NONE
}

pub(super) fn v4(v: glam::Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// The BVH build's peak host memory per triangle: boxes, centroids and order (40), the binary nodes (up to two of 32
/// per triangle), the wide nodes and the final order.
const BVH_BUILD_BYTES_PER_TRIANGLE: usize = 160;

/// `try_pack` for scenes known to fit (tests, the benchmark): out of host memory, it panics.
pub fn pack(scene: &Scene) -> PackedScene {
    try_pack(scene).unwrap_or_else(|e| panic!("{e}"))
}

/// The scene packed for the device. The big arrays (the soup, the packed triangles) are reserved fallibly, so a
/// host out of memory is an error naming the scene rather than an abort.
pub fn try_pack(scene: &Scene) -> Result<PackedScene, Error> {
    try_pack_with(scene, Instancing::Auto)
}

/// `try_pack`, instancing the meshes `rule` picks (see `Scene::instanced_meshes`).
pub fn try_pack_with(scene: &Scene, rule: Instancing) -> Result<PackedScene, Error> {
    scene.check_extent()?;
    let instanced = scene.instanced_meshes(rule);
    let (soup, keys) = scene.try_flatten_motion_except(&instanced)?;
    reserve_bvh_build(scene, soup.len())?;
    let key_positions: Vec<Vec<[glam::Vec3; 3]>> = (keys.iter().flatten())
        .map(|k| k.iter().map(|t| t.positions).collect())
        .collect();
    let start = std::time::Instant::now();
    let mut bvh = build_bvh(&soup, keys.is_some(), &key_positions);
    let bvh_build = start.elapsed();
    let mut emission = Emission::new(scene);
    let mut t =
        pack_triangles(scene, &soup, keys.as_deref(), &bvh.order, &mut emission).ok_or_else(|| Error::Scene {
            path: scene.path.clone(),
            message: format!("out of host memory packing its {} triangles", soup.len()),
        })?;
    let mut bounds = (!soup.is_empty()).then(|| soup.bounds());
    let Instanced {
        records: mut instances,
        mesh_lights,
        mesh_emitters,
        meshes,
    } = match instanced.contains(&true) {
        true => pack_instances(scene, &instanced, &mut bvh, &mut t, &mut bounds, &mut emission).ok_or_else(|| {
            Error::Scene {
                path: scene.path.clone(),
                message: "out of host memory packing its instanced meshes".into(),
            }
        })?,
        false => Instanced::default(),
    };
    let bvh_build = if instances.is_empty() {
        bvh_build
    } else {
        start.elapsed()
    };
    for k in &key_positions {
        let (lo, hi) = crate::scene::soup_bounds(k);
        bounds = bounds.map(|(a, b)| (a.min(lo), b.max(hi)));
    }
    let (motion, camera_moves) = match keys.is_some() {
        true => motion_records(scene, std::mem::take(&mut t.motion)),
        false => (Vec::new(), false),
    };
    let packed_lights = pack_lights(scene, bounds, &mut t, &mut instances, mesh_lights, mesh_emitters)?;
    let (textures, texels) = pack_textures(scene);
    Ok(PackedScene {
        bounds,
        bvh_build,
        bvh,
        tri_verts: t.tri_verts,
        tri_shading: t.tri_shading,
        materials: scene.materials.iter().map(gpu_material).collect(),
        lights: packed_lights.lights,
        light_count: packed_lights.light_count,
        total_light_power: packed_lights.total_light_power,
        env_prob: packed_lights.env_prob,
        light_tree: packed_lights.light_tree,
        env_prob_tree: packed_lights.env_prob_tree,
        env_data: scene.environment.as_ref().map(|e| e.device_data()).unwrap_or_default(),
        punctual: packed_lights.punctual,
        textures,
        texels,
        tri_texcoords: t.tri_texcoords,
        tri_tangents: t.tri_tangents,
        tri_colors: t.tri_colors,
        motion,
        camera_moves,
        instances,
        meshes,
    })
}

/// Refuses a soup of `triangles` whose BVH build the host could not give the memory for.
fn reserve_bvh_build(scene: &Scene, triangles: usize) -> Result<(), Error> {
    // The BVH builder allocates as it goes, across threads. Reserving its peak once first makes a host that cannot
    // give it an error here; memory that runs out during the build (taken by another process) still aborts.
    if Vec::<u8>::new()
        .try_reserve_exact(triangles.saturating_mul(BVH_BUILD_BYTES_PER_TRIANGLE))
        .is_err()
    {
        return Err(Error::Scene {
            path: scene.path.clone(),
            message: format!("out of host memory building the BVH of its {triangles} triangles"),
        });
    }
    Ok(())
}

/// The world BVH over the soup's triangles: over their positions alone, or when they are `moving` over those and
/// every later key's (`key_positions`).
fn build_bvh(soup: &TriangleSoup, moving: bool, key_positions: &[Vec<[glam::Vec3; 3]>]) -> Bvh {
    match moving {
        false => bvh::build(soup.positions()),
        true => {
            let mut all: Vec<&[[glam::Vec3; 3]]> = vec![soup.positions()];
            all.extend(key_positions.iter().map(Vec::as_slice));
            bvh::build_moving(&all)
        }
    }
}

/// The scene's lights on the device, as `pack_lights` makes them.
struct PackedLights {
    punctual: Vec<GpuPunctual>,
    lights: Vec<GpuLight>,
    light_count: u32,
    total_light_power: f64,
    env_prob: f32,
    light_tree: LightTree,
    env_prob_tree: f32,
}

/// The punctual lights, light selection's table (the emissive triangles `t` found, the punctual lights and the
/// environment) followed by the instanced meshes' tables, and the light tree over them; points `t`'s emissive
/// triangles and the instance records at their entries. An error when the tables hold more entries than light
/// selection can index.
fn pack_lights(
    scene: &Scene,
    bounds: Option<(glam::Vec3, glam::Vec3)>,
    t: &mut PackedTriangles,
    instances: &mut [GpuInstance],
    mesh_lights: Vec<GpuLight>,
    mesh_emitters: Vec<MeshEmitters>,
) -> Result<PackedLights, Error> {
    let radius = bounds.map_or(1.0, |(lo, hi)| ((hi - lo).length() * 0.5).max(1e-3));
    let mut emitters = std::mem::take(&mut t.emitters);
    let punctual = pack_punctual(scene, radius, &mut emitters);
    // The environment competes with the emitters by the power it sends into the scene's bounding sphere.
    if let Some(env) = &scene.environment {
        let p = env.power(radius);
        if p > 0.0 {
            emitters.push(Emitter {
                id: LIGHT_KIND_ENV << LIGHT_KIND_SHIFT,
                power: p,
                area: 0.0,
                bounds: None,
            });
        }
    }
    let entries = emitters.len() + mesh_lights.len() + emitters.iter().filter(|e| e.bounds.is_none()).count();
    if entries > LIGHT_ENTRIES_MAX as usize {
        return Err(Error::Scene {
            path: scene.path.clone(),
            message: format!("{entries} light entries (emitters and instanced emitters' triangles), more than the {LIGHT_ENTRIES_MAX} light selection can index"),
        });
    }
    let (mut lights, env_prob, total_light_power) = light_table(&emitters, instances);
    let light_count = lights.len() as u32;
    // The instanced meshes' tables follow the one light selection picks from.
    for record in instances.iter_mut().skip(1).filter(|r| r.light[1] > 0) {
        record.light[0] += light_count;
    }
    lights.extend(mesh_lights);
    // Every emissive triangle knows its entry (for MIS): in the table, or in its mesh's.
    for (j, l) in lights.iter().enumerate() {
        if l.id >> LIGHT_KIND_SHIFT == LIGHT_KIND_TRIANGLE {
            t.tri_shading[(l.id & LIGHT_INDEX_MASK) as usize].n0[3] = (j + 1) as f32;
        }
    }
    let (mut light_tree, env_prob_tree) = light_tree(&emitters, &mut lights);
    // Each emissive instanced mesh's subtree, once; its instances' records name its root.
    let mut subtree_of = std::collections::HashMap::new();
    for (first, bounds) in mesh_emitters {
        let entries = bounds.into_iter().map(|(j, b)| (j + light_count, b)).collect();
        subtree_of.insert(first + light_count, light_tree.add_subtree(entries));
    }
    for record in instances.iter_mut().skip(1).filter(|r| r.light[1] > 0) {
        record.light[3] = subtree_of.get(&record.light[0]).copied().unwrap_or(0);
    }
    Ok(PackedLights {
        punctual,
        lights,
        light_count,
        total_light_power,
        env_prob,
        light_tree,
        env_prob_tree,
    })
}

/// The motion buffer: the camera's key records first (zeros when the scene has no camera of its own), then the
/// triangles' keys `pack_triangles` made.
fn motion_records(scene: &Scene, triangles: Vec<MotionKey>) -> (Vec<MotionKey>, bool) {
    let cameras: Vec<Option<Camera>> = std::iter::once(scene.camera)
        .chain(scene.motion.iter().flat_map(|m| m.keys.iter().map(|k| k.camera)))
        .collect();
    let camera_moves = cameras.iter().all(Option::is_some) && cameras.windows(2).any(|w| w[0] != w[1]);
    let mut records = Vec::with_capacity(MOTION_CAMERA_KEYS as usize + triangles.len());
    for c in &cameras {
        records.push(match c {
            Some(c) => {
                let (right, up, forward) = c.basis();
                MotionKey {
                    v0: v4(c.origin(), 0.0),
                    e1: v4(right, 0.0),
                    e2: v4(up, 0.0),
                    n0: v4(forward, 0.0),
                    ..Default::default()
                }
            }
            None => MotionKey::default(),
        });
    }
    records.extend(triangles);
    (records, camera_moves)
}

/// The per-triangle buffers in BVH order, and the emissive triangles.
pub(super) struct PackedTriangles {
    /// With motion, each triangle's keys after the first (MOTION_SEGMENTS records a triangle).
    pub(super) motion: Vec<MotionKey>,
    pub(super) tri_verts: Vec<TriVerts>,
    pub(super) tri_shading: Vec<TriShading>,
    pub(super) tri_texcoords: Vec<TriTexcoords>,
    pub(super) tri_tangents: Vec<TriTangents>,
    pub(super) tri_colors: Vec<TriColors>,
    pub(super) emitters: Vec<Emitter>,
}

/// An empty vector with room for `n`, or None when the host cannot give it.
pub(super) fn try_vec<T>(n: usize) -> Option<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).ok()?;
    Some(v)
}

/// The soup's triangles in `order` (the BVH's): texture coordinates only when some material has a texture,
/// tangents only when some has a normal map, colours only when some mesh has COLOR_0.
pub(super) fn pack_triangles(
    scene: &Scene,
    soup: &TriangleSoup,
    keys: Option<&[Vec<KeyTriangle>]>,
    order: &[u32],
    emission: &mut Emission,
) -> Option<PackedTriangles> {
    let n = soup.len();
    let textured = scene.materials.iter().any(Material::reads_texcoords);
    let normal_mapped = scene.materials.iter().any(|m| m.tangent_set().is_some());
    let mut t = PackedTriangles {
        tri_verts: try_vec(n)?,
        tri_shading: try_vec(n)?,
        tri_texcoords: try_vec(if textured { n } else { 0 })?,
        tri_tangents: try_vec(if normal_mapped { n } else { 0 })?,
        tri_colors: try_vec(soup.colors().len())?,
        emitters: Vec::new(),
        motion: try_vec(keys.map_or(0, |k| k.len() * n))?,
    };
    for (slot, &orig) in order.iter().enumerate() {
        let orig = orig as usize;
        let [a, b, c] = soup.positions()[orig];
        let [na, nb, nc] = soup.normals()[orig];
        let material = soup.material()[orig];
        let instance = soup.instance()[orig];
        let alpha_tested = scene.materials[material as usize].alpha_tested();
        t.tri_verts.push(TriVerts {
            v0: v4(a, f32::from_bits(material)),
            e1: v4(b - a, if alpha_tested { 1.0 } else { 0.0 }),
            e2: v4(c - a, 0.0),
        });
        push_vertex_attributes(&mut t, soup, orig, textured, normal_mapped);
        let mut area = 0.5 * (b - a).cross(c - a).length();
        let mut p = emission.power(soup, orig, area);
        if let Some(keys) = keys {
            // A moving emitter is picked by its mean area over the keys (any area it has at some time), and the
            // device divides by its area at the ray's time.
            let mean = |f: &dyn Fn([glam::Vec3; 3]) -> f32| {
                (f([a, b, c]) + keys.iter().map(|k| f(k[orig].positions)).sum::<f32>()) / (keys.len() + 1) as f32
            };
            let key0 = area;
            area = mean(&|[a, b, c]| 0.5 * (b - a).cross(c - a).length());
            if key0 > 0.0 {
                p *= (area / key0) as f64;
            } else if p == 0.0 && area > 0.0 {
                p = emission.power(soup, orig, area);
            }
            push_motion_keys(&mut t.motion, keys, orig);
        }
        t.tri_shading.push(TriShading {
            n0: v4(na, 0.0),
            n1: v4(nb, area),
            n2: v4(nc, f32::from_bits(instance)),
        });
        if p > 0.0 {
            let mut places = vec![[a, b, c]];
            places.extend(keys.iter().flat_map(|k| k.iter()).map(|k| k[orig].positions));
            let two_sided = scene.materials[material as usize].double_sided;
            t.emitters.push(Emitter {
                id: slot as u32,
                power: p,
                area,
                bounds: LightBounds::triangle(&places, p as f32, two_sided),
            });
        }
    }
    Some(t)
}

/// Appends triangle `orig`'s texture coordinates (when `textured`), tangents (when `normal_mapped`) and colours
/// (when the soup has them) to `t`.
fn push_vertex_attributes(
    t: &mut PackedTriangles,
    soup: &TriangleSoup,
    orig: usize,
    textured: bool,
    normal_mapped: bool,
) {
    if textured {
        let [t0, t1, t2] = soup.texcoords()[orig].map(|t| t.to_array());
        t.tri_texcoords.push(TriTexcoords { t0, t1, t2 });
    }
    if normal_mapped {
        let [t0, t1, t2] = soup.tangents()[orig].map(|t| t.to_array());
        t.tri_tangents.push(TriTangents { t0, t1, t2 });
    }
    if let Some(c) = soup.colors().get(orig) {
        let [c0, c1, c2] = c.map(|v| v.to_array());
        t.tri_colors.push(TriColors { c0, c1, c2 });
    }
}

/// Appends triangle `orig`'s record at each key after the first to `motion`.
fn push_motion_keys(motion: &mut Vec<MotionKey>, keys: &[Vec<KeyTriangle>], orig: usize) {
    for k in keys {
        let KeyTriangle {
            positions: [a, b, c],
            normals: [n0, n1, n2],
        } = k[orig];
        motion.push(MotionKey {
            v0: v4(a, 0.0),
            e1: v4(b - a, 0.0),
            e2: v4(c - a, 0.0),
            n0: v4(n0, 0.0),
            n1: v4(n1, 0.0),
            n2: v4(n2, 0.0),
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn features_of(name: &str) -> u32 {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        pack(&crate::scene::load(&path, None).unwrap()).features()
    }

    // A bit cleared by mistake folds a lobe or light away while the scene uses it; one set by mistake only costs time.
    #[test]
    fn scene_features_name_what_materials_and_lights_use() {
        // Its colours are all untextured material factors, whose spectra the materials hold.
        assert_eq!(features_of("cornell-box.gltf"), 0);
        assert_eq!(
            features_of("glass.gltf") & !FEATURE_SPECTRUM_TABLE,
            FEATURE_COAT | FEATURE_TRANSMISSION | FEATURE_DEEP_STACK
        );
        assert_ne!(features_of("textured.gltf") & FEATURE_SPECTRUM_TABLE, 0);
        assert_eq!(features_of("punctual-lights.gltf") & FEATURE_PUNCTUAL, FEATURE_PUNCTUAL);
        let grid = features_of("material-grid.gltf");
        assert_eq!(grid & (FEATURE_COAT | FEATURE_METAL), FEATURE_COAT | FEATURE_METAL);
    }
}
