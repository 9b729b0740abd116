//! Packs a host Scene into the device layout: BVH-ordered triangles, shading data, materials and the light table.
use super::emission::Emission;
use crate::bvh::lights::{LightBounds, LightTree};
use crate::bvh::{self, Bvh};
use crate::constants::*;
use crate::error::Error;
use crate::layout::{
    GpuInstance, GpuLight, GpuMaterial, GpuPunctual, GpuTexture, MotionKey, TextureSlot, TriColors, TriShading,
    TriTangents, TriTexcoords, TriVerts,
};
use crate::scene::{
    AlphaMode, Camera, Instancing, KeyTriangle, Material, PunctualKind, Scene, TextureRef, TriangleSoup, Wrap,
};

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
        fn dielectric_layer(m: &GpuMaterial) -> bool {
            let textured = |slot: u32| m.textures[slot as usize].u[3].to_bits() != TEXTURE_NONE;
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
        bits
    }
}

fn v4(v: glam::Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

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

fn gpu_material(m: &Material) -> GpuMaterial {
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
            0.0,
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
    }
}

/// The texture table and every image's texels, each image once however many textures share it.
fn pack_textures(scene: &Scene) -> (Vec<GpuTexture>, Vec<u32>) {
    let mut offsets = Vec::with_capacity(scene.images.len());
    let mut texels = Vec::new();
    for image in &scene.images {
        offsets.push(texels.len() as u32);
        texels.extend(image.texels.iter().map(|t| u32::from_le_bytes(*t)));
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
            GpuTexture {
                offset: offsets[t.image],
                width: image.width,
                height: image.height,
                flags: wrap(t.wrap_s)
                    | wrap(t.wrap_t) << TEXTURE_WRAP_T_SHIFT
                    | if t.nearest { TEXTURE_NEAREST } else { 0 },
            }
        })
        .collect();
    (textures, texels)
}

/// A light's entry before the table is made.
struct Emitter {
    /// LIGHT_KIND_* and index, as `GpuLight::id`.
    id: u32,
    /// Estimated power (W).
    power: f64,
    /// A triangle's area (its mean over the shutter when it moves).
    area: f32,
    /// What the light BVH needs of it; None for an infinite light (the environment, a directional light).
    bounds: Option<LightBounds>,
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
    // The BVH builder allocates as it goes, across threads. Reserving its peak once first makes a host that cannot
    // give it an error here; memory that runs out during the build (taken by another process) still aborts.
    if Vec::<u8>::new()
        .try_reserve_exact(soup.len().saturating_mul(BVH_BUILD_BYTES_PER_TRIANGLE))
        .is_err()
    {
        return Err(Error::Scene {
            path: scene.path.clone(),
            message: format!("out of host memory building the BVH of its {} triangles", soup.len()),
        });
    }
    let key_positions: Vec<Vec<[glam::Vec3; 3]>> = (keys.iter().flatten())
        .map(|k| k.iter().map(|t| t.positions).collect())
        .collect();
    let start = std::time::Instant::now();
    let mut bvh = match keys {
        None => bvh::build(soup.positions()),
        Some(_) => {
            let mut all: Vec<&[[glam::Vec3; 3]]> = vec![soup.positions()];
            all.extend(key_positions.iter().map(Vec::as_slice));
            bvh::build_moving(&all)
        }
    };
    let bvh_build = start.elapsed();
    let mut emission = Emission::new(scene);
    let mut t =
        pack_triangles(scene, &soup, keys.as_deref(), &bvh.order, &mut emission).ok_or_else(|| Error::Scene {
            path: scene.path.clone(),
            message: format!("out of host memory packing its {} triangles", soup.len()),
        })?;
    let mut bounds = (!soup.is_empty()).then(|| soup.bounds());
    let (mut instances, mesh_lights, mesh_emitters, meshes) = if instanced.contains(&true) {
        pack_instances(scene, &instanced, &mut bvh, &mut t, &mut bounds, &mut emission).ok_or_else(|| Error::Scene {
            path: scene.path.clone(),
            message: "out of host memory packing its instanced meshes".into(),
        })?
    } else {
        (Vec::new(), Vec::new(), Vec::new(), Vec::new())
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
    let (mut lights, env_prob, total_light_power) = light_table(&emitters, &mut instances);
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
    let (textures, texels) = pack_textures(scene);
    Ok(PackedScene {
        bounds,
        bvh_build,
        bvh,
        tri_verts: t.tri_verts,
        tri_shading: t.tri_shading,
        materials: scene.materials.iter().map(gpu_material).collect(),
        lights,
        light_count,
        total_light_power,
        env_prob,
        light_tree,
        env_prob_tree,
        env_data: scene.environment.as_ref().map(|e| e.device_data()).unwrap_or_default(),
        punctual,
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

/// Every mesh `instanced` marks in its own space, after the world's triangles, with a BVH of its own; a top-level
/// BVH over the instances that place them; and the instance records (the header first). Nodes end up as [world
/// BVH][TLAS][each mesh's BVH], every index offset to its place. Grows `bounds` by the instances' boxes.
///
/// An emissive mesh's triangles get a table of their own (returned; records point into it from 0, so the caller
/// offsets them past light selection's table), picked in proportion to their power in the mesh's space by the power
/// and uniform samplers, and the bounds of its emitters (entries of that table) for the light tree's subtree of the
/// mesh; each of its instances becomes one emitter in `t.emitters`, whose power is the mesh's scaled by the
/// transform's area factor |det|^(2/3). Exact for rotations and uniform scales; under a stretch the pick is a little
/// off the power, which costs variance, not bias: the device divides by the pick's own probability and the
/// triangle's area in the world.
#[allow(clippy::type_complexity)]
fn pack_instances(
    scene: &Scene,
    instanced: &[bool],
    bvh: &mut Bvh,
    t: &mut PackedTriangles,
    bounds: &mut Option<(glam::Vec3, glam::Vec3)>,
    emission: &mut Emission,
) -> Option<(Vec<GpuInstance>, Vec<GpuLight>, Vec<MeshEmitters>, Vec<MeshTriangles>)> {
    use glam::Vec3;
    // Each instanced mesh's BVH and packed triangles, and where they start.
    let mut parts: Vec<(usize, Bvh, PackedTriangles, (Vec3, Vec3))> = Vec::new();
    for (m, _) in instanced.iter().enumerate().filter(|(_, &i)| i) {
        let soup = scene.object_soup(m);
        if soup.is_empty() {
            continue;
        }
        let blas = bvh::build(soup.positions());
        let packed = pack_triangles(scene, &soup, None, &blas.order, emission)?;
        parts.push((m, blas, packed, soup.bounds()));
    }
    let part_of = |m: usize| parts.iter().position(|p| p.0 == m);
    // (part, world from object at each key of the shutter, the instance's index in the scene). One key when the
    // instance does not move; MOTION_SEGMENTS + 1 when it does (the rule made every one invertible).
    let placed: Vec<(usize, Vec<glam::Mat4>, u32)> = (scene.instances.iter().enumerate())
        .filter(|(_, i)| instanced[i.mesh] && crate::scene::invertible(&i.world_from_object))
        .filter_map(|(k, i)| {
            let mut keys = vec![i.world_from_object];
            if let Some(motion) = &scene.motion {
                keys.extend(motion.keys.iter().map(|key| key.instances[k].world_from_object));
                if keys.iter().all(|w| *w == keys[0]) {
                    keys.truncate(1);
                }
            }
            Some((part_of(i.mesh)?, keys, k as u32))
        })
        .collect();
    // Each moving instance's keys as poses (None for a still one, or keys with shear, which the device interpolates
    // as matrices).
    let poses: Vec<Option<Vec<crate::bvh::motion::Pose>>> = (placed.iter())
        .map(|(_, keys, _)| {
            (keys.len() > 1)
                .then(|| crate::bvh::motion::decompose_keys(keys))
                .flatten()
        })
        .collect();
    // A moving instance's box holds its mesh all along its arc (see swept_box); keys interpolated as matrices move
    // each point linearly between its places at the keys, so there the keys' boxes hold it.
    let boxes: Vec<(Vec3, Vec3)> = (placed.iter().zip(&poses))
        .map(|((p, keys, _), poses)| {
            let (lo, hi) = parts[*p].3;
            if let Some(poses) = poses {
                return crate::bvh::motion::swept_box(lo, hi, poses);
            }
            let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
            for (w, corner) in keys
                .iter()
                .flat_map(|w| crate::scene::box_corners(lo, hi).map(|c| (w, c)))
            {
                let q = w.transform_point3(corner);
                b = (b.0.min(q), b.1.max(q));
            }
            b
        })
        .collect();
    for b in &boxes {
        *bounds = Some(bounds.map_or(*b, |(lo, hi)| (lo.min(b.0), hi.max(b.1))));
    }
    let tlas = bvh::build_boxes(&boxes);
    let tlas_root = bvh.nodes.len() as u32;
    // TLAS leaves index instance records, which start at 1 (after the header) in the TLAS's order.
    bvh.nodes.extend(tlas.nodes.iter().map(|n| {
        let mut n = *n;
        n.offset(tlas_root, 1);
        n
    }));
    let colored = !t.tri_colors.is_empty() || parts.iter().any(|p| !p.2.tri_colors.is_empty());
    let white = TriColors {
        c0: [1.0; 4],
        c1: [1.0; 4],
        c2: [1.0; 4],
    };
    if colored && t.tri_colors.is_empty() {
        t.tri_colors = vec![white; t.tri_verts.len()];
    }
    let first_blas_triangle = t.tri_verts.len() as u32;
    let mut roots = Vec::with_capacity(parts.len());
    let mut meshes = Vec::with_capacity(parts.len());
    // Per part: (where its emitter table starts, its length, its power in the mesh's space).
    let mut part_lights = Vec::with_capacity(parts.len());
    let mut mesh_lights: Vec<GpuLight> = Vec::new();
    let mut mesh_emitters = Vec::new();
    for (_, blas, packed, _) in &mut parts {
        let root = bvh.nodes.len() as u32;
        let tri_base = t.tri_verts.len() as u32;
        let power: f64 = packed.emitters.iter().map(|e| e.power).sum();
        let cone = (packed.emitters.iter().filter_map(|e| e.bounds)).reduce(|a, b| a.union(&b));
        part_lights.push((mesh_lights.len() as u32, packed.emitters.len() as u32, power, cone));
        if !packed.emitters.is_empty() {
            let first = mesh_lights.len() as u32;
            let bounds = packed.emitters.iter().enumerate();
            let bounds = bounds.filter_map(|(i, e)| e.bounds.map(|b| (first + i as u32, b)));
            mesh_emitters.push((first, bounds.collect()));
        }
        let (mut acc, mut previous_cdf) = (0.0f64, 0.0f32);
        for (i, e) in packed.emitters.iter().enumerate() {
            let (slot, area) = (e.id, e.area);
            acc += e.power;
            let cdf = if i + 1 == packed.emitters.len() {
                1.0
            } else {
                (acc / power) as f32
            };
            let prob = cdf - previous_cdf;
            previous_cdf = cdf;
            mesh_lights.try_reserve(1).ok()?;
            mesh_lights.push(GpuLight {
                id: LIGHT_KIND_TRIANGLE << LIGHT_KIND_SHIFT | (tri_base + slot),
                cdf,
                prob,
                area,
            });
        }
        bvh.nodes.extend(blas.nodes.iter().map(|n| {
            let mut n = *n;
            n.offset(root, tri_base);
            n
        }));
        roots.push(root);
        let n = packed.tri_verts.len();
        meshes.push(MeshTriangles {
            root,
            first: tri_base,
            count: n as u32,
        });
        t.tri_verts.try_reserve(n).ok()?;
        t.tri_verts.append(&mut packed.tri_verts);
        t.tri_shading.append(&mut packed.tri_shading);
        t.tri_texcoords.append(&mut packed.tri_texcoords);
        t.tri_tangents.append(&mut packed.tri_tangents);
        if colored && packed.tri_colors.is_empty() {
            packed.tri_colors = vec![white; n];
        }
        t.tri_colors.append(&mut packed.tri_colors);
        let s = &blas.stats;
        bvh.stats.max_waiting = bvh.stats.max_waiting.max(s.max_waiting);
        bvh.stats.leaves += s.leaves;
        bvh.stats.max_leaf_tris = bvh.stats.max_leaf_tris.max(s.max_leaf_tris);
    }
    bvh.stats.nodes = bvh.nodes.len();
    let moving = placed.iter().filter(|p| p.1.len() > 1).count();
    let mut records = Vec::new();
    records
        .try_reserve_exact(1 + placed.len() + moving * (MOTION_SEGMENTS as usize + 1))
        .ok()?;
    records.push(GpuInstance {
        info: [tlas_root, placed.len() as u32, first_blas_triangle, 0],
        ..Default::default()
    });
    // The TLAS's leaves in its order, then each moving instance's keys (MOTION_SEGMENTS + 1 records from the one its
    // own record's info.w names).
    let mut later_keys = 1 + placed.len() as u32;
    let mut key_records = Vec::new();
    for &i in &tlas.order {
        let (p, keys, k) = &placed[i as usize];
        let poses = poses[i as usize].as_deref();
        let mirrored = crate::scene::handedness(&keys[0]);
        let moves = keys.len() > 1;
        let first_key = if moves { later_keys } else { 0 };
        later_keys += if moves { keys.len() as u32 } else { 0 };
        let info = [roots[*p], mirrored as u32, *k, first_key];
        let (first_light, light_count, power, cone) = part_lights[*p];
        let light = [first_light, light_count, 0, 0];
        if light_count > 0 {
            let stretch = glam::Mat3::from_mat4(keys[0]).determinant().abs().powf(2.0 / 3.0) as f64;
            t.emitters.try_reserve(1).ok()?;
            t.emitters.push(Emitter {
                id: LIGHT_KIND_INSTANCE << LIGHT_KIND_SHIFT | records.len() as u32,
                power: power * stretch,
                area: 0.0,
                bounds: cone.map(|c| c.transformed(keys, poses, (power * stretch) as f32)),
            });
        }
        records.push(instance_record(&keys[0], info, light));
        if moves {
            // Only a key record's transforms are read (instance_at keeps the instance's own info and light).
            key_records.extend(
                keys.iter()
                    .enumerate()
                    .map(|(j, w)| key_record(w, poses.map(|p| p[j]), info)),
            );
        }
    }
    records.append(&mut key_records);
    Some((records, mesh_lights, mesh_emitters, meshes))
}

/// An instanced mesh's emitters for its light subtree: where its table starts among the instanced meshes' tables,
/// and each emitter's place there with its bounds in the mesh's space.
type MeshEmitters = (u32, Vec<(u32, LightBounds)>);

/// One instance record: `world_from_object` and its inverse as rows, `info` and `light` (see GpuInstance).
fn instance_record(world_from_object: &glam::Mat4, info: [u32; 4], light: [u32; 4]) -> GpuInstance {
    let (w, o) = (world_from_object, world_from_object.inverse());
    GpuInstance {
        world0: w.row(0).to_array(),
        world1: w.row(1).to_array(),
        world2: w.row(2).to_array(),
        object0: o.row(0).to_array(),
        object1: o.row(1).to_array(),
        object2: o.row(2).to_array(),
        info,
        light,
    }
}

/// One key of a moving instance: `world_from_object` as rows (interpolated when the keys do not decompose), and in
/// place of the inverse, which instance_at computes, the key's pose (see GpuInstance).
fn key_record(world_from_object: &glam::Mat4, pose: Option<crate::bvh::motion::Pose>, info: [u32; 4]) -> GpuInstance {
    let w = world_from_object;
    let (object0, object1, object2) = match pose {
        Some(p) => (
            p.translation.extend(1.0).to_array(),
            p.rotation.to_array(),
            p.scale.extend(0.0).to_array(),
        ),
        None => ([0.0; 4], [0.0; 4], [0.0; 4]),
    };
    GpuInstance {
        world0: w.row(0).to_array(),
        world1: w.row(1).to_array(),
        world2: w.row(2).to_array(),
        object0,
        object1,
        object2,
        info,
        light: [0; 4],
    }
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
struct PackedTriangles {
    /// With motion, each triangle's keys after the first (MOTION_SEGMENTS records a triangle).
    motion: Vec<MotionKey>,
    tri_verts: Vec<TriVerts>,
    tri_shading: Vec<TriShading>,
    tri_texcoords: Vec<TriTexcoords>,
    tri_tangents: Vec<TriTangents>,
    tri_colors: Vec<TriColors>,
    emitters: Vec<Emitter>,
}

/// An empty vector with room for `n`, or None when the host cannot give it.
fn try_vec<T>(n: usize) -> Option<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).ok()?;
    Some(v)
}

/// The soup's triangles in `order` (the BVH's): texture coordinates only when some material has a texture,
/// tangents only when some has a normal map, colours only when some mesh has COLOR_0.
fn pack_triangles(
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
            for k in keys {
                let KeyTriangle {
                    positions: [a, b, c],
                    normals: [n0, n1, n2],
                } = k[orig];
                t.motion.push(MotionKey {
                    v0: v4(a, 0.0),
                    e1: v4(b - a, 0.0),
                    e2: v4(c - a, 0.0),
                    n0: v4(n0, 0.0),
                    n1: v4(n1, 0.0),
                    n2: v4(n2, 0.0),
                });
            }
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

/// Punctual lights for the device, and each as an emitter by its emitted power; a directional one by what crosses
/// the disk of the scene's bounding sphere (`radius`).
fn pack_punctual(scene: &Scene, radius: f32, emitters: &mut Vec<Emitter>) -> Vec<GpuPunctual> {
    let mut punctual = Vec::with_capacity(scene.punctual.len());
    for (i, l) in scene.punctual.iter().enumerate() {
        let mean = (l.intensity.x + l.intensity.y + l.intensity.z) as f64 / 3.0;
        let pi = std::f64::consts::PI;
        let (kind, cos_outer, cos_inner, p) = match l.kind {
            PunctualKind::Point => (PUNCTUAL_POINT, -1.0, -1.0, 4.0 * pi * mean),
            PunctualKind::Spot { inner, outer } => {
                let (ci, co) = (inner.cos(), outer.cos());
                (PUNCTUAL_SPOT, co, ci, 2.0 * pi * (1.0 - 0.5 * (ci + co) as f64) * mean)
            }
            PunctualKind::Directional => (PUNCTUAL_DIRECTIONAL, 1.0, 1.0, pi * (radius as f64).powi(2) * mean),
        };
        punctual.push(GpuPunctual {
            position: v4(l.position, f32::from_bits(kind)),
            direction: v4(l.direction, cos_outer),
            intensity: v4(l.intensity, cos_inner),
        });
        if p > 0.0 {
            let bounds = match l.kind {
                PunctualKind::Point => Some(LightBounds::point(l.position, p as f32)),
                PunctualKind::Spot { inner, outer } => {
                    Some(LightBounds::spot(l.position, l.direction, inner, outer, p as f32))
                }
                PunctualKind::Directional => None,
            };
            emitters.push(Emitter {
                id: LIGHT_KIND_PUNCTUAL << LIGHT_KIND_SHIFT | i as u32,
                power: p,
                area: 0.0,
                bounds,
            });
        }
    }
    punctual
}

/// The light table light selection picks from in proportion to power, the environment's probability in it, and
/// the total power; each emissive instance's record learns its entry.
fn light_table(emitters: &[Emitter], instances: &mut [GpuInstance]) -> (Vec<GpuLight>, f32, f64) {
    let total: f64 = emitters.iter().map(|e| e.power).sum();
    let mut lights = Vec::with_capacity(emitters.len());
    let mut acc = 0.0f64;
    let mut env_prob = 0.0;
    let mut previous_cdf = 0.0f32;
    for (i, e) in emitters.iter().enumerate() {
        let (id, area) = (e.id, e.area);
        acc += e.power;
        // The last cdf is exactly 1 so every u in [0, 1) finds a light.
        let cdf = if i + 1 == emitters.len() {
            1.0
        } else {
            (acc / total) as f32
        };
        // The probability the device actually picks with is the gap between stored f32 cdfs, not p / total: for tiny
        // lights late in the table they differ.
        let prob = cdf - previous_cdf;
        previous_cdf = cdf;
        lights.push(GpuLight { id, cdf, prob, area });
        match id >> LIGHT_KIND_SHIFT {
            LIGHT_KIND_ENV => env_prob = prob,
            // Its triangles' density per unit area is its probability times their own within the mesh over their
            // world area, which the device finds at the hit (the instance may stretch or move).
            LIGHT_KIND_INSTANCE => instances[(id & LIGHT_INDEX_MASK) as usize].light[2] = i as u32,
            _ => {}
        }
    }
    (lights, env_prob, total)
}

/// The light BVH over the finite emitters of light selection's table (the first entries of `lights`, one per
/// emitter), with a leaf's place for every entry of `lights` (the instanced meshes' tables too), and the infinite
/// lights' own table, appended to `lights`. The infinite lights keep the share the power table gives them (their
/// estimated power, the environment's through the scene's bounding sphere, over the total) and split it by power;
/// the tree gets the rest. Returns the tree and the environment's probability under it.
fn light_tree(emitters: &[Emitter], lights: &mut Vec<GpuLight>) -> (LightTree, f32) {
    let infinite: Vec<usize> = (0..emitters.len()).filter(|&j| emitters[j].bounds.is_none()).collect();
    let inf_total: f32 = infinite.iter().map(|&j| lights[j].prob).sum();
    let finite: Vec<(u32, LightBounds)> = (emitters.iter().enumerate())
        .filter_map(|(j, e)| e.bounds.map(|b| (j as u32, b)))
        .collect();
    let share = match (finite.is_empty(), infinite.is_empty()) {
        (true, _) => 0.0,
        (false, true) => 1.0,
        (false, false) => (1.0 - inf_total).clamp(0.0, 1.0),
    };
    let first = lights.len() as u32;
    let mut env_prob = 0.0;
    let mut acc = 0.0f32;
    let mut previous_cdf = 0.0f32;
    for (k, &j) in infinite.iter().enumerate() {
        acc += lights[j].prob;
        let cdf = if k + 1 == infinite.len() { 1.0 } else { acc / inf_total };
        // What the device picks with: the tree's complement times the gap between the stored cdfs.
        let prob = (1.0 - share) * (cdf - previous_cdf);
        previous_cdf = cdf;
        if lights[j].id >> LIGHT_KIND_SHIFT == LIGHT_KIND_ENV {
            env_prob = prob;
        }
        lights.push(GpuLight {
            id: lights[j].id,
            cdf,
            prob,
            area: 0.0,
        });
    }
    let tree = bvh::lights::build(finite, first, share, (first, infinite.len() as u32));
    (tree, env_prob)
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
        assert_eq!(features_of("cornell-box.gltf"), 0);
        assert_eq!(
            features_of("glass.gltf"),
            FEATURE_COAT | FEATURE_TRANSMISSION | FEATURE_DEEP_STACK
        );
        assert_eq!(features_of("punctual-lights.gltf") & FEATURE_PUNCTUAL, FEATURE_PUNCTUAL);
        let grid = features_of("material-grid.gltf");
        assert_eq!(grid & (FEATURE_COAT | FEATURE_METAL), FEATURE_COAT | FEATURE_METAL);
    }
}
